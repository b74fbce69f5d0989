#include "treestereo/depth.hpp"

#include "treestereo/errors.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace treestereo {

namespace {

void check_params(const DepthParams &p)
{
  if (!(p.min_depth_mm > 0.0) || !(p.max_depth_mm > p.min_depth_mm) ||
      !std::isfinite(p.max_depth_mm))
    throw BadSettings("depth range [" + std::to_string(p.min_depth_mm) + ", " +
                             std::to_string(p.max_depth_mm) +
                             "] mm is empty: need 0 < min-depth < max-depth < infinity");
  if (!(p.outlier_k >= 0.0) || !(p.mad_floor_mm >= 0.0))
    throw BadSettings("outlier k (" + std::to_string(p.outlier_k) + ") and MAD floor (" +
                             std::to_string(p.mad_floor_mm) + " mm) must be >= 0");
}

bool finite_point(double x, double y, double z)
{
  return std::isfinite(x) && std::isfinite(y) && std::isfinite(z);
}

std::vector<double> valid_depths(const std::vector<Point3> &points)
{
  std::vector<double> z;
  z.reserve(points.size());
  for (const Point3 &p : points)
    if (p.valid)
      z.push_back(p.z);
  return z;
}

} // namespace

bool triangulate_point(const StereoGeometry &g, double xl, double yl, double disparity,
                       Point3 &out)
{
  const double dd = disparity - g.doffs();
  if (!(dd > 0.0) || g.fx <= 0.0)
    return false;
  const double z = g.baseline_mm * g.fx / dd;
  const double fy = g.fy > 0.0 ? g.fy : g.fx;
  const double x = (xl - g.cx[LEFT]) * z / g.fx;
  const double y = (yl - g.cy) * z / fy;
  if (!finite_point(x, y, z))
    return false;
  out.x = float(x);
  out.y = float(y);
  out.z = float(z);
  return true;
}

bool triangulate_point_q(const cv::Matx44d &Q, double xl, double yl, double disparity,
                         Point3 &out)
{
  const cv::Vec4d h = Q * cv::Vec4d(xl, yl, disparity, 1.0);
  if (!(h[3] > 0.0))
    return false;
  const double x = h[0] / h[3], y = h[1] / h[3], z = h[2] / h[3];
  if (!finite_point(x, y, z) || !(z > 0.0))
    return false;
  out.x = float(x);
  out.y = float(y);
  out.z = float(z);
  return true;
}

cv::Matx44d disparity_to_depth_matrix(const StereoGeometry &g)
{
  require_valid(g, "depth from disparity", "disparity_to_depth_matrix");
  // cv::stereoRectify's layout with Tx = -baseline (right camera on the +x side).
  const double b = g.baseline_mm;
  return cv::Matx44d(1, 0, 0, -g.cx[LEFT],
                     0, 1, 0, -g.cy,
                     0, 0, 0, g.fx,
                     0, 0, 1.0 / b, -g.doffs() / b);
}

DepthStats filter_depths(std::vector<Point3> &points, const DepthParams &params)
{
  check_params(params);
  DepthStats s;
  s.n_points = points.size();
  for (Point3 &p : points) {
    if (p.valid && (p.z < params.min_depth_mm || p.z > params.max_depth_mm)) {
      p.valid = false;
      ++s.dropped_range;
    }
  }
  double lo = params.min_depth_mm, hi = params.max_depth_mm;
  if (params.outlier_k > 0.0) {
    std::vector<double> z = valid_depths(points);
    if (!z.empty()) {
      const double med = median(z);
      const double spread = std::max(1.4826 * mad(z, med), params.mad_floor_mm);
      lo = std::max(lo, med - params.outlier_k * spread);
      hi = std::min(hi, med + params.outlier_k * spread);
      for (Point3 &p : points) {
        if (p.valid && (p.z < lo || p.z > hi)) {
          p.valid = false;
          ++s.dropped_outlier;
        }
      }
    }
  }
  const Summary kept = summarize(valid_depths(points));
  s.n_valid = kept.n;
  if (kept.n > 0) {
    s.median_mm = kept.median;
    s.mad_mm = kept.mad;
    s.p05_mm = kept.p05;
    s.p95_mm = kept.p95;
    s.accept_lo_mm = lo;
    s.accept_hi_mm = hi;
  }
  return s;
}

