// Triangulation, robust depth filtering and dense depth against constructed truth.
#include "treestereo/depth.hpp"
#include "treestereo/stats.hpp"

#include "simple_geometry.hpp"
#include "typed_error.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

using namespace treestereo;

namespace {

// A rectified pair from a real cv::stereoRectify of a slightly toed-in rig, without
// CALIB_ZERO_DISPARITY so that the principal points differ (doffs != 0).
struct Rig {
  StereoGeometry g;
  cv::Matx44d Q;
  cv::Matx34d P1, P2;
};

Rig make_rig()
{
  const cv::Size size(1296, 972);
  cv::Mat M1 = (cv::Mat_<double>(3, 3) << 1100, 0, 640, 0, 1100, 490, 0, 0, 1);
  cv::Mat M2 = (cv::Mat_<double>(3, 3) << 1105, 0, 655, 0, 1105, 480, 0, 0, 1);
  cv::Mat D = cv::Mat::zeros(1, 5, CV_64F);
  cv::Mat rvec = (cv::Mat_<double>(3, 1) << 0.004, -0.02, 0.003), R;
  cv::Rodrigues(rvec, R);
  cv::Mat T = (cv::Mat_<double>(3, 1) << -50.0, 0.4, -0.3); // right camera 50 mm to the right
  cv::Mat R1, R2, P1, P2, Q;
  cv::stereoRectify(M1, D, M2, D, size, R, T, R1, R2, P1, P2, Q, 0, -1);
  Rig rig;
  rig.P1 = cv::Matx34d(P1);
  rig.P2 = cv::Matx34d(P2);
  rig.Q = cv::Matx44d(Q);
  rig.g.view_size = size;
  rig.g.fx = P1.at<double>(0, 0);
  rig.g.fy = P1.at<double>(1, 1);
  rig.g.cx[LEFT] = P1.at<double>(0, 2);
  rig.g.cx[RIGHT] = P2.at<double>(0, 2);
  rig.g.cy = P1.at<double>(1, 2);
  rig.g.baseline_mm = -P2.at<double>(0, 3) / P2.at<double>(0, 0);
  rig.g.Q = rig.Q;
  return rig;
}

cv::Point2d project(const cv::Matx34d &P, const cv::Point3d &X)
{
  const cv::Vec3d h = P * cv::Vec4d(X.x, X.y, X.z, 1.0);
  return {h[0] / h[2], h[1] / h[2]};
}

// Matches of points at known depths (x, y spread over the view).
std::vector<StereoMatch> matches_at(const StereoGeometry &g, const std::vector<double> &z)
{
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(100, g.view_size.width - 100),
      uy(100, g.view_size.height - 100);
  std::vector<StereoMatch> m;
  for (double zi : z) {
    StereoMatch s;
    s.xl = float(ux(rng));
    s.yl = float(uy(rng));
    s.xr = float(s.xl - (g.fx * g.baseline_mm / zi + g.doffs()));
    s.yr = s.yl;
    m.push_back(s);
  }
  return m;
}

} // namespace

TEST(Depth, QMatrixOfGeometryIsStereoRectifys)
{
  const Rig rig = make_rig();
  ASSERT_GT(std::abs(rig.g.doffs()), 1.0) << "the rig should exercise a non-zero doffs";
  const cv::Matx44d Q = disparity_to_depth_matrix(rig.g);
  for (int i = 0; i < 16; ++i)
    EXPECT_NEAR(Q.val[i], rig.Q.val[i], 1e-9 * (1.0 + std::abs(rig.Q.val[i]))) << "element " << i;
}

TEST(Depth, ExactSyntheticDisparitiesGiveTheTruePoints)
{
  const Rig rig = make_rig();
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> ux(-1500, 1500), uy(-1000, 1000), uz(800, 9000);
  for (int i = 0; i < 500; ++i) {
    const cv::Point3d X(ux(rng), uy(rng), uz(rng));
    const cv::Point2d l = project(rig.P1, X), r = project(rig.P2, X);
    ASSERT_NEAR(l.y, r.y, 1e-9); // rectified: same row
    Point3 a, b;
    ASSERT_TRUE(triangulate_point(rig.g, l.x, l.y, l.x - r.x, a));
    ASSERT_TRUE(triangulate_point_q(rig.Q, l.x, l.y, l.x - r.x, b));
    const double scale = cv::norm(X);
    EXPECT_NEAR(a.z, X.z, 1e-6 * X.z);
    EXPECT_NEAR(a.x, X.x, 1e-6 * scale);
    EXPECT_NEAR(a.y, X.y, 1e-6 * scale);
    EXPECT_NEAR(b.x, a.x, 1e-6 * scale);
    EXPECT_NEAR(b.y, a.y, 1e-6 * scale);
    EXPECT_NEAR(b.z, a.z, 1e-6 * X.z);
  }
}

