// Tree metrics against canopies built analytically: a sphere, an ellipsoid of revolution and a
// stepped flat canopy, silhouettes by ray casting through the rectified left camera.
#include "treestereo/canopy.hpp"
#include "treestereo/metrics.hpp"
#include "treestereo/stats.hpp"
#include "simple_geometry.hpp"

#include <opencv2/imgproc.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <optional>

using namespace treestereo;

namespace {

StereoGeometry camera()
{
  return simple_geometry(cv::Size(1296, 972), 1100, 50);
}

cv::Vec3d ray(const StereoGeometry &g, double u, double v)
{
  return {(u - g.cx[LEFT]) / g.fx, (v - g.cy) / g.fy, 1.0};
}

// First hit (depth Z along the ray with z = 1) of a ray with an object, if any.
using Caster = std::function<std::optional<double>(const cv::Vec3d &)>;

// Ellipsoid of revolution about the vertical: semi-axes a (x, z) and c (y), centre C (mm).
Caster ellipsoid(cv::Vec3d C, double a, double c)
{
  return [=](const cv::Vec3d &r) -> std::optional<double> {
    // Scale y so the ellipsoid becomes a sphere of radius a; then solve |t r' - C'| = a.
    const double k = a / c;
    const cv::Vec3d rs(r[0], r[1] * k, r[2]), cs(C[0], C[1] * k, C[2]);
    const double A = rs.dot(rs), B = rs.dot(cs), D = B * B - A * (cs.dot(cs) - a * a);
    if (D < 0)
      return std::nullopt;
    return (B - std::sqrt(D)) / A; // z of the nearest hit (r has z = 1)
  };
}

struct Scene {
  Silhouette sil;
  std::vector<Point3> points;
  std::vector<double> z; // true depths of the points
};

// Silhouette of every pixel whose centre ray hits; visible-surface points every `step` px.
Scene cast(const StereoGeometry &g, const Caster &hit, int step)
{
  Scene s;
  s.sil.mask = cv::Mat::zeros(g.view_size, CV_8U);
  for (int v = 0; v < g.view_size.height; ++v)
    for (int u = 0; u < g.view_size.width; ++u) {
      const cv::Vec3d r = ray(g, u, v);
      const std::optional<double> t = hit(r);
      if (!t)
        continue;
      s.sil.mask.at<uchar>(v, u) = 255;
      if (u % step == 0 && v % step == 0) {
        Point3 p;
        p.x = float(r[0] * *t);
        p.y = float(r[1] * *t);
        p.z = float(*t);
        p.match_index = std::uint32_t(s.points.size());
        s.points.push_back(p);
        s.z.push_back(*t);
      }
    }
  s.sil.present = cv::countNonZero(s.sil.mask) > 0;
  s.sil.area_px = cv::countNonZero(s.sil.mask);
  s.sil.bbox = cv::boundingRect(s.sil.mask);
  return s;
}

void expect_finite(const TreeMetrics &m)
{
  for (double v : {m.distance_m, m.height_m, m.width_m, m.thickness_m, m.area_m2, m.perimeter_m,
                   m.complexity, m.centroid_m.x, m.centroid_m.y, m.centroid_m.z,
                   m.extent_depth_m})
    EXPECT_TRUE(std::isfinite(v));
  for (const Band &b : m.bands)
    for (double v : {b.top_m, b.bottom_m, b.left_m, b.right_m, b.width_m, b.depth_m})
      EXPECT_TRUE(std::isfinite(v));
}

void expect_no_tree(const TreeMetrics &m)
{
  EXPECT_FALSE(m.tree_present);
  expect_finite(m);
  for (double v : {m.distance_m, m.height_m, m.width_m, m.thickness_m, m.area_m2, m.perimeter_m,
                   m.complexity, m.centroid_m.x, m.centroid_m.y, m.centroid_m.z,
                   m.extent_depth_m})
    EXPECT_EQ(v, 0.0);
  EXPECT_TRUE(m.bands.empty());
  EXPECT_FALSE(m.clipped.any());
  EXPECT_EQ(m.points, 0u);
}

double rel(double got, double want) { return std::abs(got - want) / want; }

} // namespace

// R = 1 m at 3 m, off the optical axis: the test of the extent model.
TEST(Metrics, SphereHeightAndWidthWithinOnePointFivePercent)
{
  const StereoGeometry g = camera();
  const double R = 1000;
  const Scene s = cast(g, ellipsoid({300, -200, 3000}, R, R), 4);
  ASSERT_TRUE(s.sil.present);
  MetricsParams p;
  p.extent_depth = ExtentDepth::kRoundCanopy;
  const TreeMetrics m = compute_tree_metrics(s.sil, s.points, g, p);
  ASSERT_TRUE(m.tree_present);
  expect_finite(m);
  EXPECT_FALSE(m.clipped.any());
  EXPECT_LT(rel(m.width_m, 2.0), 0.015) << "width " << m.width_m;
  EXPECT_LT(rel(m.height_m, 2.0), 0.015) << "height " << m.height_m;
  // The points sample the visible surface on a regular pixel grid, so its (interpolated)
  // percentiles are the truth; the area-weighted order statistics meet them to a millimetre.
  std::vector<double> z = s.z;
  EXPECT_NEAR(m.distance_m, median(z) * 1e-3, 5e-4);
  const Summary zs = summarize(s.z);
  EXPECT_NEAR(m.thickness_m, (zs.p95 - zs.p05) * 1e-3, 2e-3);
  EXPECT_EQ(m.points, s.points.size());
  EXPECT_EQ(m.matches, s.points.size());
  // Centre of the sphere: the model's centre is off by the near-percentile's lag only.
  EXPECT_NEAR(m.centroid_m.z, 3.0, 0.03);
  EXPECT_NEAR(m.centroid_m.x, 0.3, 0.005);
  EXPECT_NEAR(m.centroid_m.y, -0.2, 0.005);
  // A disc of radius R: area pi R^2, perimeter 2 pi R, complexity ~1.
  EXPECT_LT(rel(m.area_m2, CV_PI), 0.03);
  EXPECT_LT(rel(m.perimeter_m, 2 * CV_PI), 0.06); // pixel contours run a little long
  // ~1 for a disc; the 8-connected pixel contour's length adds its ~5% twice.
  EXPECT_GE(m.complexity, 1.0);
  EXPECT_LT(m.complexity, 1.15);
}

