// The synthetic orchard renderer, checked against geometry: the camera model, the surfaces the
// rays hit, the two views seeing one 3D scene, and SIFT + rectification recovering it.
#include "treestereo/scene.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <thread>

using namespace treestereo;

namespace {

const cv::Size kVga(640, 480);

SceneParams vga(double noise = 2.0)
{
  SceneParams p;
  p.image_size = kVga;
  p.noise = noise;
  return p;
}

// The 3D hit of a pixel in its view's camera frame, from the ground-truth depth.
cv::Point3d hit_point(const SceneRenderer &r, int view, const GroundTruth &g, int x, int y)
{
  const cv::Vec2f n = r.normalized_rays(view).at<cv::Vec2f>(y, x);
  const double z = g.depth.at<float>(y, x);
  return {n[0] * z, n[1] * z, z};
}

cv::Point2d project(const cv::Point3d &X, const cv::Mat &M, const cv::Mat &D)
{
  std::vector<cv::Point3d> in{X};
  std::vector<cv::Point2d> out;
  cv::projectPoints(in, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), M, D, out);
  return out[0];
}

cv::Vec3d to_right(const StereoCalibration &c, const cv::Vec3d &X)
{
  return cv::Matx33d(c.R) * X + cv::Vec3d(c.T.at<double>(0), c.T.at<double>(1), c.T.at<double>(2));
}

cv::Vec3d to_left(const StereoCalibration &c, const cv::Vec3d &X)
{
  return cv::Matx33d(c.R).t() *
         (X - cv::Vec3d(c.T.at<double>(0), c.T.at<double>(1), c.T.at<double>(2)));
}

int excess_green(const cv::Vec3b &rgb) { return 2 * rgb[1] - rgb[0] - rgb[2]; }

cv::Vec3f bilinear(const cv::Mat &rgb, double x, double y)
{
  cv::Mat patch;
  cv::getRectSubPix(rgb, cv::Size(1, 1), cv::Point2f(float(x), float(y)), patch, CV_32F);
  return patch.at<cv::Vec3f>(0, 0);
}

} // namespace

TEST(Scene, RejectsBadParameters)
{
  SceneParams p = vga();
  p.image_size = cv::Size(3000, 2000);
  EXPECT_THROW(SceneRenderer{p}, std::runtime_error);
  p = vga();
  p.distance_mm = -1;
  EXPECT_THROW(SceneRenderer{p}, std::runtime_error);
  p = vga();
  p.light = std::nan("");
  EXPECT_THROW(SceneRenderer{p}, std::runtime_error);
  SceneRenderer r(vga());
  cv::Mat rgb;
  EXPECT_THROW(r.render(2, 0, rgb), std::runtime_error);
  EXPECT_THROW(truth_in_frame(GroundTruth{}, cv::Matx33d(2, 0, 0, 0, 1, 0, 0, 0, 1)),
               std::runtime_error);
}

TEST(Scene, RigIsTheScaledPaperCameraAndNeedsRectification)
{
  SceneParams p = vga();
  const StereoCalibration c = rig_calibration(p);
  EXPECT_EQ(c.image_size, kVga);
  EXPECT_NEAR(c.M1.at<double>(0, 0), 3503.12 * 640 / 2592, 1e-9);
  EXPECT_NE(c.M1.at<double>(0, 0), c.M2.at<double>(0, 0));
  EXPECT_NEAR(c.T.at<double>(0), -50.0, 1e-12);
  const double angle_deg = cv::norm(cv::Mat(c.R) - cv::Mat::eye(3, 3, CV_64F)) / std::sqrt(2.0) * 180 / CV_PI;
  EXPECT_GT(angle_deg, 0.3);
  EXPECT_LT(angle_deg, 1.0);
  EXPECT_NEAR(cv::determinant(c.R), 1.0, 1e-12);
}

