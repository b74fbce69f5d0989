#include "treestereo/travel.hpp"

#include "treestereo/depth.hpp"
#include "treestereo/errors.hpp"
#include "treestereo/features.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>

namespace treestereo
{

namespace
{

void require(bool ok, const char *what, const char *field, const char *range)
{
  if (!ok)
    throw BadSettings(std::string("The ") + what + " setting " + field +
                          " is out of range: set it to " + range + ".",
                      std::string(what) + " parameters: " + field + " outside " + range);
}

// A 3-point sample is refused when its triangle is this flat (the sine of its angle at the first
// point, |ab x ac| / (|ab| |ac|)): the rotation about the near-line is then undetermined.
constexpr double kMinSampleSine = 0.05;
// The inliers must spread across their main direction by at least this share of their spread
// along it (ratio of standard deviations), else they lie on one line.
constexpr double kMinSpreadRatio = 0.01;
// Least-squares refits on the inliers, at most (each one re-decides the inliers).
constexpr int kRefits = 5;

// Weighted least-squares rotation and translation carrying a[i] onto b[i] (Kabsch): the SVD of
// the weighted cross-covariance, with the reflection removed.
void kabsch(const std::vector<cv::Point3d> &a, const std::vector<cv::Point3d> &b,
            const std::vector<double> &w, const std::vector<int> &use, cv::Matx33d &R, cv::Vec3d &t)
{
  double sw = 0;
  cv::Vec3d ca(0, 0, 0), cb(0, 0, 0);
  for (int i : use) {
    const double wi = w.empty() ? 1.0 : w[std::size_t(i)];
    sw += wi;
    ca += wi * cv::Vec3d(a[std::size_t(i)]);
    cb += wi * cv::Vec3d(b[std::size_t(i)]);
  }
  ca /= sw;
  cb /= sw;
  cv::Matx33d H = cv::Matx33d::zeros();
  for (int i : use) {
    const double wi = w.empty() ? 1.0 : w[std::size_t(i)];
    const cv::Vec3d da = cv::Vec3d(a[std::size_t(i)]) - ca, db = cv::Vec3d(b[std::size_t(i)]) - cb;
    H += wi * (da * db.t());
  }
  cv::Matx31d s;
  cv::Matx33d u, vt;
  cv::SVD::compute(H, s, u, vt);
  const cv::Matx33d v = vt.t();
  const double det = cv::determinant(v * u.t());
  R = v * cv::Matx33d::diag(cv::Vec3d(1, 1, det < 0 ? -1 : 1)) * u.t();
  t = cb - R * ca;
}

bool flat_sample(const cv::Point3d &a, const cv::Point3d &b, const cv::Point3d &c)
{
  const cv::Point3d ab = b - a, ac = c - a;
  const double n = cv::norm(ab) * cv::norm(ac);
  return !(n > 0) || cv::norm(ab.cross(ac)) < kMinSampleSine * n;
}

// True when the points lie (nearly) on one line or on one point.
bool collinear(const std::vector<cv::Point3d> &p, const std::vector<int> &use)
{
  if (use.size() < 3)
    return true;
  cv::Vec3d c(0, 0, 0);
  for (int i : use)
    c += cv::Vec3d(p[std::size_t(i)]);
  c /= double(use.size());
  cv::Matx33d S = cv::Matx33d::zeros();
  for (int i : use) {
    const cv::Vec3d d = cv::Vec3d(p[std::size_t(i)]) - c;
    S += d * d.t();
  }
  cv::Matx31d ev;
  cv::eigen(S, ev); // descending
  return !(ev(0) > 0) || ev(1) < kMinSpreadRatio * kMinSpreadRatio * ev(0);
}

double residual(const cv::Matx33d &R, const cv::Vec3d &t, const cv::Point3d &a,
                const cv::Point3d &b)
{
  return cv::norm(R * cv::Vec3d(a) + t - cv::Vec3d(b));
}

} // namespace

void validate(const RigidParams &p)
{
  require(p.iterations >= 1 && p.iterations <= 100000, "rigid", "iterations", "1 to 100000");
  require(p.confidence > 0 && p.confidence < 1, "rigid", "confidence", "above 0, below 1");
  require(p.inlier_mm > 0 && std::isfinite(p.inlier_mm), "rigid", "inlier_mm", "above 0");
  require(p.min_inliers >= 3, "rigid", "min_inliers", "at least 3");
}

RigidResult rigid_align(const std::vector<cv::Point3d> &from, const std::vector<cv::Point3d> &to,
                        const RigidParams &p, const std::vector<double> &tolerance_mm)
{
  validate(p);
  if (from.size() != to.size())
    throw BadInput("The two point sets to align differ in length: give one point in each per "
                   "correspondence.",
                   "rigid_align: " + std::to_string(from.size()) + " and " +
                       std::to_string(to.size()) + " points");
  if (!tolerance_mm.empty() && tolerance_mm.size() != from.size())
    throw BadInput("The tolerances do not match the correspondences: give one tolerance per "
                   "correspondence, or none.",
                   "rigid_align: " + std::to_string(tolerance_mm.size()) + " tolerances for " +
                       std::to_string(from.size()) + " correspondences");
  for (double tol : tolerance_mm)
    if (!(tol > 0) || !std::isfinite(tol))
      throw BadInput("A correspondence's tolerance cannot be used: give finite tolerances above "
                     "0 mm.",
                     "rigid_align: tolerance " + std::to_string(tol) + " mm");

  RigidResult out;
  const std::size_t n = from.size();
  // Non-finite correspondences take no part.
  std::vector<int> usable;
  for (std::size_t i = 0; i < n; ++i) {
    const cv::Point3d &a = from[i], &b = to[i];
    if (std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z) && std::isfinite(b.x) &&
        std::isfinite(b.y) && std::isfinite(b.z))
      usable.push_back(int(i));
  }
  if (usable.size() < 3 || usable.size() < std::size_t(p.min_inliers))
    return out;
  auto tol = [&](int i) {
    return tolerance_mm.empty() ? p.inlier_mm : tolerance_mm[std::size_t(i)];
  };
  std::vector<double> w;
  if (!tolerance_mm.empty()) {
    w.resize(n);
    for (std::size_t i = 0; i < n; ++i)
      w[i] = 1.0 / (tolerance_mm[i] * tolerance_mm[i]);
  }
  // Inliers of a motion and their summed squared residual (relative to their tolerances).
  auto inliers_of = [&](const cv::Matx33d &R, const cv::Vec3d &t, std::vector<int> &in) {
    in.clear();
    double cost = 0;
    for (int i : usable) {
      const double r = residual(R, t, from[std::size_t(i)], to[std::size_t(i)]) / tol(i);
      if (r <= 1.0) {
        in.push_back(i);
        cost += r * r;
      }
    }
    return cost;
  };