// DESIGN.md: the front face (median Z) reads clearly low; the other options are reported.
TEST(Metrics, SphereExtentOptionsCompared)
{
  const StereoGeometry g = camera();
  const Scene s = cast(g, ellipsoid({300, -200, 3000}, 1000, 1000), 4);
  MetricsParams p;
  for (ExtentDepth mode : {ExtentDepth::kRoundCanopy, ExtentDepth::kEdgePoints,
                           ExtentDepth::kMidDepth, ExtentDepth::kFrontFace,
                           ExtentDepth::kTangentPoints}) {
    p.extent_depth = mode;
    const TreeMetrics m = compute_tree_metrics(s.sil, s.points, g, p);
    std::printf("[ extent mode %d ] width %.4f m (%+.2f%%) height %.4f m (%+.2f%%) at %.3f m\n",
                int(mode), m.width_m, 100 * (m.width_m / 2 - 1), m.height_m,
                100 * (m.height_m / 2 - 1), m.extent_depth_m);
    if (mode == ExtentDepth::kFrontFace) {
      EXPECT_LT(m.width_m, 0.95 * 2.0);
    }
  }
}

// The top edge's ray climbs about 20 degrees to a sphere of 0.3 m radius above the optical axis:
// it touches the sphere at its limb, 0.3 m * (1 - cos 20 deg) = 18 mm below the top, so the
// limb points alone read 3 % low. The rounding measured from the edge points gives back more than
// half of it (rho reads 180-260 mm for the true 300: the rows or columns away from the extreme
// cut smaller circles, see MetricsParams::round_limbs).
TEST(Metrics, RoundLimbsReachTheExtremeBeyondTheLimb)
{
  const StereoGeometry g = camera();
  const double R = 300;
  const Scene s = cast(g, ellipsoid({0, -400, 2000}, R, R), 3);
  ASSERT_TRUE(s.sil.present);
  MetricsParams p;
  ASSERT_TRUE(p.round_limbs);
  ASSERT_EQ(p.extent_depth, ExtentDepth::kTangentPoints);
  const TreeMetrics m = compute_tree_metrics(s.sil, s.points, g, p);
  p.round_limbs = false;
  const TreeMetrics limb = compute_tree_metrics(s.sil, s.points, g, p);
  ASSERT_TRUE(m.tree_present && limb.tree_present);
  std::printf("sphere 0.6 m: height %.4f m (limb points only %.4f), width %.4f (%.4f)\n",
              m.height_m, limb.height_m, m.width_m, limb.width_m);
  // Without: short by about the 18 mm at the top (2 mm more at the sides and the bottom).
  EXPECT_LT(limb.height_m, 0.6 - 0.012);
  EXPECT_LT(rel(m.height_m, 0.6), 0.5 * rel(limb.height_m, 0.6));
  EXPECT_LT(m.height_m, 0.6); // partial: never past the extreme on a sphere
  EXPECT_LT(rel(m.width_m, 0.6), 0.5 * rel(limb.width_m, 0.6));
  EXPECT_LT(m.width_m, 0.6);
}

// Two clusters, as flat cards of leaves facing the camera: the nearer one forms the
// silhouette's top, the farther one, beside and behind it, reaches 50 mm higher in metres but
// projects lower (its top ray, -450 / 2400, is less steep than the nearer's, -400 / 1800). No
// depth for the silhouette's top ray gives the farther cluster's top; its points do.
TEST(Metrics, ExtremePointsReachAClusterBehindTheSilhouettesEdge)
{
  const StereoGeometry g = camera();
  struct Card {
    double x0, x1, y0, y1, z;
  };
  const std::vector<Card> cards = {{-250, 250, -400, 100, 1800}, {150, 550, -450, -50, 2400}};
  const Caster two_cards = [&](const cv::Vec3d &r) -> std::optional<double> {
    for (const Card &c : cards) // nearest first
      if (r[0] * c.z >= c.x0 && r[0] * c.z <= c.x1 && r[1] * c.z >= c.y0 && r[1] * c.z <= c.y1)
        return c.z;
    return std::nullopt;
  };
  Scene s = cast(g, two_cards, 2);
  const double height = (100.0 - -450.0) * 1e-3, width = (550.0 - -250.0) * 1e-3;
  MetricsParams p;
  ASSERT_EQ(p.extreme_points, 6);
  const TreeMetrics m = compute_tree_metrics(s.sil, s.points, g, p);
  p.extreme_points = 0;
  const TreeMetrics sil = compute_tree_metrics(s.sil, s.points, g, p);
  ASSERT_TRUE(m.tree_present && sil.tree_present);
  std::printf("two clusters: height %.4f m (silhouette alone %.4f), truth %.4f; width %.4f "
              "(%.4f), truth %.4f\n",
              m.height_m, sil.height_m, height, m.width_m, sil.width_m, width);
  EXPECT_LT(sil.height_m, height * 0.95); // the silhouette's top is the nearer card's
  EXPECT_LT(rel(m.height_m, height), 0.01);
  EXPECT_LT(rel(m.width_m, width), 0.01); // each side's edge is its own card's
  // The edges themselves, and the rays that bound the silhouette there (within a pixel): the
  // nearer card's on the left, the farther one's on the right.
  EXPECT_NEAR(m.left_m, -0.250, 0.008);
  EXPECT_NEAR(m.right_m, 0.550, 0.008);
  EXPECT_DOUBLE_EQ(m.right_m - m.left_m, m.width_m);
  EXPECT_NEAR(m.left_slope, -250.0 / 1800, 1.0 / g.fx);
  EXPECT_NEAR(m.right_slope, 550.0 / 2400, 1.0 / g.fx);

  // Five points at the silhouette's top matched at a background's disparity (as at a leaf's
  // edge against the wall): the same pixels, 1.6 times the depth, so their Y reaches far above
  // the canopy. The 6th most extreme point is still the canopy's; the most extreme is not.
  std::vector<std::size_t> order(s.points.size());
  for (std::size_t i = 0; i < order.size(); ++i)
    order[i] = i;
  std::partial_sort(order.begin(), order.begin() + 5, order.end(), [&](std::size_t a, std::size_t b) {
    return s.points[a].y / s.points[a].z < s.points[b].y / s.points[b].z;
  });
  for (int i = 0; i < 5; ++i) {
    Point3 q = s.points[order[std::size_t(i)]];
    q.x *= 1.6f;
    q.y *= 1.6f;
    q.z *= 1.6f;
    s.points.push_back(q);
  }
  p.extreme_points = 6;
  const TreeMetrics robust = compute_tree_metrics(s.sil, s.points, g, p);
  p.extreme_points = 1;
  const TreeMetrics first = compute_tree_metrics(s.sil, s.points, g, p);
  EXPECT_LT(rel(robust.height_m, height), 0.01);
  EXPECT_GT(first.height_m, height * 1.05);
}