// Depth is Z along the pixel's own ray: projecting the hit back through the camera model
// (with distortion) lands on the pixel, and each kind of surface is where it was put.
TEST(Scene, DepthRoundTripsThroughTheCameraModelAndLiesOnTheSurfaces)
{
  const SceneParams p = vga();
  SceneRenderer r(p);
  const StereoCalibration &c = r.calibration();
  for (int view = 0; view < 2; ++view) {
    cv::Mat rgb;
    GroundTruth g;
    r.render(view, 0, rgb, &g);
    const cv::Mat &M = view == 0 ? c.M1 : c.M2, &D = view == 0 ? c.D1 : c.D2;
    double worst_px = 0, worst_ground = 0, worst_wall = 0, worst_trunk = 0;
    int counts[5] = {0, 0, 0, 0, 0};
    std::vector<cv::Point3d> pts;
    std::vector<cv::Point2d> pix;
    for (int y = 1; y < kVga.height; y += 5)
      for (int x = 2; x < kVga.width; x += 5) {
        const auto label = SurfaceLabel(g.labels.at<uchar>(y, x));
        ++counts[int(label)];
        if (label == SurfaceLabel::Sky) {
          EXPECT_EQ(g.depth.at<float>(y, x), 0.0f);
          continue;
        }
        const cv::Point3d X = hit_point(r, view, g, x, y);
        pts.push_back(X);
        pix.emplace_back(x, y);
        const cv::Vec3d L = view == 0 ? cv::Vec3d(X) : to_left(c, cv::Vec3d(X));
        if (label == SurfaceLabel::Ground)
          worst_ground = std::max(worst_ground, std::abs(L[1] - p.camera_height_mm));
        if (label == SurfaceLabel::Background)
          worst_wall = std::max(worst_wall, std::abs(L[2] - p.background_distance_mm));
        if (label == SurfaceLabel::Trunk)
          worst_trunk = std::max(worst_trunk, std::abs(std::hypot(L[0] - p.tree_x_mm, L[2] - p.distance_mm) -
                                                       p.trunk_radius_mm));
      }
    std::vector<cv::Point2d> back;
    cv::projectPoints(pts, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), M, D, back);
    for (std::size_t i = 0; i < pts.size(); ++i)
      worst_px = std::max(worst_px, cv::norm(back[i] - pix[i]));
    std::printf("view %d: round trip worst %.1e px over %zu pixels; worst off-surface: ground "
                "%.3f mm, wall %.3f mm, trunk %.3f mm\n",
                view, worst_px, pts.size(), worst_ground, worst_wall, worst_trunk);
    EXPECT_LT(worst_px, 0.05);
    EXPECT_LT(worst_ground, 0.05);
    EXPECT_LT(worst_wall, 0.05);
    EXPECT_LT(worst_trunk, 0.05);
    for (int label = 0; label < 5; ++label)
      EXPECT_GT(counts[label], 50) << "every kind of surface is in view, label " << label;
  }
}

// The same 3D point seen from both cameras: the right view's depth at the projected pixel
// agrees (where nothing occludes it) and so does the colour (the texture lives on the surface).
TEST(Scene, BothViewsSeeTheSameSurfaceAndTexture)
{
  SceneRenderer r(vga(0.0));
  const StereoCalibration &c = r.calibration();
  cv::Mat left, right;
  GroundTruth gl, gr;
  r.render(0, 0, left, &gl);
  r.render(1, 0, right, &gr);
  std::vector<double> dz, dcol, dcol_wrong;
  int visited = 0;
  for (int y = 3; y < kVga.height - 3; y += 3)
    for (int x = 3; x < kVga.width - 3; x += 3) {
      const auto label = SurfaceLabel(gl.labels.at<uchar>(y, x));
      if (label != SurfaceLabel::Leaf && label != SurfaceLabel::Trunk)
        continue;
      const cv::Vec3d Xr = to_right(c, cv::Vec3d(hit_point(r, 0, gl, x, y)));
      const cv::Point2d q = project(cv::Point3d(Xr), c.M2, c.D2);
      const int u = int(std::lround(q.x)), v = int(std::lround(q.y));
      if (u < 5 || v < 0 || u >= kVga.width - 5 || v >= kVga.height)
        continue;
      ++visited;
      const cv::Point3d Xr_seen = hit_point(r, 1, gr, u, v);
      const double err = cv::norm(cv::Vec3d(Xr_seen) - Xr);
      // The nearest right pixel is up to half a pixel away (about 1.2 mm on the canopy);
      // a leaf in front or a hole behind differs by centimetres.
      if (err > 6.0)
        continue;
      dz.push_back(std::abs(Xr_seen.z - Xr[2]));
      const cv::Vec3f a = left.at<cv::Vec3b>(y, x);
      dcol.push_back(cv::norm(a - bilinear(right, q.x, q.y), cv::NORM_L1) / 3.0);
      dcol_wrong.push_back(cv::norm(a - bilinear(right, q.x + 4, q.y), cv::NORM_L1) / 3.0);
    }
  const double agree = double(dz.size()) / visited;
  const double dz_med = median(dz), col = median(dcol), col_wrong = median(dcol_wrong);
  std::printf("%d canopy/trunk points: %.1f %% seen in the right view, median |dZ| %.3f mm, "
              "median colour difference %.2f levels (4 px off: %.2f)\n",
              visited, 100 * agree, dz_med, col, col_wrong);
  EXPECT_GT(visited, 3000);
  EXPECT_GT(agree, 0.80);
  EXPECT_LT(dz_med, 1.0);
  EXPECT_LT(col, 4.0);
  EXPECT_GT(col_wrong, 3.0 * col);
}

