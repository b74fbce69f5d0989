#include "treestereo/metrics.hpp"

#include "treestereo/canopy.hpp"
#include "treestereo/errors.hpp"
#include "treestereo/stats.hpp"

#include "mask_near.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>

namespace treestereo {

namespace {

constexpr double kMmToM = 1e-3;

void check_input(const Silhouette &s, const StereoGeometry &g, const MetricsParams &p)
{
  require_valid(g, "the tree's measurements", "compute_tree_metrics");
  if (s.present && !s.mask.empty() && (s.mask.size() != g.view_size || s.mask.type() != CV_8UC1))
    throw BadInput("tree metrics: the silhouette mask must be CV_8U of the view size " +
                             std::to_string(g.view_size.width) + "x" +
                             std::to_string(g.view_size.height));
  if (!(p.support_radius >= 0.0) || !(p.support_radius <= 1.0))
    throw BadSettings("tree metrics: the support radius must be in [0, 1] of the view's "
                             "width, got " + std::to_string(p.support_radius));
  if (p.n_bands < 1 || p.min_band_points < 1 || !(p.tangent_fraction > 0.0) ||
      !(p.tangent_fraction <= 0.5) || p.tangent_min_points < 5 || !(p.near_percentile >= 0.0) ||
      !(p.near_percentile <= 50.0) || !(p.edge_fraction > 0.0) || !(p.edge_fraction <= 0.5) ||
      !(p.band_depth_percentile >= 0.0) || !(p.band_depth_percentile <= 100.0))
    throw BadSettings("tree metrics: parameters out of range (bands >= 1, min band points "
                             ">= 1, near percentile in [0, 50], edge and tangent fraction in (0, "
                             "0.5], tangent min points >= 5, band "
                             "depth percentile in [0, 100])");
}

// A canopy point with where it falls in the left view.
struct CanopyPoint {
  double z_mm;
  double u, v; // left-view pixel
};

std::vector<CanopyPoint> canopy_points(const std::vector<Point3> &points, const cv::Mat &mask,
                                       const StereoGeometry &g, bool in_mask_only)
{
  const double fy = g.fy > 0 ? g.fy : g.fx;
  std::vector<CanopyPoint> out;
  out.reserve(points.size());
  for (const Point3 &p : points) {
    if (!p.valid || !(p.z > 0.0f) || !std::isfinite(p.x) || !std::isfinite(p.y))
      continue;
    const double u = g.fx * p.x / p.z + g.cx[LEFT], v = fy * p.y / p.z + g.cy;
    if (in_mask_only && !on_mask_or_beside(mask, int(std::lround(u)), int(std::lround(v))))
      continue;
    out.push_back({double(p.z), u, v});
  }
  return out;
}

// The silhouette area (pixels) nearest to each point: its Voronoi cell within the mask. Only the
// mask's bounding box `box` is labelled (the points project into it, within a pixel, and clamp
// to it).
std::vector<double> area_weights(const std::vector<CanopyPoint> &pts, const cv::Mat &full_mask,
                                 const cv::Rect &box)
{
  const cv::Mat mask = full_mask(box);
  cv::Mat seeds(mask.size(), CV_8U, cv::Scalar(255));
  std::vector<cv::Point> at(pts.size());
  for (std::size_t i = 0; i < pts.size(); i++) {
    at[i] = cv::Point(std::clamp(int(std::lround(pts[i].u)) - box.x, 0, mask.cols - 1),
                      std::clamp(int(std::lround(pts[i].v)) - box.y, 0, mask.rows - 1));
    seeds.at<uchar>(at[i]) = 0;
  }
  cv::Mat dist, labels;
  cv::distanceTransform(seeds, dist, labels, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
  std::vector<double> area_of_label;
  for (int y = 0; y < mask.rows; y++) {
    const uchar *m = mask.ptr<uchar>(y);
    const int *l = labels.ptr<int>(y);
    for (int x = 0; x < mask.cols; x++) {
      if (!m[x])
        continue;
      if (std::size_t(l[x]) >= area_of_label.size())
        area_of_label.resize(std::size_t(l[x]) + 1, 0.0);
      area_of_label[std::size_t(l[x])] += 1.0;
    }
  }
  // points on the same pixel share its cell
  std::vector<int> sharing(area_of_label.size() + 1, 0);
  std::vector<int> label(pts.size());
  for (std::size_t i = 0; i < pts.size(); i++) {
    label[i] = labels.at<int>(at[i]);
    if (std::size_t(label[i]) >= sharing.size())
      sharing.resize(std::size_t(label[i]) + 1, 0);
    sharing[std::size_t(label[i])]++;
  }
  std::vector<double> w(pts.size(), 0.0);
  for (std::size_t i = 0; i < pts.size(); i++) {
    const std::size_t k = std::size_t(label[i]);
    w[i] = k < area_of_label.size() ? area_of_label[k] / sharing[k] : 0.0;
  }
  return w;
}

std::vector<double> depths_of(const std::vector<CanopyPoint> &pts)
{
  std::vector<double> z(pts.size());
  std::transform(pts.begin(), pts.end(), z.begin(), [](const CanopyPoint &p) { return p.z_mm; });
  return z;
}

// The silhouette's leftmost and rightmost pixel per row (-1 where the row is empty).
struct RowExtents {
  cv::Rect bbox;
  std::vector<int> left, right; // indexed by row - bbox.y
  int xl(int row) const { return left[std::size_t(row - bbox.y)]; }
  int xr(int row) const { return right[std::size_t(row - bbox.y)]; }
};

RowExtents row_extents(const cv::Mat &mask)
{
  RowExtents e;
  e.bbox = cv::boundingRect(mask);
  e.left.assign(std::size_t(e.bbox.height), -1);
  e.right.assign(std::size_t(e.bbox.height), -1);
  const int x0 = e.bbox.x, x1 = e.bbox.x + e.bbox.width; // columns [x0, x1)
  for (int r = 0; r < e.bbox.height; ++r) {
    const uchar *row = mask.ptr<uchar>(e.bbox.y + r);
    // From each end inwards: only the rows' outer gaps are read, not their whole width.
    int xl = x0;
    while (xl < x1 && !row[xl])
      ++xl;
    if (xl == x1)
      continue; // an empty row inside the box (a gap between parts of the silhouette)
    int xr = x1 - 1;
    while (!row[xr])
      --xr;
    e.left[std::size_t(r)] = xl;
    e.right[std::size_t(r)] = xr;
  }
  return e;
}

// Turns image-plane slopes t = (x - cx)/fx (or (y - cy)/fy) into metres, by one of the
// header's models. `round`: signed distance of the plane X = t Z (Y = t Z) from the canopy's
// centre added to the centre; otherwise t * z_ext.
struct Converter {
  bool round = false;
  double z_ext = 0;           // mm: the equivalent conversion depth
  double xc = 0, yc = 0, zc = 0; // mm: the canopy's centre (round) / axis depth
  // kTangentPoints: the depth at each silhouette edge (left, right, top, bottom), linearly
  // interpolated in between; off when `sided` is false.
  bool sided = false;
  double t0x = 0, t1x = 1, z0x = 0, z1x = 0, t0y = 0, t1y = 1, z0y = 0, z1y = 0;
  // How far (mm) the canopy reaches beyond the limb point of each edge (MetricsParams::
  // round_limbs): left, right, top, bottom; added to the extents only (a limb is not a band's
  // edge).
  double beyond[4] = {0, 0, 0, 0};
  double x(double t) const
  {
    if (sided)
      return t * (z0x + (z1x - z0x) * (t - t0x) / (t1x - t0x));
    return round ? xc + (t * zc - xc) / std::hypot(1.0, t) : t * z_ext;
  }
  double y(double t) const
  {
    if (sided)
      return t * (z0y + (z1y - z0y) * (t - t0y) / (t1y - t0y));
    return round ? yc + (t * zc - yc) / std::hypot(1.0, t) : t * z_ext;
  }
};

struct Slopes {
  double left, right, top, bottom; // of the silhouette's outer pixel edges
};

Converter round_canopy(const Slopes &s, double z_near)
{
  const double th_l = std::atan(s.left), th_r = std::atan(s.right);
  const double phi = 0.5 * (th_l + th_r), half = 0.5 * (th_r - th_l);
  const double denom = std::cos(phi) - std::sin(half);
  Converter c;
  c.round = true;
  // denom <= 0 would mean the camera is inside the canopy's tangent cone: no finite solution.
  const double r = denom > 1e-9 ? z_near * std::sin(half) / denom : 0.0;
  c.zc = z_near + r;
  c.xc = c.zc * std::tan(phi);
  c.yc = c.zc * std::tan(0.5 * (std::atan(s.top) + std::atan(s.bottom)));
  const double dt = s.right - s.left;
  c.z_ext = dt > 0 ? (c.x(s.right) - c.x(s.left)) / dt : c.zc;
  return c;
}

// Least-squares line z = a0 + a1 * x, refitted three times on the points within 2.5 robust
// sigmas (1.4826 MAD of the residuals) of the previous line: points seen through gaps in the
// leaves lie behind the surface and must not pull the line. False when degenerate.
bool robust_line_fit(const std::vector<double> &x, const std::vector<double> &z, double &a0,
                     double &a1)
{
  std::vector<char> use(x.size(), 1);
  std::vector<double> res(x.size());
  for (int iter = 0; iter < 4; ++iter) {
    double n = 0, sx = 0, sz = 0, sxx = 0, sxz = 0;
    for (std::size_t i = 0; i < x.size(); ++i)
      if (use[i]) {
        n += 1;
        sx += x[i];
        sz += z[i];
        sxx += x[i] * x[i];
        sxz += x[i] * z[i];
      }
    const double det = n * sxx - sx * sx;
    if (n < 5 || !(std::abs(det) > 1e-12 * n * n))
      return false;
    a1 = (n * sxz - sx * sz) / det;
    a0 = (sz - a1 * sx) / n;
    for (std::size_t i = 0; i < x.size(); ++i)
      res[i] = std::abs(z[i] - a0 - a1 * x[i]);
    std::vector<double> r = res;
    const double sigma = 1.4826 * median(r);
    for (std::size_t i = 0; i < x.size(); ++i)
      use[i] = res[i] <= 2.5 * sigma + 1e-9;
  }
  return std::isfinite(a0) && std::isfinite(a1);
}

// What side_depth() needs of the silhouette's outline, per edge (left, right, top, bottom) and
// per point:
// - inset: the point's distance (px) inside the silhouette's boundary on its row (left, right)
//   or column (top, bottom); -1 when off the silhouette's rows or columns;
// - cap: whether the point lies on the rows or columns of the edge's cap: the run of them about
//   the one that forms the edge along which the boundary keeps falling away from the edge. The
//   run ends where the outline turns back towards the edge by more than kCapTolerance of the
//   extent (at least 2 px): a valley, past which another leaf cluster forms the boundary.
struct EdgeOutline {
  std::array<std::vector<double>, 4> inset;
  std::array<std::vector<char>, 4> cap;
};

constexpr double kCapTolerance = 0.02;

// The run about the most extreme entry of `at` (smaller is more extreme; `valid` false where
// the outline has no boundary) along which it does not come back by more than `tol`.
std::vector<char> cap_run(const std::vector<int> &at, const std::vector<char> &valid, double tol)
{
  std::vector<char> in(at.size(), 0);
  int apex = -1;
  for (int k = 0; k < int(at.size()); ++k)
    if (valid[std::size_t(k)] && (apex < 0 || at[std::size_t(k)] < at[std::size_t(apex)]))
      apex = k;
  if (apex < 0)
    return in;
  in[std::size_t(apex)] = 1;
  for (int dir : {-1, 1}) {
    int farthest = at[std::size_t(apex)];
    for (int k = apex + dir; k >= 0 && k < int(at.size()); k += dir) {
      const std::size_t q = std::size_t(k);
      if (!valid[q] || at[q] < farthest - tol)
        break;
      farthest = std::max(farthest, at[q]);
      in[q] = 1;
    }
  }
  return in;
}

// `rows`: row_extents() of `mask`; the columns come from the transposed bounding box alone.
EdgeOutline edge_outline(const std::vector<CanopyPoint> &pts, const cv::Mat &mask,
                         const RowExtents &rows)
{
  const cv::Rect &b = rows.bbox;
  const cv::Mat mt = mask(b).t();
  const RowExtents cols = row_extents(mt); // in bbox coordinates: column c - b.x, row - b.y
  const auto col_ok = [&](int c) {
    return c >= cols.bbox.y && c < cols.bbox.br().y && cols.xl(c) >= 0;
  };
  // Each edge's boundary as a profile, smaller towards the edge: left and right per row, top
  // and bottom per column.
  const std::size_t nr = std::size_t(b.height), nc = std::size_t(b.width);
  std::array<std::vector<int>, 4> at = {std::vector<int>(nr), std::vector<int>(nr),
                                        std::vector<int>(nc), std::vector<int>(nc)};
  std::vector<char> row_valid(nr), col_valid(nc);
  for (std::size_t r = 0; r < nr; ++r) {
    const int row = b.y + int(r);
    row_valid[r] = rows.xl(row) >= 0;
    at[0][r] = rows.xl(row);
    at[1][r] = -rows.xr(row);
  }
  for (std::size_t c = 0; c < nc; ++c) {
    col_valid[c] = col_ok(int(c));
    if (col_valid[c]) {
      at[2][c] = cols.xl(int(c));
      at[3][c] = -cols.xr(int(c));
    }
  }
  const double tol_x = std::max(2.0, kCapTolerance * b.width);
  const double tol_y = std::max(2.0, kCapTolerance * b.height);
  std::array<std::vector<char>, 4> run;
  for (int side = 0; side < 4; ++side)
    run[std::size_t(side)] = cap_run(at[std::size_t(side)], side < 2 ? row_valid : col_valid,
                                     side < 2 ? tol_x : tol_y);

  EdgeOutline out;
  for (auto &v : out.inset)
    v.assign(pts.size(), -1.0);
  for (auto &v : out.cap)
    v.assign(pts.size(), 0);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const int r = int(std::lround(pts[i].v)), c = int(std::lround(pts[i].u)) - b.x;
    if (r >= b.y && r < b.br().y && rows.xl(r) >= 0) {
      out.inset[0][i] = pts[i].u - (rows.xl(r) - 0.5);
      out.inset[1][i] = rows.xr(r) + 0.5 - pts[i].u;
      out.cap[0][i] = run[0][std::size_t(r - b.y)];
      out.cap[1][i] = run[1][std::size_t(r - b.y)];
    }
    if (c >= 0 && c < b.width && col_ok(c)) {
      out.inset[2][i] = pts[i].v - (b.y + cols.xl(c) - 0.5);
      out.inset[3][i] = b.y + cols.xr(c) + 0.5 - pts[i].v;
      out.cap[2][i] = run[2][std::size_t(c)];
      out.cap[3][i] = run[3][std::size_t(c)];
    }
  }
  return out;
}

// kTangentPoints: the depth where one bounding ray (the silhouette's extreme slope t_edge along
// x or y) touches the canopy, from the points nearest that edge: those within `fraction` of the
// extent from it (the fraction grows by 1.5x until at least `min_points` are in). Near a limb a
// convex surface recedes as the square root of the distance from it (a circle of radius r seen
// at distance d inside its limb is sqrt(2 r d) in front of it), so the depth is fitted as
// z = b0 + b1 sqrt(d) and the limb's depth is b0.
// A crown's outline is made of leaf clusters, each the limb of its own rows or columns, at its
// own depth. The edge's ray touches the cluster that forms the edge, so the fit takes the
// points on that cluster's cap (`outline.cap`, see EdgeOutline), when there are at least
// `min_points` of them, and d is each point's distance inside the silhouette's own boundary
// (`outline.inset`, px, as mm: inset * z / f). Not every point near the edge against its
// distance from the edge's line: a cluster beside the one that forms the edge, whose top is a
// little lower and which stands in front, makes the depth fall steeply away from the line, and
// the extrapolation puts the limb 50-150 mm behind the edge's cluster (heights 2-4 % high in
// the orchard, docs/results.md "The limb's depth from the edge's own cluster").
// A fit that does not recede (b1 >= 0: clusters at several depths on the cap, none showing its
// limb) still puts the boundary's depth at b0, with no rounding beyond it. Not the distance from
// the line instead: over every point near the edge that fit extrapolates far behind the edge
// (the orchard's seed 5, tree 1: its bottom's limb at 2.07-2.28 m where the cap's b0 is
// 2.00-2.04 m and the truth about 2.03 m, +3.5 % in height; docs/results.md "A cap that does
// not recede").
// When the fit fails (too few points), the distance from the line stands in,
// z = a0 + a1 sqrt(distance / extent), limb at a0; when that fails or does not recede either,
// the points' median.
// `clipped`: the edge is the image border, not a limb (the canopy goes on beyond it), so there is
// nothing to extrapolate to: the median of those points converts the border's ray, a depth at
// which that ray is inside the canopy, so the extent stays a lower bound.
// `rho` (mm): the surface's radius of curvature at the limb (MetricsParams::round_limbs),
// rho = b1^2 / 2; 0 when there was no fit.
double side_depth(const std::vector<CanopyPoint> &pts, const StereoGeometry &g, bool vertical,
                  double t_edge, double t_other, double fraction, std::size_t min_points,
                  double fallback, bool clipped, const std::vector<double> &inset,
                  const std::vector<char> &cap, double &rho)
{
  rho = 0;
  const double fy = g.fy > 0 ? g.fy : g.fx;
  const double fpx = vertical ? fy : g.fx;
  std::vector<double> dist(pts.size()); // from the edge, in units of the extent
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const double t = vertical ? (pts[i].v - g.cy) / fy : (pts[i].u - g.cx[LEFT]) / g.fx;
    dist[i] = std::abs(t - t_edge) / std::abs(t_other - t_edge);
  }
  std::size_t on_cap = 0;
  for (std::size_t i = 0; i < pts.size(); ++i)
    on_cap += cap[i] && dist[i] <= fraction;
  const bool cap_only = on_cap >= min_points;
  for (double f = fraction; f <= 0.5; f *= 1.5) {
    std::vector<double> z, r;
    for (std::size_t i = 0; i < pts.size(); ++i)
      if (dist[i] <= f && (cap[i] || !cap_only)) {
        z.push_back(pts[i].z_mm);
        r.push_back(std::sqrt(dist[i]));
      }
    if (z.size() < min_points)
      continue;
    if (clipped)
      return median(z);
    std::vector<double> sq, zz;
    for (std::size_t i = 0; i < pts.size(); ++i)
      if (dist[i] <= f && (cap[i] || !cap_only) && inset[i] >= 0) {
        sq.push_back(std::sqrt(inset[i] * pts[i].z_mm / fpx));
        zz.push_back(pts[i].z_mm);
      }
    double b0 = 0, b1 = 0;
    if (zz.size() >= min_points && robust_line_fit(sq, zz, b0, b1)) {
      rho = b1 < 0 ? 0.5 * b1 * b1 : 0.0;
      return b0;
    }
    double a0 = 0, a1 = 0;
    if (!robust_line_fit(r, z, a0, a1) || !(a1 <= 0))
      return median(z);
    return a0;
  }
  return fallback;
}

Converter tangent_points(const std::vector<CanopyPoint> &pts, const Slopes &s,
                         const StereoGeometry &g, double fraction, std::size_t min_points,
                         double fallback, const Clipped &clip, bool round_limbs,
                         const cv::Mat &mask, const RowExtents &rows)
{
  const EdgeOutline o = edge_outline(pts, mask, rows);
  Converter c;
  c.sided = true;
  c.t0x = s.left;
  c.t1x = s.right;
  c.t0y = s.top;
  c.t1y = s.bottom;
  double rho[4];
  c.z0x = side_depth(pts, g, false, s.left, s.right, fraction, min_points, fallback, clip.left,
                     o.inset[0], o.cap[0], rho[0]);
  c.z1x = side_depth(pts, g, false, s.right, s.left, fraction, min_points, fallback, clip.right,
                     o.inset[1], o.cap[1], rho[1]);
  c.z0y = side_depth(pts, g, true, s.top, s.bottom, fraction, min_points, fallback, clip.top,
                     o.inset[2], o.cap[2], rho[2]);
  c.z1y = side_depth(pts, g, true, s.bottom, s.top, fraction, min_points, fallback,
                     clip.bottom, o.inset[3], o.cap[3], rho[3]);
  const double dt = s.right - s.left;
  c.z_ext = dt > 0 ? (c.x(s.right) - c.x(s.left)) / dt : fallback;
  c.zc = c.z_ext;
  if (round_limbs) {
    // The extreme of a rounded limb is rho * (1 - cos(ray angle)) beyond the limb point; rho
    // no more than half the extent (a fit that implies more is not a rounded limb).
    const double half_w = 0.5 * std::max(0.0, c.x(s.right) - c.x(s.left));
    const double half_h = 0.5 * std::max(0.0, c.y(s.bottom) - c.y(s.top));
    const double t[4] = {s.left, s.right, s.top, s.bottom};
    for (int i = 0; i < 4; ++i)
      c.beyond[i] = std::min(rho[i], i < 2 ? half_w : half_h) * (1.0 - 1.0 / std::hypot(1.0, t[i]));
  }
  return c;
}

// Median depth of the points in the outer edge_fraction of their row's extent.
double edge_depth(const std::vector<CanopyPoint> &pts, const RowExtents &e, double fraction,
                  double fallback)
{
  std::vector<double> z;
  for (const CanopyPoint &p : pts) {
    const int row = std::clamp(int(std::lround(p.v)), e.bbox.y, e.bbox.y + e.bbox.height - 1);
    if (e.xl(row) < 0)
      continue;
    const double w = e.xr(row) - e.xl(row) + 1;
    if (p.u <= e.xl(row) - 0.5 + fraction * w || p.u >= e.xr(row) + 0.5 - fraction * w)
      z.push_back(p.z_mm);
  }
  return z.empty() ? fallback : median(z);
}

Converter choose_converter(const MetricsParams &p, const Slopes &s, const Summary &depth,
                           std::vector<double> z, const std::vector<CanopyPoint> &pts,
                           const RowExtents &e, const StereoGeometry &g, const Clipped &clip,
                           const cv::Mat &mask)
{
  Converter c;
  const double mid = depth.median + 0.5 * (depth.p95 - depth.p05);
  switch (p.extent_depth) {
  case ExtentDepth::kRoundCanopy: return round_canopy(s, percentile(z, p.near_percentile));
  case ExtentDepth::kTangentPoints:
    return tangent_points(pts, s, g, p.tangent_fraction, std::size_t(p.tangent_min_points), mid,
                          clip, p.round_limbs, mask, e);
  case ExtentDepth::kEdgePoints: c.z_ext = edge_depth(pts, e, p.edge_fraction, mid); break;
  case ExtentDepth::kMidDepth: c.z_ext = mid; break;
  case ExtentDepth::kFrontFace: c.z_ext = depth.median; break;
  }
  c.zc = c.z_ext;
  return c;
}

void fill_missing_band_depths(std::vector<Band> &bands, double canopy_near_m)
{
  const int n = int(bands.size());
  bool any = false;
  for (const Band &b : bands)
    any = any || b.depth_measured;
  for (int i = 0; i < n; ++i) {
    Band &b = bands[std::size_t(i)];
    if (!b.present || b.depth_measured)
      continue;
    if (!any) {
      b.depth_m = canopy_near_m;
      continue;
    }
    int above = i - 1, below = i + 1;
    while (above >= 0 && !bands[std::size_t(above)].depth_measured)
      --above;
    while (below < n && !bands[std::size_t(below)].depth_measured)
      ++below;
    if (above >= 0 && below < n) {
      const double w = double(i - above) / double(below - above);
      b.depth_m = (1 - w) * bands[std::size_t(above)].depth_m + w * bands[std::size_t(below)].depth_m;
    } else {
      b.depth_m = bands[std::size_t(above >= 0 ? above : below)].depth_m;
    }
  }
}

std::vector<Band> compute_bands(const MetricsParams &p, const RowExtents &e,
                                const std::vector<CanopyPoint> &pts, const Converter &c,
                                const StereoGeometry &g, double canopy_near_m, const cv::Mat &mask,
                                const std::vector<double> &weights)
{
  const double fy = g.fy > 0 ? g.fy : g.fx;
  const int n = p.n_bands;
  const double top = e.bbox.y - 0.5, step = double(e.bbox.height) / n;
  std::vector<Band> bands(static_cast<std::size_t>(n));
  std::vector<std::vector<double>> band_z(static_cast<std::size_t>(n)), band_w(band_z.size());
  for (std::size_t k = 0; k < pts.size(); ++k) {
    const int i = std::clamp(int(std::floor((pts[k].v - top) / step)), 0, n - 1);
    band_z[std::size_t(i)].push_back(pts[k].z_mm);
    if (!weights.empty())
      band_w[std::size_t(i)].push_back(weights[k]);
  }
  for (int i = 0; i < n; ++i) {
    Band &b = bands[std::size_t(i)];
    const double y0 = top + i * step, y1 = top + (i + 1) * step;
    const cv::Range rows = band_rows(e.bbox, n, i);
    int xl = -1, xr = -1;
    for (int row = rows.start; row < rows.end; ++row) {
      if (e.xl(row) < 0)
        continue;
      xl = xl < 0 ? e.xl(row) : std::min(xl, e.xl(row));
      xr = std::max(xr, e.xr(row));
    }
    b.n_points = band_z[std::size_t(i)].size();
    if (xl < 0)
      continue; // a gap in the canopy: not present, all zero
    b.present = true;
    b.top_m = c.y((y0 - g.cy) / fy) * kMmToM;
    b.bottom_m = c.y((y1 - g.cy) / fy) * kMmToM;
    b.left_m = c.x((xl - 0.5 - g.cx[LEFT]) / g.fx) * kMmToM;
    b.right_m = c.x((xr + 0.5 - g.cx[LEFT]) / g.fx) * kMmToM;
    b.width_m = b.right_m - b.left_m;
    b.fill = band_fill(mask, rows.start, rows.end);
    if (int(b.n_points) >= p.min_band_points) {
      const auto &bz = band_z[std::size_t(i)];
      b.depth_m = (weights.empty() ? percentile(band_z[std::size_t(i)], p.band_depth_percentile)
                                   : weighted_percentiles(bz, band_w[std::size_t(i)],
                                                          {p.band_depth_percentile})[0]) *
                  kMmToM;
      b.depth_measured = true;
    }
  }
  fill_missing_band_depths(bands, canopy_near_m);
  return bands;
}

// MetricsParams::extreme_points: moves each unclipped edge (mm: left/right X, top/bottom Y) out to
// the n-th most extreme point's X (Y) when that lies beyond it.
void reach_extreme_points(const std::vector<CanopyPoint> &pts, const StereoGeometry &g,
                          std::size_t n, const Clipped &clip, double &left, double &right,
                          double &top, double &bottom)
{
  const double fy = g.fy > 0 ? g.fy : g.fx;
  std::vector<double> x(pts.size()), y(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    x[i] = (pts[i].u - g.cx[LEFT]) / g.fx * pts[i].z_mm;
    y[i] = (pts[i].v - g.cy) / fy * pts[i].z_mm;
  }
  const auto nth = [n](std::vector<double> &v, bool lowest) {
    const auto it = v.begin() + std::ptrdiff_t(n - 1);
    if (lowest)
      std::nth_element(v.begin(), it, v.end());
    else
      std::nth_element(v.begin(), it, v.end(), std::greater<double>());
    return *it;
  };
  if (!clip.left)
    left = std::min(left, nth(x, true));
  if (!clip.right)
    right = std::max(right, nth(x, false));
  if (!clip.top)
    top = std::min(top, nth(y, true));
  if (!clip.bottom)
    bottom = std::max(bottom, nth(y, false));
}

} // namespace