  cv::RNG rng(p.seed);
  std::vector<int> best, in;
  double best_cost = std::numeric_limits<double>::infinity();
  const int m = int(usable.size());
  int needed = p.iterations;
  for (int it = 0; it < needed && it < p.iterations; ++it) {
    const int i0 = usable[std::size_t(rng.uniform(0, m))];
    const int i1 = usable[std::size_t(rng.uniform(0, m))];
    const int i2 = usable[std::size_t(rng.uniform(0, m))];
    if (i0 == i1 || i0 == i2 || i1 == i2 ||
        flat_sample(from[std::size_t(i0)], from[std::size_t(i1)], from[std::size_t(i2)]) ||
        flat_sample(to[std::size_t(i0)], to[std::size_t(i1)], to[std::size_t(i2)]))
      continue;
    cv::Matx33d R;
    cv::Vec3d t;
    kabsch(from, to, {}, {i0, i1, i2}, R, t);
    const double cost = inliers_of(R, t, in);
    if (in.size() > best.size() || (in.size() == best.size() && cost < best_cost)) {
      best.swap(in);
      best_cost = cost;
      // Draws needed to see one all-inlier sample with the given confidence.
      const double share = double(best.size()) / m;
      const double clean = share * share * share;
      if (clean >= 1.0)
        needed = it + 1;
      else if (clean > 0)
        needed = int(std::min<double>(p.iterations,
                                      std::ceil(std::log(1 - p.confidence) / std::log(1 - clean))));
    }
  }
  if (best.size() < 3 || best.size() < std::size_t(p.min_inliers) || collinear(from, best))
    return out;

  // Least squares on the inliers until they no longer change.
  cv::Matx33d R;
  cv::Vec3d t;
  for (int k = 0; k < kRefits; ++k) {
    kabsch(from, to, w, best, R, t);
    inliers_of(R, t, in);
    if (in == best)
      break;
    if (in.size() < 3 || in.size() < std::size_t(p.min_inliers) || collinear(from, in))
      return out;
    best.swap(in);
  }
  kabsch(from, to, w, best, R, t);

  out.found = true;
  out.R = R;
  out.t = t;
  out.inliers = best.size();
  double ss = 0;
  for (int i : best) {
    const double r = residual(R, t, from[std::size_t(i)], to[std::size_t(i)]);
    ss += r * r;
  }
  out.rms_mm = std::sqrt(ss / double(best.size()));
  out.inlier.assign(n, false);
  for (int i : best)
    out.inlier[std::size_t(i)] = true;
  return out;
}

// ---- estimate_motion ----

void validate(const TravelParams &p)
{
  require(p.max_points >= 3 && p.max_points <= 100000, "travel", "max_points", "3 to 100000");
  require(p.scale > 0.05 && p.scale <= 1, "travel", "scale", "above 0.05, at most 1");
  require(p.window >= 5 && p.window <= 101 && p.window % 2 == 1, "travel", "window",
          "odd, 5 to 101 px");
  require(p.levels >= 0 && p.levels <= 8, "travel", "levels", "0 to 8");
  require(p.max_travel_mm >= 0 && p.max_travel_mm <= 100000, "travel", "max_travel_mm",
          "0 to 100000 mm");
  require(p.max_fb_px > 0 && std::isfinite(p.max_fb_px), "travel", "max_fb_px", "above 0");
  require(p.max_row_px > 0 && std::isfinite(p.max_row_px), "travel", "max_row_px", "above 0");
  require(p.tol_mm > 0 && std::isfinite(p.tol_mm), "travel", "tol_mm", "above 0");
  require(p.tol_px >= 0 && std::isfinite(p.tol_px), "travel", "tol_px", ">= 0");
  require(p.min_inliers >= 3, "travel", "min_inliers", "at least 3");
  require(p.ransac_iterations >= 1 && p.ransac_iterations <= 100000, "travel", "ransac_iterations",
          "1 to 100000");
}

