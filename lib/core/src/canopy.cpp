#include "treestereo/canopy.hpp"

#include "treestereo/errors.hpp"
#include "treestereo/features.hpp"
#include "treestereo/segment.hpp"
#include "mask_strips.hpp"
#include "zncc.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace treestereo {

const char *canopy_mode_name(CanopyMode mode)
{
  return mode == CanopyMode::Row ? "row" : "tree";
}

CanopyMode canopy_mode_from_name(const std::string &name)
{
  if (name == "tree")
    return CanopyMode::Tree;
  if (name == "row")
    return CanopyMode::Row;
  throw BadSettings("Unknown canopy mode '" + name + "': use tree or row.",
                    "canopy_mode_from_name(\"" + name + "\")");
}

const char *ground_model_name(GroundModel model)
{
  switch (model) {
  case GroundModel::Off: return "off";
  case GroundModel::Rig: return "rig";
  default: return "fit";
  }
}

GroundModel ground_model_from_name(const std::string &name)
{
  if (name == "off")
    return GroundModel::Off;
  if (name == "fit")
    return GroundModel::Fit;
  if (name == "rig")
    return GroundModel::Rig;
  throw BadSettings("Unknown ground model '" + name + "': use off, fit or rig.",
                    "ground_model_from_name(\"" + name + "\")");
}