// A union of spheres, the first hit of a ray with any of them: centre (mm) and radius.
Caster balls_caster(const std::vector<cv::Vec4d> &balls)
{
  return [balls](const cv::Vec3d &r) -> std::optional<double> {
    std::optional<double> best;
    const double A = r.dot(r);
    for (const cv::Vec4d &b : balls) {
      const cv::Vec3d c(b[0], b[1], b[2]);
      const double B = r.dot(c), D = B * B - A * (c.dot(c) - b[3] * b[3]);
      if (D < 0)
        continue;
      const double t = (B - std::sqrt(D)) / A;
      if (!best || t < *best)
        best = t;
    }
    return best;
  };
}

// The top of a crown made of clusters: the cluster that forms the silhouette's top (r 120 mm,
// 2.1 m away) has another beside it, 60-200 mm in front, whose top projects 15-35 px lower, on a
// body below both. The points within the outer 10 % of the height below the top are the top
// cluster's and the nearer one's. Fitted together against their distance from the top line,
// the nearer cluster's points make the depth fall steeply away from it, and the extrapolation
// puts the limb behind the top cluster: the height read up to 1.7 % high, and more the farther
// in front the neighbour stands. The cap (the columns about the top one until the outline's
// first valley) leaves the neighbour out: the height is then what the top cluster and the body
// alone give, whatever the neighbour.
TEST(Metrics, LimbDepthFollowsEachClustersOwnBoundary)
{
  const StereoGeometry g = camera();
  const cv::Vec4d top(0, -430, 2100, 120), body(0, -100, 2050, 350);
  const double height = (body[1] + body[3] - (top[1] - top[3])) * 1e-3;
  MetricsParams p;
  const Scene alone = cast(g, balls_caster({top, body}), 3);
  const TreeMetrics m0 = compute_tree_metrics(alone.sil, alone.points, g, p);
  ASSERT_TRUE(m0.tree_present);
  EXPECT_LT(rel(m0.height_m, height), 0.01);
  for (double dz : {60.0, 100.0, 150.0, 200.0})
    for (double dy : {15.0, 25.0, 35.0}) {
      // The neighbour's top ray dy px below the top cluster's.
      const double z = top[2] - dz, r = 130;
      const double y = (top[1] - top[3]) / top[2] * z + dy * z / g.fy + r;
      const Scene s = cast(g, balls_caster({top, {210, y, z, r}, body}), 3);
      const TreeMetrics m = compute_tree_metrics(s.sil, s.points, g, p);
      ASSERT_TRUE(m.tree_present);
      std::printf("neighbour %3.0f mm in front, %2.0f px lower: height %.4f m (%.4f without it), "
                  "truth %.4f\n",
                  dz, dy, m.height_m, m0.height_m, height);
      EXPECT_LT(std::abs(m.height_m - m0.height_m), 0.002) << dz << " mm, " << dy << " px";
      EXPECT_LT(rel(m.height_m, height), 0.01);
    }
}

// The paper's depth noise (1.36 cm sd at ~2 m) and 300 points, like a frame of SIFT matches.
TEST(Metrics, SphereWithPaperDepthNoise)
{
  const StereoGeometry g = camera();
  const Scene s = cast(g, ellipsoid({300, -200, 3000}, 1000, 1000), 40);
  ASSERT_GT(s.points.size(), 250u);
  cv::RNG rng(9);
  std::vector<Point3> noisy = s.points;
  for (Point3 &p : noisy) { // along the pixel's ray, as a disparity error moves it
    const double k = 1.0 + rng.gaussian(13.6) / p.z;
    p.x = float(p.x * k);
    p.y = float(p.y * k);
    p.z = float(p.z * k);
  }
  MetricsParams p;
  p.extent_depth = ExtentDepth::kRoundCanopy;
  const TreeMetrics m = compute_tree_metrics(s.sil, noisy, g, p);
  std::printf("[ sphere, noisy, %zu points ] width %.4f m height %.4f m\n", m.points, m.width_m,
              m.height_m);
  EXPECT_LT(rel(m.width_m, 2.0), 0.02);
  EXPECT_LT(rel(m.height_m, 2.0), 0.02);
}

