#include "treestereo/rectify.hpp"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>

using namespace treestereo;

namespace {

// A rig defined analytically: different intrinsics, visible distortion, a small rotation and a
// 120 mm baseline mostly along x.
StereoCalibration make_rig()
{
  StereoCalibration c;
  c.image_size = {640, 480};
  c.M1 = (cv::Mat_<double>(3, 3) << 700, 0, 326, 0, 702, 236, 0, 0, 1);
  c.M2 = (cv::Mat_<double>(3, 3) << 710, 0, 315, 0, 709, 244, 0, 0, 1);
  c.D1 = (cv::Mat_<double>(1, 5) << -0.12, 0.05, 0.0008, -0.0006, 0);
  c.D2 = (cv::Mat_<double>(1, 5) << -0.10, 0.04, -0.0005, 0.0007, 0);
  cv::Rodrigues(cv::Vec3d(0.006, -0.02, 0.004), c.R);
  c.T = (cv::Mat_<double>(3, 1) << -120.0, 1.5, -2.0);
  return c;
}

// Points spread over the common field of view, 1.2 to 4 m away (left camera frame, mm).
std::vector<cv::Point3d> scene_points()
{
  std::vector<cv::Point3d> pts;
  for (double z : {1200.0, 2000.0, 4000.0})
    for (double u = -0.35; u <= 0.35; u += 0.1)
      for (double v = -0.25; v <= 0.25; v += 0.1)
        pts.emplace_back(u * z, v * z, z);
  return pts;
}

// Bilinear lookup of a float 2-channel map at a non-integer position.
cv::Point2d sample(const cv::Mat &map, cv::Point2d p)
{
  const int x0 = static_cast<int>(std::floor(p.x)), y0 = static_cast<int>(std::floor(p.y));
  const double ax = p.x - x0, ay = p.y - y0;
  auto at = [&](int y, int x) {
    const cv::Vec2f v = map.at<cv::Vec2f>(y, x);
    return cv::Point2d(v[0], v[1]);
  };
  return (1 - ay) * ((1 - ax) * at(y0, x0) + ax * at(y0, x0 + 1)) +
         ay * ((1 - ax) * at(y0 + 1, x0) + ax * at(y0 + 1, x0 + 1));
}

} // namespace

