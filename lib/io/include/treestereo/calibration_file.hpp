// Calibration files: reading and writing the StereoCalibration of treestereo/calibration.hpp.
#pragma once

#include "treestereo/calibration.hpp"

#include <string>

namespace treestereo {

// Loads a calibration. `spec` is one of
//  - one OpenCV FileStorage file (.yml/.yaml/.xml, optionally .gz) holding image_width,
//    image_height, M1 D1 M2 D2 R T (T in mm) and optionally R1 R2 P1 P2 Q and pixel_size_um;
//  - "intrinsics.yml;extrinsics.yml" as OpenCV's stereo_calib sample writes them (recognised by
//    M1 in the first file); the image size must be in one of them;
//  - "left.yaml;right.yaml", two ROS camera_info files. R = R2^T R1 and T = R2^T (-B, 0, 0)
//    with B = -P_right[0,3] / P_right[0,0] converted from metres to mm; R1 R2 P1 P2 are kept
//    (the Tx column of P in px*mm, like cv::stereoRectify's) and Q is derived from P1 P2.
// The result is validated; throws CalibrationError (file missing, not a calibration, syntax
// error, missing key, wrong shape, NaN/inf, R not a rotation, zero baseline, no image size).
StereoCalibration load_calibration(const std::string &spec);

// Writes an OpenCV FileStorage file (format from the extension: .yml/.yaml or .xml).
void save_calibration(const StereoCalibration &calib, const std::string &path);

} // namespace treestereo