namespace
{

// Which candidates lie near a depth edge: another point within radius_px (in the left view)
// differs in depth by more than kEdgeDepthShare. A patch across such an edge holds two surfaces
// that move apart between frames (parallax), and its track follows neither exactly.
constexpr double kEdgeDepthShare = 0.05;

std::vector<uchar> depth_edges(const std::vector<PixelPoint> &pts, const std::vector<int> &cand,
                               double radius_px, cv::Size size)
{
  std::vector<uchar> edge(pts.size(), 0);
  const double cell = std::max(1.0, radius_px);
  const int gw = int(size.width / cell) + 1, gh = int(size.height / cell) + 1;
  std::vector<std::vector<int>> bucket(std::size_t(gw) * std::size_t(gh));
  auto cell_of = [&](const cv::Point2f &q) {
    return cv::Point(std::clamp(int(q.x / cell), 0, gw - 1),
                     std::clamp(int(q.y / cell), 0, gh - 1));
  };
  for (int i : cand) {
    const cv::Point c = cell_of(pts[std::size_t(i)].px);
    bucket[std::size_t(c.y) * std::size_t(gw) + std::size_t(c.x)].push_back(i);
  }
  const double r2 = radius_px * radius_px;
  for (int i : cand) {
    const PixelPoint &q = pts[std::size_t(i)];
    const cv::Point c = cell_of(q.px);
    const double tol = kEdgeDepthShare * q.p.z;
    for (int y = std::max(0, c.y - 1); y <= std::min(gh - 1, c.y + 1) && !edge[std::size_t(i)]; ++y)
      for (int x = std::max(0, c.x - 1); x <= std::min(gw - 1, c.x + 1); ++x) {
        for (int j : bucket[std::size_t(y) * std::size_t(gw) + std::size_t(x)]) {
          const PixelPoint &o = pts[std::size_t(j)];
          const cv::Point2f d = o.px - q.px;
          if (double(d.x) * d.x + double(d.y) * d.y <= r2 && std::abs(o.p.z - q.p.z) > tol) {
            edge[std::size_t(i)] = 1;
            break;
          }
        }
        if (edge[std::size_t(i)])
          break;
      }
  }
  return edge;
}

// At most `cap` of the candidate points, one per cell of a grid over their bounding box: the
// one nearest the cell's centre, a point away from depth edges (`edge`) before any other. The
// grid is made finer while too few cells are occupied (points covering only part of their box),
// and thinned evenly when too many are.
std::vector<int> spread_points(const std::vector<PixelPoint> &pts, const std::vector<int> &cand,
                               const std::vector<uchar> &edge, int cap)
{
  if (cand.size() <= std::size_t(cap))
    return cand;
  cv::Rect2f box;
  {
    float x0 = std::numeric_limits<float>::max(), y0 = x0, x1 = -x0, y1 = -x0;
    for (int i : cand) {
      const cv::Point2f &q = pts[std::size_t(i)].px;
      x0 = std::min(x0, q.x);
      y0 = std::min(y0, q.y);
      x1 = std::max(x1, q.x);
      y1 = std::max(y1, q.y);
    }
    box = cv::Rect2f(x0, y0, std::max(x1 - x0, 1.0f), std::max(y1 - y0, 1.0f));
  }
  double cell = std::sqrt(double(box.area()) / cap);
  std::vector<int> chosen;
  for (int attempt = 0; attempt < 4; ++attempt) {
    const int gw = std::max(1, int(std::ceil(box.width / cell))),
              gh = std::max(1, int(std::ceil(box.height / cell)));
    std::vector<int> pick(std::size_t(gw) * std::size_t(gh), -1);
    std::vector<double> dist(pick.size(), std::numeric_limits<double>::infinity());
    for (int i : cand) {
      const cv::Point2f &q = pts[std::size_t(i)].px;
      const double fx = (q.x - box.x) / cell, fy = (q.y - box.y) / cell;
      const int cx = std::clamp(int(fx), 0, gw - 1), cy = std::clamp(int(fy), 0, gh - 1);
      const double dx = fx - (cx + 0.5), dy = fy - (cy + 0.5);
      const double d =
          dx * dx + dy * dy + (edge[std::size_t(i)] ? 1.0 : 0.0); // beyond any in-cell distance
      const std::size_t k = std::size_t(cy) * std::size_t(gw) + std::size_t(cx);
      if (d < dist[k]) {
        dist[k] = d;
        pick[k] = i;
      }
    }
    chosen.clear();
    for (int i : pick)
      if (i >= 0)
        chosen.push_back(i);
    if (chosen.size() >= std::size_t(cap) * 8 / 10)
      break;
    cell *= std::sqrt(double(chosen.size()) / cap);
  }
  if (chosen.size() > std::size_t(cap)) {
    std::vector<int> thin;
    const double step = double(chosen.size()) / cap;
    for (int k = 0; k < cap; ++k)
      thin.push_back(chosen[std::size_t(k * step)]);
    chosen.swap(thin);
  }
  return chosen;
}

cv::Mat reduced(const cv::Mat &view, double scale)
{
  const cv::Mat grey = to_gray8(view);
  if (scale >= 1)
    return grey;
  cv::Mat small;
  cv::resize(grey, small, cv::Size(), scale, scale, cv::INTER_AREA);
  return small;
}

std::vector<cv::Mat> pyramid(const cv::Mat &grey, const TravelParams &p)
{
  std::vector<cv::Mat> pyr;
  cv::buildOpticalFlowPyramid(grey, pyr, cv::Size(p.window, p.window), p.levels, true);
  return pyr;
}

// The travel that best explains the previous left view, tried over [-max_mm, max_mm] on views
// reduced to about kSearchWidthPx: each point of depth Z stood f T / Z px further right (T
// positive) in the previous view. Scored by the mean absolute difference of 5x5 patches,
// capped per point so that occlusions and points leaving the view weigh no more than a miss.
// With an expected travel (finite `expected_mm`) only expected_mm +- kExpectedSlack of it (at
// least kExpectedSlackMm) is tried, within the range.
constexpr int kSearchWidthPx = 160;
constexpr int kSearchHalf = 2;
constexpr double kSearchCap = 40.0;
// The expected travel's window: a rig's speed changes by far less than a quarter between two
// frames (a tractor gaining 2 m/s^2 changes a 7 frames/s step by 40 mm, a seventh of a 2 m/s
// step), and a standing rig that starts moves a few centimetres in a frame. Half of it let a
// key frame two steps back match at one step on the drive-by (1 m/s, seed 2).
constexpr double kExpectedSlack = 0.25;
constexpr double kExpectedSlackMm = 50.0;
// Points the search scores at most (an even share of those tracked): one travel for all of them
// needs no more, and the search is the dearest step after the tracking.
constexpr std::size_t kSearchPoints = 150;

double search_travel(const cv::Mat &prev, const cv::Mat &cur, double scale,
                     const std::vector<cv::Point2f> &px, const std::vector<double> &z, double fx,
                     double max_mm, double expected_mm)
{
  double c = scale;
  cv::Mat a = cur, b = prev;
  while (a.cols / 2 >= kSearchWidthPx) {
    cv::pyrDown(a, a);
    cv::pyrDown(b, b);
    c *= 0.5;
  }
  const int n = int(px.size()), side = 2 * kSearchHalf + 1;
  std::vector<int> patch(std::size_t(n) * side * side, -1);
  std::vector<cv::Point> at(px.size());
  double z_min = std::numeric_limits<double>::infinity();
  for (int i = 0; i < n; ++i) {
    at[std::size_t(i)] = cv::Point(int(std::lround(px[std::size_t(i)].x * c)),
                                   int(std::lround(px[std::size_t(i)].y * c)));
    const cv::Point q = at[std::size_t(i)];
    if (q.x < kSearchHalf || q.y < kSearchHalf || q.x >= a.cols - kSearchHalf ||
        q.y >= a.rows - kSearchHalf)
      continue;
    for (int dy = -kSearchHalf, k = 0; dy <= kSearchHalf; ++dy)
      for (int dx = -kSearchHalf; dx <= kSearchHalf; ++dx, ++k)
        patch[std::size_t(i) * side * side + std::size_t(k)] = a.at<uchar>(q.y + dy, q.x + dx);
    z_min = std::min(z_min, z[std::size_t(i)]);
  }
  if (!std::isfinite(z_min))
    return std::isfinite(expected_mm) ? std::clamp(expected_mm, -max_mm, max_mm) : 0.0;
  const double fc = fx * c;
  // Steps of half a pixel of shift for the nearest point.
  const double step = 0.5 * z_min / fc;
  double lo_mm = -max_mm, hi_mm = max_mm;
  if (std::isfinite(expected_mm)) {
    const double slack = std::max(kExpectedSlackMm, kExpectedSlack * std::abs(expected_mm));
    lo_mm = std::max(lo_mm, expected_mm - slack);
    hi_mm = std::min(hi_mm, expected_mm + slack);
    if (lo_mm > hi_mm) // expected beyond the range: its nearer end
      lo_mm = hi_mm = expected_mm < 0 ? -max_mm : max_mm;
  }
  const int k_lo = std::max(-2000, int(std::floor(lo_mm / step)));
  const int k_hi = std::min(2000, int(std::ceil(hi_mm / step)));
  double best_t = 0, best = std::numeric_limits<double>::infinity();
  for (int k = k_lo; k <= k_hi; ++k) {
    const double t = k * step;
    double score = 0;
    for (int i = 0; i < n; ++i) {
      const int *pa = &patch[std::size_t(i) * side * side];
      if (pa[0] < 0) {
        score += kSearchCap;
        continue;
      }
      const cv::Point q(at[std::size_t(i)].x + int(std::lround(fc * t / z[std::size_t(i)])),
                        at[std::size_t(i)].y);
      if (q.x < kSearchHalf || q.x >= b.cols - kSearchHalf) {
        score += kSearchCap;
        continue;
      }
      int sad = 0;
      for (int dy = -kSearchHalf, m = 0; dy <= kSearchHalf; ++dy) {
        const uchar *row = b.ptr<uchar>(q.y + dy) + q.x;
        for (int dx = -kSearchHalf; dx <= kSearchHalf; ++dx, ++m)
          sad += std::abs(int(row[dx]) - pa[m]);
      }
      score += std::min(kSearchCap, double(sad) / (side * side));
    }
    // Ties (a flat view) go to the smallest travel.
    if (score < best - 1e-9 || (std::abs(score - best) <= 1e-9 && std::abs(t) < std::abs(best_t))) {
      best = score;
      best_t = t;
    }
  }
  return best_t;
}

// Tracks `from` (in view a) into view b, starting at `to`, then back; ok[i] cleared for a lost
// track or one that does not return within max_fb (px at this scale).
void track(const std::vector<cv::Mat> &a, const std::vector<cv::Mat> &b,
           const std::vector<cv::Point2f> &from, std::vector<cv::Point2f> &to,
           std::vector<uchar> &ok, double max_fb, const TravelParams &p)
{
  const cv::TermCriteria crit(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01);
  const cv::Size win(p.window, p.window);
  std::vector<uchar> st;
  std::vector<float> err;
  cv::calcOpticalFlowPyrLK(a, b, from, to, st, err, win, p.levels, crit,
                           cv::OPTFLOW_USE_INITIAL_FLOW);
  std::vector<cv::Point2f> back(from);
  std::vector<uchar> st2;
  cv::calcOpticalFlowPyrLK(b, a, to, back, st2, err, win, p.levels, crit,
                           cv::OPTFLOW_USE_INITIAL_FLOW);
  const cv::Size size = b[0].size();
  for (std::size_t i = 0; i < from.size(); ++i) {
    const cv::Point2f d = back[i] - from[i];
    if (!st[i] || !st2[i] || !(d.x * d.x + d.y * d.y <= max_fb * max_fb) || to[i].x < 0 ||
        to[i].y < 0 || to[i].x > size.width - 1 || to[i].y > size.height - 1)
      ok[i] = 0;
  }
}

// A point of the current frame and where it was tracked to in the previous views.
struct Tracked {
  cv::Point3d cur;  // current 3D point
  cv::Point2d left; // tracked previous left pixel (y: the mean of both views' rows)
  double right = 0; // tracked previous right x
};

// A point's reprojection into the previous views under the pose X_prev = Rc X_cur + tc: the
// residuals (px) of left x, left y and right x against the tracked pixels and, when `dp` is
// given, their derivatives by the moved point. False when the point falls behind the rig.
bool reproject(const StereoGeometry &g, const cv::Matx33d &Rc, const cv::Vec3d &tc,
               const Tracked &q, double r[3], cv::Vec3d *X_out = nullptr, cv::Vec3d *dp = nullptr)
{
  const double fx = g.fx, fy = g.fy > 0 ? g.fy : g.fx, b = g.baseline_mm;
  const cv::Vec3d X = Rc * cv::Vec3d(q.cur) + tc;
  if (!(X[2] > 0))
    return false;
  const double iz = 1.0 / X[2];
  r[0] = fx * X[0] * iz + g.cx[LEFT] - q.left.x;
  r[1] = fy * X[1] * iz + g.cy - q.left.y;
  r[2] = fx * (X[0] - b) * iz + g.cx[RIGHT] - q.right;
  if (X_out)
    *X_out = X;
  if (dp) {
    dp[0] = cv::Vec3d(fx * iz, 0, -fx * X[0] * iz * iz);
    dp[1] = cv::Vec3d(0, fy * iz, -fy * X[1] * iz * iz);
    dp[2] = cv::Vec3d(fx * iz, 0, -fx * (X[0] - b) * iz * iz);
  }
  return true;
}

// The largest of a point's three reprojection residuals (px); infinite behind the rig.
double reprojection_error(const StereoGeometry &g, const cv::Matx33d &Rc, const cv::Vec3d &tc,
                          const Tracked &q)
{
  double r[3];
  if (!reproject(g, Rc, tc, q, r))
    return std::numeric_limits<double>::infinity();
  return std::max({std::abs(r[0]), std::abs(r[1]), std::abs(r[2])});
}

// Refines the pose (X_prev = Rc X_cur + tc) by Gauss-Newton on the reprojection of the points
// into the previous left (x, y) and right (x) views, with Huber weights (kHuberPx), all six
// parameters or the translation alone. Returns the RMS of the residuals within kHuberPx (px),
// or -1 when the system is singular.
constexpr double kHuberPx = 1.0;
constexpr int kRefineIterations = 8;

double refine_reprojection(const std::vector<Tracked> &pts, const StereoGeometry &g,
                           cv::Matx33d &Rc, cv::Vec3d &tc, bool translation_only = false)
{
  double rms = -1;
  for (int it = 0; it < kRefineIterations; ++it) {
    cv::Matx66d A = cv::Matx66d::zeros();
    cv::Vec6d rhs(0, 0, 0, 0, 0, 0);
    double ss = 0;
    std::size_t n_in = 0;
    for (const Tracked &q : pts) {
      double r[3];
      cv::Vec3d X, dp[3];
      if (!reproject(g, Rc, tc, q, r, &X, dp))
        continue;
      for (int k = 0; k < 3; ++k) {
        const double a = std::abs(r[k]);
        const double w = a <= kHuberPx ? 1.0 : kHuberPx / a;
        if (a <= kHuberPx) {
          ss += r[k] * r[k];
          ++n_in;
        }
        // X' = X + w x X + d: d(X')/d(w) = -[X]x, d(X')/d(d) = I; dp^T (-[X]x) = (X x dp)^T.
        const cv::Vec3d jw = X.cross(dp[k]);
        const cv::Vec6d J(jw[0], jw[1], jw[2], dp[k][0], dp[k][1], dp[k][2]);
        A += w * (J * J.t());
        rhs -= w * r[k] * J;
      }
    }
    rms = n_in ? std::sqrt(ss / double(n_in)) : -1;
    cv::Vec6d delta(0, 0, 0, 0, 0, 0);
    if (translation_only) {
      const cv::Matx33d At = A.get_minor<3, 3>(3, 3);
      cv::Vec3d d;
      if (!cv::solve(At, cv::Vec3d(rhs[3], rhs[4], rhs[5]), d, cv::DECOMP_CHOLESKY))
        return -1;
      delta = cv::Vec6d(0, 0, 0, d[0], d[1], d[2]);
    } else if (!cv::solve(A, rhs, delta, cv::DECOMP_CHOLESKY)) {
      return -1;
    }
    cv::Matx33d dR;
    cv::Rodrigues(cv::Vec3d(delta[0], delta[1], delta[2]), dR);
    Rc = dR * Rc;
    tc = dR * tc + cv::Vec3d(delta[3], delta[4], delta[5]);
    if (cv::norm(delta) < 1e-6)
      break;
  }
  return rms;
}

// Reprojection outliers of a refined pose (see refine_trimmed).
constexpr double kOutlierSpread = 3.0;
constexpr int kOutlierPasses = 3;
constexpr double kMinOutlierPx = 0.5;
// Two refined poses are compared by how many points they bring within this (px).
constexpr double kConsensusPx = 1.0;

// The pose refined from a start, the points far off set aside. The 3D fit's inliers still hold
// tracks a few pixels off in both views alike (a patch straddling a leaf's edge follows what
// shows through the gap): consistent in 3D within the depth's tolerance, but far off in the
// image. Points whose largest residual exceeds kOutlierSpread times 1.4826 times the median one
// (at least kMinOutlierPx) are set aside and the pose refined again; each pass judges all the
// points by the latest pose, so that a point set aside by a worse pose comes back.
struct Refined {
  bool ok = false;
  cv::Matx33d Rc;
  cv::Vec3d tc;
  double rms_px = -1;
  std::size_t kept = 0;      // points within the last cut
  std::size_t consensus = 0; // points within kConsensusPx
};

Refined refine_trimmed(const std::vector<Tracked> &in, const StereoGeometry &g, cv::Matx33d Rc,
                       cv::Vec3d tc, std::size_t min_points, bool translation_only = false)
{
  Refined out;
  if (in.size() < min_points)
    return out;
  double rms = refine_reprojection(in, g, Rc, tc, translation_only);
  if (rms < 0)
    return out;
  std::size_t kept_n = in.size();
  for (int pass = 0; pass < kOutlierPasses; ++pass) {
    std::vector<double> err;
    for (const Tracked &q : in)
      err.push_back(reprojection_error(g, Rc, tc, q));
    std::vector<double> sorted = err;
    std::nth_element(sorted.begin(), sorted.begin() + std::ptrdiff_t(sorted.size() / 2),
                     sorted.end());
    const double cut = std::max(kMinOutlierPx, kOutlierSpread * 1.4826 * sorted[sorted.size() / 2]);
    std::vector<Tracked> kept;
    for (std::size_t i = 0; i < in.size(); ++i)
      if (err[i] <= cut)
        kept.push_back(in[i]);
    if (kept.size() < min_points)
      break;
    cv::Matx33d Rk = Rc;
    cv::Vec3d tk = tc;
    const double rms_kept = refine_reprojection(kept, g, Rk, tk, translation_only);
    if (rms_kept < 0)
      break;
    Rc = Rk;
    tc = tk;
    rms = rms_kept;
    kept_n = kept.size();
  }
  out.ok = true;
  out.Rc = Rc;
  out.tc = tc;
  out.rms_px = rms;
  out.kept = kept_n;
  for (const Tracked &q : in)
    out.consensus += reprojection_error(g, Rc, tc, q) <= kConsensusPx;
  return out;
}

// The Huber cost (kHuberPx) of the points' reprojection residuals under a pose; a point behind
// the rig counts as three residuals of 1.5 kHuberPx.
double huber_cost(const std::vector<Tracked> &pts, const StereoGeometry &g, const cv::Matx33d &Rc,
                  const cv::Vec3d &tc)
{
  double c = 0;
  for (const Tracked &q : pts) {
    double r[3];
    if (!reproject(g, Rc, tc, q, r)) {
      c += 3 * kHuberPx * kHuberPx;
      continue;
    }
    for (double e : r) {
      const double a = std::abs(e);
      c += a <= kHuberPx ? 0.5 * a * a : kHuberPx * (a - 0.5 * kHuberPx);
    }
  }
  return c;
}

} // namespace