DepthResult triangulate_matches(const std::vector<StereoMatch> &matches,
                                const StereoGeometry &geometry, const DepthParams &params)
{
  require_valid(geometry, "triangulation", "triangulate_matches");
  check_params(params);
  DepthResult r;
  r.points.resize(matches.size());
  std::size_t no_depth = 0;
  for (std::size_t i = 0; i < matches.size(); ++i) {
    const StereoMatch &m = matches[i];
    Point3 &p = r.points[i];
    p.match_index = std::uint32_t(i);
    p.valid = triangulate_point(geometry, m.xl, m.yl, m.disparity(), p);
    if (!p.valid)
      ++no_depth;
  }
  r.stats = filter_depths(r.points, params);
  r.stats.dropped_disparity = no_depth;
  return r;
}

cv::Vec2i disparity_window(const StereoGeometry &g, double min_depth_mm, double max_depth_mm)
{
  require_valid(g, "the disparity window", "disparity_window");
  DepthParams p;
  p.min_depth_mm = min_depth_mm;
  p.max_depth_mm = max_depth_mm;
  check_params(p);
  const double d_lo = g.fx * g.baseline_mm / max_depth_mm + g.doffs();
  const double d_hi = g.fx * g.baseline_mm / min_depth_mm + g.doffs();
  // One disparity of slack on each side so that the range's ends are not at the window's edge,
  // where SGBM's sub-pixel fit and uniqueness test are unreliable.
  const int min_d = int(std::floor(d_lo)) - 1;
  const int span = int(std::ceil(d_hi)) + 1 - min_d + 1;
  const int num = std::max(16, (span + 15) / 16 * 16);
  return {min_d, num};
}

namespace {

cv::Mat to_gray(const cv::Mat &m, const char *what)
{
  cv::Mat g;
  switch (m.type()) {
  case CV_8UC1: return m;
  case CV_8UC3: cv::cvtColor(m, g, cv::COLOR_BGR2GRAY); return g;
  case CV_8UC4: cv::cvtColor(m, g, cv::COLOR_BGRA2GRAY); return g;
  default: // check_dense_input() lets nothing else through
    throw std::runtime_error(std::string("dense depth: unsupported ") + what + " view type " +
                             std::to_string(m.type()));
  }
}

void check_dense_input(const cv::Mat &left, const cv::Mat &right, const cv::Mat &mask,
                       const StereoGeometry &g, const DenseParams &p)
{
  require_valid(g, "dense matching", "dense_depth");
  check_params(p.filter);
  if (left.empty() || right.empty() || left.size() != right.size() ||
      left.size() != g.view_size)
    throw std::runtime_error("dense depth: the left and right views must both be the "
                             "geometry's view size " + std::to_string(g.view_size.width) + "x" +
                             std::to_string(g.view_size.height));
  const int t = left.type();
  if (t != right.type() || (t != CV_8UC1 && t != CV_8UC3 && t != CV_8UC4))
    throw std::runtime_error("dense depth: both views must be 8-bit gray, BGR or BGRA, of the "
                             "same type (got OpenCV types " + std::to_string(t) + " and " +
                             std::to_string(right.type()) + ")");
  if (!mask.empty() && (mask.size() != g.view_size || mask.type() != CV_8UC1))
    throw BadInput("dense depth: the vegetation mask must be CV_8U of the view size");
  if (p.block_size < 1 || p.block_size % 2 == 0 || p.sample_step < 1)
    throw BadSettings("dense depth: block size must be odd and >= 1, sample step >= 1");
  if (p.num_disparities < 0 || p.num_disparities % 16 != 0)
    throw BadSettings("dense depth: num-disparities must be 0 (auto) or a positive "
                             "multiple of 16, got " + std::to_string(p.num_disparities));
}

} // namespace

