#include "treestereo/rowmap.hpp"

#include "treestereo/errors.hpp"
#include "treestereo/stats.hpp"

#include "mask_near.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

namespace treestereo {

namespace {

constexpr double kMmToM = 1e-3;
constexpr double kDeg = 3.14159265358979323846 / 180.0;
// A cell under min_fill continues a present neighbour's canopy when both reach their common edge
// within this share of a bin, and its canopy reaches further into it than that.
constexpr double kTouchBins = 0.2;
// A cell the nearest frame reads empty is present when at least this many frames whose span
// holds its bin, and that see the bin's centre within kVoteSlope of the optical axis, saw it
// present (add_frame). Within that slope a pixel placed 100 mm off in depth moves 10 mm along
// the row, a fifth of a bin; farther out a frame's canopy edges land in the bins beside theirs
// (the depth of a strip of columns is one depth).
constexpr int kVotes = 2;
constexpr double kVoteSlope = 0.1;
// Canopy rows a crown's cap needs in a band, rising into it from the band below, to be present
// there whatever its fill (RowMap::add_frame).
constexpr int kCrossRows = 3;
// Strips without points take the depth of the nearest strip with points within this many
// strips; farther out, the canopy's median depth.
constexpr int kStripReach = 6;
// Rows of a depth block: a strip's points are split into blocks of this many strips' widths
// down the view (see add_frame).
constexpr int kBlockStrips = 4;
// Points a block needs to speak for its pixels' depth.
constexpr std::size_t kBlockMinPoints = 3;

// at(s) if it is set (> 0), else the nearest set value within kStripReach of s (the lower side
// first at equal distance), else -1. `at` reads position 0..n-1.
template <class At> double nearest_set(int s, int n, At at)
{
  double z = at(s);
  for (int d = 1; z < 0 && d <= kStripReach; ++d) {
    if (s - d >= 0 && at(s - d) > 0)
      z = at(s - d);
    else if (s + d < n && at(s + d) > 0)
      z = at(s + d);
  }
  return z;
}

// A block's depth as a line down the view, z = z0 + dz_dv * (v - v0), fitted (least squares) to
// the points around it; within the block it is held to their depths' range.
struct BlockFit {
  double v0 = 0, z0 = -1, dz_dv = 0, z_lo = 0, z_hi = 0;
  bool valid() const { return z0 > 0; }
  double at(double v) const { return std::clamp(z0 + dz_dv * (v - v0), z_lo, z_hi); }
};

BlockFit fit_block(const std::vector<cv::Point2d> &vz)
{
  BlockFit f;
  double sv = 0, sz = 0;
  for (const cv::Point2d &p : vz) {
    sv += p.x;
    sz += p.y;
  }
  f.v0 = sv / double(vz.size());
  f.z0 = sz / double(vz.size());
  double svv = 0, svz = 0;
  f.z_lo = f.z_hi = vz.front().y;
  for (const cv::Point2d &p : vz) {
    svv += (p.x - f.v0) * (p.x - f.v0);
    svz += (p.x - f.v0) * (p.y - f.z0);
    f.z_lo = std::min(f.z_lo, p.y);
    f.z_hi = std::max(f.z_hi, p.y);
  }
  f.dz_dv = svv > 0 ? svz / svv : 0;
  return f;
}

// A round crown's section in a column of the view, beyond its outermost points (above the top
// ones or below the bottom ones): a circle in the column's plane (camera y, z) tangent to the
// outermost block's fit at its points' centroid and to the silhouette's bounding ray, so the
// surface recedes towards the limb as a round crown's does, to about the crown's middle depth at
// the limb. A fit that comes nearer towards the limb is taken as flat there; the circle's radius
// is at most half the column's canopy chord (a sphere's section is a circle of that radius), and
// depths lie from the fit's at the centroid to that much deeper.
class LimbArc {
public:
  LimbArc() = default;
  // `fit`: the outermost block's; `t_rim`: the silhouette's bounding ray ((v - cy) / fy at the
  // silhouette's outer pixel edge); `chord_px`: the column's canopy rows from top to bottom.
  LimbArc(const BlockFit &fit, double t_rim, double chord_px, double fy, double cy)
  {
    const double z0 = fit.z0, t0 = (fit.v0 - cy) / fy;
    if (!fit.valid() || t_rim == t0)
      return;
    const bool top = t_rim < t0;
    // Receding towards the limb: z rises as v falls (top) or rises (bottom).
    const double b = top ? std::min(fit.dz_dv, 0.0) : std::max(fit.dz_dv, 0.0);
    // The fit's normal in (Y, z), Y = t z: the tangent per row is (z0 / fy + t0 b, b).
    double nY = -b, nz = z0 / fy + t0 * b;
    if (nz < 0) {
      nY = -nY;
      nz = -nz;
    }
    const double n = std::hypot(nY, nz);
    nY /= n;
    nz /= n;
    // Centre c = P0 + r n at distance r from the ray Y = t_rim z, on P0's side of it.
    const double a = (t0 - t_rim) * z0, k = std::hypot(1.0, t_rim), bk = nY - t_rim * nz;
    const double den = k - (a > 0 ? bk : -bk);
    const double max_r = 0.5 * chord_px * z0 / fy;
    r_ = den > 0 ? std::min(std::abs(a) / den, max_r) : max_r;
    cY_ = t0 * z0 + r_ * nY;
    cz_ = z0 + r_ * nz;
    z_lo_ = z0;
    z_hi_ = z0 + max_r;
  }
  bool valid() const { return r_ > 0; }
  // The depth where the ray of slope t (= (v - cy) / fy) meets the circle (the point nearest it
  // when it passes outside).
  double depth(double t) const
  {
    const double p = t * cY_ + cz_, q = 1 + t * t;
    const double disc = p * p - q * (cY_ * cY_ + cz_ * cz_ - r_ * r_);
    const double z = disc > 0 ? (p - std::sqrt(disc)) / q : p / q;
    return std::clamp(z, z_lo_, z_hi_);
  }

private:
  double cY_ = 0, cz_ = 0, r_ = 0, z_lo_ = 0, z_hi_ = 0;
};

void require(bool ok, const char *field, const char *range)
{
  if (!ok)
    throw BadSettings(std::string("row map parameter ") + field + " out of range: " + range);
}

std::string fixed(double v, int digits)
{
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

} // namespace

void validate(const RowMapParams &p)
{
  require(std::isfinite(p.bin_mm) && p.bin_mm >= 5 && p.bin_mm <= 2000, "bin_mm", "5 to 2000 mm");
  if (p.band_edges_mm.empty()) {
    require(p.n_bands >= 1 && p.n_bands <= 100, "n_bands", "1 to 100");
    require(std::isfinite(p.min_height_mm) && p.min_height_mm >= -1000, "min_height_mm",
            "finite, at least -1000 mm");
    require(std::isfinite(p.max_height_mm) && p.max_height_mm > p.min_height_mm &&
                p.max_height_mm <= 20000,
            "max_height_mm", "above min_height_mm, at most 20000 mm");
  } else {
    require(p.band_edges_mm.size() >= 2 && p.band_edges_mm.size() <= 101, "band_edges_mm",
            "2 to 101 edges");
    for (std::size_t i = 0; i < p.band_edges_mm.size(); ++i) {
      require(std::isfinite(p.band_edges_mm[i]) && p.band_edges_mm[i] >= -1000 &&
                  p.band_edges_mm[i] <= 20000,
              "band_edges_mm", "finite, -1000 to 20000 mm");
      require(i == 0 || p.band_edges_mm[i] > p.band_edges_mm[i - 1], "band_edges_mm",
              "strictly ascending");
    }
  }
  require(p.min_fill >= 0 && p.min_fill <= 1, "min_fill", "0 to 1");
  require(p.strip_px >= 1 && p.strip_px <= 256, "strip_px", "1 to 256 px");
}

GroundPlane rig_ground(const StereoGeometry &g, double camera_height_mm, double pitch_deg)
{
  if (!(camera_height_mm > 0) || !std::isfinite(camera_height_mm))
    throw BadSettings("rig_ground: camera_height_mm must be above 0");
  if (!(std::abs(pitch_deg) <= 80))
    throw BadSettings("rig_ground: pitch_deg must be -80 to 80 degrees");
  GroundPlane p;
  const cv::Vec3d up_cam(0, -std::cos(pitch_deg * kDeg), -std::sin(pitch_deg * kDeg));
  p.normal = g.R1 * up_cam;
  p.d = camera_height_mm;
  p.found = true;
  return p;
}

RowMap::RowMap(const RowMapParams &params) : params_(params)
{
  validate(params_);
  if (!params_.band_edges_mm.empty()) {
    edges_ = params_.band_edges_mm;
  } else {
    for (int k = 0; k <= params_.n_bands; ++k)
      edges_.push_back(params_.min_height_mm +
                       (params_.max_height_mm - params_.min_height_mm) * k / params_.n_bands);
  }
}

long RowMap::first_bin() const
{
  return bins_.empty() ? 0 : bins_.begin()->first;
}

long RowMap::last_bin() const
{
  return bins_.empty() ? -1 : bins_.rbegin()->first;
}

RowMapCell RowMap::cell(long bin, int band) const
{
  const auto own = [&](long b) -> std::optional<RowMapCell> {
    const auto it = bins_.find(b);
    return it == bins_.end() ? std::nullopt : std::optional<RowMapCell>(it->second.cell(band));
  };
  if (band < 0 || band >= n_bands())
    return RowMapCell();
  const std::optional<RowMapCell> c = own(bin);
  if (!c)
    return RowMapCell();
  RowMapCell out = *c;
  if (out.present || !(out.fill > 0))
    return out;
  // Canopy under min_fill is present where it goes on into a present neighbour across their
  // common edge: the end of a cap that enters the band with a sliver.
  const double bin_m = params_.bin_mm * kMmToM, tol = kTouchBins * bin_m;
  const double lo_edge = double(bin) * bin_m, hi_edge = lo_edge + bin_m;
  const std::optional<RowMapCell> left = own(bin - 1), right = own(bin + 1);
  // (reaching more than the tolerance into the cell: a pixel's spill across the edge is not it)
  out.present =
      out.hi_m - out.lo_m > tol &&
      ((left && left->present && out.lo_m <= lo_edge + tol && left->hi_m >= lo_edge - tol) ||
       (right && right->present && out.hi_m >= hi_edge - tol && right->lo_m <= hi_edge + tol));
  if (!out.present)
    out.lo_m = out.hi_m = out.distance_m = 0;
  return out;
}

void RowMap::add_frame(const cv::Mat &mask, const std::vector<PixelPoint> &points,
                       const StereoGeometry &g, const GroundPlane &ground, double position_mm,
                       const cv::Vec3d &row_direction, double span_lo_mm, double span_hi_mm)
{
  require_valid(g, "the row map", "RowMap::add_frame");
  if (mask.type() != CV_8U || mask.size() != g.view_size)
    throw BadInput("row map: the canopy mask must be CV_8U of the view size " +
                   std::to_string(g.view_size.width) + "x" + std::to_string(g.view_size.height));
  if (!ground.found)
    throw BadInput("row map: a ground plane is needed (select_canopy's or rig_ground())");
  if (!std::isfinite(position_mm))
    throw BadInput("row map: position_mm must be finite");
  const cv::Vec3d &dir = row_direction;
  if (!is_row_direction(dir))
    throw BadInput("row map: the row's direction must be a unit vector within 60 degrees of the "
                   "camera's x axis (RowDirection::direction())");

  const int W = g.view_size.width, H = g.view_size.height;
  const double fx = g.fx, fy = g.fy > 0 ? g.fy : g.fx, cx = g.cx[LEFT], cy = g.cy;
  const int nb = n_bands();
  const double lo_h = edges_.front(), hi_h = edges_.back();
  auto band_of = [&](double h) {
    if (!(h >= lo_h) || !(h < hi_h))
      return -1;
    return int(std::upper_bound(edges_.begin(), edges_.end(), h) - edges_.begin()) - 1;
  };

  // The canopy's points and the depth of each strip of columns.
  struct Pt {
    double x, z, h; // x: along the row (along_row())
    int u, v;
  };
  std::vector<Pt> pts;
  for (const PixelPoint &q : points) {
    if (!q.p.valid || !(q.p.z > 0) || !std::isfinite(q.p.x) || !std::isfinite(q.p.y) ||
        !std::isfinite(q.px.x) || !std::isfinite(q.px.y))
      continue;
    const int u = int(std::lround(q.px.x)), v = int(std::lround(q.px.y));
    if (u < 0 || v < 0 || u >= W || v >= H || !on_mask_or_beside(mask, u, v))
      continue;
    const cv::Point3d P(q.p.x, q.p.y, q.p.z);
    pts.push_back({along_row(cv::Vec3d(P), dir), P.z, ground.height_of(P), u, v});
  }
  if (pts.empty())
    return; // no depth: where the canopy-free view lies along the row is unknown
  std::vector<double> all_z;
  for (const Pt &p : pts)
    all_z.push_back(p.z);
  const double row_z = median(all_z);
  // the frames still to vote for a bin see its centre within kVoteSlope of their axis, which
  // lies row_z * dir[2] beside the rig's position
  settle_mm_ = row_z * (kVoteSlope + std::abs(dir[2]));

  const int S = (W + params_.strip_px - 1) / params_.strip_px;
  std::vector<std::vector<double>> strip_z(static_cast<std::size_t>(S));
  for (const Pt &p : pts)
    strip_z[std::size_t(p.u / params_.strip_px)].push_back(p.z);
  std::vector<double> sz(std::size_t(S), -1);
  for (int s = 0; s < S; ++s)
    if (!strip_z[std::size_t(s)].empty())
      sz[std::size_t(s)] = median(strip_z[std::size_t(s)]);
  std::vector<double> col_z(static_cast<std::size_t>(W));
  for (int s = 0; s < S; ++s) {
    double z = nearest_set(s, S, [&](int t) { return sz[std::size_t(t)]; });
    if (z < 0)
      z = row_z;
    for (int u = s * params_.strip_px; u < std::min(W, (s + 1) * params_.strip_px); ++u)
      col_z[std::size_t(u)] = z;
  }

  // The depth of each block of a strip: the crown's top and bottom lie deeper than its front at
  // the camera's height, and placed at the strip's depth a pixel above the camera would read
  // too low (and one below too high): the outer bands would lose canopy to the middle ones.
  // A block with kBlockMinPoints points around it takes their fitted line down the view
  // (BlockFit), else the nearest such block's median beside it (same rows, within kStripReach
  // strips), else the strip's depth. Pixels beyond a strip's outermost such block (above its
  // centroid at the top, below it at the bottom) follow a round crown's section towards the
  // silhouette (LimbArc): no points reach the limb, where the crown is deepest.
  const int block_rows = params_.strip_px * kBlockStrips;
  const int B = (H + block_rows - 1) / block_rows;
  std::vector<std::vector<cv::Point2d>> block_pts(static_cast<std::size_t>(S) * std::size_t(B));
  for (const Pt &p : pts)
    block_pts[std::size_t(p.u / params_.strip_px) * std::size_t(B) + std::size_t(p.v / block_rows)]
        .emplace_back(p.v, p.z);
  // A block's own depth: the points of its rows in its strip and the strips beside it (3 strips
  // by 4 strips' widths: a handful of points at stereodepth's grid spacing).
  std::vector<double> own_z(block_pts.size(), -1);
  std::vector<BlockFit> fit(block_pts.size());
  std::vector<cv::Point2d> near;
  std::vector<double> near_z;
  for (int s = 0; s < S; ++s)
    for (int r = 0; r < B; ++r) {
      near.clear();
      for (int t = std::max(0, s - 1); t <= std::min(S - 1, s + 1); ++t) {
        const auto &q = block_pts[std::size_t(t) * std::size_t(B) + std::size_t(r)];
        near.insert(near.end(), q.begin(), q.end());
      }
      if (near.size() < kBlockMinPoints)
        continue;
      near_z.clear();
      for (const cv::Point2d &q : near)
        near_z.push_back(q.y);
      const std::size_t i = std::size_t(s) * std::size_t(B) + std::size_t(r);
      own_z[i] = median(near_z);
      fit[i] = fit_block(near);
    }
  std::vector<double> block_z(own_z.size());
  for (int s = 0; s < S; ++s)
    for (int r = 0; r < B; ++r)
      block_z[std::size_t(s) * std::size_t(B) + std::size_t(r)] = nearest_set(
          s, S, [&](int t) { return own_z[std::size_t(t) * std::size_t(B) + std::size_t(r)]; });
  // Each strip's outermost fitted blocks: the top and bottom ones (-1: none).
  std::vector<int> top_block(std::size_t(S), -1), bottom_block(std::size_t(S), -1);
  for (int s = 0; s < S; ++s)
    for (int r = 0; r < B; ++r)
      if (fit[std::size_t(s) * std::size_t(B) + std::size_t(r)].valid()) {
        if (top_block[std::size_t(s)] < 0)
          top_block[std::size_t(s)] = r;
        bottom_block[std::size_t(s)] = r;
      }

  // Every pixel placed on the canopy's surface: counts per (bin, band).
  const double bin = params_.bin_mm;
  // The view's edges along the row: their rays at the outer columns' depths, the inner of the
  // top and bottom rows (the row's direction may lean across the view's rows).
  const auto edge_at = [&](double u, double z, bool low) {
    const double a = along_row(cv::Vec3d((u - cx) / fx * z, (-0.5 - cy) / fy * z, z), dir);
    const double b = along_row(cv::Vec3d((u - cx) / fx * z, (H - 0.5 - cy) / fy * z, z), dir);
    return (low ? std::max(a, b) : std::min(a, b)) + position_mm;
  };
  const double view_lo = edge_at(-0.5, col_z.front(), true);
  const double view_hi = edge_at(W - 0.5, col_z.back(), false);
  const long b0 = long(std::floor(view_lo / bin)), b1 = long(std::floor(view_hi / bin));
  // The span the mask speaks for, along the row (world x) at the canopy's depth.
  const auto span_at = [&](double X) {
    return std::isfinite(X) ? along_row(cv::Vec3d(X, 0, row_z), dir) + position_mm : X;
  };
  const double span_lo = span_at(span_lo_mm), span_hi = span_at(span_hi_mm);
  const long nbins = b1 - b0 + 1;
  if (nbins <= 0 || nbins > 1000000)
    return;
  std::vector<int> total(std::size_t(nbins * nb), 0);
  std::vector<double> canopy(std::size_t(nbins * nb), 0.0);
  std::vector<double> min_z(std::size_t(nbins * nb), std::numeric_limits<double>::infinity());
  std::vector<double> lo_x(std::size_t(nbins * nb), std::numeric_limits<double>::infinity());
  std::vector<double> hi_x(std::size_t(nbins * nb), -std::numeric_limits<double>::infinity());
  // Along the row, the columns where the canopy rises into a cell from the band below it
  // (consecutive canopy rows in both) for kCrossRows rows or more: a crown's cap (a row alone
  // may be a pixel's spill across the band's edge).
  std::vector<double> cross_lo(lo_x), cross_hi(hi_x);
  auto mark_cross = [&](long c, double x, double half_px) {
    cross_lo[std::size_t(c)] = std::min(cross_lo[std::size_t(c)], x - half_px);
    cross_hi[std::size_t(c)] = std::max(cross_hi[std::size_t(c)], x + half_px);
  };
  // The cells' pixels (total) are counted at the strip's depth: one depth down each column, so
  // a column's rows tile the bands without overlap. Canopy pixels are placed at their block's
  // depth, where the canopy is, each weighing the area it covers there in pixels at the strip's
  // depth, (z / z_strip)^2.
  // The cell of pixel row v seen in column u at depth z (-1: none), and its world x.
  auto cell_of = [&](int u, int v, double z, double &wx) {
    const cv::Point3d P((u - cx) / fx * z, (v - cy) / fy * z, z);
    wx = along_row(cv::Vec3d(P), dir) + position_mm;
    const long b = long(std::floor(wx / bin)) - b0;
    if (b < 0 || b >= nbins)
      return -1L;
    const int k = band_of(ground.height_of(P));
    return k < 0 ? -1L : b * nb + k;
  };
  for (int u = 0; u < W; ++u) {
    const double z_col = col_z[std::size_t(u)];
    const int s = u / params_.strip_px;
    const std::size_t strip = std::size_t(s) * std::size_t(B);
    // The column's silhouette: its top and bottom canopy rows. A limb at the image's edge is
    // none (the canopy goes on beyond it).
    int v_top = -1, v_bottom = -1;
    for (int v = 0; v < H; ++v)
      if (mask.at<uchar>(v, u)) {
        if (v_top < 0)
          v_top = v;
        v_bottom = v;
      }
    // Rows beyond these follow the arcs (above_v: above the top fit's centroid, below_v: below
    // the bottom one's).
    LimbArc above, below;
    double above_v = -1, below_v = H;
    const int chord = v_bottom - v_top + 1;
    if (v_top > 0 && top_block[std::size_t(s)] >= 0) {
      const BlockFit &f = fit[strip + std::size_t(top_block[std::size_t(s)])];
      above = LimbArc(f, (v_top - 0.5 - cy) / fy, chord, fy, cy);
      above_v = above.valid() ? f.v0 : -1;
    }
    if (v_bottom >= 0 && v_bottom < H - 1 && bottom_block[std::size_t(s)] >= 0) {
      const BlockFit &f = fit[strip + std::size_t(bottom_block[std::size_t(s)])];
      below = LimbArc(f, (v_bottom + 0.5 - cy) / fy, chord, fy, cy);
      below_v = below.valid() ? f.v0 : H;
    }
    double wx = 0;
    // The run of canopy rows down the column in one band: its cell, its length, and the world x
    // of its first pixel.
    long run_c = -1;
    int run_rows = 0;
    double run_x = 0, run_half = 0;
    for (int v = 0; v < H; ++v) {
      const long c_all = cell_of(u, v, z_col, wx);
      if (c_all >= 0)
        ++total[std::size_t(c_all)];
      if (!mask.at<uchar>(v, u)) {
        run_c = -1;
        continue;
      }
      const std::size_t blk = strip + std::size_t(v / block_rows);
      double z = block_z[blk] > 0 ? block_z[blk] : z_col;
      if (v < above_v)
        z = above.depth((v - cy) / fy);
      else if (v > below_v)
        z = below.depth((v - cy) / fy);
      else if (fit[blk].valid())
        z = fit[blk].at(v);
      const long c = z != z_col ? cell_of(u, v, z, wx) : c_all;
      if (c < 0) {
        run_c = -1;
        continue;
      }
      const double half_px = 0.5 * z / fx; // a column covers wx +- half a pixel along the row
      if (run_c < 0 || run_c % nb != c % nb) { // a new run
        if (run_c >= 0 && run_rows >= kCrossRows)
          mark_cross(run_c, run_x, run_half); // the canopy below rose into the run's cell
        run_rows = 0;
        run_x = wx;
        run_half = half_px;
      }
      run_c = c;
      ++run_rows;
      canopy[std::size_t(c)] += (z / z_col) * (z / z_col);
      min_z[std::size_t(c)] = std::min(min_z[std::size_t(c)], z);
      lo_x[std::size_t(c)] = std::min(lo_x[std::size_t(c)], wx - half_px);
      hi_x[std::size_t(c)] = std::max(hi_x[std::size_t(c)], wx + half_px);
    }
  }
  std::vector<std::vector<double>> cell_z(std::size_t(nbins * nb));
  for (const Pt &p : pts) {
    const long b = long(std::floor((p.x + position_mm) / bin)) - b0;
    const int k = band_of(p.h);
    if (b >= 0 && b < nbins && k >= 0)
      cell_z[std::size_t(b * nb + k)].push_back(p.z);
  }

  // Each bin the view holds whole: taken when this frame sees it nearer the image centre, and
  // each band's presence counted (kVotes).
  for (long b = 0; b < nbins; ++b) {
    const double lo = double(b + b0) * bin, hi = lo + bin;
    if (lo < view_lo || hi > view_hi)
      continue;
    const double offset = std::abs(0.5 * (lo + hi) - (position_mm + row_z * dir[2])) / row_z;
    const double centre = 0.5 * (lo + hi);
    const bool in_span = !(centre < span_lo) && !(centre > span_hi);
    auto it = bins_.find(b + b0);
    const bool keep_old = it != bins_.end() && (in_span != it->second.in_span ? !in_span
                                                             : !(offset < it->second.centre_offset));
    std::vector<RowMapCell> frame_cells(static_cast<std::size_t>(nb));
    for (int k = 0; k < nb; ++k) {
      const std::size_t c = std::size_t(b * nb + k);
      RowMapCell &cell = frame_cells[std::size_t(k)];
      cell.seen = in_span && total[c] > 0; // outside the span the mask says nothing
      if (!cell.seen)
        continue;
      // Canopy placed at its own depth may outnumber the cell's pixels at the strip's.
      cell.fill = std::min(1.0, canopy[c] / total[c]);
      cell.present = canopy[c] > 0 && (cell.fill >= params_.min_fill ||
                                        cross_hi[c] - cross_lo[c] > kTouchBins * bin);
      if (canopy[c] > 0) { // also under min_fill: cell() may find it a present cell's end
        cell.distance_m =
            (cell_z[c].empty() ? min_z[c] : percentile(cell_z[c], 5.0)) * kMmToM;
        cell.lo_m = std::max(lo, lo_x[c]) * kMmToM;
        cell.hi_m = std::min(hi, hi_x[c]) * kMmToM;
      }
    }
    Bin &out = bins_[b + b0];
    if (out.nearest.empty()) {
      out.nearest.resize(std::size_t(nb));
      out.votes.resize(std::size_t(nb));
    }
    if (in_span && offset <= kVoteSlope)
      for (std::size_t k = 0; k < std::size_t(nb); ++k)
        if (frame_cells[k].present) {
          Vote &v = out.votes[k];
          ++v.count;
          v.lo_m = std::min(v.lo_m, frame_cells[k].lo_m);
          v.hi_m = std::max(v.hi_m, frame_cells[k].hi_m);
          if (offset < v.offset) {
            v.offset = offset;
            v.cell = frame_cells[k];
          }
        }
    if (!keep_old) {
      out.in_span = in_span;
      out.centre_offset = offset;
      out.nearest = std::move(frame_cells);
    }
  }
}

RowMapCell RowMap::Bin::cell(int band) const
{
  const std::size_t k = std::size_t(band);
  RowMapCell c = !nearest[k].present && votes[k].count >= kVotes ? votes[k].cell : nearest[k];
  if (c.present && votes[k].count > 0) {
    c.lo_m = std::min(c.lo_m, votes[k].lo_m);
    c.hi_m = std::max(c.hi_m, votes[k].hi_m);
  }
  return c;
}

void RowMap::write_csv(const std::string &path) const
{
  std::ofstream f(path);
  if (!f)
    throw FileError(path, FileAccess::Write,
                    "row map: cannot write " + path + ": " + std::strerror(errno));
  f << kCsvHeader << '\n';
  const int nb = n_bands();
  for (long b = first_bin(); b <= last_bin(); ++b)
    for (int k = 0; k < nb; ++k) {
      const RowMapCell c = cell(b, k);
      f << fixed((double(b) + 0.5) * params_.bin_mm * kMmToM, 4) << ',' << k << ','
        << (c.present ? 1 : 0) << ',' << (c.present ? fixed(c.distance_m, 4) : std::string())
        << ',' << fixed(c.fill, 4) << ',' << (c.seen ? 1 : 0) << '\n';
    }
  f.flush();
  if (!f)
    throw FileError(path, FileAccess::Write,
                    "row map: writing " + path + " failed: " + std::strerror(errno));
}

namespace
{

// The distances (m) of the present cells of bins [first, last): (+inf, -inf) when none.
template <class It> std::pair<double, double> present_distances(It first, It last)
{
  std::pair<double, double> r(std::numeric_limits<double>::infinity(),
                              -std::numeric_limits<double>::infinity());
  for (; first != last; ++first)
    for (int k = 0; k < int(first->second.nearest.size()); ++k)
      if (const RowMapCell &c = first->second.cell(k); c.present) {
        r.first = std::min(r.first, c.distance_m);
        r.second = std::max(r.second, c.distance_m);
      }
  return r;
}

// The distance colours of the map's pictures: cv::COLORMAP_TURBO (BGR) over [near_m, far_m],
// widened to 5 cm around its middle for a flat row.
struct DistanceColours {
  double near_m, far_m;
  cv::Mat lut;
  DistanceColours(double dmin, double dmax) : near_m(dmin), far_m(dmax)
  {
    if (far_m - near_m < 0.05) {
      const double mid = 0.5 * (near_m + far_m);
      near_m = std::max(0.0, mid - 0.025);
      far_m = near_m + 0.05;
    }
    cv::Mat ramp(1, 256, CV_8U);
    for (int i = 0; i < 256; ++i)
      ramp.at<uchar>(0, i) = uchar(i);
    cv::applyColorMap(ramp, lut, cv::COLORMAP_TURBO);
  }
  cv::Vec3b operator()(double d) const
  {
    const int i = std::clamp(int(std::lround((d - near_m) / (far_m - near_m) * 255.0)), 0, 255);
    return lut.at<cv::Vec3b>(0, i);
  }
};

} // namespace

cv::Size RowMap::render_size(const RowMapRenderParams &r) const
{
  const long bins = bins_.empty() ? 0 : last_bin() - first_bin() + 1;
  const double top_m = std::max(0.0, edges_.back() * kMmToM);
  return {kMarginLeft + int(bins) * r.px_per_bin + kMarginRight,
          kMarginTop + int(std::lround(top_m * r.px_per_m_height)) + kMarginBottom};
}

cv::Mat RowMap::render(const std::vector<TreeRecord> &trees, const RowMapRenderParams &r) const
{
  if (r.px_per_bin < 1 || r.px_per_bin > 100)
    throw BadSettings("row map render parameter px_per_bin out of range: 1 to 100");
  if (!(r.px_per_m_height >= 10) || !(r.px_per_m_height <= 2000))
    throw BadSettings("row map render parameter px_per_m_height out of range: 10 to 2000");
  if (!std::isfinite(r.distance_min_m) || !std::isfinite(r.distance_max_m) ||
      r.distance_min_m < 0 || r.distance_max_m < r.distance_min_m)
    throw BadSettings("row map render parameter distance_min_m / distance_max_m out of "
                             "range: 0 <= min <= max");
  const cv::Size size = render_size(r);
  if (double(size.width) * size.height > 2.5e8)
    throw std::runtime_error("row map: the picture would be too large; lower px_per_bin");
  cv::Mat img(size, CV_8UC3, cv::Scalar(255, 255, 255));
  const int nb = n_bands();
  const long b0 = first_bin(), nbins = bins_.empty() ? 0 : last_bin() - b0 + 1;
  const int ground_y = size.height - kMarginBottom;
  auto y_of = [&](double h_mm) {
    return ground_y - int(std::lround(h_mm * kMmToM * r.px_per_m_height));
  };
  auto x_of_m = [&](double x_m) {
    return kMarginLeft +
           int(std::lround((x_m * 1000.0 / params_.bin_mm - double(b0)) * r.px_per_bin));
  };
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  const cv::Scalar ink(30, 30, 30);

  // The distance scale.
  double dmin = r.distance_min_m, dmax = r.distance_max_m;
  if (dmin == 0 && dmax == 0) {
    std::tie(dmin, dmax) = present_distances(bins_.begin(), bins_.end());
    if (!std::isfinite(dmin)) {
      dmin = 0;
      dmax = 1;
    }
  }
  const DistanceColours scale(dmin, dmax);
  dmin = scale.near_m;
  dmax = scale.far_m;
  auto colour = [&](double d) {
    const cv::Vec3b c = scale(d);
    return cv::Scalar(c[0], c[1], c[2]);
  };

  // The plot area: unseen black, then each band of each bin.
  cv::rectangle(img, cv::Point(kMarginLeft, y_of(edges_.back())),
                cv::Point(kMarginLeft + int(nbins) * r.px_per_bin - 1, y_of(edges_.front()) - 1),
                cv::Scalar(0, 0, 0), cv::FILLED);
  for (const auto &bn : bins_) {
    const int x0 = kMarginLeft + int(bn.first - b0) * r.px_per_bin;
    for (int k = 0; k < nb; ++k) {
      const RowMapCell c = cell(bn.first, k);
      if (!c.seen)
        continue;
      const cv::Scalar fill = c.present ? colour(c.distance_m) : cv::Scalar(60, 60, 60);
      cv::rectangle(img, cv::Point(x0, y_of(edges_[std::size_t(k) + 1])),
                    cv::Point(x0 + r.px_per_bin - 1, y_of(edges_[std::size_t(k)]) - 1), fill,
                    cv::FILLED);
    }
  }
  // Band edges and the ground.
  for (double e : edges_) {
    cv::line(img, cv::Point(kMarginLeft - 4, y_of(e)),
             cv::Point(kMarginLeft + int(nbins) * r.px_per_bin - 1, y_of(e)),
             cv::Scalar(150, 150, 150), 1);
    cv::putText(img, fixed(e * kMmToM, 2) + " m", cv::Point(4, y_of(e) + 4), font, 0.4, ink, 1,
                cv::LINE_AA);
  }
  cv::line(img, cv::Point(kMarginLeft, ground_y), cv::Point(size.width - kMarginRight, ground_y),
           cv::Scalar(40, 90, 140), 2);
  cv::putText(img, "ground", cv::Point(4, ground_y + 4), font, 0.4, ink, 1, cv::LINE_AA);
  // Travel ticks every metre.
  if (nbins > 0) {
    const double from_m = double(b0) * params_.bin_mm * kMmToM;
    const double to_m = double(b0 + nbins) * params_.bin_mm * kMmToM;
    for (double m = std::ceil(from_m); m <= to_m; m += 1.0) {
      const int x = x_of_m(m);
      cv::line(img, cv::Point(x, ground_y), cv::Point(x, ground_y + 5), ink, 1);
      cv::putText(img, std::to_string(std::lround(m)), cv::Point(x - 4, ground_y + 18), font,
                  0.4, ink, 1, cv::LINE_AA);
    }
    // In the left margin, on the ticks' line: clear of every tick's number.
    cv::putText(img, "travel (m)", cv::Point(4, ground_y + 18), font, 0.4, ink, 1, cv::LINE_AA);
  }
  // The trees: extent as a bracket above the map, id above its position.
  const double map_lo_m = double(b0) * params_.bin_mm * kMmToM;
  const double map_hi_m = double(b0 + nbins) * params_.bin_mm * kMmToM;
  for (const TreeRecord &t : trees) {
    if (t.end_m < map_lo_m || t.start_m > map_hi_m) // not on this map
      continue;
    const int xs = x_of_m(t.start_m), xe = x_of_m(t.end_m), xc = x_of_m(t.position_m);
    const int y = kMarginTop - 10;
    const cv::Scalar c = t.complete ? cv::Scalar(20, 120, 20) : cv::Scalar(0, 100, 200);
    cv::line(img, cv::Point(xs, y), cv::Point(xe, y), c, 2);
    cv::line(img, cv::Point(xs, y - 5), cv::Point(xs, y + 5), c, 1);
    cv::line(img, cv::Point(xe, y - 5), cv::Point(xe, y + 5), c, 1);
    cv::putText(img, std::to_string(t.id), cv::Point(xc - 4, y - 10), font, 0.45, c, 1,
                cv::LINE_AA);
  }
  // The distance scale bar.
  const int bar_y = ground_y + 32, bar_h = 12, bar_w = std::min(256, size.width - kMarginLeft - 90);
  if (bar_w > 16) {
    for (int i = 0; i < bar_w; ++i)
      cv::line(img, cv::Point(kMarginLeft + i, bar_y), cv::Point(kMarginLeft + i, bar_y + bar_h),
               colour(dmin + (dmax - dmin) * i / (bar_w - 1)), 1);
    cv::putText(img, fixed(dmin, 2), cv::Point(kMarginLeft, bar_y + bar_h + 14), font, 0.4, ink,
                1, cv::LINE_AA);
    cv::putText(img, fixed(dmax, 2) + " m distance", cv::Point(kMarginLeft + bar_w - 20,
                bar_y + bar_h + 14), font, 0.4, ink, 1, cv::LINE_AA);
  }
  // The other two cell kinds: seen without canopy, never seen.
  cv::putText(img, "empty", cv::Point(4, bar_y + 10), font, 0.35, ink, 1, cv::LINE_AA);
  cv::rectangle(img, cv::Point(44, bar_y), cv::Point(56, bar_y + bar_h), cv::Scalar(60, 60, 60),
                cv::FILLED);
  cv::putText(img, "unseen", cv::Point(4, bar_y + 30), font, 0.35, ink, 1, cv::LINE_AA);
  cv::rectangle(img, cv::Point(44, bar_y + 20), cv::Point(56, bar_y + 20 + bar_h),
                cv::Scalar(0, 0, 0), cv::FILLED);
  return img;
}

cv::Mat RowMap::render_with_timeline(const std::vector<TreeRecord> &trees,
                                     const std::vector<SprayedStretch> &sprayed, int sections,
                                     const RowMapRenderParams &r) const
{
  int needed = 0;
  for (const SprayedStretch &s : sprayed) {
    if (s.section < 0 || !std::isfinite(s.start_m) || std::isnan(s.end_m) || s.end_m < s.start_m)
      throw std::runtime_error("row map timeline: a stretch with a negative section or an end "
                               "before its start");
    needed = std::max(needed, s.section + 1);
  }
  if (sections < needed || sections > 256)
    throw std::runtime_error("row map timeline: sections out of range (every stretch's section "
                             "+ 1 to 256)");
  const cv::Mat map = render(trees, r);
  cv::Mat img(map.rows + kTimelineTop + sections * kStripHeight, map.cols, CV_8UC3,
              cv::Scalar(255, 255, 255));
  map.copyTo(img(cv::Rect(0, 0, map.cols, map.rows)));
  const long b0 = first_bin(), nbins = bins_.empty() ? 0 : last_bin() - b0 + 1;
  const double lo_m = double(b0) * params_.bin_mm * kMmToM;
  const double hi_m = double(b0 + nbins) * params_.bin_mm * kMmToM;
  auto x_of_m = [&](double x_m) {
    return kMarginLeft + int(std::lround((std::clamp(x_m, lo_m, hi_m) * 1000.0 / params_.bin_mm -
                                          double(b0)) *
                                         r.px_per_bin));
  };
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  const cv::Scalar ink(30, 30, 30);
  const int top = map.rows + kTimelineTop;
  cv::putText(img, "valves open (section, along the canopy they spray)",
              cv::Point(kMarginLeft, map.rows + kTimelineTop - 8), font, 0.4, ink, 1, cv::LINE_AA);
  for (int k = 0; k < sections; ++k) {
    const int y0 = top + (sections - 1 - k) * kStripHeight;
    cv::rectangle(img, cv::Point(kMarginLeft, y0 + 2),
                  cv::Point(kMarginLeft + int(nbins) * r.px_per_bin - 1, y0 + kStripHeight - 3),
                  cv::Scalar(225, 225, 225), cv::FILLED);
    cv::putText(img, "S" + std::to_string(k), cv::Point(4, y0 + kStripHeight - 4), font, 0.4, ink,
                1, cv::LINE_AA);
  }
  for (const SprayedStretch &s : sprayed) {
    if (s.end_m < lo_m || s.start_m > hi_m)
      continue;
    const int y0 = top + (sections - 1 - s.section) * kStripHeight;
    cv::rectangle(img, cv::Point(x_of_m(s.start_m), y0 + 2),
                  cv::Point(std::max(x_of_m(s.start_m), x_of_m(s.end_m) - 1), y0 + kStripHeight - 3),
                  cv::Scalar(40, 120, 20), cv::FILLED);
  }
  return img;
}

void RowMap::draw_strip(cv::Mat &strip, double from_m, double to_m, double now_m,
                        double dmin, double dmax) const
{
  if (strip.empty() || strip.type() != CV_8UC3)
    throw std::runtime_error("row map strip: an empty image or not 8-bit BGR");
  if (!(from_m < to_m) || !std::isfinite(from_m) || !std::isfinite(to_m) || !std::isfinite(now_m))
    throw std::runtime_error("row map strip: the travel window must have from_m < to_m");
  const int nb = n_bands();
  const double m_per_px = (to_m - from_m) / strip.cols;
  if (dmin == 0 && dmax == 0) {
    std::tie(dmin, dmax) = present_distances(
        bins_.lower_bound(long(std::floor(from_m * 1000.0 / params_.bin_mm))),
        bins_.upper_bound(long(std::floor(to_m * 1000.0 / params_.bin_mm))));
    if (!std::isfinite(dmin))
      dmin = dmax = 0;
  }
  const DistanceColours colour(dmin, dmax);
  strip.setTo(cv::Scalar(0, 0, 0));
  for (int x = 0; x < strip.cols; ++x) {
    const double w_m = from_m + (x + 0.5) * m_per_px;
    const auto it = bins_.find(long(std::floor(w_m * 1000.0 / params_.bin_mm)));
    if (it == bins_.end())
      continue;
    for (int k = 0; k < nb; ++k) {
      const RowMapCell c = cell(it->first, k);
      if (!c.seen)
        continue;
      const cv::Vec3b fill = c.present ? colour(c.distance_m) : cv::Vec3b(60, 60, 60);
      const int y0 = strip.rows * (nb - 1 - k) / nb, y1 = strip.rows * (nb - k) / nb;
      for (int y = y0; y < y1; ++y)
        strip.at<cv::Vec3b>(y, x) = fill;
    }
  }
  const int xn = int(std::lround((now_m - from_m) / m_per_px));
  if (xn >= 0 && xn < strip.cols)
    cv::line(strip, cv::Point(xn, 0), cv::Point(xn, strip.rows - 1), cv::Scalar(255, 255, 255),
             std::max(1, strip.rows / 40));
}

namespace
{

void write_picture(const std::string &path, const cv::Mat &img)
{
  bool ok = false;
  try {
    ok = cv::imwrite(path, img);
  } catch (const cv::Exception &e) {
    throw FileError(path, FileAccess::Write, "row map: cannot write " + path + ": " + e.what());
  }
  if (!ok)
    throw FileError(path, FileAccess::Write,
                    "row map: cannot write " + path +
                        " (no such directory, no permission or an unknown extension)");
}

} // namespace

void RowMap::write_png(const std::string &path, const std::vector<TreeRecord> &trees,
                       const RowMapRenderParams &r) const
{
  if (bins_.empty())
    throw std::runtime_error("row map: nothing to write to " + path + ": no frame added a bin");
  write_picture(path, render(trees, r));
}

void RowMap::write_png(const std::string &path, const std::vector<TreeRecord> &trees,
                       const std::vector<SprayedStretch> &sprayed, int sections,
                       const RowMapRenderParams &r) const
{
  if (bins_.empty())
    throw std::runtime_error("row map: nothing to write to " + path + ": no frame added a bin");
  write_picture(path, render_with_timeline(trees, sprayed, sections, r));
}

std::string with_extension(const std::string &path, const std::string &extension)
{
  std::string out = path;
  const std::size_t slash = out.find_last_of('/');
  const std::size_t dot = out.find_last_of('.');
  if (dot != std::string::npos && (slash == std::string::npos || dot > slash))
    out.erase(dot);
  return out + extension;
}

} // namespace treestereo