TEST(Metrics, EllipsoidOfRevolutionWidthExactHeightClose)
{
  const StereoGeometry g = camera();
  const Scene s = cast(g, ellipsoid({-150, 100, 3200}, 800, 1200), 4);
  MetricsParams p;
  p.extent_depth = ExtentDepth::kRoundCanopy;
  const TreeMetrics m = compute_tree_metrics(s.sil, s.points, g, p);
  ASSERT_TRUE(m.tree_present);
  std::printf("[ ellipsoid a=0.8 c=1.2 ] width %.4f m height %.4f m\n", m.width_m, m.height_m);
  EXPECT_LT(rel(m.width_m, 1.6), 0.015);
  EXPECT_LT(rel(m.height_m, 2.4), 0.05);
}

// An orchard-like canopy: a union of 50 spheres (r 100-140 mm) whose centres fill an ellipsoid
// 0.9 m high, 0.7 m wide and 0.6 m deep at 2 m, the shape of treetestsrc's trees. It is no solid
// of revolution (its depth is not its width) and its extreme clusters lie at random depths, so
// the round-canopy model reads up to 5 % off; tangent-points converts each edge at the depth
// where its ray touches the canopy and reads within 2.5 % (measured -1.7 to +1.5 %: each edge's
// limb depth comes from the one cluster that forms it, and the limb is not the extreme).
TEST(Metrics, ClusterCanopyTangentPointsBeatRoundCanopy)
{
  const StereoGeometry g = camera();
  double worst_round = 0, worst_tangent = 0;
  for (std::uint64_t seed : {1, 2, 3}) {
    cv::RNG rng(seed);
    std::vector<cv::Vec4d> balls; // centre, radius
    cv::Vec3d lo(1e9, 1e9, 1e9), hi(-1e9, -1e9, -1e9);
    while (balls.size() < 50) {
      const cv::Vec3d u(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0));
      if (u.dot(u) > 1.0)
        continue;
      const double r = rng.uniform(100.0, 140.0);
      const cv::Vec3d c(u[0] * 230, -100 + u[1] * 330, 2000 + u[2] * 180);
      balls.emplace_back(c[0], c[1], c[2], r);
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], c[a] - r);
        hi[a] = std::max(hi[a], c[a] + r);
      }
    }
    const Scene s = cast(g, balls_caster(balls), 8);
    const double width = (hi[0] - lo[0]) * 1e-3, height = (hi[1] - lo[1]) * 1e-3;
    MetricsParams p;
    const TreeMetrics m = compute_tree_metrics(s.sil, s.points, g, p);
    ASSERT_TRUE(m.tree_present);
    expect_finite(m);
    EXPECT_LT(rel(m.width_m, width), 0.025) << "seed " << seed << " width " << m.width_m
                                            << " truth " << width;
    EXPECT_LT(rel(m.height_m, height), 0.025) << "seed " << seed << " height " << m.height_m
                                              << " truth " << height;
    worst_tangent = std::max({worst_tangent, rel(m.width_m, width), rel(m.height_m, height)});
    p.extent_depth = ExtentDepth::kRoundCanopy;
    const TreeMetrics r = compute_tree_metrics(s.sil, s.points, g, p);
    std::printf("[ cluster canopy %d ] truth %.3f x %.3f m: tangent-points %.3f x %.3f, "
                "round-canopy %.3f x %.3f\n",
                int(seed), height, width, m.height_m, m.width_m, r.height_m, r.width_m);
    worst_round = std::max({worst_round, rel(r.width_m, width), rel(r.height_m, height)});
  }
  // What the default replaced: the solid-of-revolution model is clearly off on this canopy.
  EXPECT_GT(worst_round, 0.04);
  EXPECT_LT(worst_tangent, 0.5 * worst_round);
}

TEST(Metrics, ClippedFlagsFollowTheBorders)
{
  const StereoGeometry g = camera();
  // Centre up and left of the view: the canopy runs off the top and left borders.
  const Scene s = cast(g, ellipsoid({-2200, -1300, 3000}, 1000, 1000), 6);
  const TreeMetrics m = compute_tree_metrics(s.sil, s.points, g, MetricsParams{});
  ASSERT_TRUE(m.tree_present);
  EXPECT_TRUE(m.clipped.top);
  EXPECT_TRUE(m.clipped.left);
  EXPECT_FALSE(m.clipped.bottom);
  EXPECT_FALSE(m.clipped.right);
  // The borders are no limbs. A sphere of 2 m whose centre is in the view but whose left and
  // top limbs are beyond the borders: its extents are lower bounds, at least what the view shows
  // at the nearest depth any of it can have (3000 - 1000 mm) from the far limbs.
  const double fy = g.fy > 0 ? g.fy : g.fx;
  const double t_left = (-0.5 - g.cx[LEFT]) / g.fx, t_top = (-0.5 - g.cy) / fy;
  // Sparse (step 40) with the paper's depth noise along the rays, like a frame of matches.
  const Scene b = cast(g, ellipsoid({-1500, -1100, 3000}, 1000, 1000), 40);
  cv::RNG rng(3);
  std::vector<Point3> noisy = b.points;
  for (Point3 &p : noisy) {
    const double k = 1.0 + rng.gaussian(13.6) / p.z;
    p.x = float(p.x * k);
    p.y = float(p.y * k);
    p.z = float(p.z * k);
  }
  const TreeMetrics mb = compute_tree_metrics(b.sil, noisy, g, MetricsParams{});
  ASSERT_TRUE(mb.clipped.left && mb.clipped.top && !mb.clipped.right && !mb.clipped.bottom);
  const double x_right = -1.5 + 1.0, y_bottom = -1.1 + 1.0; // the far limbs (m)
  std::printf("clipped sphere: width %.3f m, height %.3f m (true 2 m; at least %.3f, %.3f)\n",
              mb.width_m, mb.height_m, x_right - t_left * 2.0, y_bottom - t_top * 2.0);
  EXPECT_LE(mb.width_m, 2.0);
  EXPECT_LE(mb.height_m, 2.0);
  EXPECT_GE(mb.width_m, x_right - t_left * 2.0);
  EXPECT_GE(mb.height_m, y_bottom - t_top * 2.0);
  const Scene c = cast(g, ellipsoid({0, 0, 3000}, 1000, 1000), 6);
  const TreeMetrics mc = compute_tree_metrics(c.sil, c.points, g, MetricsParams{});
  EXPECT_FALSE(mc.clipped.any());
}

