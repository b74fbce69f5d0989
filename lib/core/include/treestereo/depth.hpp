// From stereo correspondences to metres: triangulation of matches, robust filtering of the
// canopy's depths and dense depth by semi-global matching. The algorithms behind `stereodepth`.
//
// Depth from disparity. For a rectified pair with disparity d = xl - xr (px):
//
//     Z = b * fx / (d - doffs),      doffs = cx_left - cx_right
//
// This is the paper's Z = b*f/(k*d) with f the focal length in mm and k the pixel size in mm/px:
// f/k is the focal length in pixels (fx), and doffs is 0 when both rectified principal points
// coincide (cv::stereoRectify with CALIB_ZERO_DISPARITY). The full 3D point is
//
//     X = (xl - cx_left) * Z / fx,   Y = (yl - cy) * Z / fy
//
// which is what cv::stereoRectify's Q matrix computes, [X Y Z W]^T = Q [xl yl d 1]^T, when
// fx == fy (always so after stereoRectify). All points are in the rectified-left camera frame
// (x right, y down, z forward), millimetres.
#pragma once

#include "treestereo/types.hpp"

#include <opencv2/core.hpp>

#include <cstddef>
#include <vector>

namespace treestereo {

// How the canopy's depths are cleaned. Points that fail stay in the vector with valid=false.
struct DepthParams {
  double min_depth_mm = 300.0;    // nearer points are dropped (counted in dropped_range)
  double max_depth_mm = 20000.0;  // farther points are dropped (counted in dropped_range)
  // Outliers of the depth distribution: |z - median| > outlier_k * 1.4826 * MAD. 0 = off.
  // 3.5 is Iglewicz and Hoaglin's cut for the modified z-score.
  double outlier_k = 3.5;
  // MAD below this is raised to it, so a canopy that is (nearly) flat in depth does not
  // turn every point off the exact median into an "outlier".
  double mad_floor_mm = 5.0;
};

// What the kept (valid) points rest on. Depths in mm; all zero when nothing is kept.
struct DepthStats {
  std::size_t n_points = 0;         // points produced (valid or not)
  std::size_t n_valid = 0;          // points kept
  std::size_t dropped_disparity = 0; // non-positive effective disparity (d - doffs <= 0)
  std::size_t dropped_range = 0;    // outside [min_depth_mm, max_depth_mm]
  std::size_t dropped_outlier = 0;  // outside the median/MAD band
  std::size_t dropped_zone = 0;     // off the 3D canopy (canopy_depth(): another tree, the
                                    // next row, the ground), before the other cuts
  double median_mm = 0, mad_mm = 0, p05_mm = 0, p95_mm = 0;
  // The accepted depth interval after range and outlier cuts (mm); 0/0 when nothing is kept.
  double accept_lo_mm = 0, accept_hi_mm = 0;
};

struct DepthResult {
  std::vector<Point3> points; // one per match, same order, match_index = its index
  DepthStats stats;
};

// One point by the closed-form formula above. Returns false (and leaves `out` untouched) when
// d - doffs <= 0 or the input is not finite: such a point has no finite depth.
bool triangulate_point(const StereoGeometry &geometry, double xl, double yl, double disparity,
                       Point3 &out);

// The same through a Q matrix (cv::stereoRectify's layout): [X Y Z W] = Q [xl yl d 1].
// Returns false when W is not positive or the result is not finite.
bool triangulate_point_q(const cv::Matx44d &Q, double xl, double yl, double disparity,
                         Point3 &out);

// Q of the given geometry in cv::stereoRectify's layout (fx used for both axes).
cv::Matx44d disparity_to_depth_matrix(const StereoGeometry &geometry);

// Range, then median/MAD outlier cut on the valid points, in place; returns the statistics of
// what is kept. Points already invalid on entry are left alone and not counted as dropped.
DepthStats filter_depths(std::vector<Point3> &points, const DepthParams &params);

// Triangulates every match, then filters as above. Throws std::runtime_error when the geometry
// is not valid or the parameters make no sense (min >= max depth, negative k).
DepthResult triangulate_matches(const std::vector<StereoMatch> &matches,
                                const StereoGeometry &geometry, const DepthParams &params);

// ---- Dense depth (semi-global block matching on the canopy's box) ----

struct DenseParams {
  DepthParams filter;        // the depth range also bounds the disparity search
  // Disparity search window. num_disparities = 0: both derived from filter's depth range and
  // the geometry (the smallest window, a multiple of 16, that covers the range). Otherwise
  // min_disparity is the smallest disparity searched and num_disparities (a positive multiple of
  // 16) how many.
  int min_disparity = 0;
  int num_disparities = 0;
  int block_size = 5;        // odd, >= 1
  int p1 = 0, p2 = 0;        // smoothness penalties; 0 = 8*bs^2 and 32*bs^2 (one channel)
  int uniqueness_ratio = 10; // percent
  int speckle_window = 100;  // px; 0 = no speckle filtering
  int speckle_range = 2;     // disparity units (px)
  int disp12_max_diff = 1;   // left-right check tolerance (px); < 0 = off
  int pre_filter_cap = 63;
  int sample_step = 4;       // 3D points from every sample_step-th pixel in x and in y
};

struct DenseResult {
  cv::Rect box;              // the region of the left view the map covers (clipped to the view)
  cv::Mat depth_mm;          // CV_16U, box.size(): depth in mm, 0 = unknown / not canopy / cut
  // Sampled 3D points (grid of sample_step) of canopy pixels with a disparity; match_index is the
  // left-view pixel index y * width + x. Filtered as in filter_depths().
  std::vector<Point3> points;
  DepthStats stats;
  int min_disparity = 0, num_disparities = 0; // the search window used
};

// The search window for a depth range: {min_disparity, num_disparities}.
// Throws std::runtime_error when the range is empty or not positive.
cv::Vec2i disparity_window(const StereoGeometry &geometry, double min_depth_mm,
                           double max_depth_mm);

// Dense depth of the canopy. `left` and `right` are the rectified views (CV_8UC1, or CV_8UC3 /
// CV_8UC4 in BGR(A) order, same size, the geometry's view size), `mask` the left view's
// vegetation mask (CV_8U, view size, non-zero = canopy; empty = every pixel of the box), `box`
// the canopy's box in the left view. Only the box and, in the right view, the columns a match
// can come from (the box shifted left by up to the largest disparity) are matched.
// Throws std::runtime_error on inconsistent input.
DenseResult dense_depth(const cv::Mat &left, const cv::Mat &right, const cv::Mat &mask,
                        const cv::Rect &box, const StereoGeometry &geometry,
                        const DenseParams &params);

} // namespace treestereo