// The whole point of the renderer: rectify with the rig's calibration, match SIFT, triangulate,
// and get the ground truth back.
TEST(Scene, RectifiedSiftMatchesAreOnOneRowAndTriangulateToTheTruth)
{
  SceneRenderer r(vga());
  const StereoCalibration &c = r.calibration();
  cv::Mat rgb[2];
  GroundTruth g[2];
  for (int v = 0; v < 2; ++v)
    r.render(v, 0, rgb[v], &g[v]);

  cv::Mat R1, R2, P1, P2, Q;
  cv::stereoRectify(c.M1, c.D1, c.M2, c.D2, kVga, c.R, c.T, R1, R2, P1, P2, Q,
                    cv::CALIB_ZERO_DISPARITY, 0);
  cv::Mat map[2][2], rect[2], mask_rect;
  for (int v = 0; v < 2; ++v) {
    cv::initUndistortRectifyMap(v == 0 ? c.M1 : c.M2, v == 0 ? c.D1 : c.D2, v == 0 ? R1 : R2,
                                v == 0 ? P1 : P2, kVga, CV_32FC1, map[v][0], map[v][1]);
    cv::Mat gray;
    cv::cvtColor(rgb[v], gray, cv::COLOR_RGB2GRAY);
    cv::remap(gray, rect[v], map[v][0], map[v][1], cv::INTER_LINEAR);
  }
  cv::remap(g[0].canopy_mask, mask_rect, map[0][0], map[0][1], cv::INTER_NEAREST);

  auto sift = cv::SIFT::create();
  std::vector<cv::KeyPoint> kp[2];
  cv::Mat desc[2];
  for (int v = 0; v < 2; ++v)
    sift->detectAndCompute(rect[v], cv::noArray(), kp[v], desc[v]);
  std::vector<std::vector<cv::DMatch>> knn;
  cv::BFMatcher(cv::NORM_L2).knnMatch(desc[0], desc[1], knn, 2);

  const double f = P1.at<double>(0, 0), b = cv::norm(c.T);
  const cv::Matx33d R1m(R1);
  std::vector<double> dy, rel_err, signed_d;
  int on_canopy = 0, correct = 0, within = 0, n_smooth = 0, within_smooth = 0;
  for (const auto &m : knn) {
    if (m.size() < 2 || m[0].distance > 0.75f * m[1].distance)
      continue;
    const cv::Point2f pl = kp[0][std::size_t(m[0].queryIdx)].pt, pr = kp[1][std::size_t(m[0].trainIdx)].pt;
    dy.push_back(std::abs(pl.y - pr.y));
    const int xi = int(std::lround(pl.x)), yi = int(std::lround(pl.y));
    if (mask_rect.at<uchar>(yi, xi) == 0)
      continue;
    ++on_canopy;
    // Truth: the left pixel this rectified keypoint comes from, its 3D hit, rotated by R1.
    const cv::Vec3d ray = R1m.t() * cv::Vec3d((pl.x - P1.at<double>(0, 2)) / f,
                                             (pl.y - P1.at<double>(1, 2)) / f, 1.0);
    const cv::Point2d src = project(cv::Point3d(ray), c.M1, c.D1);
    const int sx = int(std::lround(src.x)), sy = int(std::lround(src.y));
    if (sx < 1 || sy < 1 || sx >= kVga.width - 1 || sy >= kVga.height - 1)
      continue;
    if (g[0].depth.at<float>(sy, sx) <= 0)
      continue;
    const cv::Vec3d X = R1m * cv::Vec3d(hit_point(r, 0, g[0], sx, sy));
    // A keypoint is a blob several pixels wide; where it straddles a hole, the two views see
    // different things through the hole (parallax) and its centre moves along the row: a real
    // effect of the scene, not an error of the camera model. Smooth blobs are counted apart.
    const int rad = std::max(2, int(std::lround(0.5 * kp[0][std::size_t(m[0].queryIdx)].size)));
    const cv::Rect win = cv::Rect(sx - rad, sy - rad, 2 * rad + 1, 2 * rad + 1) & cv::Rect(cv::Point(), kVga);
    double zmin, zmax;
    cv::minMaxLoc(g[0].depth(win), &zmin, &zmax);
    const bool smooth = zmax - zmin < 0.01 * X[2];
    const double d_true = f * b / X[2];
    const double d = pl.x - pr.x;
    if (std::abs(d - d_true) > 2.0 || std::abs(pl.y - pr.y) > 2.0)
      continue; // a wrong match (the matcher's business, not the renderer's)
    ++correct;
    cv::Mat Xh = Q * (cv::Mat_<double>(4, 1) << pl.x, pl.y, d, 1.0);
    const double z = Xh.at<double>(2) / Xh.at<double>(3);
    const double tol = X[2] * X[2] / (f * b) * 0.5; // depth change of half a pixel of disparity
    rel_err.push_back(std::abs(z - X[2]) / tol);
    signed_d.push_back(d - d_true);
    within += std::abs(z - X[2]) <= tol;
    n_smooth += smooth;
    within_smooth += smooth && std::abs(z - X[2]) <= tol;
  }
  const double dy_med = median(dy);
  std::printf("%zu matches, median |dy| %.3f px; %d on the canopy, %d correct, %.1f %% of those "
              "triangulate within 0.5 px of disparity (median error %.2f of that)\n",
              dy.size(), dy_med, on_canopy, correct, 100.0 * within / std::max(1, correct),
              median(rel_err));
  const Summary sd = summarize(signed_d);
  std::printf("disparity error: median %+.3f px, MAD %.3f px; on %d smooth blobs %.1f %% within\n",
              sd.median, sd.mad, n_smooth, 100.0 * within_smooth / std::max(1, n_smooth));
  EXPECT_LT(dy_med, 0.5);
  EXPECT_GE(on_canopy, 100);
  EXPECT_GE(correct, 0.8 * on_canopy);
  EXPECT_LT(std::abs(sd.median), 0.1) << "the triangulated depth is biased";
  EXPECT_LT(median(rel_err), 0.5);
  EXPECT_GE(within, 0.7 * correct);
  EXPECT_GE(n_smooth, 50);
  EXPECT_GE(within_smooth, 0.85 * n_smooth);
}