DenseResult dense_depth(const cv::Mat &left, const cv::Mat &right, const cv::Mat &mask,
                        const cv::Rect &box, const StereoGeometry &g, const DenseParams &p)
{
  check_dense_input(left, right, mask, g, p);
  DenseResult r;
  if (p.num_disparities == 0) {
    const cv::Vec2i w = disparity_window(g, p.filter.min_depth_mm, p.filter.max_depth_mm);
    r.min_disparity = w[0];
    r.num_disparities = w[1];
  } else {
    r.min_disparity = p.min_disparity;
    r.num_disparities = p.num_disparities;
  }
  r.box = box & cv::Rect(cv::Point(0, 0), g.view_size);
  r.depth_mm = cv::Mat::zeros(r.box.size(), CV_16U);
  const int W = g.view_size.width;
  const int s = r.min_disparity, num = r.num_disparities;

  // The right crop is the left crop shifted by the smallest disparity, so SGBM searches
  // [0, num) and only the num columns left of the box are extra work. SGBM leaves its first
  // num columns without disparity, hence the left margin.
  const int x0 = std::max({r.box.x - num, 0, s});
  const int x1 = std::min(r.box.x + r.box.width, W + s);
  if (r.box.empty() || x1 - x0 <= num)
    return r; // nothing of the box can be matched; an empty map and no points
  const cv::Rect lrect(x0, r.box.y, x1 - x0, r.box.height);
  const cv::Rect rrect(x0 - s, r.box.y, x1 - x0, r.box.height);
  const cv::Mat lg = to_gray(left(lrect), "left"), rg = to_gray(right(rrect), "right");

  const int bs = p.block_size;
  auto sgbm = cv::StereoSGBM::create(0, num, bs, p.p1 > 0 ? p.p1 : 8 * bs * bs,
                                     p.p2 > 0 ? p.p2 : 32 * bs * bs, p.disp12_max_diff,
                                     p.pre_filter_cap, p.uniqueness_ratio, p.speckle_window,
                                     p.speckle_range, cv::StereoSGBM::MODE_SGBM_3WAY);
  cv::Mat disp; // CV_16S, 16 * disparity, negative = none
  sgbm->compute(lg, rg, disp);

  // Triangulate every canopy pixel with a disparity; sample a grid of them as points.
  cv::Mat_<float> z_box(r.box.size(), 0.0f);
  for (int v = 0; v < r.box.height; ++v) {
    const int y = r.box.y + v;
    const short *drow = disp.ptr<short>(v);
    const uchar *mrow = mask.empty() ? nullptr : mask.ptr<uchar>(y);
    for (int u = 0; u < r.box.width; ++u) {
      const int x = r.box.x + u;
      if (x < x0 || x >= x1 || (mrow && !mrow[x]))
        continue;
      const short d16 = drow[x - x0];
      if (d16 < 0)
        continue;
      Point3 pt;
      if (!triangulate_point(g, x, y, d16 / 16.0 + s, pt))
        continue;
      z_box(v, u) = pt.z;
      if (v % p.sample_step == 0 && u % p.sample_step == 0) {
        pt.match_index = std::uint32_t(y) * std::uint32_t(W) + std::uint32_t(x);
        r.points.push_back(pt);
      }
    }
  }
  r.stats = filter_depths(r.points, p.filter);

  // The map keeps what the points' range and outlier cut keep.
  const double lo = r.stats.accept_lo_mm, hi = r.stats.accept_hi_mm;
  if (r.stats.n_valid > 0) {
    for (int v = 0; v < r.box.height; ++v)
      for (int u = 0; u < r.box.width; ++u) {
        const double z = z_box(v, u);
        if (z > 0.0 && z >= lo && z <= hi)
          r.depth_mm.at<std::uint16_t>(v, u) =
              std::uint16_t(std::min(std::lround(z), long(std::numeric_limits<std::uint16_t>::max())));
      }
  }
  return r;
}

} // namespace treestereo
