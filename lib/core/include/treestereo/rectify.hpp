// Rectification of a calibrated stereo pair: the maps, the geometry of the rectified pair,
// and remapping one view (optionally straight into half of a side-by-side frame).
#pragma once

#include "treestereo/calibration.hpp"
#include "treestereo/types.hpp"

#include <opencv2/core.hpp>

namespace treestereo {

struct StereoRectification {
  StereoGeometry geometry;      // of the rectified (or already rectified) views
  cv::Mat map1[2], map2[2];     // per view, fixed-point maps (CV_16SC2 + CV_16UC1); empty when !rectify
  cv::Rect valid_roi[2];        // the part of each rectified view with only valid pixels
  bool rectify = true;          // false: the input is already rectified, views pass unchanged
};

// Computes the rectification for views of `input_size`. The calibration is scaled to that size
// when it is a pure scale of the calibration's size (else CalibrationError).
// rectify = true: cv::stereoRectify with CALIB_ZERO_DISPARITY and `alpha` (-1 = OpenCV's default,
// 0 = only valid pixels, 1 = all source pixels kept), then fixed-point maps.
// rectify = false (already rectified input, e.g. Middlebury or a factory-rectified camera): no
// maps; the geometry comes from the calibration's P1/P2/Q when present, else from M1/M2 and |T|.
StereoRectification compute_rectification(const StereoCalibration &calib, cv::Size input_size,
                                          double alpha = -1, bool rectify = true);

// Rectifies view `view` (LEFT or RIGHT) of size geometry.view_size, CV_8U with 1, 3 or 4
// channels. `dst` is written in place when it is already allocated (it may be a ROI of a larger
// side-by-side frame: it is never reallocated) and must then have src's type and the view size;
// an empty dst is allocated. Throws std::invalid_argument on a mismatch.
void rectify_view(const StereoRectification &rect, int view, const cv::Mat &src, cv::Mat &dst);

} // namespace treestereo