TEST(Scene, LightChangesBrightnessNotGeometry)
{
  SceneParams dim = vga(0.0), bright = vga(0.0);
  dim.light = 0.7;
  bright.light = 1.3;
  SceneRenderer rd(dim), rb(bright);
  cv::Mat a, b;
  GroundTruth ga, gb;
  rd.render(0, 0, a, &ga);
  rb.render(0, 0, b, &gb);
  EXPECT_EQ(cv::norm(ga.depth, gb.depth, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::countNonZero(ga.canopy_mask != gb.canopy_mask), 0);
  EXPECT_EQ(ga.distance_m, gb.distance_m);
  const double ratio = cv::mean(b)[1] / cv::mean(a)[1];
  std::printf("green mean %.1f at light 0.7, %.1f at 1.3 (ratio %.3f, ideal 1.857)\n",
              cv::mean(a)[1], cv::mean(b)[1], ratio);
  EXPECT_GT(ratio, 1.7);
  EXPECT_LT(ratio, 1.9);
}

TEST(Scene, SameSeedSameImagesOtherSeedOtherTree)
{
  const SceneParams p = vga();
  SceneRenderer r1(p), r2(p);
  cv::Mat a, b, c;
  GroundTruth ga, gc;
  r1.render(1, 5, a, &ga);
  r2.render(1, 5, b);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  // Another frame of a still scene: new sensor noise, the same geometry.
  r1.render(1, 6, b);
  EXPECT_GT(cv::norm(a, b, cv::NORM_L1), 0.0);
  SceneParams q = p;
  q.seed = 2;
  SceneRenderer r3(q);
  r3.render(1, 5, c, &gc);
  const double inter = cv::countNonZero(ga.canopy_mask & gc.canopy_mask);
  const double uni = cv::countNonZero(ga.canopy_mask | gc.canopy_mask);
  std::printf("canopy overlap between seeds 1 and 2: IoU %.3f\n", inter / uni);
  EXPECT_LT(inter / uni, 0.85);
  // Both trees still have the requested size.
  EXPECT_NEAR(gc.canopy_height_m, ga.canopy_height_m, 1e-9);
}

TEST(Scene, CanopyIsGreenAndNothingElseIs)
{
  SceneRenderer r(vga());
  cv::Mat rgb;
  GroundTruth g;
  r.render(0, 0, rgb, &g);
  // The lens blur mixes the colours of the pixels right beside the canopy (as a real lens does):
  // those are counted apart.
  cv::Mat near_canopy;
  cv::dilate(g.canopy_mask, near_canopy, cv::Mat());
  int canopy = 0, canopy_green = 0, other = 0, other_green = 0, border = 0, border_green = 0;
  for (int y = 0; y < kVga.height; ++y)
    for (int x = 0; x < kVga.width; ++x) {
      const bool green = excess_green(rgb.at<cv::Vec3b>(y, x)) > 0;
      if (g.canopy_mask.at<uchar>(y, x)) {
        ++canopy;
        canopy_green += green;
      } else if (near_canopy.at<uchar>(y, x)) {
        ++border;
        border_green += green;
      } else {
        ++other;
        other_green += green;
      }
    }
  std::printf("2G-R-B > 0 on %.2f %% of %d canopy pixels, on %.2f %% of %d other pixels "
              "(%.1f %% of the %d pixels bordering the canopy)\n",
              100.0 * canopy_green / canopy, canopy, 100.0 * other_green / other, other,
              100.0 * border_green / border, border);
  EXPECT_GT(canopy, kVga.area() / 10);
  EXPECT_GT(canopy_green, 0.95 * canopy);
  EXPECT_LT(other_green, 0.01 * other);
}

TEST(Scene, TruthMatchesTheParametersAndTheVisibleSurface)
{
  SceneParams p = vga();
  p.distance_mm = 2300;
  p.canopy_height_mm = 1000;
  p.canopy_width_mm = 600;
  SceneRenderer r(p);
  cv::Mat rgb;
  GroundTruth g;
  r.render(0, 0, rgb, &g);
  EXPECT_NEAR(g.canopy_height_m, 1.0, 0.01);
  EXPECT_NEAR(g.canopy_width_m, 0.6, 0.006);
  EXPECT_NEAR(g.canopy_depth_m, p.canopy_depth_mm / 1000, 0.006);
  EXPECT_NEAR(g.trunk_distance_m, 2.3, 1e-9);
  EXPECT_NEAR(g.lateral_offset_m, 0.0, 1e-9);
  ASSERT_EQ(g.canopy_points_mm.size(), std::size_t(cv::countNonZero(g.canopy_mask)));

  // Every visible canopy point lies in the union's box, and the visible surface nearly spans it.
  const double top = p.camera_height_mm - p.trunk_height_mm - p.canopy_height_mm;
  double lo[3] = {1e9, 1e9, 1e9}, hi[3] = {-1e9, -1e9, -1e9};
  for (const auto &q : g.canopy_points_mm) {
    const double v[3] = {q.x, q.y, q.z};
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], v[a]);
      hi[a] = std::max(hi[a], v[a]);
    }
  }
  std::printf("visible canopy spans x %.1f..%.1f, y %.1f..%.1f, z %.1f..%.1f mm; median Z %.4f m, "
              "thickness %.4f m\n", lo[0], hi[0], lo[1], hi[1], lo[2], hi[2], g.distance_m, g.thickness_m);
  EXPECT_GE(lo[0], -300.0 - 0.1);
  EXPECT_LE(hi[0], 300.0 + 0.1);
  EXPECT_GE(lo[1], top - 0.1);
  EXPECT_LE(hi[1], top + 1000 + 0.1);
  EXPECT_GE(lo[2], 2300 - 300 - 0.1);
  EXPECT_LE(hi[2], 2300 + 300 + 0.1);
  EXPECT_GT(hi[0] - lo[0], 0.93 * 600);
  EXPECT_GT(hi[1] - lo[1], 0.93 * 1000);
  // We look at the front of the canopy: the median is in front of the trunk, past the front.
  EXPECT_LT(g.distance_m, 2.3);
  EXPECT_GT(g.distance_m, 2.0);
  EXPECT_NEAR(g.thickness_m, g.depth_p95_m - g.depth_p05_m, 1e-12);
  EXPECT_GT(g.thickness_m, 0.05);
}