TEST(Rectify, CorrespondingPointsShareARowAndTriangulate)
{
  const StereoCalibration rig = make_rig();
  const StereoRectification rect = compute_rectification(rig, rig.image_size, 0);
  ASSERT_TRUE(rect.rectify);
  const StereoGeometry &g = rect.geometry;
  EXPECT_TRUE(g.valid());
  EXPECT_EQ(g.view_size, rig.image_size);
  EXPECT_NEAR(g.baseline_mm, cv::norm(rig.T), 1e-9);
  EXPECT_DOUBLE_EQ(g.cx[LEFT], g.cx[RIGHT]); // CALIB_ZERO_DISPARITY
  EXPECT_DOUBLE_EQ(g.doffs(), 0.0);
  EXPECT_NEAR(cv::determinant(cv::Mat(g.R1)), 1.0, 1e-12);

  // Raw pixels of known 3D points through each real camera, distortion included.
  const std::vector<cv::Point3d> X = scene_points();
  cv::Vec3d rvec;
  cv::Rodrigues(rig.R, rvec);
  std::vector<cv::Point2d> raw_l, raw_r;
  cv::projectPoints(X, cv::Vec3d(), cv::Vec3d(), rig.M1, rig.D1, raw_l);
  cv::projectPoints(X, rvec, cv::Vec3d(rig.T), rig.M2, rig.D2, raw_r);

  // Rectified positions: undistort + rotate + project with the rectification's R_i and P_i.
  cv::Mat R1, R2, P1, P2, Q;
  cv::stereoRectify(rig.M1, rig.D1, rig.M2, rig.D2, rig.image_size, rig.R, rig.T, R1, R2, P1, P2, Q,
                    cv::CALIB_ZERO_DISPARITY, 0);
  const cv::TermCriteria crit(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 200, 1e-12);
  std::vector<cv::Point2d> rl, rr;
  cv::undistortPoints(raw_l, rl, rig.M1, rig.D1, R1, P1, crit);
  cv::undistortPoints(raw_r, rr, rig.M2, rig.D2, R2, P2, crit);

  // The maps, turned into float to look them up: rectified pixel -> raw pixel.
  cv::Mat fmap[2], unused;
  for (int v = 0; v < 2; ++v)
    cv::convertMaps(rect.map1[v], rect.map2[v], fmap[v], unused, CV_32FC2);

  double worst_dy = 0, worst_z = 0, worst_map = 0;
  int checked = 0;
  const cv::Rect inside(cv::Point(2, 2), rig.image_size - cv::Size(4, 4));
  for (std::size_t i = 0; i < X.size(); ++i) {
    if (!inside.contains(cv::Point(rl[i])) || !inside.contains(cv::Point(rr[i])) ||
        !inside.contains(cv::Point(raw_l[i])) || !inside.contains(cv::Point(raw_r[i])))
      continue;
    ++checked;
    worst_dy = std::max(worst_dy, std::abs(rl[i].y - rr[i].y));
    // Depth from the geometry's Q, against the true depth in the rectified-left frame.
    const cv::Vec4d h = g.Q * cv::Vec4d(rl[i].x, rl[i].y, rl[i].x - rr[i].x, 1.0);
    const cv::Vec3d Xrect = g.R1 * cv::Vec3d(X[i].x, X[i].y, X[i].z);
    worst_z = std::max(worst_z, std::abs(h[2] / h[3] - Xrect[2]) / Xrect[2]);
    EXPECT_NEAR(h[0] / h[3], Xrect[0], 1e-3 * Xrect[2]);
    EXPECT_NEAR(h[1] / h[3], Xrect[1], 1e-3 * Xrect[2]);
    // The fixed-point maps send the rectified position back to the raw projection.
    worst_map = std::max(worst_map, cv::norm(sample(fmap[LEFT], rl[i]) - raw_l[i]));
    worst_map = std::max(worst_map, cv::norm(sample(fmap[RIGHT], rr[i]) - raw_r[i]));
  }
  EXPECT_GT(checked, 60);
  EXPECT_LT(worst_dy, 0.05);
  EXPECT_LT(worst_z, 1e-3);
  EXPECT_LT(worst_map, 0.05);
  RecordProperty("worst_dy_px", std::to_string(worst_dy));
  std::printf("points %d: max |dy| %.2e px, max depth error %.2e rel, max map error %.3f px\n",
              checked, worst_dy, worst_z, worst_map);
}

TEST(Rectify, ScalesTheCalibrationToTheStream)
{
  const StereoCalibration rig = make_rig();
  const StereoRectification full = compute_rectification(rig, rig.image_size, 0);
  const StereoRectification half = compute_rectification(rig, {320, 240}, 0);
  EXPECT_EQ(half.geometry.view_size, cv::Size(320, 240));
  EXPECT_EQ(half.map1[LEFT].size(), cv::Size(320, 240));
  EXPECT_NEAR(half.geometry.fx, full.geometry.fx * 0.5, 0.02 * full.geometry.fx);
  EXPECT_NEAR(half.geometry.baseline_mm, cv::norm(rig.T), 1e-9);
  EXPECT_THROW(compute_rectification(rig, {320, 320}, 0), CalibrationError);
}