TreeMetrics compute_tree_metrics(const Silhouette &left, const std::vector<Point3> &points,
                                 const StereoGeometry &g, const MetricsParams &p)
{
  check_input(left, g, p);
  TreeMetrics m;
  if (!left.present || left.mask.empty() || cv::countNonZero(left.mask) == 0)
    return m;
  const std::vector<CanopyPoint> pts = canopy_points(points, left.mask, g, p.points_in_mask_only);
  if (pts.empty())
    return m;

  const double fy = g.fy > 0 ? g.fy : g.fx;
  const RowExtents e = row_extents(left.mask);
  const Slopes s{(e.bbox.x - 0.5 - g.cx[LEFT]) / g.fx, (e.bbox.br().x - 0.5 - g.cx[LEFT]) / g.fx,
                 (e.bbox.y - 0.5 - g.cy) / fy, (e.bbox.br().y - 0.5 - g.cy) / fy};
  std::vector<double> z = depths_of(pts);
  const Summary depth = summarize(z);
  const cv::Size vs = g.view_size;
  m.clipped.top = e.bbox.y == 0;
  m.clipped.left = e.bbox.x == 0;
  m.clipped.bottom = e.bbox.br().y == vs.height;
  m.clipped.right = e.bbox.br().x == vs.width;
  const Converter c = choose_converter(p, s, depth, z, pts, e, g, m.clipped, left.mask);

  m.tree_present = true;
  m.points = pts.size();
  m.matches = points.size();
  std::vector<double> w;
  if (p.area_weighted) {
    w = area_weights(pts, left.mask, e.bbox);
    const std::vector<double> q = weighted_percentiles(z, w, {50.0, 5.0, 95.0});
    m.distance_m = q[0] * kMmToM;
    m.thickness_m = (q[2] - q[1]) * kMmToM;
  } else {
    m.distance_m = depth.median * kMmToM;
    m.thickness_m = (depth.p95 - depth.p05) * kMmToM;
  }
  m.extent_depth_m = c.z_ext * kMmToM;
  // The extent's edges (mm): the silhouette's, each past its limb by what round_limbs adds.
  double x_left = c.x(s.left) - c.beyond[0], x_right = c.x(s.right) + c.beyond[1];
  double y_top = c.y(s.top) - c.beyond[2], y_bottom = c.y(s.bottom) + c.beyond[3];
  if (p.extreme_points > 0 && pts.size() >= std::size_t(p.extreme_points))
    reach_extreme_points(pts, g, std::size_t(p.extreme_points), m.clipped, x_left, x_right,
                         y_top, y_bottom);
  m.width_m = (x_right - x_left) * kMmToM;
  m.left_m = x_left * kMmToM;
  m.right_m = x_right * kMmToM;
  m.left_slope = s.left;
  m.right_slope = s.right;
  m.height_m = (y_bottom - y_top) * kMmToM;

  // Area and perimeter at the equivalent depth, so that area ~ width * height for a box.
  const double area_px = left.area_px > 0 ? left.area_px : double(cv::countNonZero(left.mask));
  double perim_px = left.perimeter_px;
  if (!(perim_px > 0)) {
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(left.mask.clone(), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
    for (const auto &ct : contours)
      perim_px += cv::arcLength(ct, true);
  }
  const double mpp_x = c.z_ext / g.fx * kMmToM, mpp_y = c.z_ext / fy * kMmToM;
  m.area_m2 = area_px * mpp_x * mpp_y;
  m.perimeter_m = perim_px * std::sqrt(mpp_x * mpp_y);
  m.complexity = m.area_m2 > 0 ? m.perimeter_m * m.perimeter_m / (4.0 * CV_PI * m.area_m2) : 0.0;

  if (c.round) {
    m.centroid_m = cv::Point3d(c.xc, c.yc, c.zc) * kMmToM;
  } else {
    // Over the bounding box alone: the rest of the view holds no silhouette.
    const cv::Moments mo = cv::moments(left.mask(e.bbox), true);
    const double tcx = (mo.m10 / mo.m00 + e.bbox.x - g.cx[LEFT]) / g.fx,
                 tcy = (mo.m01 / mo.m00 + e.bbox.y - g.cy) / fy;
    m.centroid_m = cv::Point3d(tcx * c.z_ext, tcy * c.z_ext, c.z_ext) * kMmToM;
  }

  std::vector<double> zb = z;
  const double near_m = percentile(zb, p.band_depth_percentile) * kMmToM;
  m.bands = compute_bands(p, e, pts, c, g, near_m, left.mask, w);

  std::vector<cv::Point2f> px(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i)
    px[i] = cv::Point2f(float(pts[i].u), float(pts[i].v));
  m.confidence = depth_support(left.mask, px, p.support_radius * vs.width);
  return m;
}

cv::Range band_rows(const cv::Rect &bbox, int n_bands, int band)
{
  const double top = bbox.y - 0.5, step = double(bbox.height) / n_bands;
  // rows with ceil(y0) <= row < y1, i.e. row < ceil(y1), inside the box
  const int start = std::max(bbox.y, int(std::ceil(top + band * step)));
  const int end = std::min(bbox.br().y, int(std::ceil(top + (band + 1) * step)));
  return cv::Range(start, std::max(start, end));
}

double band_fill(const cv::Mat &mask, int row0, int row1, int *left, int *right)
{
  CV_Assert(mask.type() == CV_8UC1);
  if (left)
    *left = -1;
  if (right)
    *right = -1;
  row0 = std::max(row0, 0);
  row1 = std::min(row1, mask.rows);
  if (row0 >= row1 || mask.cols == 0)
    return 0.0;
  cv::Mat any; // 1 x cols: non-zero where a column has canopy in one of the rows
  cv::reduce(mask.rowRange(row0, row1), any, 0, cv::REDUCE_MAX);
  const uchar *a = any.ptr<uchar>(0);
  int xl = 0, xr = mask.cols - 1;
  while (xl < mask.cols && !a[xl])
    ++xl;
  if (xl == mask.cols)
    return 0.0;
  while (!a[xr])
    --xr;
  int covered = 0;
  for (int x = xl; x <= xr; ++x)
    covered += a[x] ? 1 : 0;
  if (left)
    *left = xl;
  if (right)
    *right = xr;
  return double(covered) / double(xr - xl + 1);
}

// ---- MetricsSmoother ----

MetricsSmoother::MetricsSmoother(double alpha) : alpha_(alpha)
{
  if (!(alpha >= 0.0) || !(alpha < 1.0))
    throw BadSettings("metrics smoothing alpha must be in [0, 1), got " +
                             std::to_string(alpha));
}

TreeMetrics MetricsSmoother::update(const TreeMetrics &cur)
{
  if (!cur.tree_present || alpha_ == 0.0 || !has_state_ ||
      state_.bands.size() != cur.bands.size()) {
    has_state_ = cur.tree_present && alpha_ > 0.0;
    state_ = cur;
    return cur;
  }
  const double a = alpha_;
  auto mix = [a](double prev, double now) { return a * prev + (1.0 - a) * now; };
  TreeMetrics out = cur;
  out.distance_m = mix(state_.distance_m, cur.distance_m);
  out.height_m = mix(state_.height_m, cur.height_m);
  out.width_m = mix(state_.width_m, cur.width_m);
  out.thickness_m = mix(state_.thickness_m, cur.thickness_m);
  out.area_m2 = mix(state_.area_m2, cur.area_m2);
  out.perimeter_m = mix(state_.perimeter_m, cur.perimeter_m);
  out.complexity = mix(state_.complexity, cur.complexity);
  out.extent_depth_m = mix(state_.extent_depth_m, cur.extent_depth_m);
  out.centroid_m = a * state_.centroid_m + (1.0 - a) * cur.centroid_m;
  out.confidence = mix(state_.confidence, cur.confidence);
  for (std::size_t i = 0; i < out.bands.size(); ++i) {
    const Band &prev = state_.bands[i];
    Band &b = out.bands[i];
    if (!prev.present || !b.present)
      continue; // a band that appears or vanishes takes the current frame's values
    b.top_m = mix(prev.top_m, b.top_m);
    b.bottom_m = mix(prev.bottom_m, b.bottom_m);
    b.left_m = mix(prev.left_m, b.left_m);
    b.right_m = mix(prev.right_m, b.right_m);
    b.width_m = b.right_m - b.left_m;
    b.depth_m = mix(prev.depth_m, b.depth_m);
    b.fill = mix(prev.fill, b.fill);
  }
  state_ = out;
  return out;
}

} // namespace treestereo