TEST(Metrics, NoCanopyOrNoPointsMeansNoTreeAndZeros)
{
  const StereoGeometry g = camera();
  Silhouette none; // not present
  expect_no_tree(compute_tree_metrics(none, {}, g, MetricsParams{}));

  const Scene s = cast(g, ellipsoid({0, 0, 3000}, 1000, 1000), 8);
  expect_no_tree(compute_tree_metrics(s.sil, {}, g, MetricsParams{}));

  std::vector<Point3> invalid = s.points;
  for (Point3 &p : invalid)
    p.valid = false;
  expect_no_tree(compute_tree_metrics(s.sil, invalid, g, MetricsParams{}));

  // Points that all fall off the silhouette (the view's corner) are not the canopy's.
  Point3 off;
  off.x = -1800;
  off.y = -1300;
  off.z = 3000;
  expect_no_tree(compute_tree_metrics(s.sil, {off}, g, MetricsParams{}));

  Silhouette empty_mask;
  empty_mask.present = true;
  empty_mask.mask = cv::Mat::zeros(g.view_size, CV_8U);
  expect_no_tree(compute_tree_metrics(empty_mask, s.points, g, MetricsParams{}));
}

TEST(Metrics, PointsOffTheSilhouetteDoNotMoveTheFigures)
{
  const StereoGeometry g = camera();
  const Scene s = cast(g, ellipsoid({0, 0, 3000}, 1000, 1000), 6);
  std::vector<Point3> with_bg = s.points;
  for (int i = 0; i < 200; ++i) { // a background wall at 9 m in the view's lower-left corner
    Point3 p;
    p.z = 9000;
    p.x = float((20 + i - g.cx[LEFT]) * p.z / g.fx);
    p.y = float((900 - g.cy) * p.z / g.fy);
    with_bg.push_back(p);
  }
  const TreeMetrics a = compute_tree_metrics(s.sil, s.points, g, MetricsParams{});
  const TreeMetrics b = compute_tree_metrics(s.sil, with_bg, g, MetricsParams{});
  EXPECT_DOUBLE_EQ(a.distance_m, b.distance_m);
  EXPECT_DOUBLE_EQ(a.width_m, b.width_m);
  EXPECT_EQ(b.points, s.points.size());
  EXPECT_EQ(b.matches, with_bg.size());
}

namespace {

// A flat canopy facing the camera at z0 = 2750 mm: four 400 mm steps, widths 0.6/1.0/1.4/1.8 m
// top to bottom, centred at x = 1.25 mm. At fx = 1100 px that is 0.4 px/mm, and every step
// edge falls on a pixel boundary, so the band profile is exact.
const double kZ0 = 2750, kXc = 1.25, kY0 = -798.75, kStep = 400;
const double kWidths[4] = {600, 1000, 1400, 1800};

Scene stepped(const StereoGeometry &g, std::function<double(int band)> depth_of_band)
{
  Scene s = cast(
      g,
      [](const cv::Vec3d &r) -> std::optional<double> {
        const double X = r[0] * kZ0, Y = r[1] * kZ0;
        const int band = int(std::floor((Y - kY0) / kStep));
        if (band < 0 || band > 3 || std::abs(X - kXc) > kWidths[band] / 2)
          return std::nullopt;
        return kZ0;
      },
      5);
  for (Point3 &p : s.points) {
    const int band = int(std::floor((p.y - kY0) / kStep));
    const double z = depth_of_band(band);
    p.x = float(p.x / kZ0 * z); // same pixel, another depth
    p.y = float(p.y / kZ0 * z);
    p.z = float(z);
  }
  return s;
}

} // namespace

TEST(Metrics, BandProfileOfASteppedCanopy)
{
  const StereoGeometry g = camera();
  const Scene s = stepped(g, [](int) { return kZ0; });
  MetricsParams p;
  p.n_bands = 4;
  p.extent_depth = ExtentDepth::kMidDepth; // flat: thickness 0, converts at z0 exactly
  const TreeMetrics m = compute_tree_metrics(s.sil, s.points, g, p);
  ASSERT_TRUE(m.tree_present);
  ASSERT_EQ(m.bands.size(), 4u);
  EXPECT_NEAR(m.height_m, 1.6, 1e-6);
  EXPECT_NEAR(m.width_m, 1.8, 1e-6);
  EXPECT_NEAR(m.thickness_m, 0.0, 1e-9);
  for (int i = 0; i < 4; ++i) {
    const Band &b = m.bands[std::size_t(i)];
    SCOPED_TRACE("band " + std::to_string(i));
    EXPECT_TRUE(b.present);
    EXPECT_TRUE(b.depth_measured);
    EXPECT_NEAR(b.top_m, (kY0 + i * kStep) * 1e-3, 1e-6);
    EXPECT_NEAR(b.bottom_m, (kY0 + (i + 1) * kStep) * 1e-3, 1e-6);
    EXPECT_NEAR(b.width_m, kWidths[i] * 1e-3, 1e-6);
    EXPECT_NEAR(b.left_m, (kXc - kWidths[i] / 2) * 1e-3, 1e-6);
    EXPECT_NEAR(b.right_m, (kXc + kWidths[i] / 2) * 1e-3, 1e-6);
    EXPECT_NEAR(b.depth_m, kZ0 * 1e-3, 1e-6);
  }
  // Area of the steps: 0.4 * (0.6 + 1.0 + 1.4 + 1.8) m^2.
  EXPECT_NEAR(m.area_m2, 0.4 * 4.8, 1e-6);
}