TEST(Rectify, AlreadyRectifiedInputUsesTheCalibrationAsIs)
{
  // Middlebury-like: two pinhole cameras, no distortion, principal points 20 px apart.
  StereoCalibration c;
  c.image_size = {700, 500};
  c.M1 = (cv::Mat_<double>(3, 3) << 1000, 0, 330, 0, 1000, 250, 0, 0, 1);
  c.M2 = (cv::Mat_<double>(3, 3) << 1000, 0, 350, 0, 1000, 250, 0, 0, 1);
  c.D1 = cv::Mat::zeros(1, 5, CV_64F);
  c.D2 = cv::Mat::zeros(1, 5, CV_64F);
  c.R = cv::Mat::eye(3, 3, CV_64F);
  c.T = (cv::Mat_<double>(3, 1) << -176.252, 0, 0);
  const StereoRectification r = compute_rectification(c, c.image_size, -1, false);
  EXPECT_FALSE(r.rectify);
  EXPECT_TRUE(r.map1[LEFT].empty());
  const StereoGeometry &g = r.geometry;
  EXPECT_EQ(g.fx, 1000);
  EXPECT_EQ(g.cx[LEFT], 330);
  EXPECT_EQ(g.cx[RIGHT], 350);
  EXPECT_EQ(g.cy, 250);
  EXPECT_NEAR(g.baseline_mm, 176.252, 1e-9);
  EXPECT_EQ(r.valid_roi[RIGHT], cv::Rect(0, 0, 700, 500));
  // A point at Z = 2.5 m: d = f B / Z + doffs; Q must give Z back.
  const double z = 2500, x = 120, y = -60;
  const double xl = 330 + 1000 * x / z, xr = 350 + 1000 * (x - 176.252) / z, yy = 250 + 1000 * y / z;
  const cv::Vec4d h = g.Q * cv::Vec4d(xl, yy, xl - xr, 1);
  EXPECT_NEAR(h[2] / h[3], z, 1e-9 * z);
  EXPECT_NEAR(h[0] / h[3], x, 1e-9 * z);
  EXPECT_NEAR(h[1] / h[3], y, 1e-9 * z);
  EXPECT_NEAR(1000 * 176.252 / (xl - xr - g.doffs()), z, 1e-9 * z);

  // With stored P1/P2/Q those win (here: the same rig, stated by its projection matrices).
  c.R1 = cv::Mat::eye(3, 3, CV_64F);
  c.R2 = cv::Mat::eye(3, 3, CV_64F);
  c.P1 = (cv::Mat_<double>(3, 4) << 900, 0, 330, 0, 0, 900, 250, 0, 0, 0, 1, 0);
  c.P2 = (cv::Mat_<double>(3, 4) << 900, 0, 350, -900 * 176.252, 0, 900, 250, 0, 0, 0, 1, 0);
  const StereoGeometry g2 = compute_rectification(c, c.image_size, -1, false).geometry;
  EXPECT_EQ(g2.fx, 900);
  EXPECT_NEAR(g2.baseline_mm, 176.252, 1e-9);
  const cv::Vec4d h2 = g2.Q * cv::Vec4d(0, 0, 900 * 176.252 / z + 330 - 350, 1);
  EXPECT_NEAR(h2[2] / h2[3], z, 1e-9 * z);
}

