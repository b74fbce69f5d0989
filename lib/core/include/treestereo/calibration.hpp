// Stereo calibration: the data, checking it and scaling it. Reading and writing calibration
// files is io's (treestereo/calibration_file.hpp).
#pragma once

#include "treestereo/errors.hpp"

#include <opencv2/core.hpp>

#include <stdexcept>
#include <string>

namespace treestereo {

// A calibrated stereo pair in OpenCV's conventions (the layout of OpenCV's stereo_calib sample).
// Lengths in millimetres. R and T take a point from the left camera's frame to the right's:
// X_right = R * X_left + T, so for a right camera to the right of the left one T.x < 0.
struct StereoCalibration {
  cv::Size image_size;   // the size the intrinsics refer to
  cv::Mat M1, D1;        // left camera matrix 3x3 (CV_64F), distortion 1xN (N = 4, 5, 8, 12, 14)
  cv::Mat M2, D2;        // right camera
  cv::Mat R, T;          // rotation 3x3, translation 3x1 (mm)
  // Optional: the rectification OpenCV's stereoRectify computed, as stored beside the above.
  cv::Mat R1, R2, P1, P2, Q;
  double pixel_size_um = 0.0; // optional, 0 = unknown

  double baseline_mm() const; // |T|
  bool has_rectification() const { return !R1.empty() && !P1.empty(); }
};

// Every problem with a calibration is one of these: where (file, key) and what. A calibration is
// a setting: its content is BadSettings; access says when the file itself could not be read or
// written.
class CalibrationError : public BadSettings {
public:
  CalibrationError(std::string file, std::string key, const std::string &problem,
                   FileAccess access = FileAccess::None);
  const std::string &file() const { return file_; }
  const std::string &key() const { return key_; }
  FileAccess access() const { return access_; }

private:
  std::string file_, key_;
  FileAccess access_;
};

// Below this the rig has no baseline worth the name (mm): validate_calibration's limit, and the
// ROS reader's for a baseline it derives.
constexpr double kMinBaselineMm = 1e-3;

// Checks shapes, finiteness, that R is a rotation, that the baseline is not zero and that the
// image size is set. `source` names the file in the messages. Throws CalibrationError.
void validate_calibration(const StereoCalibration &calib, const std::string &source);

// The same rig at another image size. Only a pure scale (binning, a smaller capture) is allowed:
// both axes by the same factor within half a pixel. Throws CalibrationError naming both sizes.
StereoCalibration scale_calibration(const StereoCalibration &calib, cv::Size new_size,
                                    const std::string &source = "calibration");

// cv::stereoRectify's disparity-to-depth matrix from two rectified projection matrices
// (P2[0,3] = fx * Tx, Tx = -baseline): [x y d 1] -> [X Y Z W] with d = xl - xr.
cv::Matx44d disparity_to_depth(const cv::Mat &P1, const cv::Mat &P2);

} // namespace treestereo
