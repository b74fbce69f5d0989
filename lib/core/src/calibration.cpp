// Checking and scaling stereo calibrations: the maths, no files (reading and writing them is
// calibration_file.cpp in io).
#include "treestereo/calibration.hpp"

#include <opencv2/core.hpp>

#include <cmath>
#include <string>
#include <utility>

namespace treestereo {

CalibrationError::CalibrationError(std::string file, std::string key, const std::string &problem,
                                   FileAccess access)
    : BadSettings(file + (key.empty() ? std::string() : ": " + key) + ": " + problem),
      file_(std::move(file)), key_(std::move(key)), access_(access)
{
}

double StereoCalibration::baseline_mm() const
{
  return T.empty() ? 0.0 : cv::norm(T);
}

namespace {

// Tolerances for "is a rotation": files written by hand or by MATLAB carry 4-6 digits.
constexpr double kRotationTolerance = 1e-3;
constexpr int kMaxImageSide = 32768; // larger than any camera sensor: a typo or a corrupt file

void check_shape(const cv::Mat &m, const std::string &source, const std::string &key, int rows,
                 int cols)
{
  if (m.rows != rows || m.cols != cols)
    throw CalibrationError(source, key, "wrong shape " + std::to_string(m.rows) + "x" +
                                            std::to_string(m.cols) + ", expected " +
                                            std::to_string(rows) + "x" + std::to_string(cols));
}

void check_finite(const cv::Mat &m, const std::string &source, const std::string &key)
{
  if (!cv::checkRange(m))
    throw CalibrationError(source, key, "holds a non-finite value (NaN or inf)");
}

void check_distortion(const cv::Mat &d, const std::string &source, const std::string &key)
{
  const int n = static_cast<int>(d.total());
  const bool vector = d.rows == 1 || d.cols == 1;
  if (!vector || (n != 4 && n != 5 && n != 8 && n != 12 && n != 14))
    throw CalibrationError(source, key, "wrong shape " + std::to_string(d.rows) + "x" +
                                            std::to_string(d.cols) +
                                            ", expected 1xN with N = 4, 5, 8, 12 or 14");
  check_finite(d, source, key);
}

void check_camera_matrix(const cv::Mat &m, const std::string &source, const std::string &key)
{
  check_shape(m, source, key, 3, 3);
  check_finite(m, source, key);
  if (!(m.at<double>(0, 0) > 0 && m.at<double>(1, 1) > 0))
    throw CalibrationError(source, key, "focal lengths fx, fy must be positive");
}

void check_rotation(const cv::Mat &r, const std::string &source, const std::string &key)
{
  check_shape(r, source, key, 3, 3);
  check_finite(r, source, key);
  const double orth = cv::norm(r.t() * r - cv::Mat::eye(3, 3, CV_64F), cv::NORM_INF);
  const double det = cv::determinant(r);
  if (orth > kRotationTolerance || std::abs(det - 1.0) > kRotationTolerance) {
    std::ostringstream s;
    s << "is not a rotation matrix (max |R^T R - I| = " << orth << ", det = " << det
      << "; expected R^T R = I and det = +1)";
    throw CalibrationError(source, key, s.str());
  }
}

std::string size_str(cv::Size s)
{
  return std::to_string(s.width) + "x" + std::to_string(s.height);
}

// Resampling maps an old pixel centre u to (u + 0.5) * s - 0.5, i.e. pixels' = A * pixels with
// A = [sx 0 ox; 0 sy oy; 0 0 1]; applied to a camera or projection matrix: M' = A * M.
void scale_projection(cv::Mat &m, double sx, double sy)
{
  if (m.empty())
    return;
  const double ox = 0.5 * sx - 0.5, oy = 0.5 * sy - 0.5;
  const cv::Mat a = (cv::Mat_<double>(3, 3) << sx, 0, ox, 0, sy, oy, 0, 0, 1);
  // A new buffer: assigning the product to m would write into data shared with the input.
  m = cv::Mat(a * m).clone();
}

} // namespace

cv::Matx44d disparity_to_depth(const cv::Mat &P1, const cv::Mat &P2)
{
  cv::Mat p1, p2;
  P1.convertTo(p1, CV_64F);
  P2.convertTo(p2, CV_64F);
  const double f = p1.at<double>(0, 0);
  const double tx = p2.at<double>(0, 3) / p2.at<double>(0, 0); // -baseline
  const double cx1 = p1.at<double>(0, 2), cx2 = p2.at<double>(0, 2), cy = p1.at<double>(1, 2);
  return cv::Matx44d(1, 0, 0, -cx1,
                     0, 1, 0, -cy,
                     0, 0, 0, f,
                     0, 0, -1.0 / tx, (cx1 - cx2) / tx);
}

void validate_calibration(const StereoCalibration &c, const std::string &source)
{
  if (c.image_size.width == 0 && c.image_size.height == 0)
    throw CalibrationError(source, "image_width", "image size missing: add image_width and "
                                                  "image_height (the calibration images' size)");
  if (c.image_size.width <= 0 || c.image_size.height <= 0)
    throw CalibrationError(source, "image_width",
                           "image size " + size_str(c.image_size) + " is not positive");
  if (c.image_size.width > kMaxImageSide || c.image_size.height > kMaxImageSide)
    throw CalibrationError(source, "image_width",
                           "image size " + size_str(c.image_size) + " is larger than " +
                               std::to_string(kMaxImageSide) +
                               " px on a side: no camera's (check image_width and image_height)");
  check_camera_matrix(c.M1, source, "M1");
  check_distortion(c.D1, source, "D1");
  check_camera_matrix(c.M2, source, "M2");
  check_distortion(c.D2, source, "D2");
  check_rotation(c.R, source, "R");
  if (c.T.total() != 3 || (c.T.rows != 1 && c.T.cols != 1))
    throw CalibrationError(source, "T", "wrong shape " + std::to_string(c.T.rows) + "x" +
                                            std::to_string(c.T.cols) + ", expected 3x1");
  check_finite(c.T, source, "T");
  if (!(c.baseline_mm() >= kMinBaselineMm))
    throw CalibrationError(source, "T", "zero baseline: the two cameras are at the same place");
  if (!c.R1.empty())
    check_rotation(c.R1, source, "R1");
  if (!c.R2.empty())
    check_rotation(c.R2, source, "R2");
  for (const auto &[m, key] : {std::pair<const cv::Mat &, const char *>{c.P1, "P1"},
                               std::pair<const cv::Mat &, const char *>{c.P2, "P2"}}) {
    if (m.empty())
      continue;
    check_shape(m, source, key, 3, 4);
    check_finite(m, source, key);
  }
  if (!c.Q.empty()) {
    check_shape(c.Q, source, "Q", 4, 4);
    check_finite(c.Q, source, "Q");
  }
  if (c.R1.empty() != c.P1.empty() || c.R2.empty() != c.P2.empty() || c.P1.empty() != c.P2.empty())
    throw CalibrationError(source, c.P1.empty() ? "P1" : "P2",
                           "rectification is incomplete: give all of R1 R2 P1 P2 or none");
  if (!c.P2.empty() && !(std::abs(c.P2.at<double>(0, 3)) > 0))
    throw CalibrationError(source, "P2", "P2[0,3] is zero: the rectified pair has no baseline");
  if (!std::isfinite(c.pixel_size_um) || c.pixel_size_um < 0)
    throw CalibrationError(source, "pixel_size_um", "must be a positive number (or absent)");
}

StereoCalibration scale_calibration(const StereoCalibration &calib, cv::Size new_size,
                                    const std::string &source)
{
  const cv::Size old = calib.image_size;
  if (new_size == old)
    return calib;
  if (old.width <= 0 || old.height <= 0 || new_size.width <= 0 || new_size.height <= 0)
    throw CalibrationError(source, "image_width",
                           "cannot scale a calibration for " + size_str(old) + " to " +
                               size_str(new_size));
  const double sx = static_cast<double>(new_size.width) / old.width;
  const double sy = static_cast<double>(new_size.height) / old.height;
  // Same factor within half a pixel on each axis: a crop or a different aspect is not the rig.
  if (std::abs(old.height * sx - new_size.height) > 0.5 ||
      std::abs(old.width * sy - new_size.width) > 0.5)
    throw CalibrationError(source, "image_width",
                           "calibration is for " + size_str(old) + " but the stream is " +
                               size_str(new_size) + ": not a pure scale");
  StereoCalibration c = calib;
  c.image_size = new_size;
  for (cv::Mat *m : {&c.M1, &c.M2, &c.P1, &c.P2}) {
    scale_projection(*m, sx, sy);
  }
  if (!c.P1.empty())
    c.Q = cv::Mat(disparity_to_depth(c.P1, c.P2));
  if (c.pixel_size_um > 0)
    c.pixel_size_um /= sx; // a binned pixel is larger
  return c;
}

} // namespace treestereo