Motion estimate_motion(const cv::Mat &prev_left, const cv::Mat &prev_right, const cv::Mat &left,
                       const cv::Mat &right, const std::vector<PixelPoint> &points,
                       const StereoGeometry &g, const TravelParams &p, const cv::Vec3d &along,
                       double expected_mm)
{
  validate(p);
  require_valid(g, "the rig's motion", "estimate_motion");
  if (!is_row_direction(along))
    throw BadInput("The row's direction is not a unit vector within 60 degrees of the camera's x "
                   "axis: give RowDirection::direction().",
                   "estimate_motion: along (" + std::to_string(along[0]) + ", " +
                       std::to_string(along[1]) + ", " + std::to_string(along[2]) + ")");
  const cv::Mat *views[4] = {&prev_left, &prev_right, &left, &right};
  for (const cv::Mat *v : views) {
    if (v->size() != g.view_size)
      throw BadInput("A view is not of the stereo geometry's view size: give the rectified "
                     "views the geometry describes.",
                     "estimate_motion: a view of " + std::to_string(v->cols) + "x" +
                         std::to_string(v->rows) + ", geometry " +
                         std::to_string(g.view_size.width) + "x" +
                         std::to_string(g.view_size.height));
    if (v->type() != left.type())
      throw BadInput("The views differ in pixel type: give four views of one type.",
                     "estimate_motion: type " + std::to_string(v->type()) + " and " +
                         std::to_string(left.type()));
  }
  if (left.depth() != CV_8U ||
      (left.channels() != 1 && left.channels() != 3 && left.channels() != 4))
    throw BadInput("The views' pixel type cannot be used: the rig's motion needs 8-bit grey, "
                   "BGR or BGRA views.",
                   "estimate_motion: depth " + std::to_string(left.depth()) + ", " +
                       std::to_string(left.channels()) + " channels");

  Motion out;
  out.along = along;

  // Candidates: valid points in front of the rig whose right pixel is inside the view.
  std::vector<int> cand;
  std::vector<float> xr(points.size(), 0.0f);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const PixelPoint &q = points[i];
    if (!q.p.valid || !(q.p.z > 0) || !std::isfinite(q.p.x) || !std::isfinite(q.p.y) ||
        !std::isfinite(q.px.x) || !std::isfinite(q.px.y))
      continue;
    xr[i] = float(q.px.x - (g.fx * g.baseline_mm / q.p.z + g.doffs()));
    if (q.px.x < 0 || q.px.y < 0 || q.px.x > g.view_size.width - 1 ||
        q.px.y > g.view_size.height - 1 || xr[i] < 0 || xr[i] > g.view_size.width - 1)
      continue;
    cand.push_back(int(i));
  }
  const std::vector<uchar> edge = depth_edges(points, cand, 0.5 * p.window / p.scale, g.view_size);
  std::vector<int> use = spread_points(points, cand, edge, p.max_points);
  if (use.size() < std::size_t(p.min_inliers)) {
    out.points = use.size();
    return out;
  }

  const double s = p.scale;
  const cv::Mat grey[4] = {reduced(prev_left, s), reduced(prev_right, s), reduced(left, s),
                           reduced(right, s)};
  // Where each point stood in the previous views at the most likely travel: the start of the
  // tracks, so that the pyramid need not span the whole image motion.
  double guess = 0;
  if (p.max_travel_mm > 0) {
    std::vector<cv::Point2f> px;
    std::vector<double> z;
    const std::size_t stride = (use.size() + kSearchPoints - 1) / kSearchPoints;
    for (std::size_t k = 0; k < use.size(); k += stride) {
      px.push_back(points[std::size_t(use[k])].px);
      z.push_back(points[std::size_t(use[k])].p.z);
    }
    guess = search_travel(grey[0], grey[2], s, px, z, g.fx, p.max_travel_mm, expected_mm);
  }
  out.prior_mm = guess;
  // A point that travel carries out of the previous views cannot be tracked: when some are,
  // the points are chosen again among those it keeps in view.
  auto in_view = [&](int i) {
    const double shift = g.fx * guess / points[std::size_t(i)].p.z;
    const double xl0 = points[std::size_t(i)].px.x + shift, xr0 = xr[std::size_t(i)] + shift;
    return xl0 >= 0 && xr0 >= 0 && xl0 <= g.view_size.width - 1 && xr0 <= g.view_size.width - 1;
  };
  if (!std::all_of(use.begin(), use.end(), in_view)) {
    std::vector<int> kept;
    std::copy_if(cand.begin(), cand.end(), std::back_inserter(kept), in_view);
    use = spread_points(points, kept, edge, p.max_points);
  }
  out.points = use.size();
  if (use.size() < std::size_t(p.min_inliers))
    return out;
  std::vector<cv::Point2f> cur_l, cur_r, prev_l, prev_r;
  for (std::size_t k = 0; k < use.size(); ++k) {
    const PixelPoint &q = points[std::size_t(use[k])];
    const float shift = float(g.fx * guess / q.p.z);
    cur_l.emplace_back(float(q.px.x * s), float(q.px.y * s));
    cur_r.emplace_back(float(xr[std::size_t(use[k])] * s), float(q.px.y * s));
    prev_l.emplace_back(float((q.px.x + shift) * s), float(q.px.y * s));
    prev_r.emplace_back(float((xr[std::size_t(use[k])] + shift) * s), float(q.px.y * s));
  }
  const std::vector<cv::Mat> pyr_prev_l = pyramid(grey[0], p), pyr_prev_r = pyramid(grey[1], p),
                             pyr_l = pyramid(grey[2], p), pyr_r = pyramid(grey[3], p);
  std::vector<uchar> ok(use.size(), 1);
  track(pyr_l, pyr_prev_l, cur_l, prev_l, ok, p.max_fb_px * s, p);
  track(pyr_r, pyr_prev_r, cur_r, prev_r, ok, p.max_fb_px * s, p);

  std::vector<cv::Point3d> from, to;
  std::vector<cv::Point2d> obs_l;
  std::vector<double> obs_r, tol;
  const double depth_error = p.tol_px / (g.fx * g.baseline_mm); // mm of depth per mm^2 of Z^2
  for (std::size_t k = 0; k < use.size(); ++k) {
    if (!ok[k])
      continue;
    const double xl0 = prev_l[k].x / s, yl0 = prev_l[k].y / s;
    const double xr0 = prev_r[k].x / s, yr0 = prev_r[k].y / s;
    if (std::abs(yl0 - yr0) > p.max_row_px)
      continue;
    Point3 X;
    if (!triangulate_point(g, xl0, 0.5 * (yl0 + yr0), xl0 - xr0, X))
      continue;
    const Point3 &Y = points[std::size_t(use[k])].p;
    from.emplace_back(X.x, X.y, X.z);
    to.emplace_back(Y.x, Y.y, Y.z);
    obs_l.emplace_back(xl0, 0.5 * (yl0 + yr0));
    obs_r.push_back(xr0);
    const double zz = std::max<double>(X.z, Y.z);
    tol.push_back(p.tol_mm + depth_error * zz * zz);
  }
  out.tracked = from.size();
  if (from.size() < std::size_t(p.min_inliers))
    return out;

  RigidParams rp;
  rp.iterations = p.ransac_iterations;
  rp.min_inliers = p.min_inliers;
  rp.inlier_mm = p.tol_mm;
  const RigidResult fit = rigid_align(from, to, rp, tol);
  if (!fit.found)
    return out;
  cv::Matx33d R = fit.R;
  cv::Vec3d t = fit.t;
  out.rms_px = -1;
  std::size_t inliers = fit.inliers;
  if (p.refine) {
    std::vector<Tracked> in;
    cv::Vec3d shift(0, 0, 0); // mean 3D displacement of the inliers
    for (std::size_t i = 0; i < from.size(); ++i)
      if (fit.inlier[i]) {
        in.push_back({to[i], obs_l[i], obs_r[i]});
        shift += cv::Vec3d(from[i] - to[i]);
      }
    shift /= double(in.size());
    // Two starts: the 3D fit, and no rotation with the inliers' mean displacement. Over a
    // narrow stretch of canopy at one depth, a turn and a move along the row shift the image
    // almost alike, and a few biased tracks can tip the 3D fit into a turn it does not have;
    // the start nearer the truth gathers more points within kConsensusPx.
    const Refined a = refine_trimmed(in, g, R.t(), -(R.t() * t), std::size_t(p.min_inliers));
    Refined b = refine_trimmed(in, g, cv::Matx33d::eye(), shift, std::size_t(p.min_inliers), true);
    const Refined b_translation = b;
    if (b.ok) {
      // Its rotation freed on the points the translation alone explains.
      std::vector<Tracked> near;
      for (const Tracked &q : in)
        if (reprojection_error(g, b.Rc, b.tc, q) <= kConsensusPx)
          near.push_back(q);
      b = refine_trimmed(near, g, b.Rc, b.tc, std::size_t(p.min_inliers));
      // Judged by all the points, as a is.
      if (b.ok) {
        b.consensus = 0;
        for (const Tracked &q : in)
          b.consensus += reprojection_error(g, b.Rc, b.tc, q) <= kConsensusPx;
      }
    }
    const Refined *best = a.ok ? &a : nullptr;
    if (b.ok && (!best || b.consensus > best->consensus ||
                 (b.consensus == best->consensus && b.rms_px < best->rms_px)))
      best = &b;
    // A turn only where the data asks for one (step 5 of travel.hpp): the Bayesian information
    // criterion over all the inliers' residuals, n ln(c3 / c6) > 3 ln n for n residuals.
    if (best && b_translation.ok) {
      const double c6 = huber_cost(in, g, best->Rc, best->tc);
      const double c3 = huber_cost(in, g, b_translation.Rc, b_translation.tc);
      const double n = 3.0 * double(in.size()); // left x and y, right x per point
      if (!(c6 > 0) || n * std::log(c3 / c6) <= 3.0 * std::log(n))
        best = &b_translation;
    }
    if (best) {
      R = best->Rc.t();
      t = -(R * best->tc);
      out.rms_px = best->rms_px;
      inliers = best->kept;
    }
  }
  out.found = true;
  out.R = R;
  out.t = t;
  out.displacement_mm = -t;
  out.travel_mm = out.displacement_mm.dot(along);
  out.rotation_deg = std::acos(std::clamp((cv::trace(R) - 1.0) / 2.0, -1.0, 1.0)) * 180.0 / CV_PI;
  out.inliers = inliers;
  out.rms_mm = fit.rms_mm;
  return out;
}