TEST(Metrics, BandDepthIsTheNearFaceAndGapsInterpolate)
{
  const StereoGeometry g = camera();
  // Each band's points spread over 200 mm behind its own front: 2.5, 2.6, 2.7, 2.8 m.
  int counter = 0;
  auto depth = [&counter](int band) { return 2500.0 + 100.0 * band + double(counter++ % 201); };
  Scene s = stepped(g, depth);
  MetricsParams p;
  p.n_bands = 4;
  p.band_depth_percentile = 5;
  const TreeMetrics m = compute_tree_metrics(s.sil, s.points, g, p);
  ASSERT_EQ(m.bands.size(), 4u);
  for (int i = 0; i < 4; ++i) // p05 of ~uniform [f, f + 200]: f + 10 (mm), give or take 2
    EXPECT_NEAR(m.bands[std::size_t(i)].depth_m, (2510.0 + 100.0 * i) * 1e-3, 0.002) << i;

  // Remove the points of bands 1 and 2: their depths interpolate between bands 0 and 3.
  std::vector<Point3> kept;
  for (const Point3 &pt : s.points) {
    const int band = int(std::floor((pt.y / pt.z * kZ0 - kY0) / kStep));
    if (band == 0 || band == 3)
      kept.push_back(pt);
  }
  const TreeMetrics h = compute_tree_metrics(s.sil, kept, g, p);
  const double d0 = h.bands[0].depth_m, d3 = h.bands[3].depth_m;
  EXPECT_TRUE(h.bands[0].depth_measured && h.bands[3].depth_measured);
  EXPECT_FALSE(h.bands[1].depth_measured || h.bands[2].depth_measured);
  EXPECT_TRUE(h.bands[1].present && h.bands[2].present);
  EXPECT_NEAR(h.bands[1].depth_m, d0 + (d3 - d0) / 3, 1e-9);
  EXPECT_NEAR(h.bands[2].depth_m, d0 + 2 * (d3 - d0) / 3, 1e-9);
}

TEST(Metrics, BandDepthWeighsPointsByTheAreaTheyStandFor)
{
  // Band 1: its left half faces the camera at 2.6 m, its right half at 2.7 m; the right half's
  // points are crowded thirty to a pixel (SIFT matches piling up on contrasted leaves). The near
  // face is the left half's: the area each point stands for counts, not how many points there are.
  const StereoGeometry g = camera();
  Scene s = stepped(g, [](int) { return kZ0; });
  std::vector<Point3> pts;
  for (const Point3 &pt : s.points) {
    const int band = int(std::floor((pt.y - kY0) / kStep));
    if (band != 1) {
      pts.push_back(pt);
      continue;
    }
    const bool right = pt.x > kXc;
    const double z = right ? 2700.0 : 2600.0;
    Point3 q = pt;
    q.x = float(pt.x / kZ0 * z);
    q.y = float(pt.y / kZ0 * z);
    q.z = float(z);
    for (int k = 0; k < (right ? 30 : 1); ++k)
      pts.push_back(q);
  }
  MetricsParams p;
  p.n_bands = 4;
  p.band_depth_percentile = 5;
  const TreeMetrics m = compute_tree_metrics(s.sil, pts, g, p);
  ASSERT_EQ(m.bands.size(), 4u);
  EXPECT_NEAR(m.bands[1].depth_m, 2.6, 1e-6);
  p.area_weighted = false; // every point once: the crowded far half outvotes the near one
  EXPECT_NEAR(compute_tree_metrics(s.sil, pts, g, p).bands[1].depth_m, 2.7, 1e-6);
}

TEST(Metrics, BadInputThrows)
{
  const StereoGeometry g = camera();
  Silhouette s;
  s.present = true;
  s.mask = cv::Mat::zeros(cv::Size(10, 10), CV_8U);
  EXPECT_THROW(compute_tree_metrics(s, {}, g, MetricsParams{}), std::runtime_error);
  MetricsParams p;
  p.n_bands = 0;
  EXPECT_THROW(compute_tree_metrics(Silhouette{}, {}, g, p), std::runtime_error);
  EXPECT_THROW(compute_tree_metrics(Silhouette{}, {}, StereoGeometry{}, MetricsParams{}),
               std::runtime_error);
  EXPECT_THROW(MetricsSmoother(1.0), std::runtime_error);
}

TEST(MetricsSmoother, ExponentialAndResetOnNoTree)
{
  TreeMetrics a;
  a.tree_present = true;
  a.width_m = 1.0;
  a.distance_m = 2.0;
  a.bands.resize(2);
  a.bands[0].present = true;
  a.bands[0].width_m = a.bands[0].right_m = 1.0;
  TreeMetrics b = a;
  b.width_m = 2.0;
  b.distance_m = 3.0;
  b.bands[0].width_m = b.bands[0].right_m = 3.0;

  MetricsSmoother off(0.0);
  EXPECT_EQ(off.update(a).width_m, 1.0);
  EXPECT_EQ(off.update(b).width_m, 2.0);

  MetricsSmoother sm(0.5);
  EXPECT_DOUBLE_EQ(sm.update(a).width_m, 1.0);
  const TreeMetrics s2 = sm.update(b);
  EXPECT_DOUBLE_EQ(s2.width_m, 1.5);
  EXPECT_DOUBLE_EQ(s2.distance_m, 2.5);
  EXPECT_DOUBLE_EQ(s2.bands[0].width_m, 2.0);
  const TreeMetrics none = sm.update(TreeMetrics{});
  EXPECT_FALSE(none.tree_present);
  EXPECT_EQ(none.width_m, 0.0);
  EXPECT_DOUBLE_EQ(sm.update(b).width_m, 2.0) << "no stale value after a no-tree frame";
}