TEST(Depth, MatchesTriangulateInOrderWithIndices)
{
  const Rig rig = make_rig();
  std::vector<cv::Point3d> truth;
  std::vector<StereoMatch> matches;
  for (int i = 0; i < 50; ++i) {
    const cv::Point3d X(-600 + 25.0 * i, 300 - 13.0 * i, 1500 + 40.0 * i);
    const cv::Point2d l = project(rig.P1, X), r = project(rig.P2, X);
    truth.push_back(X);
    matches.push_back({float(l.x), float(l.y), float(r.x), float(r.y), 0.0f});
  }
  DepthParams p;
  p.outlier_k = 0;
  const DepthResult res = triangulate_matches(matches, rig.g, p);
  ASSERT_EQ(res.points.size(), matches.size());
  EXPECT_EQ(res.stats.n_valid, matches.size());
  for (std::size_t i = 0; i < truth.size(); ++i) {
    EXPECT_EQ(res.points[i].match_index, i);
    EXPECT_TRUE(res.points[i].valid);
    // StereoMatch holds float pixels (~6e-5 px at x ~ 1000): a few 1e-6 of a 30-60 px disparity.
    EXPECT_NEAR(res.points[i].z, truth[i].z, 1e-5 * truth[i].z);
  }
}

TEST(Depth, NonPositiveDisparityIsInvalidNotInfinite)
{
  const StereoGeometry g = simple_geometry({640, 480}, 800, 50);
  std::vector<StereoMatch> m = {{300, 200, 300, 200, 0}, {300, 200, 310, 200, 0},
                                {300, 200, 280, 200, 0}};
  const DepthResult r = triangulate_matches(m, g, DepthParams{});
  ASSERT_EQ(r.points.size(), 3u);
  EXPECT_FALSE(r.points[0].valid);
  EXPECT_FALSE(r.points[1].valid);
  EXPECT_TRUE(r.points[2].valid);
  EXPECT_NEAR(r.points[2].z, 800.0 * 50.0 / 20.0, 1e-3);
  EXPECT_EQ(r.stats.dropped_disparity, 2u);
  EXPECT_EQ(r.stats.n_valid, 1u);
  for (const Point3 &p : r.points)
    EXPECT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
  Point3 q;
  EXPECT_FALSE(triangulate_point_q(disparity_to_depth_matrix(g), 10, 10, 0.0, q));
}

TEST(Depth, OutliersAtHalfAndFiveMetresAreDroppedMedianKept)
{
  const StereoGeometry g = simple_geometry({1296, 972}, 1100, 50);
  std::mt19937 rng(3);
  std::normal_distribution<double> canopy(2000.0, 40.0);
  std::vector<double> z, inliers;
  for (int i = 0; i < 950; ++i) {
    z.push_back(canopy(rng));
    inliers.push_back(z.back());
  }
  for (int i = 0; i < 25; ++i) {
    z.push_back(5000.0);
    z.push_back(500.0);
  }
  DepthParams p; // range 0.3-20 m keeps both outlier groups: only the MAD cut may drop them
  const DepthResult r = triangulate_matches(matches_at(g, z), g, p);
  EXPECT_EQ(r.stats.n_points, 1000u);
  EXPECT_EQ(r.stats.dropped_range, 0u);
  EXPECT_EQ(r.stats.dropped_outlier, 50u);
  EXPECT_EQ(r.stats.n_valid, 950u);
  for (std::size_t i = 950; i < 1000; ++i)
    EXPECT_FALSE(r.points[i].valid) << "outlier " << i << " at z=" << r.points[i].z;
  const Summary truth = summarize(inliers);
  EXPECT_NEAR(r.stats.median_mm, truth.median, 0.05); // float points, pixel rounding
  EXPECT_NEAR(r.stats.p05_mm, truth.p05, 0.05);
  EXPECT_NEAR(r.stats.p95_mm, truth.p95, 0.05);
  EXPECT_NEAR(r.stats.mad_mm, truth.mad, 0.05);
}

