// Rectification maps and the geometry of the rectified pair.
#include "treestereo/rectify.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <stdexcept>
#include <string>

namespace treestereo {

namespace {

std::string size_str(cv::Size s)
{
  return std::to_string(s.width) + "x" + std::to_string(s.height);
}

// Geometry of a rectified pair from its two projection matrices (P2[0,3] = fx * Tx).
StereoGeometry geometry_from_projections(const cv::Mat &P1, const cv::Mat &P2, cv::Size size)
{
  StereoGeometry g;
  g.view_size = size;
  g.fx = P1.at<double>(0, 0);
  g.fy = P1.at<double>(1, 1);
  g.cx[LEFT] = P1.at<double>(0, 2);
  g.cx[RIGHT] = P2.at<double>(0, 2);
  g.cy = P1.at<double>(1, 2);
  g.baseline_mm = std::abs(P2.at<double>(0, 3) / P2.at<double>(0, 0));
  g.Q = disparity_to_depth(P1, P2);
  return g;
}

// Already rectified views: the projection matrices are the camera matrices, the right one
// shifted by the baseline.
void passthrough_projections(const StereoCalibration &c, cv::Mat &P1, cv::Mat &P2)
{
  P1 = cv::Mat::zeros(3, 4, CV_64F);
  P2 = cv::Mat::zeros(3, 4, CV_64F);
  c.M1.copyTo(P1.colRange(0, 3));
  c.M2.copyTo(P2.colRange(0, 3));
  P2.at<double>(0, 3) = -c.M2.at<double>(0, 0) * c.baseline_mm();
}

} // namespace

StereoRectification compute_rectification(const StereoCalibration &calib_in, cv::Size input_size,
                                          double alpha, bool rectify)
{
  const StereoCalibration calib = scale_calibration(calib_in, input_size);
  StereoRectification r;
  r.rectify = rectify;
  if (!rectify) {
    cv::Mat P1 = calib.P1, P2 = calib.P2;
    if (P1.empty())
      passthrough_projections(calib, P1, P2);
    r.geometry = geometry_from_projections(P1, P2, input_size);
    if (!calib.Q.empty() && !calib.P1.empty())
      r.geometry.Q = cv::Matx44d(calib.Q);
    // Views that are already rectified have no rotation to undo.
    r.geometry.R1 = cv::Matx33d::eye();
    r.valid_roi[LEFT] = r.valid_roi[RIGHT] = cv::Rect(cv::Point(), input_size);
    return r;
  }
  cv::Mat R1, R2, P1, P2, Q;
  cv::stereoRectify(calib.M1, calib.D1, calib.M2, calib.D2, input_size, calib.R, calib.T, R1, R2,
                    P1, P2, Q, cv::CALIB_ZERO_DISPARITY, alpha, input_size, &r.valid_roi[LEFT],
                    &r.valid_roi[RIGHT]);
  r.geometry = geometry_from_projections(P1, P2, input_size);
  r.geometry.Q = cv::Matx44d(Q);
  r.geometry.R1 = cv::Matx33d(R1);
  cv::initUndistortRectifyMap(calib.M1, calib.D1, R1, P1, input_size, CV_16SC2, r.map1[LEFT],
                              r.map2[LEFT]);
  cv::initUndistortRectifyMap(calib.M2, calib.D2, R2, P2, input_size, CV_16SC2, r.map1[RIGHT],
                              r.map2[RIGHT]);
  return r;
}

void rectify_view(const StereoRectification &rect, int view, const cv::Mat &src, cv::Mat &dst)
{
  if (view != LEFT && view != RIGHT)
    throw std::invalid_argument("rectify_view: view must be 0 (left) or 1 (right), got " +
                                std::to_string(view));
  const cv::Size size = rect.geometry.view_size;
  if (src.depth() != CV_8U || (src.channels() != 1 && src.channels() != 3 && src.channels() != 4))
    throw std::invalid_argument("rectify_view: expected an 8-bit image with 1, 3 or 4 channels");
  if (src.size() != size)
    throw std::invalid_argument("rectify_view: the view is " + size_str(src.size()) +
                                " but the rectification was computed for " + size_str(size));
  if (dst.empty()) {
    dst.create(size, src.type());
  } else if (dst.size() != size || dst.type() != src.type()) {
    throw std::invalid_argument("rectify_view: destination is " + size_str(dst.size()) +
                                " type " + std::to_string(dst.type()) + ", expected " +
                                size_str(size) + " type " + std::to_string(src.type()));
  }
  if (src.data == dst.data)
    throw std::invalid_argument("rectify_view: source and destination must not overlap");
  if (!rect.rectify) {
    src.copyTo(dst);
    return;
  }
  if (rect.map1[view].size() != size)
    throw std::invalid_argument("rectify_view: the rectification has no maps");
  // dst already has the right size and type, so remap writes into it (a ROI stays a ROI).
  cv::remap(src, dst, rect.map1[view], rect.map2[view], cv::INTER_LINEAR, cv::BORDER_CONSTANT);
}

} // namespace treestereo