// Points crowd where the texture is (SIFT on the lit front leaves): the median of the points
// then sits in front of the surface's. Weighting each point by the silhouette area nearest to it
// gives the surface's figures back.
TEST(Metrics, AreaWeightingUndoesCrowdedPoints)
{
  const StereoGeometry g = simple_geometry(cv::Size(400, 300), 800, 50);
  Silhouette sil;
  sil.present = true;
  sil.mask = cv::Mat::zeros(g.view_size, CV_8U);
  const cv::Rect box(100, 100, 200, 100); // left 80 px at 2000 mm, right 120 px at 2200 mm
  sil.mask(box).setTo(255);
  sil.bbox = box;
  sil.area_px = box.area();
  std::vector<Point3> pts;
  auto add = [&](double u, double v, double z) {
    Point3 p;
    p.x = float((u - g.cx[0]) * z / g.fx);
    p.y = float((v - g.cy) * z / g.fy);
    p.z = float(z);
    p.match_index = std::uint32_t(pts.size());
    pts.push_back(p);
  };
  for (int v = 102; v < 200; v += 4) // crowded: every 4 px on the near 40 % of the area
    for (int u = 102; u < 180; u += 4)
      add(u, v, 2000);
  for (int v = 110; v < 200; v += 20) // sparse: every 20 px on the far 60 %
    for (int u = 190; u < 300; u += 20)
      add(u, v, 2200);
  MetricsParams p;
  p.area_weighted = false;
  const TreeMetrics plain = compute_tree_metrics(sil, pts, g, p);
  p.area_weighted = true;
  const TreeMetrics weighted = compute_tree_metrics(sil, pts, g, p);
  ASSERT_TRUE(plain.tree_present && weighted.tree_present);
  // the surface: 60 % of it at 2.2 m, so its median is 2.2 m and p05..p95 spans 0.2 m
  EXPECT_NEAR(plain.distance_m, 2.0, 1e-9) << "the crowd wins without weights";
  EXPECT_NEAR(weighted.distance_m, 2.2, 1e-9);
  EXPECT_NEAR(weighted.thickness_m, 0.2, 1e-9);
}

namespace {

// A flat canopy at z_mm in a 400 x 300 view: points on the mask's pixels every `step` px where
// `take(u, v)` says so.
struct FlatCase {
  StereoGeometry g;
  Silhouette sil;
  std::vector<Point3> pts;
};

FlatCase flat_case(const cv::Mat &mask, int step, double z_mm,
                   const std::function<bool(int, int)> &take)
{
  FlatCase c;
  c.g.view_size = mask.size();
  c.g.fx = c.g.fy = 800;
  c.g.cx[0] = c.g.cx[1] = mask.cols / 2.0;
  c.g.cy = mask.rows / 2.0;
  c.g.baseline_mm = 50;
  c.sil.present = true;
  c.sil.mask = mask;
  c.sil.bbox = cv::boundingRect(mask);
  c.sil.area_px = cv::countNonZero(mask);
  for (int v = 0; v < mask.rows; v += step)
    for (int u = 0; u < mask.cols; u += step) {
      if (!mask.at<uchar>(v, u) || !take(u, v))
        continue;
      Point3 p;
      p.x = float((u - c.g.cx[0]) * z_mm / c.g.fx);
      p.y = float((v - c.g.cy) * z_mm / c.g.fy);
      p.z = float(z_mm);
      p.match_index = std::uint32_t(c.pts.size());
      c.pts.push_back(p);
    }
  return c;
}

} // namespace

TEST(BandFill, ColumnCoverageOfConstructedMasks)
{
  cv::Mat mask = cv::Mat::zeros(100, 200, CV_8U);
  mask(cv::Rect(50, 10, 100, 10)).setTo(255); // rows 10-19: columns 50-149 all canopy
  mask(cv::Rect(50, 20, 25, 10)).setTo(255);  // rows 20-29: 50-74 and 125-149, half of 50-149
  mask(cv::Rect(125, 20, 25, 10)).setTo(255);
  mask(cv::Rect(50, 30, 100, 10)).setTo(255); // rows 30-39: a gap of 10 columns in 100
  mask(cv::Rect(100, 30, 10, 10)).setTo(0);
  mask(cv::Rect(50, 40, 50, 5)).setTo(255);   // rows 40-49: each column in one of the rows
  mask(cv::Rect(100, 45, 50, 5)).setTo(255);
  int l = 0, r = 0;
  EXPECT_DOUBLE_EQ(band_fill(mask, 10, 20, &l, &r), 1.0);
  EXPECT_EQ(l, 50);
  EXPECT_EQ(r, 149);
  EXPECT_DOUBLE_EQ(band_fill(mask, 20, 30, &l, &r), 0.5);
  EXPECT_EQ(l, 50);
  EXPECT_EQ(r, 149);
  EXPECT_DOUBLE_EQ(band_fill(mask, 30, 40), 0.9);
  EXPECT_DOUBLE_EQ(band_fill(mask, 40, 50), 1.0);
  EXPECT_DOUBLE_EQ(band_fill(mask, 60, 100, &l, &r), 0.0) << "no canopy in the rows";
  EXPECT_EQ(l, -1);
  EXPECT_EQ(r, -1);
  EXPECT_DOUBLE_EQ(band_fill(mask, 50, 10), 0.0) << "no rows";
  EXPECT_DOUBLE_EQ(band_fill(mask, -20, 20), 1.0) << "rows clamped to the mask";
  // one row: a single pixel is its own extent
  cv::Mat dot = cv::Mat::zeros(5, 5, CV_8U);
  dot.at<uchar>(2, 3) = 1;
  EXPECT_DOUBLE_EQ(band_fill(dot, 0, 5, &l, &r), 1.0);
  EXPECT_EQ(l, 3);
  EXPECT_EQ(r, 3);
}

