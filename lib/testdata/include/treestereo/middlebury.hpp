// Reading the Middlebury stereo datasets (2014 / v3 layout): PFM disparities, calib.txt, and
// scoring stereo matches against the ground truth.
#pragma once

#include "treestereo/types.hpp"

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace treestereo {

// A PFM image ("Pf" grey or "PF" colour): float32 rows stored bottom-to-top, byte order from the
// sign of the scale line (negative = little endian). Returned top-to-bottom as CV_32FC1 or
// CV_32FC3 in the machine's byte order; infinities (Middlebury: unknown) are kept as they are.
// Throws std::runtime_error on a missing, truncated or malformed file.
cv::Mat read_pfm(const std::string &path);

// calib.txt of a Middlebury scene.
struct MiddleburyCalib {
  cv::Matx33d cam0 = cv::Matx33d::eye(), cam1 = cv::Matx33d::eye(); // intrinsics (px)
  double doffs = 0;        // cx1 - cx0 (px): Z = baseline * f / (d + doffs)
  double baseline_mm = 0;
  int width = 0, height = 0, ndisp = 0;

  // The same pair as a rectified StereoGeometry (note StereoGeometry::doffs() = -doffs).
  StereoGeometry geometry() const;
};
// Throws std::runtime_error when the file is missing or a required key is absent/malformed.
MiddleburyCalib read_middlebury_calib(const std::string &path);

// One scene directory: im0.png, im1.png, calib.txt and, when present, disp0GT.pfm and
// mask0nocc.png (255 = seen by both cameras).
struct MiddleburyScene {
  cv::Mat left, right;  // BGR
  cv::Mat disp_gt;      // CV_32F left disparity, inf = unknown; empty when absent
  cv::Mat mask_nocc;    // CV_8U; empty when absent
  MiddleburyCalib calib;
  bool has_ground_truth() const { return !disp_gt.empty(); }
};
// Throws std::runtime_error when the images or calib.txt are missing.
MiddleburyScene load_middlebury_scene(const std::string &dir);

struct MatchAccuracy {
  std::size_t evaluated = 0; // matches whose left pixel has known, non-occluded ground truth
  std::size_t correct = 0;   // |d - d_gt| <= tolerance and |yr - yl| <= tolerance
  std::size_t unknown = 0;   // not evaluated
  std::size_t wrong() const { return evaluated - correct; }
  double correct_rate() const { return evaluated ? double(correct) / double(evaluated) : 0.0; }
};
// Scores matches against a left ground-truth disparity, read at the left keypoint's nearest
// pixel. `mask_nocc` (optional) limits the evaluation to pixels where it is 255.
MatchAccuracy evaluate_matches(const std::vector<StereoMatch> &matches, const cv::Mat &disp_gt,
                               const cv::Mat &mask_nocc, double tolerance = 1.0);

} // namespace treestereo