TEST(Depth, RangeDropsBeforeOutliers)
{
  const StereoGeometry g = simple_geometry({1296, 972}, 1100, 50);
  std::vector<double> z;
  for (int i = 0; i < 100; ++i)
    z.push_back(1900.0 + 2.0 * i);
  z.push_back(500.0);
  z.push_back(5000.0);
  z.push_back(999.0);
  DepthParams p;
  p.min_depth_mm = 1000;
  p.max_depth_mm = 4000;
  p.outlier_k = 0; // off
  const DepthResult r = triangulate_matches(matches_at(g, z), g, p);
  EXPECT_EQ(r.stats.dropped_range, 3u);
  EXPECT_EQ(r.stats.dropped_outlier, 0u);
  EXPECT_EQ(r.stats.n_valid, 100u);
  EXPECT_NEAR(r.stats.median_mm, 1999.0, 0.01);
  EXPECT_EQ(r.points.size(), 103u); // dropped points stay, flagged
  EXPECT_FALSE(r.points[100].valid);
}

TEST(Depth, FlatCanopyIsNotShreddedByAZeroMad)
{
  const StereoGeometry g = simple_geometry({640, 480}, 800, 50);
  std::vector<double> z(40, 2000.0);
  z.push_back(2001.0); // a hair off the exact median
  const DepthResult r = triangulate_matches(matches_at(g, z), g, DepthParams{});
  EXPECT_EQ(r.stats.dropped_outlier, 0u);
  EXPECT_EQ(r.stats.n_valid, 41u);
}

TEST(Depth, BadInputThrowsWithAMessage)
{
  StereoGeometry bad;
  EXPECT_THROW(triangulate_matches({}, bad, DepthParams{}), std::runtime_error);
  const StereoGeometry g = simple_geometry({640, 480}, 800, 50);
  DepthParams p;
  p.min_depth_mm = 5000;
  p.max_depth_mm = 1000;
  EXPECT_THROW(triangulate_matches({}, g, p), std::runtime_error);
  const DepthResult empty = triangulate_matches({}, g, DepthParams{});
  EXPECT_EQ(empty.stats.n_valid, 0u);
  EXPECT_EQ(empty.stats.median_mm, 0.0);
}

TEST(Depth, DisparityWindowCoversTheRange)
{
  const StereoGeometry g = simple_geometry({1296, 972}, 1100, 50);
  const cv::Vec2i w = disparity_window(g, 1000, 5000);
  EXPECT_LE(w[0], 1100.0 * 50 / 5000);                  // 11 px at 5 m
  EXPECT_GE(w[0] + w[1] - 1, 1100.0 * 50 / 1000);       // 55 px at 1 m
  EXPECT_EQ(w[1] % 16, 0);
  EXPECT_LE(w[1], 64); // small: 44 px of range
  EXPECT_THROW(disparity_window(g, 0, 1000), std::runtime_error);
}

namespace {

// A random texture on a fronto-parallel plane: the right view is the left shifted by a known
// sub-pixel disparity.
struct PlanePair {
  cv::Mat left, right, mask;
  cv::Rect box;
};

PlanePair plane_pair(cv::Size size, double disparity)
{
  PlanePair p;
  cv::Mat noise(size, CV_8U);
  cv::RNG rng(11);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(noise, p.left, cv::Size(0, 0), 1.2);
  cv::normalize(p.left, p.left, 0, 255, cv::NORM_MINMAX);
  const cv::Matx23d shift(1, 0, disparity, 0, 1, 0); // right(x) = left(x + d)
  cv::warpAffine(p.left, p.right, shift, size, cv::INTER_CUBIC | cv::WARP_INVERSE_MAP,
                 cv::BORDER_REFLECT);
  p.box = cv::Rect(size.width / 4, size.height / 5, size.width / 2, size.height * 3 / 5);
  p.mask = cv::Mat::zeros(size, CV_8U);
  cv::ellipse(p.mask, (p.box.tl() + p.box.br()) / 2, p.box.size() / 2, 0, 0, 360,
              cv::Scalar(255), cv::FILLED);
  return p;
}

} // namespace