TEST(Scene, TruthInAnotherFrameRotatesThePoints)
{
  SceneRenderer r(vga());
  cv::Mat rgb;
  GroundTruth g;
  r.render(0, 0, rgb, &g);
  // A roll about the optical axis leaves every Z, hence the depth statistics, unchanged.
  cv::Matx33d roll;
  cv::Rodrigues(cv::Vec3d(0, 0, 0.3), roll);
  const GroundTruth rolled = truth_in_frame(g, roll);
  EXPECT_NEAR(rolled.distance_m, g.distance_m, 1e-6);
  EXPECT_NEAR(rolled.thickness_m, g.thickness_m, 1e-6);
  EXPECT_NEAR(cv::norm(rolled.centroid_m), cv::norm(g.centroid_m), 1e-6);
  // A pitch by a about x: the trunk point's Z becomes cos(a) Z - sin(a) Y... exactly.
  const double a = 0.01;
  cv::Matx33d pitch;
  cv::Rodrigues(cv::Vec3d(a, 0, 0), pitch);
  const GroundTruth pitched = truth_in_frame(g, pitch);
  const cv::Vec3d t = g.trunk_point_mm;
  EXPECT_NEAR(pitched.trunk_distance_m, (std::cos(a) * t[2] + std::sin(a) * t[1]) / 1000, 1e-9);
  EXPECT_NE(pitched.distance_m, g.distance_m);
  // And back again.
  const GroundTruth back = truth_in_frame(pitched, pitch.t());
  EXPECT_NEAR(back.distance_m, g.distance_m, 1e-6);
  EXPECT_NEAR(back.depth_p95_m, g.depth_p95_m, 1e-6);
}

TEST(Scene, DrivingAlongTheRowShiftsTheSceneAndTheTexturesWithIt)
{
  SceneParams p = vga(0.0);
  p.speed_m_s = 1.0;
  p.framerate = 10.0;
  SceneRenderer r(p);
  cv::Mat a, b;
  GroundTruth ga, gb;
  r.render(0, 0, a, &ga);
  r.render(0, 1, b, &gb);
  EXPECT_NEAR(r.travel_mm(1), 100.0, 1e-9);
  EXPECT_NEAR(gb.lateral_offset_m - ga.lateral_offset_m, -0.1, 1e-9);
  // A ground point of frame 0 is 100 mm further left in frame 1, with the same colour.
  const StereoCalibration &c = r.calibration();
  std::vector<double> diff;
  for (int y = 300; y < kVga.height; y += 7)
    for (int x = 100; x < kVga.width - 100; x += 7) {
      if (SurfaceLabel(ga.labels.at<uchar>(y, x)) != SurfaceLabel::Ground)
        continue;
      cv::Point3d X = hit_point(r, 0, ga, x, y);
      X.x -= 100.0;
      const cv::Point2d q = project(X, c.M1, c.D1);
      const int u = int(std::lround(q.x)), v = int(std::lround(q.y));
      if (u < 1 || v < 1 || u >= kVga.width - 1 || v >= kVga.height - 1 ||
          SurfaceLabel(gb.labels.at<uchar>(v, u)) != SurfaceLabel::Ground)
        continue;
      diff.push_back(cv::norm(cv::Vec3f(a.at<cv::Vec3b>(y, x)) - bilinear(b, q.x, q.y), cv::NORM_L1) / 3);
    }
  std::printf("%zu ground points followed: median colour difference %.2f levels\n", diff.size(),
              median(diff));
  EXPECT_GT(diff.size(), 500u);
  EXPECT_LT(median(diff), 4.0);
}