TEST(Rectify, WritesIntoHalfOfASideBySideFrame)
{
  const StereoCalibration rig = make_rig();
  const StereoRectification rect = compute_rectification(rig, rig.image_size, 0);
  // Raw views whose colour encodes the raw position: blue = x, green = y (smooth ramps).
  cv::Mat raw(rig.image_size, CV_8UC3);
  for (int y = 0; y < raw.rows; ++y)
    for (int x = 0; x < raw.cols; ++x)
      raw.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uchar>(x * 255.0 / 639),
                                          cv::saturate_cast<uchar>(y * 255.0 / 479), 200);
  cv::Mat frame(rig.image_size.height, 2 * rig.image_size.width, CV_8UC3, cv::Scalar::all(0));
  const uchar *before = frame.data;
  for (int v = 0; v < 2; ++v) {
    cv::Mat half = frame(cv::Rect(v * rig.image_size.width, 0, rig.image_size.width, rig.image_size.height));
    rectify_view(rect, v, raw, half);
    EXPECT_EQ(half.data, frame.data + v * rig.image_size.width * 3);
  }
  EXPECT_EQ(frame.data, before);

  // At the rectified position of a 3D point, the colour says where in the raw image it came from.
  cv::Vec3d rvec;
  cv::Rodrigues(rig.R, rvec);
  const std::vector<cv::Point3d> X{{100, 50, 1500}, {-300, -100, 2500}};
  std::vector<cv::Point2d> raw_px[2], rect_px[2];
  cv::projectPoints(X, cv::Vec3d(), cv::Vec3d(), rig.M1, rig.D1, raw_px[LEFT]);
  cv::projectPoints(X, rvec, cv::Vec3d(rig.T), rig.M2, rig.D2, raw_px[RIGHT]);
  cv::Mat R1, R2, P1, P2, Q;
  cv::stereoRectify(rig.M1, rig.D1, rig.M2, rig.D2, rig.image_size, rig.R, rig.T, R1, R2, P1, P2, Q,
                    cv::CALIB_ZERO_DISPARITY, 0);
  const cv::TermCriteria crit(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 200, 1e-12);
  cv::undistortPoints(raw_px[LEFT], rect_px[LEFT], rig.M1, rig.D1, R1, P1, crit);
  cv::undistortPoints(raw_px[RIGHT], rect_px[RIGHT], rig.M2, rig.D2, R2, P2, crit);
  for (int v = 0; v < 2; ++v)
    for (std::size_t i = 0; i < X.size(); ++i) {
      const cv::Point p(cvRound(rect_px[v][i].x), cvRound(rect_px[v][i].y));
      const cv::Vec3b c = frame.at<cv::Vec3b>(p.y, p.x + v * rig.image_size.width);
      // One rectified pixel spans about one raw pixel: 0.4 grey levels per pixel plus rounding.
      EXPECT_NEAR(c[0], raw_px[v][i].x * 255.0 / 639, 1.5) << "view " << v;
      EXPECT_NEAR(c[1], raw_px[v][i].y * 255.0 / 479, 1.5) << "view " << v;
      EXPECT_EQ(c[2], 200);
    }
}

TEST(Rectify, AnyChannelCountAndPassThrough)
{
  const StereoCalibration rig = make_rig();
  const StereoRectification rect = compute_rectification(rig, rig.image_size, 0);
  for (int ch : {1, 3, 4}) {
    cv::Mat src(rig.image_size, CV_8UC(ch), cv::Scalar::all(90)), dst;
    rectify_view(rect, RIGHT, src, dst);
    EXPECT_EQ(dst.type(), src.type());
    // The middle of a uniform image stays uniform.
    EXPECT_EQ(dst.at<uchar>(240, 320 * ch), 90);
  }
  StereoCalibration c = rig;
  c.D1 = cv::Mat::zeros(1, 5, CV_64F);
  const StereoRectification pass = compute_rectification(c, c.image_size, -1, false);
  cv::Mat src(rig.image_size, CV_8UC1), dst;
  cv::randu(src, 0, 255);
  rectify_view(pass, LEFT, src, dst);
  EXPECT_EQ(cv::norm(src, dst, cv::NORM_INF), 0);
}

TEST(Rectify, RejectsMismatchedImages)
{
  const StereoCalibration rig = make_rig();
  const StereoRectification rect = compute_rectification(rig, rig.image_size, 0);
  cv::Mat src(rig.image_size, CV_8UC3, cv::Scalar::all(1));
  cv::Mat small(100, 100, CV_8UC3), gray(rig.image_size, CV_8UC1), wide(rig.image_size, CV_16UC3);
  cv::Mat two(rig.image_size, CV_8UC2), dst;
  EXPECT_THROW(rectify_view(rect, 2, src, dst), std::invalid_argument);
  EXPECT_THROW(rectify_view(rect, LEFT, small, dst), std::invalid_argument);
  EXPECT_THROW(rectify_view(rect, LEFT, wide, dst), std::invalid_argument);
  EXPECT_THROW(rectify_view(rect, LEFT, two, dst), std::invalid_argument);
  EXPECT_THROW(rectify_view(rect, LEFT, src, small), std::invalid_argument);
  EXPECT_THROW(rectify_view(rect, LEFT, src, gray), std::invalid_argument);
  EXPECT_EQ(small.size(), cv::Size(100, 100)); // not reallocated
  EXPECT_EQ(gray.type(), CV_8UC1);
}