namespace {

void require(bool ok, const char *field, const char *range)
{
  if (!ok)
    throw BadSettings(std::string("The canopy setting ") + field +
                          " is out of range: set it to " + range + ".",
                      std::string("canopy parameters: ") + field + " outside " + range);
}

constexpr double kDeg = CV_PI / 180.0;
// Views of at least this many pixels (1296x972 and up) split mixed regions on a grid reduced by
// 2: one decision per 2x2 pixels, about a tenth of a 7x7 patch's reach at that size.
constexpr int kSplitHalfSizeMinPx = 1000000;
// The seam test's band: this many sample spacings either side of the border.
constexpr double kSeamBandSpacings = 1.5;
// A region is shared with something else when at least this share of its points, and this
// many, are not the canopy's.
constexpr int kMinOtherPoints = 3;
constexpr double kMinOtherShare = 0.05;
// A piece of a split region smaller than this share of the canopy is a crumb.
constexpr double kMinPieceShare = 0.005;
// Strips of the split canopy less than kStripPx tall (full-size px) that reach more than
// kStripReachPx out of the canopy's body are cut off (section 4 of select_canopy).
constexpr int kStripPx = 11, kStripReachPx = 3;
// Mask value of a pixel not yet decided.
constexpr uchar kUnknown = 128;
// A region with an area of at least one sample spacing squared farther than this many spacings
// from every sample holds a surface the samples could not measure: it is split, not taken whole.
constexpr double kUnreachedSpacings = 3.0;
// RANSAC draws for the ground plane (from the points below the camera).
constexpr int kGroundIterations = 250;
// A ground point's inlier distance is at least this share of its depth.
constexpr double kGroundDepthTolerance = 0.02;
// A fitted ground's inliers spread this far in depth and across (10th to 90th percentile).
constexpr double kGroundSpreadMm = 1000.0;
// A fitted ground lies at least this far below the camera.
constexpr double kMinCameraHeightMm = 150.0;
// The seam test: the nearer surface's patch must correlate at least this well to win.
constexpr double kSeamMinScore = 0.6;
// A score the centred window needs for the shifted windows to be skipped.
constexpr double kSeamClearScore = 0.85;

// Image-area weights: each point stands for its share of the cell (cell x cell px) it falls in,
// so that SIFT matches crowding on contrasted leaves do not outweigh an even grid.
std::vector<double> area_weights(const std::vector<PixelPoint> &pts, const std::vector<int> &use,
                                 cv::Size size, int cell)
{
  const int gw = (size.width + cell - 1) / cell, gh = (size.height + cell - 1) / cell;
  std::vector<int> count(std::size_t(gw) * std::size_t(gh), 0);
  auto cell_of = [&](const cv::Point2f &px) {
    const int cx = std::clamp(int(px.x) / cell, 0, gw - 1), cy = std::clamp(int(px.y) / cell, 0, gh - 1);
    return std::size_t(cy) * std::size_t(gw) + std::size_t(cx);
  };
  for (int i : use)
    ++count[cell_of(pts[std::size_t(i)].px)];
  std::vector<double> w(use.size());
  for (std::size_t k = 0; k < use.size(); ++k)
    w[k] = 1.0 / count[cell_of(pts[std::size_t(use[k])].px)];
  return w;
}

// Runs of occupied bins separated by at least `gap_bins` empty ones: [first, last] bin pairs.
// A bin is occupied when its weight reaches `min_weight`.
std::vector<cv::Vec2i> occupied_runs(const std::vector<double> &hist, double min_weight,
                                     int gap_bins)
{
  std::vector<cv::Vec2i> runs;
  int start = -1, last = -1;
  for (int b = 0; b < int(hist.size()); ++b) {
    if (hist[std::size_t(b)] < min_weight)
      continue;
    if (start >= 0 && b - last - 1 >= gap_bins) {
      runs.emplace_back(start, last);
      start = -1;
    }
    if (start < 0)
      start = b;
    last = b;
  }
  if (start >= 0)
    runs.emplace_back(start, last);
  return runs;
}

// Cuts runs of bins (along the row) where the top line dips between two crowns (CanopyParams::
// valley_share). `top`, `bottom`: per bin, the heights of its highest and lowest point (-inf and
// +inf: none); `heights`: the heights of the points `zone`, `bin_of` their bin. The lines are
// first closed over one bin on each side (a bin between two points of a crown's top that holds
// only lower leaves is no notch). Where two crowns of unequal height meet, the top line is
// lowest on the lower crown's shoulder, not where they meet: the cut is placed between the two
// summits where the canopy is thinnest from top to bottom (both crowns near their edge), the
// valley's middle on a tie. A cut leaves that bin out of both runs: the cut falls on its centre.
template <class BinOf>
std::vector<cv::Vec2i> split_at_valleys(const std::vector<cv::Vec2i> &runs,
                                        const std::vector<double> &top,
                                        const std::vector<double> &bottom,
                                        const std::vector<double> &heights,
                                        const std::vector<int> &zone, BinOf bin_of, double bin,
                                        const CanopyParams &p)
{
  const double ninf = -std::numeric_limits<double>::infinity();
  const int nb = int(top.size());
  std::vector<double> line(top.size(), ninf), low(top.size(), -ninf);
  for (int b = 0; b < nb; ++b)
    for (int d = -1; d <= 1; ++d)
      if (b + d >= 0 && b + d < nb) {
        line[std::size_t(b)] = std::max(line[std::size_t(b)], top[std::size_t(b + d)]);
        low[std::size_t(b)] = std::min(low[std::size_t(b)], bottom[std::size_t(b + d)]);
      }
  // The lowest canopy under each run: the 5th percentile of its points' heights.
  std::vector<std::vector<double>> run_heights(runs.size());
  for (std::size_t k = 0; k < zone.size(); ++k) {
    const int b = bin_of(zone[k]);
    for (std::size_t r = 0; r < runs.size(); ++r)
      if (b >= runs[r][0] && b <= runs[r][1])
        run_heights[r].push_back(heights[k]);
  }
  const int min_bins = std::max(1, int(std::ceil(p.min_crown_mm / bin)));
  std::vector<cv::Vec2i> out;
  for (std::size_t r = 0; r < runs.size(); ++r) {
    auto &h = run_heights[r];
    if (h.empty()) {
      out.push_back(runs[r]);
      continue;
    }
    const auto q = h.begin() + std::ptrdiff_t(0.05 * double(h.size() - 1));
    std::nth_element(h.begin(), q, h.end());
    const double base = *q;
    // Split recursively: the deepest qualifying valley first.
    std::vector<cv::Vec2i> todo{runs[r]};
    while (!todo.empty()) {
      const cv::Vec2i run = todo.back();
      todo.pop_back();
      const int s = run[0], e = run[1];
      int best = -1;
      double best_share = p.valley_share;
      if (e - s + 1 >= 2 * min_bins + 1) {
        // Highest top line left of each bin and right of it.
        const int n = e - s + 1;
        std::vector<double> left(std::size_t(n), ninf), right(std::size_t(n), ninf);
        for (int i = 1; i < n; ++i)
          left[std::size_t(i)] = std::max(left[std::size_t(i - 1)], line[std::size_t(s + i - 1)]);
        for (int i = n - 2; i >= 0; --i)
          right[std::size_t(i)] = std::max(right[std::size_t(i + 1)], line[std::size_t(s + i + 1)]);
        for (int i = min_bins; i < n - min_bins; ++i) {
          const double v = line[std::size_t(s + i)];
          const double lower = std::min(left[std::size_t(i)], right[std::size_t(i)]);
          if (v == ninf || lower == ninf || lower - base <= 0)
            continue;
          const double share = (lower - v) / (lower - base);
          if (share >= best_share) {
            best_share = share;
            best = s + i;
          }
        }
      }
      if (best < 0) {
        out.push_back(run);
        continue;
      }
      // Between the summits on either side (the first bins as high as each side's top), where
      // the canopy is thinnest; the middle of the thinnest stretch.
      int peak_l = best - 1, peak_r = best + 1;
      {
        double hl = ninf, hr = ninf;
        for (int b = s; b < best; ++b)
          if (line[std::size_t(b)] >= hl) {
            hl = line[std::size_t(b)];
            peak_l = b;
          }
        for (int b = e; b > best; --b)
          if (line[std::size_t(b)] >= hr) {
            hr = line[std::size_t(b)];
            peak_r = b;
          }
      }
      const int lo_b = std::max(peak_l + 1, s + min_bins), hi_b = std::min(peak_r - 1, e - min_bins);
      double thinnest = std::numeric_limits<double>::infinity();
      int first = best, last = best;
      for (int b = lo_b; b <= hi_b; ++b) {
        const double t = line[std::size_t(b)] - low[std::size_t(b)];
        if (!std::isfinite(t))
          continue;
        if (t < thinnest - 1e-9) {
          thinnest = t;
          first = last = b;
        } else if (t <= thinnest + 1e-9) {
          last = b;
        }
      }
      best = (first + last) / 2;
      todo.emplace_back(best + 1, e);
      todo.emplace_back(s, best - 1);
    }
  }
  std::sort(out.begin(), out.end(), [](const cv::Vec2i &a, const cv::Vec2i &b) { return a[0] < b[0]; });
  return out;
}

// The ground plane by RANSAC over the points (deterministic), then least squares on the inliers.
// Nothing may lie under the ground and the camera stands above it: a candidate plane with more
// than 2 % of the points well below it, or above the camera (a slice through a canopy), is
// refused, and so is one away from the prior (CanopyParams::ground_prior). No plane: the prior,
// held (or none).
GroundPlane fit_ground(const std::vector<cv::Point3d> &X, const CanopyParams &p,
                       const cv::Vec3d &up)
{
  GroundPlane best;
  // With a prior, only a plane near it is this frame's ground.
  const GroundPlane &prior = p.ground_prior;
  const double cos_prior = std::cos(p.ground_prior_tilt_deg * kDeg);
  auto near_prior = [&](const cv::Vec3d &nn, double d) {
    return !prior.found ||
           (nn.dot(prior.normal) >= cos_prior && std::abs(d - prior.d) <= p.ground_prior_shift_mm);
  };
  auto keep_prior = [&]() {
    GroundPlane held = prior;
    held.inliers = 0;
    held.held = prior.found;
    return held;
  };
  const std::size_t n = X.size();
  if (n < 30)
    return keep_prior();
  const double cos_tilt = std::cos(p.ground_max_tilt_deg * kDeg);
  // Inlier distance: the tolerance, or kGroundDepthTolerance of the point's depth where stereo's
  // depth error is larger than that (far grass, small views).
  auto tol_at = [&](const cv::Point3d &q) {
    return std::max(p.ground_tolerance_mm, kGroundDepthTolerance * q.z);
  };
  std::uint64_t state = 0x9e3779b97f4a7c15ULL;
  auto next = [&state]() {
    state ^= state << 13;
    state ^= state >> 7;
    state ^= state << 17;
    return state;
  };
  // The ground is broad: its inliers spread at least kGroundSpreadMm in depth and across (the
  // lowest slice of a canopy is a plane with enough points too, but a small one).
  std::vector<double> zs, xs;
  auto broad = [&](const cv::Vec3d &nn, double d) {
    zs.clear();
    xs.clear();
    for (const cv::Point3d &q : X)
      if (std::abs(nn.dot(cv::Vec3d(q.x, q.y, q.z)) + d) <= tol_at(q)) {
        zs.push_back(q.z);
        xs.push_back(q.x);
      }
    auto spread = [](std::vector<double> &v) {
      const std::size_t lo = v.size() / 10, hi = v.size() - 1 - v.size() / 10;
      std::nth_element(v.begin(), v.begin() + long(lo), v.end());
      const double a = v[lo];
      std::nth_element(v.begin(), v.begin() + long(hi), v.end());
      return v[hi] - a;
    };
    return zs.size() >= 3 && spread(zs) >= kGroundSpreadMm && spread(xs) >= kGroundSpreadMm;
  };
  std::size_t best_inliers = 0;
  cv::Vec3d best_n;
  double best_d = 0;
  const std::size_t min_inliers = std::max<std::size_t>(30, n / 20);
  // Samples come from the points below the camera (the ground is there on a rig that looks
  // sideways, level or pitched down).
  std::vector<std::size_t> low;
  for (std::size_t i = 0; i < n; ++i)
    if (cv::Vec3d(X[i].x, X[i].y, X[i].z).dot(up) < 0)
      low.push_back(i);
  if (low.size() < 3)
    return keep_prior();
  for (int it = 0; it < kGroundIterations; ++it) {
    const cv::Point3d &a = X[low[next() % low.size()]], &b = X[low[next() % low.size()]],
                      &c = X[low[next() % low.size()]];
    cv::Vec3d nn = cv::Vec3d(b - a).cross(cv::Vec3d(c - a));
    const double len = cv::norm(nn);
    if (len < 1e-9)
      continue;
    nn /= len;
    if (nn.dot(up) < 0)
      nn = -nn;
    if (nn.dot(up) < cos_tilt)
      continue;
    const double d = -nn.dot(cv::Vec3d(a.x, a.y, a.z));
    if (d < kMinCameraHeightMm || !near_prior(nn, d)) // the camera stands above its ground
      continue;
    std::size_t in = 0, under = 0;
    for (const cv::Point3d &q : X) {
      const double h = nn.dot(cv::Vec3d(q.x, q.y, q.z)) + d;
      if (std::abs(h) <= tol_at(q))
        ++in;
      else if (h < -3 * tol_at(q))
        ++under;
    }
    if (in > best_inliers && under * 50 <= n && broad(nn, d)) {
      best_inliers = in;
      best_n = nn;
      best_d = d;
    }
  }
  if (best_inliers < min_inliers)
    return keep_prior();
  // Least squares on the inliers (the plane through their centroid, normal = the smallest
  // principal axis).
  cv::Mat pts(0, 3, CV_64F);
  for (const cv::Point3d &q : X)
    if (std::abs(best_n.dot(cv::Vec3d(q.x, q.y, q.z)) + best_d) <= tol_at(q))
      pts.push_back(cv::Mat(cv::Matx13d(q.x, q.y, q.z)));
  cv::PCA pca(pts, cv::noArray(), cv::PCA::DATA_AS_ROW);
  cv::Vec3d nn(pca.eigenvectors.at<double>(2, 0), pca.eigenvectors.at<double>(2, 1),
               pca.eigenvectors.at<double>(2, 2));
  if (nn.dot(up) < 0)
    nn = -nn;
  const cv::Vec3d m(pca.mean.at<double>(0), pca.mean.at<double>(1), pca.mean.at<double>(2));
  if (nn.dot(up) < cos_tilt || !near_prior(nn, -nn.dot(m)))
    nn = best_n;
  best.found = true;
  best.normal = nn;
  best.d = -nn.dot(m);
  best.inliers = std::size_t(pts.rows);
  return best;
}

bool other_class(PointClass c)
{
  return c != PointClass::Canopy && c != PointClass::Unknown;
}

} // namespace