// Two GStreamer sources render the two views of one renderer at the same time.
TEST(Scene, ConcurrentRendersEqualSequentialOnes)
{
  SceneRenderer r(vga());
  cv::Mat seq[2], par[2];
  r.render(0, 3, seq[0]);
  r.render(1, 3, seq[1]);
  std::thread t([&] { r.render(1, 3, par[1]); });
  r.render(0, 3, par[0]);
  t.join();
  EXPECT_EQ(cv::norm(seq[0], par[0], cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(seq[1], par[1], cv::NORM_INF), 0.0);
}

// ---------------------------------------------------------------------------------------------
// Orchard and hedgerow

namespace
{

SceneParams row_scene(SceneKind kind, double noise = 2.0)
{
  SceneParams p = vga(noise);
  p.kind = kind;
  p.seed = 3;
  return p;
}

int count_label(const GroundTruth &g, SurfaceLabel l)
{
  cv::Mat m;
  cv::compare(g.labels, int(l), m, cv::CMP_EQ);
  return cv::countNonZero(m);
}

} // namespace

TEST(SceneOrchard, KindNamesRoundTripAndUnknownNamesAreRejected)
{
  for (SceneKind k : {SceneKind::Lab, SceneKind::Orchard, SceneKind::Hedgerow})
    EXPECT_EQ(scene_kind_from_name(scene_kind_name(k)), k);
  try {
    scene_kind_from_name("forest");
    FAIL() << "no exception";
  } catch (const std::runtime_error &e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("forest"), std::string::npos) << what;
    EXPECT_NE(what.find("lab, orchard, hedgerow"), std::string::npos) << what;
  }
}

TEST(SceneOrchard, BadRowParametersAreNamed)
{
  auto message = [](const SceneParams &p) -> std::string {
    try {
      SceneRenderer r(p);
    } catch (const std::runtime_error &e) {
      return e.what();
    }
    return "";
  };
  SceneParams p = row_scene(SceneKind::Orchard);
  p.row_gap_min_mm = 500;
  p.row_gap_max_mm = 100;
  EXPECT_NE(message(p).find("row_gap_max_mm"), std::string::npos) << message(p);
  p = row_scene(SceneKind::Orchard);
  p.row_gap_min_mm = -0.6 * p.canopy_width_mm;
  EXPECT_NE(message(p).find("row_gap_min_mm"), std::string::npos) << message(p);
  p = row_scene(SceneKind::Orchard);
  p.row_spacing_mm = 1000;
  EXPECT_NE(message(p).find("row_spacing_mm"), std::string::npos) << message(p);
  p = row_scene(SceneKind::Hedgerow);
  p.row_spacing_mm = std::nan("");
  p.row_gap_max_mm = std::numeric_limits<double>::infinity();
  EXPECT_NE(message(p).find("row_gap_max_mm"), std::string::npos) << message(p);
  // The wall must stand at least 1 m behind the back row; left at its default it moves back.
  p = row_scene(SceneKind::Orchard);
  p.row_spacing_mm = 8000;
  p.background_distance_mm = 10500;
  EXPECT_NE(message(p).find("background_distance_mm"), std::string::npos) << message(p);
  p.background_distance_mm = SceneParams{}.background_distance_mm;
  EXPECT_EQ(message(p), "");
  EXPECT_GE(resolve_scene_params(p).background_distance_mm,
            p.distance_mm + 8000 + 0.5 * 1.3 * p.canopy_depth_mm + 3000 - 1e-9);
  // Lab ignores the row parameters.
  p = vga();
  p.row_spacing_mm = 1;
  EXPECT_EQ(message(p), "");
}

TEST(SceneOrchard, EveryKindOfSurfaceIsThereAndTheGrassIsGreenWithDryPatches)
{
  const SceneParams p = row_scene(SceneKind::Orchard, 0.0);
  SceneRenderer r(p);
  cv::Mat rgb;
  GroundTruth g;
  r.render(0, 0, rgb, &g);
  for (SurfaceLabel l :
       {SurfaceLabel::Sky, SurfaceLabel::Ground, SurfaceLabel::Background, SurfaceLabel::Trunk,
        SurfaceLabel::Leaf, SurfaceLabel::RowLeaf, SurfaceLabel::BackLeaf})
    EXPECT_GT(count_label(g, l), 100) << "label " << int(l);
  // Grass: green on most of it (well inside, away from the blur of other surfaces), dry patches.
  cv::Mat ground;
  cv::compare(g.labels, int(SurfaceLabel::Ground), ground, cv::CMP_EQ);
  cv::erode(ground, ground, cv::Mat());
  int n = 0, green = 0, dry = 0;
  for (int y = 0; y < kVga.height; ++y)
    for (int x = 0; x < kVga.width; ++x)
      if (ground.at<uchar>(y, x)) {
        const int exg = excess_green(rgb.at<cv::Vec3b>(y, x));
        ++n;
        green += exg > 20;
        dry += exg < 10;
      }
  std::printf("grass: 2G-R-B > 20 on %.1f %%, < 10 on %.1f %% of %d pixels\n", 100.0 * green / n,
              100.0 * dry / n, n);
  EXPECT_GT(green, n / 2);
  EXPECT_GT(dry, n / 50);
  // tree_index: the tree in front's leaves and trunk, the near row's, nothing else.
  ASSERT_EQ(g.tree_index.type(), CV_16S);
  ASSERT_EQ(g.tree_index.size(), kVga);
  for (int y = 0; y < kVga.height; ++y)
    for (int x = 0; x < kVga.width; ++x) {
      const auto l = SurfaceLabel(g.labels.at<uchar>(y, x));
      const int k = g.tree_index.at<std::int16_t>(y, x);
      if (l == SurfaceLabel::Leaf) {
        ASSERT_EQ(k, g.front_tree);
      } else if (l == SurfaceLabel::RowLeaf) {
        ASSERT_TRUE(k != g.front_tree && k != kNoTree);
      } else if (l != SurfaceLabel::Trunk) {
        ASSERT_EQ(k, kNoTree);
      }
    }
  cv::Mat rows;
  cv::compare(g.labels, int(SurfaceLabel::RowLeaf), rows, cv::CMP_EQ);
  cv::bitwise_or(rows, g.canopy_mask, rows);
  EXPECT_EQ(cv::countNonZero(rows != g.row_mask), 0);
  EXPECT_EQ(g.row_points_mm.size(), std::size_t(cv::countNonZero(g.row_mask)));
  EXPECT_EQ(g.canopy_points_mm.size(), std::size_t(cv::countNonZero(g.canopy_mask)));
}