void validate(const OdometerParams &p)
{
  validate(p.travel);
  require(std::isfinite(p.key_span_mm) && p.key_span_mm >= 0 &&
              p.key_span_mm <= p.travel.max_travel_mm,
          "odometer", "key_span_mm", "0 to travel.max_travel_mm");
}

Odometer::Odometer(const OdometerParams &params) : params_(params)
{
  validate(params_);
}

void Odometer::reset()
{
  for (cv::Mat &m : key_)
    m.release();
  for (cv::Mat &m : prev_)
    m.release();
  since_key_mm_ = 0;
  last_step_mm_ = 0;
  has_step_ = false;
  key_is_prev_ = true;
}

OdometryStep Odometer::add(const cv::Mat &left, const cv::Mat &right,
                           const std::vector<PixelPoint> &points, const StereoGeometry &geometry,
                           const cv::Vec3d &along)
{
  OdometryStep out;
  const bool usable = !prev_[0].empty() && prev_[0].size() == left.size() &&
                      prev_[0].type() == left.type() && right.size() == left.size() &&
                      right.type() == left.type();
  if (usable) {
    // The last step is the next one's likely size: the coarse search looks near it (a repeating
    // texture matches at every repeat), and over the whole range when that finds nothing (a
    // jolt).
    const auto measure = [&](const cv::Mat *from, double expected) {
      Motion m = estimate_motion(from[0], from[1], left, right, points, geometry, params_.travel,
                                 along, has_step_ ? expected : kNoExpectedTravel);
      if (!m.found && has_step_)
        m = estimate_motion(from[0], from[1], left, right, points, geometry, params_.travel,
                            along);
      return m;
    };
    // From the key frame while this frame is likely within the span of it; a key frame whose
    // tracks fail (a frame of sky, a turn) leaves the previous frame to try.
    if (!key_is_prev_ &&
        std::abs(since_key_mm_ + last_step_mm_) <= params_.key_span_mm) {
      const Motion m = measure(key_, since_key_mm_ + last_step_mm_);
      if (m.found && std::isfinite(m.travel_mm)) {
        out.found = out.from_key = true;
        out.travel_mm = m.travel_mm - since_key_mm_;
        out.motion = m;
        since_key_mm_ = m.travel_mm;
      }
    }
    if (!out.found) {
      const Motion m = measure(prev_, last_step_mm_);
      if (m.found && std::isfinite(m.travel_mm)) {
        out.found = true;
        out.travel_mm = m.travel_mm;
        out.motion = m;
        // The previous frame is the key frame from now on.
        key_[0] = prev_[0];
        key_[1] = prev_[1];
        key_is_prev_ = false;
        since_key_mm_ = m.travel_mm;
      }
    }
  }
  prev_[0] = left;
  prev_[1] = right;
  if (out.found)
    last_step_mm_ = out.travel_mm;
  // A lost frame, or a next frame likely beyond the span: this frame is the next key.
  if (!out.found || params_.key_span_mm <= 0 ||
      std::abs(since_key_mm_ + last_step_mm_) > params_.key_span_mm) {
    key_[0] = left;
    key_[1] = right;
    key_is_prev_ = true;
    since_key_mm_ = 0;
  }
  if (!out.found)
    last_step_mm_ = 0;
  has_step_ = out.found;
  return out;
}