void validate(const CanopyParams &p)
{
  require(p.near_mm >= 0 && std::isfinite(p.near_mm), "near_mm", ">= 0");
  require(p.far_mm >= 0 && std::isfinite(p.far_mm), "far_mm", ">= 0");
  require(p.far_mm == 0 || p.far_mm > p.near_mm, "far_mm", "0 or above near_mm");
  require(p.min_height_mm >= -100000 && p.min_height_mm <= 100000, "min_height_mm", "-100 m to 100 m");
  require(p.max_height_mm == 0 || p.max_height_mm > p.min_height_mm, "max_height_mm",
          "0 or above min_height_mm");
  require(p.ground != GroundModel::Rig || p.camera_height_mm > 0, "camera_height_mm",
          "above 0 with the rig's ground model");
  require(std::abs(p.camera_pitch_deg) <= 80, "camera_pitch_deg", "-80 to 80 degrees");
  require(p.ground_max_tilt_deg > 0 && p.ground_max_tilt_deg <= 60, "ground_max_tilt_deg",
          "above 0, at most 60 degrees");
  require(p.ground_tolerance_mm > 0, "ground_tolerance_mm", "above 0");
  require(p.ground_prior_tilt_deg > 0 && p.ground_prior_tilt_deg <= 60, "ground_prior_tilt_deg",
          "above 0, at most 60 degrees");
  require(p.ground_prior_shift_mm > 0, "ground_prior_shift_mm", "above 0");
  require(p.layer_bin_mm >= 5 && p.layer_bin_mm <= 1000, "layer_bin_mm", "5 to 1000 mm");
  require(p.layer_min_share > 0 && p.layer_min_share <= 1, "layer_min_share", "above 0, at most 1");
  require(p.layer_gap_mm >= p.layer_bin_mm, "layer_gap_mm", "at least layer_bin_mm");
  require(p.max_row_depth_mm >= p.layer_bin_mm, "max_row_depth_mm", "at least layer_bin_mm");
  require(p.min_gap_mm >= 10, "min_gap_mm", "at least 10 mm");
  require(p.valley_share >= 0 && p.valley_share < 1, "valley_share", "0 (off) to below 1");
  require(p.min_crown_mm >= 0 && p.min_crown_mm <= 10000, "min_crown_mm", "0 to 10000 mm");
  require(p.sample_spacing_px >= 0, "sample_spacing_px", ">= 0");
  require(p.seam_half_window >= 0 && p.seam_half_window <= 15, "seam_half_window", "0 to 15 px");
}

void GroundTracker::update(const GroundPlane &ground)
{
  if (ground.found && !ground.held) {
    prior_ = ground;
    held_ = 0;
  } else if (prior_.found && ++held_ > max_held_) {
    prior_ = GroundPlane();
    held_ = 0;
  }
}