TEST(SceneOrchard, TheTreeInFrontIsTheOneAskedForAndTheRowIsLaidOutWithTheGaps)
{
  SceneParams p = row_scene(SceneKind::Orchard);
  p.distance_mm = 2300;
  p.canopy_height_mm = 1000;
  p.canopy_width_mm = 600;
  SceneRenderer r(p);
  cv::Mat rgb;
  GroundTruth g;
  r.render(0, 0, rgb, &g);
  EXPECT_EQ(g.front_tree, 0);
  EXPECT_NEAR(g.canopy_height_m, 1.0, 0.01);
  EXPECT_NEAR(g.canopy_width_m, 0.6, 0.006);
  EXPECT_NEAR(g.canopy_depth_m, p.canopy_depth_mm / 1000, 0.006);
  EXPECT_NEAR(g.trunk_distance_m, 2.3, 1e-9);
  EXPECT_NEAR(g.lateral_offset_m, 0.0, 1e-9);
  for (const auto &q : g.canopy_points_mm) {
    ASSERT_GE(q.x, -300.0 - 0.1);
    ASSERT_LE(q.x, 300.0 + 0.1);
  }

  const auto row = r.row_trees(-30000, 30000);
  ASSERT_GT(row.size(), 30u);
  for (std::size_t i = 0; i + 1 < row.size(); ++i) {
    ASSERT_EQ(row[i + 1].index, row[i].index + 1);
    const double gap = row[i + 1].start_m - row[i].end_m;
    EXPECT_GE(gap, 0.2 - 1e-6);
    EXPECT_LE(gap, 0.6 + 1e-6);
    EXPECT_NEAR(row[i].x_m, 0.5 * (row[i].start_m + row[i].end_m), 1e-6);
    EXPECT_NEAR(row[i].distance_m, 2.3, 1e-9);
    if (row[i].index == 0) {
      EXPECT_NEAR(row[i].x_m, 0.0, 1e-9);
      EXPECT_NEAR(row[i].width_m, 0.6, 1e-6);
      EXPECT_NEAR(row[i].height_m, 1.0, 1e-6);
    } else {
      EXPECT_GE(row[i].width_m, 0.85 * 0.6 - 1e-6);
      EXPECT_LE(row[i].width_m, 1.15 * 0.6 + 1e-6);
      EXPECT_GE(row[i].height_m, 0.85 * 1.0 - 1e-6);
      EXPECT_LE(row[i].height_m, 1.1 * 1.0 + 1e-6);
    }
  }
  // Driving on, the tree in front is the one whose trunk is nearest to the optical axis and the
  // truth is about it.
  p.speed_m_s = 1.0;
  SceneRenderer moving(p);
  for (std::uint64_t f : {5u, 9u, 23u}) {
    moving.render(0, f, rgb, &g);
    const double travel = moving.travel_mm(f);
    const auto near = moving.row_trees(travel - 3000, travel + 3000);
    const RowTree *best = &near.front();
    for (const auto &t : near)
      if (std::abs(t.x_m * 1000 - travel) < std::abs(best->x_m * 1000 - travel))
        best = &t;
    EXPECT_EQ(g.front_tree, best->index) << "frame " << f;
    EXPECT_NEAR(g.lateral_offset_m, best->x_m - travel / 1000, 1e-9);
    EXPECT_NEAR(g.canopy_width_m, best->width_m, 1e-9);
    EXPECT_NEAR(g.canopy_height_m, best->height_m, 1e-9);
  }
}

TEST(SceneOrchard, HedgerowCanopiesTouchOrOverlap)
{
  SceneRenderer r(row_scene(SceneKind::Hedgerow));
  const auto row = r.row_trees(-20000, 20000);
  ASSERT_GT(row.size(), 30u);
  for (std::size_t i = 0; i + 1 < row.size(); ++i) {
    const double gap = row[i + 1].start_m - row[i].end_m;
    EXPECT_LE(gap, 1e-6);
    EXPECT_GE(gap, -0.15 * 0.7 - 1e-6);
  }
  cv::Mat rgb;
  GroundTruth g;
  r.render(0, 0, rgb, &g);
  EXPECT_GT(count_label(g, SurfaceLabel::RowLeaf), kVga.area() / 10);
}