// Three bands of 20 rows each: full, half (two ends), a 10 % gap.
TEST(Metrics, BandFillOfConstructedBands)
{
  cv::Mat mask = cv::Mat::zeros(300, 400, CV_8U);
  mask(cv::Rect(100, 100, 200, 20)).setTo(255);
  mask(cv::Rect(100, 120, 50, 20)).setTo(255);
  mask(cv::Rect(250, 120, 50, 20)).setTo(255);
  mask(cv::Rect(100, 140, 200, 20)).setTo(255);
  mask(cv::Rect(200, 140, 20, 20)).setTo(0);
  const FlatCase c = flat_case(mask, 4, 2000, [](int, int) { return true; });
  MetricsParams p;
  p.n_bands = 3;
  const TreeMetrics m = compute_tree_metrics(c.sil, c.pts, c.g, p);
  ASSERT_TRUE(m.tree_present);
  ASSERT_EQ(m.bands.size(), 3u);
  EXPECT_DOUBLE_EQ(m.bands[0].fill, 1.0);
  EXPECT_DOUBLE_EQ(m.bands[1].fill, 0.5);
  EXPECT_DOUBLE_EQ(m.bands[2].fill, 0.9);

  // a band without canopy (a gap between two parts of the canopy): absent, fill 0
  cv::Mat gap = cv::Mat::zeros(300, 400, CV_8U);
  gap(cv::Rect(100, 100, 200, 20)).setTo(255);
  gap(cv::Rect(100, 140, 200, 20)).setTo(255);
  const FlatCase cg = flat_case(gap, 4, 2000, [](int, int) { return true; });
  const TreeMetrics mg = compute_tree_metrics(cg.sil, cg.pts, cg.g, p);
  ASSERT_EQ(mg.bands.size(), 3u);
  EXPECT_FALSE(mg.bands[1].present);
  EXPECT_EQ(mg.bands[1].fill, 0.0);
  EXPECT_DOUBLE_EQ(mg.bands[0].fill, 1.0);
  EXPECT_DOUBLE_EQ(mg.bands[2].fill, 1.0);
}

// Confidence: the share of the silhouette within support_radius of a counted point.
TEST(Metrics, ConfidenceIsTheSilhouettesDepthSupport)
{
  cv::Mat mask = cv::Mat::zeros(300, 400, CV_8U);
  mask(cv::Rect(100, 100, 200, 100)).setTo(255);
  MetricsParams p;
  p.support_radius = 0.005; // 2 px in 400
  // points every 2 px on the whole canopy: all of it supported
  const FlatCase all = flat_case(mask, 2, 2000, [](int, int) { return true; });
  const TreeMetrics ma = compute_tree_metrics(all.sil, all.pts, all.g, p);
  ASSERT_TRUE(ma.tree_present);
  EXPECT_DOUBLE_EQ(ma.confidence, 1.0);
  // on its left half only (u < 200): half of it, plus the 2 px the discs reach beyond
  const FlatCase half = flat_case(mask, 2, 2000, [](int u, int) { return u < 200; });
  const TreeMetrics mh = compute_tree_metrics(half.sil, half.pts, half.g, p);
  ASSERT_TRUE(mh.tree_present);
  EXPECT_NEAR(mh.confidence, 0.5, 0.015);
  // the default radius (6 px here) reaches a little further
  const TreeMetrics md = compute_tree_metrics(half.sil, half.pts, half.g, MetricsParams{});
  EXPECT_NEAR(md.confidence, 0.5, 0.04);
  EXPECT_GT(md.confidence, mh.confidence);
  // points off the silhouette do not count (they are not the figures' points)
  FlatCase off = flat_case(mask, 2, 2000, [](int u, int) { return u < 200; });
  cv::Mat outside = cv::Mat::zeros(300, 400, CV_8U);
  outside(cv::Rect(310, 100, 90, 100)).setTo(255);
  const FlatCase extra = flat_case(outside, 2, 2000, [](int, int) { return true; });
  off.pts.insert(off.pts.end(), extra.pts.begin(), extra.pts.end());
  EXPECT_NEAR(compute_tree_metrics(off.sil, off.pts, off.g, p).confidence, mh.confidence, 0.011);
  // no point: no tree, confidence 0
  const TreeMetrics none = compute_tree_metrics(all.sil, {}, all.g, p);
  EXPECT_FALSE(none.tree_present);
  EXPECT_EQ(none.confidence, 0.0);
  EXPECT_EQ(depth_support(mask, {}, 6.0), 0.0);
  p.support_radius = -1;
  EXPECT_THROW(compute_tree_metrics(all.sil, all.pts, all.g, p), std::runtime_error);
}

TEST(MetricsSmoother, FillAndConfidenceAreSmoothed)
{
  TreeMetrics a;
  a.tree_present = true;
  a.confidence = 0.4;
  a.bands.resize(2);
  a.bands[0].present = true;
  a.bands[0].fill = 1.0;
  a.bands[1].fill = 0.0; // absent
  TreeMetrics b = a;
  b.confidence = 0.8;
  b.bands[0].fill = 0.5;
  b.bands[1].present = true;
  b.bands[1].fill = 0.7;
  MetricsSmoother sm(0.5);
  sm.update(a);
  const TreeMetrics s = sm.update(b);
  EXPECT_DOUBLE_EQ(s.confidence, 0.6);
  EXPECT_DOUBLE_EQ(s.bands[0].fill, 0.75);
  EXPECT_DOUBLE_EQ(s.bands[1].fill, 0.7) << "a band that appears takes the current value";
}