CanopyResult select_canopy(const cv::Mat &vegetation, const std::vector<PixelPoint> &points,
                           const StereoGeometry &g, const CanopyParams &p, const cv::Mat &left,
                           const cv::Mat &right, ChannelOrder order, const Silhouette *colour)
{
  validate(p);
  require_valid(g, "the canopy", "select_canopy");
  if (vegetation.type() != CV_8U || vegetation.size() != g.view_size)
    throw BadInput("The vegetation mask does not fit the view: give an 8-bit mask of the view's "
                   "size.",
                   "select_canopy: mask type " + std::to_string(vegetation.type()) + ", " +
                       std::to_string(vegetation.cols) + "x" + std::to_string(vegetation.rows) +
                       " for a view of " + std::to_string(g.view_size.width) + "x" +
                       std::to_string(g.view_size.height));
  const bool seam = p.seam_half_window > 0 && !left.empty() && !right.empty();
  if (seam && (left.size() != g.view_size || right.size() != g.view_size))
    throw BadInput("The views are not of the stereo geometry's view size: give the rectified "
                   "views the geometry describes.",
                   "select_canopy: left " + std::to_string(left.cols) + "x" +
                       std::to_string(left.rows) + ", right " + std::to_string(right.cols) +
                       "x" + std::to_string(right.rows) + ", geometry " +
                       std::to_string(g.view_size.width) + "x" +
                       std::to_string(g.view_size.height));

  CanopyResult r;
  const cv::Size size = g.view_size;
  r.classes.assign(points.size(), PointClass::Unknown);
  r.silhouette.mask = cv::Mat::zeros(size, CV_8U);

  // The vegetation points: valid, on the view, on (or next to) the mask.
  std::vector<int> use;
  use.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const PixelPoint &q = points[i];
    if (!q.p.valid || !(q.p.z > 0) || !std::isfinite(q.px.x) || !std::isfinite(q.px.y))
      continue;
    const int x = int(std::lround(q.px.x)), y = int(std::lround(q.px.y));
    if (x < 0 || y < 0 || x >= size.width || y >= size.height || !vegetation.at<uchar>(y, x))
      continue;
    use.push_back(int(i));
  }
  if (use.empty())
    return r;
  auto P = [&](int i) {
    const Point3 &q = points[std::size_t(i)].p;
    return cv::Point3d(q.x, q.y, q.z);
  };

  // 1. The ground.
  const cv::Vec3d up_cam(0, -std::cos(p.camera_pitch_deg * kDeg), -std::sin(p.camera_pitch_deg * kDeg));
  const cv::Vec3d up = g.R1 * up_cam;
  if (p.ground == GroundModel::Rig) {
    r.ground.found = true;
    r.ground.normal = up;
    r.ground.d = p.camera_height_mm;
  } else if (p.ground == GroundModel::Fit) {
    std::vector<cv::Point3d> X;
    X.reserve(use.size());
    for (int i : use)
      X.push_back(P(i));
    r.ground = fit_ground(X, p, up);
  }
  std::vector<int> rest;
  rest.reserve(use.size());
  for (int i : use) {
    if (r.ground.found) {
      const double h = r.ground.height_of(P(i));
      if (h < p.min_height_mm) {
        r.classes[std::size_t(i)] = PointClass::Ground;
        continue;
      }
      if (p.max_height_mm > 0 && h > p.max_height_mm) {
        r.classes[std::size_t(i)] = PointClass::High;
        continue;
      }
    }
    rest.push_back(i);
  }
  if (rest.empty())
    return r;
  const int cell = std::max(8, size.width / 81);
  std::vector<double> w = area_weights(points, rest, size, cell);

  // 2. The near row in depth.
  if (p.near_mm > 0 || p.far_mm > 0) {
    r.zone_from_data = false;
    r.near_mm = p.near_mm;
    r.far_mm = p.far_mm > 0 ? p.far_mm : std::numeric_limits<double>::infinity();
  } else {
    double zmin = std::numeric_limits<double>::infinity(), zmax = 0, total = 0;
    for (std::size_t k = 0; k < rest.size(); ++k) {
      zmin = std::min(zmin, P(rest[k]).z);
      zmax = std::max(zmax, P(rest[k]).z);
      total += w[k];
    }
    const int nb = int((zmax - zmin) / p.layer_bin_mm) + 1;
    std::vector<double> hist(std::size_t(nb), 0.0);
    for (std::size_t k = 0; k < rest.size(); ++k)
      hist[std::size_t((P(rest[k]).z - zmin) / p.layer_bin_mm)] += w[k];
    const int gap_bins = std::max(1, int(std::lround(p.layer_gap_mm / p.layer_bin_mm)));
    const auto runs = occupied_runs(hist, 0.002 * total, gap_bins);
    // A run longer than a row is cut at max_row_depth_mm behind its front: its last bin.
    const int row_bins = int(p.max_row_depth_mm / p.layer_bin_mm);
    const auto run_end = [&](const cv::Vec2i &run) { return std::min(run[1], run[0] + row_bins); };
    int chosen = -1;
    double best_w = -1;
    int best = -1;
    for (std::size_t k = 0; k < runs.size(); ++k) {
      const int last = run_end(runs[k]);
      double sum = 0;
      for (int b = runs[k][0]; b <= last; ++b)
        sum += hist[std::size_t(b)];
      if (sum > best_w) {
        best_w = sum;
        best = int(k);
      }
      if (chosen < 0 && sum >= p.layer_min_share * total)
        chosen = int(k);
    }
    if (chosen < 0)
      chosen = best;
    if (chosen < 0)
      return r;
    const cv::Vec2i &run = runs[std::size_t(chosen)];
    const int last = run_end(run);
    r.near_mm = zmin + (run[0] - 1) * p.layer_bin_mm;
    // Behind the layer lies an empty stretch of at least gap_bins: a point within its first half
    // (too few to occupy a bin: a leaf cluster deep in a crown, seen through a hole) is nearer
    // the layer than anything behind it, and is the layer's. A layer cut at max_row_depth_mm
    // goes on behind the cut: it ends two bins past it.
    r.far_mm = zmin + (last < run[1] ? last + 2 : last + 1 + gap_bins / 2) * p.layer_bin_mm;
  }
  std::vector<int> zone;
  std::vector<double> zw;
  for (std::size_t k = 0; k < rest.size(); ++k) {
    const double z = P(rest[k]).z;
    if (z < r.near_mm)
      r.classes[std::size_t(rest[k])] = PointClass::Front;
    else if (z > r.far_mm)
      r.classes[std::size_t(rest[k])] = PointClass::Behind;
    else {
      zone.push_back(rest[k]);
      zw.push_back(w[k]);
    }
  }
  if (zone.empty())
    return r;

  // 3. Along the row: segments of x separated by empty stretches.
  {
    const double bin = std::max(5.0, 0.25 * p.min_gap_mm);
    double xmin = std::numeric_limits<double>::infinity(), xmax = -xmin;
    for (int i : zone) {
      xmin = std::min(xmin, P(i).x);
      xmax = std::max(xmax, P(i).x);
    }
    const int nb = int((xmax - xmin) / bin) + 1;
    std::vector<double> hist(std::size_t(nb), 0.0);
    std::vector<int> count(std::size_t(nb), 0);
    double total = 0;
    for (std::size_t k = 0; k < zone.size(); ++k) {
      const std::size_t b = std::size_t((P(zone[k]).x - xmin) / bin);
      hist[b] += zw[k];
      ++count[b];
      total += zw[k];
    }
    // Occupied: at least two points, and a weight that is not a stray point's.
    std::vector<double> occ(hist.size(), 0.0);
    for (std::size_t b = 0; b < hist.size(); ++b)
      occ[b] = count[b] >= 2 ? hist[b] : 0.0;
    auto runs = occupied_runs(occ, 0.001 * total,
                              std::max(1, int(std::ceil(p.min_gap_mm / bin))));
    if (p.mode == CanopyMode::Tree && p.valley_share > 0) {
      // The top line of each bin: the height of its highest point (above the ground when it is
      // known, else up in the camera frame).
      std::vector<double> top(hist.size(), -std::numeric_limits<double>::infinity());
      std::vector<double> bottom(hist.size(), std::numeric_limits<double>::infinity());
      std::vector<double> heights(zone.size());
      for (std::size_t k = 0; k < zone.size(); ++k) {
        const cv::Point3d X = P(zone[k]);
        heights[k] = r.ground.found ? r.ground.height_of(X) : -X.y;
        const std::size_t b = std::size_t((X.x - xmin) / bin);
        top[b] = std::max(top[b], heights[k]);
        bottom[b] = std::min(bottom[b], heights[k]);
      }
      runs = split_at_valleys(runs, top, bottom, heights, zone,
                              [&](int i) { return int((P(i).x - xmin) / bin); }, bin, p);
    }
    r.n_segments = int(runs.size());
    // Points in no run (stray bins) go to the nearest run.
    auto run_of = [&](double x) {
      const double b = (x - xmin) / bin;
      int bestk = 0;
      double bestd = std::numeric_limits<double>::infinity();
      for (std::size_t k = 0; k < runs.size(); ++k) {
        const double d = b < runs[k][0] ? runs[k][0] - b : (b > runs[k][1] + 1 ? b - runs[k][1] - 1 : 0);
        if (d < bestd) {
          bestd = d;
          bestk = int(k);
        }
      }
      return bestk;
    };
    int front = 0;
    if (p.mode == CanopyMode::Tree && !runs.empty()) {
      // The tree in front: the run holding the optical axis (x = 0 at the row's depth), or the
      // one nearest to it.
      front = run_of(0.0);
      // Where the tree ends along the row: halfway across the gaps beside it.
      const std::size_t f = std::size_t(front);
      if (f > 0)
        r.cut_lo_mm = xmin + 0.5 * (runs[f - 1][1] + 1 + runs[f][0]) * bin;
      if (f + 1 < runs.size())
        r.cut_hi_mm = xmin + 0.5 * (runs[f][1] + 1 + runs[f + 1][0]) * bin;
    }
    r.left_mm = std::numeric_limits<double>::infinity();
    r.right_mm = -r.left_mm;
    std::vector<std::vector<double>> seg_z(std::max<std::size_t>(runs.size(), 1));
    r.segments.assign(seg_z.size(), RowSegment{});
    for (auto &s : r.segments) {
      s.lo_mm = std::numeric_limits<double>::infinity();
      s.hi_mm = -s.lo_mm;
    }
    // Runs a valley cut apart lie one bin apart (the valley's); an empty stretch between runs
    // is at least min_gap_mm, four bins or more.
    for (std::size_t k = 0; k + 1 < runs.size(); ++k)
      if (runs[k + 1][0] - runs[k][1] <= 2)
        r.segments[k].joined_hi = r.segments[k + 1].joined_lo = true;
    for (auto &s : r.segments)
      s.lo_clear_mm = s.hi_clear_mm = std::numeric_limits<double>::infinity();
    for (int i : zone) {
      const int k = runs.empty() ? 0 : run_of(P(i).x);
      const bool in = runs.empty() || p.mode == CanopyMode::Row || k == front;
      r.classes[std::size_t(i)] = in ? PointClass::Canopy : PointClass::Neighbour;
      RowSegment &s = r.segments[std::size_t(k)];
      if (P(i).x < s.lo_mm) {
        s.lo_mm = P(i).x;
        s.lo_y_mm = P(i).y;
        s.lo_z_mm = P(i).z;
      }
      if (P(i).x > s.hi_mm) {
        s.hi_mm = P(i).x;
        s.hi_y_mm = P(i).y;
        s.hi_z_mm = P(i).z;
      }
      // Its distance from the view's edges, in px of both views (the point needs both), then
      // mm at its depth: (column + 0.5) * z / fx is its distance from the ray of view_slopes().
      const double xl = points[std::size_t(i)].px.x;
      const double xr = xl - (g.fx * g.baseline_mm / P(i).z + g.doffs());
      const double mm_per_px = P(i).z / g.fx;
      s.lo_clear_mm = std::min(s.lo_clear_mm, (std::min(xl, xr) + 0.5) * mm_per_px);
      s.hi_clear_mm =
          std::min(s.hi_clear_mm, (size.width - 0.5 - std::max(xl, xr)) * mm_per_px);
      ++s.n_points;
      s.selected = in;
      seg_z[std::size_t(k)].push_back(P(i).z);
      if (in) {
        ++r.n_canopy_points;
        r.left_mm = std::min(r.left_mm, P(i).x);
        r.right_mm = std::max(r.right_mm, P(i).x);
      }
    }
    for (std::size_t k = 0; k < r.segments.size(); ++k) {
      auto &z = seg_z[k];
      if (z.empty())
        continue;
      const auto q = z.begin() + std::ptrdiff_t(0.05 * double(z.size() - 1));
      std::nth_element(z.begin(), q, z.end());
      r.segments[k].near_mm = *q;
    }
    r.segments.erase(std::remove_if(r.segments.begin(), r.segments.end(),
                                    [](const RowSegment &s) { return s.n_points == 0; }),
                     r.segments.end());
  }
  if (r.n_canopy_points == 0) {
    r.left_mm = r.right_mm = 0;
    return r;
  }

  // 4. The mask, region by region of the vegetation mask (within the colour silhouette's box).
  const cv::Rect vbox = colour && colour->present
                            ? ((colour->bbox + cv::Size(2, 2)) - cv::Point(1, 1)) &
                                  cv::Rect(cv::Point(0, 0), size)
                            : cv::Rect(cv::Point(0, 0), size);
  cv::Mat labels(size, CV_32S, cv::Scalar(0)), region_stats, region_centroids;
  const int n_regions = cv::connectedComponentsWithStats(vegetation(vbox), labels(vbox),
                                                         region_stats, region_centroids, 8, CV_32S);
  std::vector<int> n_in(std::size_t(n_regions), 0), n_out(std::size_t(n_regions), 0);
  for (int i : use) {
    const cv::Point px(int(std::lround(points[std::size_t(i)].px.x)),
                       int(std::lround(points[std::size_t(i)].px.y)));
    const int l = labels.at<int>(px);
    if (r.classes[std::size_t(i)] == PointClass::Canopy)
      ++n_in[std::size_t(l)];
    else if (other_class(r.classes[std::size_t(i)]))
      ++n_out[std::size_t(l)];
  }
  // How far a sample speaks for its surroundings: 1.5 sample spacings (full-size px).
  const double spacing = p.sample_spacing_px > 0
                             ? p.sample_spacing_px
                             : std::sqrt(double(cv::countNonZero(vegetation)) / double(use.size()));
  const float reach = float(std::max(4.0, 1.5 * spacing));
  // Each region's area far from every sample (full-size px): more than kUnreachedSpacings
  // sample spacings from the nearest one, so that a whole patch of grid points failed to match
  // there (a surface without texture, such as mown grass), not a sliver along an edge. The strip
  // along the left border that the right camera does not see at the near row's depth has no
  // samples either and does not count. Counted on a grid reduced by 2.
  std::vector<double> unreached(std::size_t(n_regions), 0.0);
  // The columns left of this the right camera does not see at the near row's depth.
  const double one_view = r.near_mm > 0 ? g.fx * g.baseline_mm / r.near_mm + g.doffs() : 0.0;
  {
    const int f = 2;
    const cv::Size ss((vbox.width + f - 1) / f, (vbox.height + f - 1) / f);
    cv::Mat free_all(ss, CV_8U, cv::Scalar(255)), dist;
    for (int i : use) {
      if (r.classes[std::size_t(i)] == PointClass::Unknown)
        continue;
      const cv::Point q((int(std::lround(points[std::size_t(i)].px.x)) - vbox.x) / f,
                        (int(std::lround(points[std::size_t(i)].px.y)) - vbox.y) / f);
      if (cv::Rect(cv::Point(0, 0), ss).contains(q))
        free_all.at<uchar>(q) = 0;
    }
    cv::distanceTransform(free_all, dist, cv::DIST_L2, 3);
    const float far_px = float(kUnreachedSpacings * spacing);
    for (int y = 0; y < ss.height; ++y) {
      const float *d = dist.ptr<float>(y);
      const int *lab = labels.ptr<int>(vbox.y + y * f) + vbox.x;
      for (int x = 0; x < ss.width; ++x)
        if (lab[x * f] && d[x] * f > far_px && vbox.x + x * f >= one_view)
          unreached[std::size_t(lab[x * f])] += f * f;
    }
  }
  // 0: not canopy, 1: the whole region, 2: split by the samples.
  std::vector<uchar> kind(std::size_t(n_regions), 0);
  cv::Rect mixed_box;
  bool whole = true; // every region is canopy whole: the canopy is the colour silhouette
  for (int l = 1; l < n_regions; ++l) {
    // A few points of something else in a crown (the background seen through a hole, a stray
    // match) do not make its region a shared one.
    const int in = n_in[std::size_t(l)], out_ = n_out[std::size_t(l)];
    const bool shared = out_ >= std::max(kMinOtherPoints, int(kMinOtherShare * (in + out_))) ||
                        unreached[std::size_t(l)] >= spacing * spacing;
    kind[std::size_t(l)] = in == 0 ? 0 : shared ? 2 : 1;
    whole = whole && kind[std::size_t(l)] == 1;
    if (kind[std::size_t(l)] == 2)
      mixed_box |= cv::Rect(region_stats.at<int>(l, cv::CC_STAT_LEFT) + vbox.x,
                            region_stats.at<int>(l, cv::CC_STAT_TOP) + vbox.y,
                            region_stats.at<int>(l, cv::CC_STAT_WIDTH),
                            region_stats.at<int>(l, cv::CC_STAT_HEIGHT));
  }
  if (whole && colour && colour->present) {
    const cv::Mat own = vegetation.clone();
    r.silhouette = *colour;
    r.silhouette.mask = own;
    r.present = true;
    return r;
  }
  cv::Mat &mask = r.silhouette.mask;
  for (int y = vbox.y; y < vbox.br().y; ++y) {
    const int *lab = labels.ptr<int>(y);
    uchar *m = mask.ptr<uchar>(y);
    for (int x = vbox.x; x < vbox.br().x; ++x)
      if (kind[std::size_t(lab[x])] == 1)
        m[x] = 255;
  }
  if (!mixed_box.empty()) {
    // The split runs on a grid reduced by f (2 for a large region: a decision every other pixel
    // in x and y, which the 7x7 patches of the seam test do not resolve finer anyway), and its
    // result is brought back to full size inside the colour mask.
    const cv::Rect box = mixed_box;
    const int f = size.area() >= kSplitHalfSizeMinPx ? 2 : 1;
    const cv::Size ss((box.width + f - 1) / f, (box.height + f - 1) / f);
    auto full = [&](int xs, int ys) { return cv::Point(box.x + xs * f, box.y + ys * f); };
    cv::Mat split(ss, CV_8U, cv::Scalar(0)); // 255 canopy, kUnknown, 0 not; only in mixed regions
    cv::Mat mixed(ss, CV_8U, cv::Scalar(0));
    for (int y = 0; y < ss.height; ++y)
      for (int x = 0; x < ss.width; ++x) {
        const cv::Point q = full(x, y);
        mixed.at<uchar>(y, x) = kind[std::size_t(labels.at<int>(std::min(q.y, size.height - 1),
                                                                std::min(q.x, size.width - 1)))] == 2
                                    ? 255
                                    : 0;
      }
    // Each cell of a mixed region takes the class of the nearest sample: two distance
    // transforms, one to the canopy's samples and one to the others', with the sample each
    // distance comes from.
    cv::Mat free_in(ss, CV_8U, cv::Scalar(255)), free_out(ss, CV_8U, cv::Scalar(255));
    auto cell_of = [&](int i, cv::Point &c) {
      c = cv::Point((int(std::lround(points[std::size_t(i)].px.x)) - box.x) / f,
                    (int(std::lround(points[std::size_t(i)].px.y)) - box.y) / f);
      return cv::Rect(cv::Point(0, 0), ss).contains(c);
    };
    for (int i : use) {
      const PointClass c = r.classes[std::size_t(i)];
      cv::Point q;
      if (c != PointClass::Unknown && cell_of(i, q))
        (c == PointClass::Canopy ? free_in : free_out).at<uchar>(q) = 0;
    }
    cv::Mat d_in, d_out, l_in, l_out;
    cv::distanceTransform(free_in, d_in, l_in, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
    cv::distanceTransform(free_out, d_out, l_out, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
    // The disparity of each label's sample (the seam test, and where the pixel lies along the
    // row).
    double lmax_in = 0, lmax_out = 0;
    cv::minMaxLoc(l_in, nullptr, &lmax_in);
    cv::minMaxLoc(l_out, nullptr, &lmax_out);
    std::vector<float> disp_in(std::size_t(lmax_in) + 1, -1.0f), disp_out(std::size_t(lmax_out) + 1, -1.0f);
    for (int i : use) {
      const PointClass c = r.classes[std::size_t(i)];
      cv::Point q;
      if (c == PointClass::Unknown || !cell_of(i, q))
        continue;
      const float d = float(g.fx * g.baseline_mm / points[std::size_t(i)].p.z + g.doffs());
      if (c == PointClass::Canopy)
        disp_in[std::size_t(l_in.at<int>(q))] = d;
      else
        disp_out[std::size_t(l_out.at<int>(q))] = d;
    }
    const bool cut = std::isfinite(r.cut_lo_mm) || std::isfinite(r.cut_hi_mm);
    cv::Mat L, R, Lback;
    int rx0 = 0;
    const int h = p.seam_half_window;
    if (seam) {
      // Right-view columns the disparities can reach.
      float dmax = 0;
      for (float d : disp_in)
        dmax = std::max(dmax, d);
      for (float d : disp_out)
        dmax = std::max(dmax, d);
      rx0 = std::max(0, box.x - int(std::ceil(dmax)) - h - 3);
      const int rx1 = std::min(size.width, box.x + box.width + h + 3);
      R = to_gray8(right(cv::Rect(rx0, box.y, rx1 - rx0, box.height)), order);
      // Left-view columns those right-view columns see the farther surfaces at (the check back
      // from the right view), from rx0 on; they hold the box's, which the seam test reads.
      const int lx1 = std::min(size.width, rx1 + int(std::ceil(dmax)) + 3);
      Lback = to_gray8(left(cv::Rect(rx0, box.y, lx1 - rx0, box.height)), order);
      L = Lback(cv::Rect(box.x - rx0, 0, box.width, box.height));
    }
    detail::Patch patch, back_patch;
    // Best ZNCC of the pixel at (x, y) (box coordinates) with the right view at disparities
    // d_in and d_out (whole pixels within +-2 of each), over shiftable windows: the patch
    // centred on the pixel and the two with the pixel at their top or bottom edge, so that a
    // pixel below or above a depth edge is judged by a window on its own side. (Windows shifted
    // sideways would give the background beside a near surface's left edge, which the right
    // camera does not see, the near surface's match.) Each window's patch is built once; the
    // shifted ones are only tried when the centred one leaves the nearer hypothesis short of a
    // clear match.
    // `in_at` (when given) receives the right-view window (column in R, row) of the best d_in
    // score.
    // With `in_only` the d_out score is not computed (s_out stays -2).
    auto seam_scores = [&](int x, int y, float d_in, float d_out, double &s_in, double &s_out,
                           cv::Point *in_at = nullptr, bool in_only = false) {
      s_in = s_out = -2;
      static const int shifts[3][2] = {{0, 0}, {0, -1}, {0, 1}};
      const bool in_near = in_only || d_in > d_out;
      for (const auto &sh : shifts) {
        const int px = x + sh[0] * h, py = y + sh[1] * h;
        if (px - h < 0 || px + h >= L.cols || py - h < 0 || py + h >= L.rows ||
            !detail::centred_patch(L, px, py, h, patch))
          continue;
        for (int k = 0; k < (in_only ? 1 : 2); ++k) {
          double &best = k == 0 ? s_in : s_out;
          const int xr_c = int(std::lround(px + box.x - (k == 0 ? d_in : d_out))) - rx0;
          for (int dx = -2; dx <= 2; ++dx) {
            const int xr = xr_c + dx;
            if (xr - h >= 0 && xr + h < R.cols) {
              const double score = detail::zncc(patch, R, xr, py);
              if (score > best) {
                best = score;
                if (k == 0 && in_at)
                  *in_at = cv::Point(xr, py);
              }
            }
          }
        }
        if ((in_near ? s_in : s_out) >= kSeamClearScore)
          break;
      }
    };
    // The check back from the right view: the best ZNCC of the right-view window at `at` (R
    // coordinates) with the left view at disparity d (+-2 px), the left pixel that would show
    // the same surface if it lies at that disparity.
    auto back_score = [&](cv::Point at, float d) {
      double best = -2;
      if (at.y - h < 0 || at.y + h >= R.rows ||
          !detail::centred_patch(R, at.x, at.y, h, back_patch))
        return best;
      const int xl_c = at.x + int(std::lround(d));
      for (int dx = -2; dx <= 2; ++dx) {
        const int xl = xl_c + dx;
        if (xl - h >= 0 && xl + h < Lback.cols)
          best = std::max(best, detail::zncc(back_patch, Lback, xl, at.y));
      }
      return best;
    };
    for (int y = 0; y < ss.height; ++y) {
      const float *di = d_in.ptr<float>(y), *dout = d_out.ptr<float>(y);
      const int *li = l_in.ptr<int>(y);
      const uchar *mx = mixed.ptr<uchar>(y);
      uchar *m = split.ptr<uchar>(y);
      for (int x = 0; x < ss.width; ++x) {
        if (!mx[x])
          continue;
        const float din = di[x] * f, dot = dout[x] * f; // full-size px
        // In the strip only the left camera sees, no sample can lie: the samples beside it
        // speak for it across the strip.
        const float rx = reach + std::max(0.0f, float(one_view - full(x, y).x));
        if (din > rx) {
          // Far from every canopy sample: another class's near it, or nobody's (a surface
          // without texture, such as mown grass, or a dark gap); decided below.
          m[x] = dot > rx ? kUnknown : 0;
          continue;
        }
        bool in = din <= dot;
        const float dv_in = disp_in[std::size_t(li[x])];
        if (in && cut && dv_in > 0) {
          // Along the row at the depth of the nearest canopy sample: beyond the gap to a
          // neighbour, the pixel is the neighbour's.
          const double X = (full(x, y).x - g.cx[0]) * g.baseline_mm / (dv_in - g.doffs());
          if (X < r.cut_lo_mm || X > r.cut_hi_mm)
            continue;
        }
        if (in)
          m[x] = 255;
      }
    }
    // Cells no sample reaches are canopy where the canopy encloses them (a hole without texture
    // in the crown), and not where they reach anything else (grass under the crown).
    {
      cv::Mat unknown, ul;
      cv::compare(split, kUnknown, unknown, cv::CMP_EQ);
      const int nu = cv::connectedComponents(unknown, ul, 8, CV_32S);
      std::vector<uchar> open(std::size_t(nu), 0);
      static const int dx[4] = {1, -1, 0, 0}, dy[4] = {0, 0, 1, -1};
      for (int y = 0; y < ss.height; ++y) {
        const int *u = ul.ptr<int>(y);
        for (int x = 0; x < ss.width; ++x) {
          if (!u[x] || open[std::size_t(u[x])])
            continue;
          // Open: on the box's border, or beside a cell that is neither canopy nor unknown.
          bool o = x == 0 || y == 0 || x == ss.width - 1 || y == ss.height - 1;
          for (int k = 0; k < 4 && !o; ++k) {
            const uchar v = split.at<uchar>(y + dy[k], x + dx[k]);
            o = v != 255 && v != kUnknown;
          }
          if (o)
            open[std::size_t(u[x])] = 1;
        }
      }
      for (int y = 0; y < ss.height; ++y) {
        const int *u = ul.ptr<int>(y);
        uchar *m = split.ptr<uchar>(y);
        for (int x = 0; x < ss.width; ++x)
          if (u[x])
            m[x] = open[std::size_t(u[x])] ? 0 : 255;
      }
    }
    // The seam: cells within `band` of the border between the canopy and the rest of its
    // region are tested by photo-consistency, the nearest canopy sample's disparity against the
    // nearest other sample's (when there is one within reach and it differs): the nearest
    // sample is only as right as the samples are dense, and grass without texture has few.
    if (seam) {
      const cv::Mat canopy_cells = split == 255, other_cells = mixed & (split != 255);
      cv::Mat d_to_other, d_to_canopy;
      cv::distanceTransform(~other_cells, d_to_other, cv::DIST_L2, 3);
      cv::distanceTransform(~canopy_cells, d_to_canopy, cv::DIST_L2, 3);
      const float band = float(std::max(2.0, kSeamBandSpacings * spacing / f));
      // The canopy samples' range of disparities (full-size px).
      float din_lo = std::numeric_limits<float>::infinity(), din_hi = 0;
      for (float d : disp_in)
        if (d > 0) {
          din_lo = std::min(din_lo, d + 2.0f);
          din_hi = std::max(din_hi, d);
        }
      for (int y = 0; y < ss.height; ++y) {
        const float *di = d_in.ptr<float>(y);
        const float *to_other = d_to_other.ptr<float>(y), *to_canopy = d_to_canopy.ptr<float>(y);
        const int *li = l_in.ptr<int>(y), *lo = l_out.ptr<int>(y);
        const uchar *mx = mixed.ptr<uchar>(y);
        uchar *m = split.ptr<uchar>(y);
        for (int x = 0; x < ss.width; ++x) {
          if (!mx[x] || (m[x] == 255 ? to_other[x] : to_canopy[x]) > band)
            continue;
          const float dv_in = disp_in[std::size_t(li[x])];
          // Untestable: no nearby canopy sample, or the right view does not see the pixel at
          // the canopy's disparity (the strip along the left border): the nearest sample
          // decides.
          if (dv_in <= 0 || di[x] * f > reach || full(x, y).x - dv_in - h - 2 < 0)
            continue;
          if (cut) {
            const double X = (full(x, y).x - g.cx[0]) * g.baseline_mm / (dv_in - g.doffs());
            if (X < r.cut_lo_mm || X > r.cut_hi_mm)
              continue;
          }
          // The other surfaces the pixel may show: the nearest other sample's (however far
          // away), and the ground's at this pixel (grass varies in depth down the view).
          float others[2] = {disp_out[std::size_t(lo[x])], -1.0f};
          if (r.ground.found) {
            const cv::Point q = full(x, y);
            const cv::Vec3d ray((q.x - g.cx[0]) / g.fx, (q.y - g.cy) / g.fy, 1.0);
            const double down = r.ground.normal.dot(ray);
            if (down < 0)
              others[1] = float(g.fx * g.baseline_mm * -down / r.ground.d + g.doffs());
          }
          // A nearer surface is never hidden by a farther one: when the nearer hypothesis finds
          // no match, the pixel belongs to the farther one (seen by the left camera only, beside
          // the nearer surface's left edge) or is not known; the farther wins, and so it does
          // on a tie (a smooth patch matches anywhere).
          double s_in = -2, s_far = -2;
          bool canopy_nearer = true;
          cv::Point in_at(-1, -1);
          float d_far = 0;
          for (float dv_out : others) {
            if (dv_out <= 0 || std::abs(dv_in - dv_out) <= 3.0f)
              continue;
            double a, b;
            cv::Point at(-1, -1);
            seam_scores(x * f, y * f, dv_in, dv_out, a, b, &at);
            if (a > s_in) {
              s_in = a;
              in_at = at;
            }
            if (b > s_far) {
              s_far = b;
              d_far = dv_out;
              canopy_nearer = dv_in > dv_out;
            }
          }
          if (s_far <= -2) { // nothing else to weigh against: the canopy's own match decides
            double a, b;
            seam_scores(x * f, y * f, dv_in, dv_in, a, b);
            s_in = a;
          }
          bool in = canopy_nearer ? s_in >= kSeamMinScore && s_in > s_far
                                  : !(s_far >= kSeamMinScore && s_far > s_in);
          // Beside the canopy's left edge lies a strip of the farther surface the right camera
          // does not see (as wide as the two disparities differ): there the farther hypothesis
          // finds the canopy in the right view, and a surface with little texture of its own
          // (mown grass, shaded along the view) may correlate with itself a strip further on at
          // the canopy's disparity. The right-view window that canopy match found shows the
          // canopy if the pixel is the canopy's, and the farther surface if it is not; that
          // surface's own left pixel, at its disparity, then matches it at least as well.
          if (in && canopy_nearer && d_far > 0 && in_at.x >= 0 && back_score(in_at, d_far) >= s_in)
            in = false;
          // A leaf cluster behind the one whose sample is nearest may show here (a sliver
          // beside the nearer cluster's edge, where no sample lies): before the pixel goes, the
          // canopy is tried over its samples' range of disparities, in steps the +-2 px search
          // covers, unless the farther surface matches clearly.
          if (!in && canopy_nearer && s_far < kSeamClearScore) {
            for (float d = din_lo; d <= din_hi + 2.0f; d += 5.0f) {
              if (std::abs(d - dv_in) <= 2.0f || (d_far > 0 && std::abs(d - d_far) <= 3.0f))
                continue;
              double a, b;
              cv::Point at(-1, -1);
              seam_scores(x * f, y * f, d, d, a, b, &at, true);
              if (a >= kSeamMinScore && a > s_far &&
                  !(d_far > 0 && at.x >= 0 && back_score(at, d_far) >= a)) {
                in = true;
                break;
              }
            }
          }
          m[x] = in ? 255 : 0;
          ++r.n_seam_pixels;
        }
      }
    }
    // Slivers the split leaves along thin structures (a trunk's edge mixed with the grass behind
    // it) are no canopy: the split part is opened (5 full-size px).
    cv::morphologyEx(split, split, cv::MORPH_OPEN,
                     cv::getStructuringElement(cv::MORPH_ELLIPSE, f == 1 ? cv::Size(5, 5)
                                                                         : cv::Size(3, 3)));
    // Pieces of the canopy that hold none of its samples (islands the split left behind) go,
    // and so do crumbs (less than kMinPieceShare of the canopy pieces' area: a few pixels along
    // a trunk's edge where a trunk point fell).
    cv::Mat cl, stats, centroids;
    const int nc = cv::connectedComponentsWithStats(split, cl, stats, centroids, 8, CV_32S);
    std::vector<uchar> keep(std::size_t(nc), 0);
    for (int i : use) {
      cv::Point q;
      if (r.classes[std::size_t(i)] == PointClass::Canopy && cell_of(i, q))
        keep[std::size_t(cl.at<int>(q))] = 1;
    }
    keep[0] = 0; // the background, where a canopy sample the split turned down may lie
    double kept_area = 0;
    for (int k = 1; k < nc; ++k)
      if (keep[std::size_t(k)])
        kept_area += stats.at<int>(k, cv::CC_STAT_AREA);
    for (int k = 1; k < nc; ++k)
      if (stats.at<int>(k, cv::CC_STAT_AREA) < kMinPieceShare * kept_area)
        keep[std::size_t(k)] = 0;
    for (int y = 0; y < ss.height; ++y) {
      const int *c = cl.ptr<int>(y);
      uchar *m = split.ptr<uchar>(y);
      for (int x = 0; x < ss.width; ++x)
        m[x] = keep[std::size_t(c[x])] ? 255 : 0;
    }
    // Back to full size, inside the colour mask's mixed regions.
    cv::Mat part(box.size(), CV_8U, cv::Scalar(0));
    for (int y = 0; y < box.height; ++y) {
      const int *lab = labels.ptr<int>(y + box.y) + box.x;
      const uchar *sp = split.ptr<uchar>(y / f);
      uchar *m = part.ptr<uchar>(y);
      for (int x = 0; x < box.width; ++x)
        if (sp[x / f] && kind[std::size_t(lab[x])] == 2)
          m[x] = 255;
    }
    // A strip of it a few pixels tall that runs out of the canopy's body is not canopy: where
    // grass meets what stands behind it (a wall, the next row), the grass's top rows beside a
    // crown take the crown's samples as their nearest, in a strip taller than the opening
    // above removes. Such a strip set a crown's edge 28-45 mm out.
    detail::cut_thin_strips(part, kStripPx, kStripReachPx);
    cv::Mat into = mask(box);
    into |= part;
  }
  // Described over the canopy's bounding box and a pixel around it (a contour finder's border
  // reads as background, as the view's edge does): the rest of the view holds no canopy.
  const cv::Rect view(cv::Point(0, 0), size);
  cv::Rect around = cv::boundingRect(r.silhouette.mask);
  around = around.empty() ? view : (around + cv::Size(2, 2) - cv::Point(1, 1)) & view;
  r.present = describe_silhouette(r.silhouette, around, 1.0);
  return r;
}

CanopyDepth canopy_depth(const cv::Mat &left, const cv::Mat &right, const Silhouette &vegetation,
                         const std::vector<StereoMatch> &seeds, const StereoGeometry &g,
                         const CanopyDepthParams &p)
{
  if (vegetation.mask.empty())
    throw BadInput("The vegetation silhouette has no mask: the canopy depth needs the "
                   "segmentation's mask.",
                   "canopy_depth: Silhouette::mask is empty");
  if (p.coarse_points < 1)
    throw BadSettings("The canopy depth setting coarse_points is out of range: set it to 1 or "
                      "more.",
                      "canopy_depth: coarse_points = " + std::to_string(p.coarse_points));
  CanopyDepth out;
  // Colour views in grey once: both densifications and the seam test below read them, and each
  // would convert its crops again (cvtColor is per pixel: a crop of the grey view is the grey
  // crop). Views that do not fit each other or their layout go on as given, for the checks
  // downstream to name.
  cv::Mat left_grey = left, right_grey = right;
  if (!left.empty() && left.size() == right.size() && left.type() == right.type() &&
      left.depth() == CV_8U && left.channels() > 1 && left.channels() == p.grid.order.channels) {
    left_grey = to_gray8(left, p.grid.order);
    right_grey = to_gray8(right, p.grid.order);
  }
  // 1. Everything green, coarsely: the seeds and a coarse grid, triangulated without the
  // outlier cut (the next row is no outlier here, it is what the canopy is told from).
  DensifyParams coarse = p.grid;
  coarse.step = 0;
  coarse.target_points = p.coarse_points;
  coarse.edge_band = 0;
  DensifyStats coarse_stats;
  const std::vector<StereoMatch> grid0 =
      densify_matches(left_grey, right_grey, vegetation.mask, seeds, coarse, &coarse_stats);
  out.coarse = grid0.size();
  DepthParams range = p.filter;
  range.outlier_k = 0;
  std::vector<PixelPoint> pts;
  pts.reserve(seeds.size() + grid0.size());
  auto add = [&](const StereoMatch &m) {
    PixelPoint q;
    q.px = cv::Point2f(m.xl, m.yl);
    q.p.valid = triangulate_point(g, m.xl, m.yl, m.disparity(), q.p);
    pts.push_back(q);
  };
  for (const StereoMatch &m : seeds)
    add(m);
  for (const StereoMatch &m : grid0)
    add(m);
  {
    std::vector<Point3> p3(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i)
      p3[i] = pts[i].p;
    filter_depths(p3, range);
    for (std::size_t i = 0; i < pts.size(); ++i)
      pts[i].p.valid = p3[i].valid;
  }
  CanopyParams cp = p.canopy;
  if (cp.sample_spacing_px <= 0 && coarse_stats.step > 0)
    cp.sample_spacing_px = coarse_stats.step;
  out.canopy =
      select_canopy(vegetation.mask, pts, g, cp, left_grey, right_grey, p.grid.order, &vegetation);
  if (p.row_view && cp.mode == CanopyMode::Tree) {
    CanopyParams rp = cp;
    rp.mode = CanopyMode::Row;
    CanopyResult row =
        select_canopy(vegetation.mask, pts, g, rp, left_grey, right_grey, p.grid.order, &vegetation);
    out.row = std::move(row.silhouette);
    out.row.present = row.present && out.row.present;
  }
  if (out.canopy.present && cp.mode == CanopyMode::Tree)
    for (RowSegment &s : out.canopy.segments)
      if (s.selected)
        s.trunk_mm = find_trunk(left_grey, right_grey, vegetation.mask, out.canopy.silhouette.mask,
                                s, out.canopy.ground, g, &s.trunk_y_mm);

  // 2. The canopy alone, densely: seeded by the matches on it.
  out.matches = seeds;
  out.n_seeds = seeds.size();
  if (out.canopy.present) {
    std::vector<StereoMatch> on;
    for (std::size_t i = 0; i < seeds.size(); ++i)
      if (out.canopy.classes[i] == PointClass::Canopy)
        on.push_back(seeds[i]);
    // Too few SIFT matches on the canopy: the coarse grid's canopy points bound the search.
    if (int(on.size()) < p.grid.min_seeds)
      for (std::size_t i = 0; i < grid0.size(); ++i)
        if (out.canopy.classes[seeds.size() + i] == PointClass::Canopy)
          on.push_back(grid0[i]);
    const std::vector<StereoMatch> grid =
        densify_matches(left_grey, right_grey, out.canopy.silhouette.mask, on, p.grid);
    out.matches.insert(out.matches.end(), grid.begin(), grid.end());
  }

  // 3. Every point; those off the canopy are out of the zone.
  DepthResult &r = out.depth;
  r.points.resize(out.matches.size());
  std::size_t no_depth = 0, zone = 0;
  const cv::Mat &mask = out.canopy.silhouette.mask;
  for (std::size_t i = 0; i < out.matches.size(); ++i) {
    const StereoMatch &m = out.matches[i];
    Point3 &q = r.points[i];
    q.match_index = std::uint32_t(i);
    q.valid = triangulate_point(g, m.xl, m.yl, m.disparity(), q);
    if (!q.valid) {
      ++no_depth;
      continue;
    }
    const int x = int(std::lround(m.xl)), y = int(std::lround(m.yl));
    const bool on_mask = out.canopy.present && x >= 0 && y >= 0 && x < mask.cols &&
                         y < mask.rows && mask.at<uchar>(y, x);
    if (!on_mask || q.z < out.canopy.near_mm || q.z > out.canopy.far_mm ||
        q.x < out.canopy.cut_lo_mm || q.x > out.canopy.cut_hi_mm ||
        (i < out.n_seeds && out.canopy.classes[i] != PointClass::Canopy)) {
      q.valid = false;
      ++zone;
    }
  }
  r.stats = filter_depths(r.points, p.filter);
  r.stats.dropped_disparity = no_depth;
  r.stats.dropped_zone = zone;
  r.stats.n_points = r.points.size();
  return out;
}

double depth_support(const cv::Mat &mask, const std::vector<cv::Point2f> &px, double radius_px)
{
  if (mask.type() != CV_8U)
    throw BadInput("The silhouette mask is not 8-bit: the depth support needs an 8-bit mask.",
                   "depth_support: mask type " + std::to_string(mask.type()));
  const int total = cv::countNonZero(mask);
  if (total == 0)
    return 0.0;
  cv::Mat seen(mask.size(), CV_8U, cv::Scalar(0));
  const int r = std::max(0, int(std::lround(radius_px)));
  for (const cv::Point2f &p : px) {
    const cv::Point c(int(std::lround(p.x)), int(std::lround(p.y)));
    if (c.x < -r || c.y < -r || c.x >= mask.cols + r || c.y >= mask.rows + r)
      continue;
    cv::circle(seen, c, r, cv::Scalar(255), cv::FILLED);
  }
  cv::bitwise_and(seen, mask, seen);
  return double(cv::countNonZero(seen)) / double(total);
}

} // namespace treestereo