TEST(DenseDepth, TexturedPlaneAtKnownDisparity)
{
  const cv::Size size(480, 360);
  StereoGeometry g = simple_geometry(size, 700, 60);
  const double d = 35.4;
  const double z_true = g.fx * g.baseline_mm / d;
  const PlanePair pp = plane_pair(size, d);
  DenseParams p;
  p.filter.min_depth_mm = 800;
  p.filter.max_depth_mm = 2500;
  const DenseResult r = dense_depth(pp.left, pp.right, pp.mask, pp.box, g, p);
  ASSERT_EQ(r.depth_mm.type(), CV_16U);
  ASSERT_EQ(r.depth_mm.size(), pp.box.size());
  EXPECT_LE(r.num_disparities, 48); // derived from the range, not the whole width

  std::vector<double> z;
  int in_mask = 0, outside_with_depth = 0;
  for (int v = 0; v < r.box.height; ++v)
    for (int u = 0; u < r.box.width; ++u) {
      const bool m = pp.mask.at<uchar>(r.box.y + v, r.box.x + u) != 0;
      const auto dz = r.depth_mm.at<std::uint16_t>(v, u);
      in_mask += m;
      if (dz && m)
        z.push_back(dz);
      outside_with_depth += (dz && !m);
    }
  std::printf("[ dense plane ] true Z %.2f mm, map median %.2f mm, coverage %.1f%% of the mask\n",
              z_true, median(z), 100.0 * double(z.size()) / in_mask);
  EXPECT_EQ(outside_with_depth, 0) << "depth only on the vegetation mask";
  EXPECT_GT(double(z.size()), 0.8 * in_mask);
  EXPECT_NEAR(median(z), z_true, 0.01 * z_true);
  ASSERT_GT(r.stats.n_valid, 100u);
  EXPECT_NEAR(r.stats.median_mm, z_true, 0.01 * z_true);
  for (const Point3 &pt : r.points) {
    const int x = int(pt.match_index % std::uint32_t(size.width));
    const int y = int(pt.match_index / std::uint32_t(size.width));
    EXPECT_EQ((x - r.box.x) % p.sample_step, 0);
    EXPECT_EQ((y - r.box.y) % p.sample_step, 0);
    ASSERT_TRUE(pp.mask.at<uchar>(y, x));
    // X from the pixel: the triangulation of the sampled pixel itself.
    EXPECT_NEAR(pt.x, (x - g.cx[LEFT]) * pt.z / g.fx, 1e-2);
  }

  // The same pair as BGR frames (what a video stream carries) gives the same depth.
  cv::Mat lc, rc;
  cv::cvtColor(pp.left, lc, cv::COLOR_GRAY2BGR);
  cv::cvtColor(pp.right, rc, cv::COLOR_GRAY2BGR);
  const DenseResult rb = dense_depth(lc, rc, pp.mask, pp.box, g, p);
  EXPECT_NEAR(rb.stats.median_mm, z_true, 0.01 * z_true);
}

TEST(DenseDepth, InconsistentInputThrows)
{
  const cv::Size size(160, 120);
  const StereoGeometry g = simple_geometry(size, 300, 60);
  const cv::Mat a(size, CV_8U, cv::Scalar(0)), b(cv::Size(100, 100), CV_8U, cv::Scalar(0));
  EXPECT_THROW(dense_depth(a, b, cv::Mat(), cv::Rect(0, 0, 50, 50), g, DenseParams{}),
               std::runtime_error);
  const cv::Mat f(size, CV_32F, cv::Scalar(0));
  EXPECT_THROW(dense_depth(f, f, cv::Mat(), cv::Rect(0, 0, 50, 50), g, DenseParams{}),
               std::runtime_error);
  DenseParams p;
  p.num_disparities = 20;
  EXPECT_THROW(dense_depth(a, a, cv::Mat(), cv::Rect(0, 0, 50, 50), g, p), std::runtime_error);
  // A box with nothing to match gives an empty result, not an error.
  const DenseResult r = dense_depth(a, a, cv::Mat(), cv::Rect(200, 200, 10, 10), g, DenseParams{});
  EXPECT_TRUE(r.box.empty());
  EXPECT_TRUE(r.points.empty());
}

// Every lib function that takes a geometry refuses one that is not valid with the same typed
// error: a sentence naming what needs it, the values in its detail (require_valid()).
TEST(Geometry, AnInvalidGeometryIsRefusedNamingWhatNeedsIt)
{
  StereoGeometry none;
  StereoGeometry inf = make_rig().g;
  inf.baseline_mm = std::numeric_limits<double>::infinity();
  for (const StereoGeometry &g : {none, inf}) {
    expect_typed_error<BadInput>([&] { disparity_to_depth_matrix(g); }, "depth from disparity");
    expect_typed_error<BadInput>([&] { triangulate_matches({}, g, DepthParams()); },
                                 "triangulation");
    expect_typed_error<BadInput>([&] { disparity_window(g, 1000, 5000); },
                                 "the disparity window");
  }
  try {
    disparity_window(inf, 1000, 5000);
  } catch (const BadInput &e) {
    EXPECT_NE(std::string(e.what()).find("The stereo geometry is not valid"), std::string::npos);
    EXPECT_NE(e.detail().find("disparity_window: fx=1"), std::string::npos) << e.detail();
    EXPECT_NE(e.detail().find("baseline_mm=inf"), std::string::npos) << e.detail();
  }
}