cv::Vec3d in_ground_plane(const cv::Vec3d &v, const GroundPlane &ground)
{
  const double len = cv::norm(v);
  if (!(len > 0) || !std::isfinite(len))
    return cv::Vec3d(1, 0, 0);
  const cv::Vec3d u = v / len;
  if (!ground.found || !(cv::norm(ground.normal) > 0))
    return u;
  const cv::Vec3d n = cv::normalize(ground.normal);
  const cv::Vec3d a = u - u.dot(n) * n;
  return cv::norm(a) > 0.5 ? cv::normalize(a) : u; // the plane is not (nearly) across v
}

bool is_row_direction(const cv::Vec3d &d)
{
  return std::isfinite(d[0]) && std::isfinite(d[1]) && std::isfinite(d[2]) &&
         std::abs(cv::norm(d) - 1) <= 1e-6 && d[0] > 0.5;
}

RowDirection::RowDirection(double min_span_mm) : min_span_mm_(min_span_mm)
{
  if (!(min_span_mm >= 0) || !std::isfinite(min_span_mm))
    throw BadSettings("The row direction's span must be a finite length of 0 mm or more.",
                      "RowDirection: min_span_mm = " + std::to_string(min_span_mm));
}

void RowDirection::add(const cv::Vec3d &d)
{
  if (!std::isfinite(d[0]) || !std::isfinite(d[1]) || !std::isfinite(d[2]) ||
      cv::norm(d) < kMinStepMm)
    return;
  sum_ += d[0] < 0 ? -d : d;
}

bool RowDirection::measured() const
{
  const double n = cv::norm(sum_);
  return n >= min_span_mm_ && n > 0 && sum_[0] > 0.5 * n;
}

cv::Vec3d RowDirection::direction(const GroundPlane &ground) const
{
  return measured() ? cv::normalize(sum_) : in_ground_plane(cv::Vec3d(1, 0, 0), ground);
}

} // namespace treestereo