TEST(SceneOrchard, ATouchingPairOverlapsAndTheRestKeepTheirGaps)
{
  SceneParams p = row_scene(SceneKind::Orchard);
  p.touching_pair = 2;
  SceneRenderer r(p);
  const auto row = r.row_trees(-10000, 10000);
  ASSERT_GT(row.size(), 10u);
  int touching = 0;
  for (std::size_t i = 0; i + 1 < row.size(); ++i) {
    const double gap = row[i + 1].start_m - row[i].end_m;
    if (row[i].index == 2) {
      EXPECT_NEAR(gap, -SceneParams::kTouchingOverlapMm / 1000.0, 1e-6);
      ++touching;
    } else {
      EXPECT_GE(gap, 0.2 - 1e-6);
    }
  }
  EXPECT_EQ(touching, 1);
  p.touching_pair = 101;
  EXPECT_THROW(SceneRenderer{p}, std::runtime_error);
}

TEST(SceneOrchard, TheBackRowStandsRowSpacingBehind)
{
  SceneParams p = row_scene(SceneKind::Orchard, 0.0);
  p.row_spacing_mm = 3000;
  SceneRenderer r(p);
  cv::Mat rgb;
  GroundTruth g;
  int n = 0;
  for (int view = 0; view < 2; ++view) {
    r.render(view, 0, rgb, &g);
    for (int y = 0; y < kVga.height; ++y)
      for (int x = 0; x < kVga.width; ++x)
        if (SurfaceLabel(g.labels.at<uchar>(y, x)) == SurfaceLabel::BackLeaf) {
          const cv::Point3d X = hit_point(r, view, g, x, y);
          const cv::Vec3d L = view == 0 ? cv::Vec3d(X) : to_left(r.calibration(), cv::Vec3d(X));
          ASSERT_GE(L[2], 2000 + 3000 - 0.5 * 1.3 * 600 - 0.5);
          ASSERT_LE(L[2], 2000 + 3000 + 0.5 * 1.3 * 600 + 0.5);
          ++n;
        }
  }
  EXPECT_GT(n, 1000);
}

TEST(SceneOrchard, BothViewsSeeTheSameGrass)
{
  // Stereo works on the grass: a ground point seen by the left view has the same colour where
  // the right view sees it.
  const SceneParams p = row_scene(SceneKind::Orchard, 0.0);
  SceneRenderer r(p);
  cv::Mat a, b;
  GroundTruth ga, gb;
  r.render(0, 0, a, &ga);
  r.render(1, 0, b, &gb);
  const StereoCalibration &c = r.calibration();
  double sum = 0;
  int n = 0;
  for (int y = kVga.height / 2 + 40; y < kVga.height - 4; y += 7)
    for (int x = 8; x < kVga.width - 8; x += 7) {
      if (SurfaceLabel(ga.labels.at<uchar>(y, x)) != SurfaceLabel::Ground)
        continue;
      const cv::Vec3d R = to_right(c, cv::Vec3d(hit_point(r, 0, ga, x, y)));
      const cv::Point2d q = project(cv::Point3d(R), c.M2, c.D2);
      const int u = int(std::lround(q.x)), v = int(std::lround(q.y));
      if (u < 1 || v < 1 || u >= kVga.width - 1 || v >= kVga.height - 1 ||
          SurfaceLabel(gb.labels.at<uchar>(v, u)) != SurfaceLabel::Ground)
        continue;
      const cv::Vec3f pa = a.at<cv::Vec3b>(y, x), pb = bilinear(b, q.x, q.y);
      sum += cv::norm(pa - pb);
      ++n;
    }
  ASSERT_GT(n, 500);
  std::printf("grass: mean colour difference between the views %.2f levels over %d points\n",
              sum / n, n);
  EXPECT_LT(sum / n, 12.0);
}

TEST(SceneOrchard, LabFillsTheRowFieldsWithTheOneTree)
{
  SceneRenderer r(vga());
  cv::Mat rgb;
  GroundTruth g;
  r.render(0, 0, rgb, &g);
  EXPECT_EQ(g.front_tree, 0);
  EXPECT_EQ(count_label(g, SurfaceLabel::RowLeaf) + count_label(g, SurfaceLabel::BackLeaf), 0);
  ASSERT_EQ(g.row_points_mm.size(), g.canopy_points_mm.size());
  EXPECT_EQ(cv::countNonZero(g.row_mask != g.canopy_mask), 0);
  for (int y = 0; y < kVga.height; ++y)
    for (int x = 0; x < kVga.width; ++x) {
      const auto l = SurfaceLabel(g.labels.at<uchar>(y, x));
      const bool tree = l == SurfaceLabel::Leaf || l == SurfaceLabel::Trunk;
      ASSERT_EQ(g.tree_index.at<std::int16_t>(y, x), tree ? 0 : kNoTree);
    }
  const auto row = r.row_trees(-100, 100);
  ASSERT_EQ(row.size(), 1u);
  EXPECT_EQ(row[0].index, 0);
  EXPECT_NEAR(row[0].width_m, g.canopy_width_m, 1e-12);
}
