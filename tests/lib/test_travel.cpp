// The rig's motion between frames: rigid_align on constructed point sets with a known motion, and
// estimate_motion on consecutive frames of the synthetic orchard, whose travel is known exactly.
#include "treestereo/errors.hpp"
#include "treestereo/travel.hpp"

#include "treestereo/rectify.hpp"
#include "treestereo/scene.hpp"
#include "simple_geometry.hpp"
#include "typed_error.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

using namespace treestereo;

namespace
{

double angle_deg(const cv::Matx33d &R)
{
  return std::acos(std::clamp((cv::trace(R) - 1.0) / 2.0, -1.0, 1.0)) * 180.0 / CV_PI;
}

cv::Matx33d rotation(const cv::Vec3d &axis, double deg)
{
  cv::Matx33d R;
  cv::Rodrigues(cv::normalize(axis) * (deg * CV_PI / 180.0), R);
  return R;
}

// Points spread through a box like an orchard seen from the rig (mm), their images under
// (R, t) with Gaussian noise, and a share of them replaced by points anywhere in the box.
struct PointSets {
  std::vector<cv::Point3d> from, to;
  std::vector<bool> outlier;
};

PointSets make_sets(int n, const cv::Matx33d &R, const cv::Vec3d &t, double noise_mm,
                    double outlier_share, std::uint64_t seed)
{
  cv::RNG rng(seed);
  PointSets s;
  for (int i = 0; i < n; ++i) {
    const cv::Point3d a(rng.uniform(-1200.0, 1200.0), rng.uniform(-900.0, 900.0),
                        rng.uniform(1500.0, 6000.0));
    const cv::Vec3d b = R * cv::Vec3d(a) + t;
    const bool out = i < int(std::lround(outlier_share * n));
    s.from.push_back(a);
    s.to.push_back(out ? cv::Point3d(rng.uniform(-1200.0, 1200.0), rng.uniform(-900.0, 900.0),
                                     rng.uniform(1500.0, 6000.0))
                       : cv::Point3d(b[0] + rng.gaussian(noise_mm), b[1] + rng.gaussian(noise_mm),
                                     b[2] + rng.gaussian(noise_mm)));
    s.outlier.push_back(out);
  }
  return s;
}

} // namespace

TEST(RigidAlign, ExactPointsGiveTheExactMotion)
{
  const cv::Matx33d R = rotation({0.2, 1.0, -0.1}, 7.0);
  const cv::Vec3d t(-286.0, 4.0, -12.0);
  const PointSets s = make_sets(50, R, t, 0.0, 0.0, 11);
  const RigidResult r = rigid_align(s.from, s.to);
  ASSERT_TRUE(r.found);
  EXPECT_EQ(r.inliers, 50u);
  EXPECT_LT(cv::norm(r.R - R, cv::NORM_INF), 1e-9);
  EXPECT_LT(cv::norm(r.t - t), 1e-6);
  EXPECT_LT(r.rms_mm, 1e-6);
}

TEST(RigidAlign, RecoversTheMotionWith30PercentOutliersAndNoise)
{
  struct Case {
    cv::Vec3d axis;
    double deg;
    cv::Vec3d t;
  };
  const Case cases[] = {
      {{0, 1, 0}, 0.0, {-71.4, 0.0, 0.0}},       // driving straight at 0.5 m/s, 7 frames/s
      {{0.1, 1, 0.05}, 1.5, {-285.7, 3.0, 8.0}}, // 2 m/s with a little yaw
      {{1, -0.3, 0.4}, 25.0, {150.0, -300.0, 900.0}},
      {{-0.5, 0.2, 1}, 120.0, {2000.0, 500.0, -1000.0}},
  };
  int k = 0;
  for (const Case &c : cases) {
    SCOPED_TRACE("case " + std::to_string(k));
    const cv::Matx33d R = rotation(c.axis, c.deg);
    const double noise = 1.0;
    const PointSets s = make_sets(300, R, c.t, noise, 0.3, 100 + std::uint64_t(k++));
    const RigidResult r = rigid_align(s.from, s.to); // inlier_mm 10: 5.8 sigma of the 3D noise
    ASSERT_TRUE(r.found);
    // Every clean point within the tolerance is kept, no outlier is.
    std::size_t wrong = 0;
    for (std::size_t i = 0; i < s.from.size(); ++i)
      wrong += r.inlier[i] == s.outlier[i];
    EXPECT_EQ(wrong, 0u);
    EXPECT_EQ(r.inliers, 210u);
    // 210 points over ~2 m with 1 mm noise: the rotation to a few thousandths of a degree, the
    // translation to well under a millimetre (its error is the rotation's times ~4 m of lever).
    EXPECT_LT(angle_deg(r.R.t() * R), 0.01);
    EXPECT_LT(cv::norm(r.t - c.t), 1.0);
    // The residual of 3D Gaussian noise on one side: sqrt(3) sigma.
    EXPECT_NEAR(r.rms_mm, std::sqrt(3.0) * noise, 0.25);
  }
}

TEST(RigidAlign, PerPointTolerancesDecideTheInliersAndWeighTheFit)
{
  // Far points with large errors: inliers under their own (large) tolerance, and weighed so
  // little that they do not pull the fit off the near points' motion.
  const cv::Matx33d R = rotation({0, 1, 0}, 2.0);
  const cv::Vec3d t(-100, 0, 5);
  PointSets s = make_sets(200, R, t, 0.2, 0.0, 7);
  std::vector<double> tol(s.from.size(), 2.0);
  cv::RNG rng(8);
  for (std::size_t i = 0; i < s.from.size(); i += 4) {
    s.to[i] += cv::Point3d(rng.uniform(-25.0, 25.0), 0, rng.uniform(-25.0, 25.0));
    tol[i] = 60.0;
  }
  const RigidResult r = rigid_align(s.from, s.to, RigidParams(), tol);
  ASSERT_TRUE(r.found);
  EXPECT_EQ(r.inliers, s.from.size());
  EXPECT_LT(cv::norm(r.t - t), 0.5);
  EXPECT_LT(angle_deg(r.R.t() * R), 0.01);
  // With one tolerance for all (10 mm) most of the disturbed points are outliers.
  const RigidResult plain = rigid_align(s.from, s.to);
  ASSERT_TRUE(plain.found);
  EXPECT_LT(plain.inliers, s.from.size() - 20);
}

TEST(RigidAlign, DegenerateInputIsNotFoundAndBadInputThrows)
{
  const cv::Matx33d R = rotation({0, 1, 0}, 3.0);
  const cv::Vec3d t(-50, 0, 0);
  // Too few points.
  for (int n : {0, 1, 2}) {
    const PointSets s = make_sets(n, R, t, 0.0, 0.0, 1);
    RigidParams p;
    p.min_inliers = 3;
    EXPECT_FALSE(rigid_align(s.from, s.to, p).found) << n << " points";
  }
  // Points on one line (with and without a little noise across it): the rotation about the line
  // is undetermined.
  for (double across : {0.0, 0.01}) {
    std::vector<cv::Point3d> a, b;
    cv::RNG rng(3);
    for (int i = 0; i < 100; ++i) {
      const double s = rng.uniform(-1000.0, 1000.0);
      const cv::Point3d p(0.6 * s + rng.gaussian(across), 0.3 * s + rng.gaussian(across),
                          3000 + 0.74 * s);
      a.push_back(p);
      const cv::Vec3d q = R * cv::Vec3d(p) + t;
      b.emplace_back(q[0], q[1], q[2]);
    }
    EXPECT_FALSE(rigid_align(a, b).found) << "collinear, noise " << across;
  }
  // All at one point.
  {
    std::vector<cv::Point3d> a(20, cv::Point3d(1, 2, 3000)), b(20, cv::Point3d(-49, 2, 3000));
    EXPECT_FALSE(rigid_align(a, b).found);
  }
  // Non-finite points take no part.
  {
    PointSets s = make_sets(40, R, t, 0.0, 0.0, 5);
    s.from[3].x = std::nan("");
    s.to[7].z = std::numeric_limits<double>::infinity();
    const RigidResult r = rigid_align(s.from, s.to);
    ASSERT_TRUE(r.found);
    EXPECT_EQ(r.inliers, 38u);
    EXPECT_LT(cv::norm(r.t - t), 1e-6);
  }
  const PointSets s = make_sets(10, R, t, 0.0, 0.0, 1);
  std::vector<cv::Point3d> shorter(s.to.begin(), s.to.end() - 1);
  EXPECT_THROW(rigid_align(s.from, shorter), BadInput);
  EXPECT_THROW(rigid_align(s.from, s.to, RigidParams(), std::vector<double>(3, 1.0)),
               BadInput);
  EXPECT_THROW(rigid_align(s.from, s.to, RigidParams(), std::vector<double>(10, 0.0)),
               BadInput);
  RigidParams bad;
  bad.inlier_mm = 0;
  try {
    rigid_align(s.from, s.to, bad);
    ADD_FAILURE() << "no exception";
  } catch (const BadSettings &e) {
    EXPECT_NE(std::string(e.what()).find("inlier_mm"), std::string::npos) << e.what();
  }
  bad = RigidParams();
  bad.min_inliers = 2;
  EXPECT_THROW(rigid_align(s.from, s.to, bad), BadSettings);
}

TEST(RigidAlign, ErrorsAreTypedAndNameTheProblem)
{
  const std::vector<cv::Point3d> three(3), two(2);
  expect_typed_error<BadInput>([&] { rigid_align(three, two); }, "differ in length");
  RigidParams bad;
  bad.min_inliers = 2;
  expect_typed_error<BadSettings>([&] { rigid_align(three, three, bad); }, "min_inliers");
}

// ---- estimate_motion on the synthetic orchard ----

namespace
{

// One frame of an orchard sequence: both views rendered and rectified with the rig's own
// calibration, and 3D points of the left view from the renderer's exact depth.
struct Frame {
  cv::Mat view[2];                    // BGR, rectified
  std::vector<PixelPoint> vegetation; // a grid over the leaves (any tree, either row)
  std::vector<PixelPoint> textured;   // a grid over everything but the sky
};

struct Sequence {
  std::unique_ptr<SceneRenderer> renderer;
  StereoRectification rect;
};

SceneParams orchard(cv::Size size, double speed_m_s)
{
  SceneParams p;
  p.kind = SceneKind::Orchard;
  p.seed = 5;
  p.image_size = size;
  p.speed_m_s = speed_m_s;
  p.framerate = 7.0;
  return p;
}

// Grid samples (every `step` px of the rendered view) of the surfaces, carried exactly into the
// rectified-left frame: the 3D hit rotated by R1 and projected with the rectified camera.
Frame render_frame(const Sequence &s, std::uint64_t frame, int step)
{
  Frame f;
  GroundTruth truth;
  for (int v = 0; v < 2; ++v) {
    cv::Mat rgb, bgr;
    s.renderer->render(v, frame, rgb, v == LEFT ? &truth : nullptr);
    cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
    rectify_view(s.rect, v, bgr, f.view[v]);
  }
  const StereoGeometry &g = s.rect.geometry;
  const cv::Mat &rays = s.renderer->normalized_rays(LEFT);
  for (int y = step / 2; y < truth.depth.rows; y += step)
    for (int x = step / 2; x < truth.depth.cols; x += step) {
      const float z = truth.depth.at<float>(y, x);
      if (!(z > 0))
        continue;
      const cv::Vec2f n = rays.at<cv::Vec2f>(y, x);
      const cv::Vec3d X = g.R1 * cv::Vec3d(n[0] * z, n[1] * z, z);
      PixelPoint q;
      q.px = cv::Point2f(float(g.fx * X[0] / X[2] + g.cx[LEFT]), float(g.fy * X[1] / X[2] + g.cy));
      q.p.x = float(X[0]);
      q.p.y = float(X[1]);
      q.p.z = float(X[2]);
      if (q.px.x < 0 || q.px.y < 0 || q.px.x > g.view_size.width - 1 ||
          q.px.y > g.view_size.height - 1)
        continue;
      const SurfaceLabel l = SurfaceLabel(truth.labels.at<uchar>(y, x));
      f.textured.push_back(q);
      if (l == SurfaceLabel::Leaf || l == SurfaceLabel::RowLeaf || l == SurfaceLabel::BackLeaf)
        f.vegetation.push_back(q);
    }
  return f;
}

Sequence make_sequence(cv::Size size, double speed)
{
  Sequence s;
  s.renderer = std::make_unique<SceneRenderer>(orchard(size, speed));
  s.rect = compute_rectification(s.renderer->calibration(), size);
  return s;
}

// Frames rendered once for all tests: key = (width, speed in mm/s, frame).
const Frame &frame_of(cv::Size size, double speed, std::uint64_t frame,
                      const StereoGeometry **g = nullptr)
{
  static std::map<std::pair<int, int>, Sequence> seqs;
  static std::map<std::tuple<int, int, std::uint64_t>, Frame> frames;
  const std::pair<int, int> key(size.width, int(std::lround(speed * 1000)));
  auto it = seqs.find(key);
  if (it == seqs.end())
    it = seqs.emplace(key, make_sequence(size, speed)).first;
  if (g)
    *g = &it->second.rect.geometry;
  const auto fk = std::make_tuple(key.first, key.second, frame);
  auto ft = frames.find(fk);
  if (ft == frames.end())
    ft = frames.emplace(fk, render_frame(it->second, frame, size.width > 1000 ? 8 : 4)).first;
  return ft->second;
}

double truth_travel(cv::Size size, double speed, std::uint64_t k)
{
  const SceneRenderer r(orchard(size, speed));
  return r.travel_mm(k) - r.travel_mm(k - 1);
}

const cv::Size kFull(1296, 972), kVga(640, 480);

} // namespace

// The travel of consecutive frames at 0.5 and 2 m/s (7 frames/s), at both sizes, from a grid
// over the vegetation and from a grid over everything with texture.
TEST(EstimateMotion, TravelOfConsecutiveOrchardFramesIsTheRenderersTravel)
{
  for (cv::Size size : {kVga, kFull})
    for (double speed : {0.5, 2.0})
      for (std::uint64_t k : {std::uint64_t(3), std::uint64_t(9)}) {
        const StereoGeometry *g = nullptr;
        const Frame &prev = frame_of(size, speed, k - 1);
        const Frame &cur = frame_of(size, speed, k, &g);
        const double truth = truth_travel(size, speed, k);
        for (int which = 0; which < 2; ++which) {
          const std::vector<PixelPoint> &pts = which == 0 ? cur.vegetation : cur.textured;
          const Motion m = estimate_motion(prev.view[LEFT], prev.view[RIGHT], cur.view[LEFT],
                                           cur.view[RIGHT], pts, *g);
          std::printf("%dx%d %.1f m/s frame %d %-10s: travel %.2f mm (truth %.2f, error %+.2f mm, "
                      "%+.2f %%), prior %.0f mm, rotation %.3f deg, %zu points, %zu tracked, %zu "
                      "inliers, rms %.2f mm %.3f px\n",
                      size.width, size.height, speed, int(k),
                      which == 0 ? "vegetation" : "textured", m.travel_mm, truth,
                      m.travel_mm - truth, 100 * (m.travel_mm - truth) / truth, m.prior_mm,
                      m.rotation_deg, m.points, m.tracked, m.inliers, m.rms_mm, m.rms_px);
          SCOPED_TRACE(std::to_string(size.width) + " px, " + std::to_string(speed) +
                       " m/s, frame " + std::to_string(k) +
                       (which == 0 ? ", vegetation" : ", textured"));
          ASSERT_TRUE(m.found);
          EXPECT_NEAR(m.travel_mm, truth, std::max(0.02 * truth, 3.0));
          // The rig drives straight: no rotation, and the displacement is along x (in the
          // rectified frame, R1 turns the rig's x by a fraction of a degree).
          const cv::Vec3d d_true = g->R1 * cv::Vec3d(truth, 0, 0);
          EXPECT_LT(cv::norm(m.displacement_mm - d_true), std::max(0.03 * truth, 4.0));
          EXPECT_LT(m.rotation_deg, 0.1);
          EXPECT_GE(m.tracked, std::size_t(0.25 * double(m.points)));
          EXPECT_GE(m.inliers, std::size_t(0.5 * double(m.tracked)));
          EXPECT_LE(m.points, 400u);
        }
      }
}

TEST(EstimateMotion, TravelIsTheDisplacementAlongTheRowsDirection)
{
  const StereoGeometry *g = nullptr;
  const Frame &prev = frame_of(kVga, 2.0, 2);
  const Frame &cur = frame_of(kVga, 2.0, 3, &g);
  const double truth = truth_travel(kVga, 2.0, 3);
  // The renderer's rig drives along the rendered left camera's x, R1 x in the rectified frame;
  // before the row's direction is measured, the x axis in the ground plane stands in.
  GroundPlane level;
  level.found = true;
  level.normal = g->R1 * cv::Vec3d(0, -1, 0);
  level.d = 950;
  const cv::Vec3d drive = g->R1 * cv::Vec3d(1, 0, 0);
  for (const cv::Vec3d &along : {drive, in_ground_plane(cv::Vec3d(1, 0, 0), level)}) {
    const Motion a = estimate_motion(prev.view[LEFT], prev.view[RIGHT], cur.view[LEFT],
                                     cur.view[RIGHT], cur.vegetation, *g, TravelParams(), along);
    ASSERT_TRUE(a.found);
    EXPECT_NEAR(a.travel_mm, truth, 0.02 * truth);
    EXPECT_EQ(a.along, along);
  }
  // A row 30 degrees off the rig's motion: only cos(30) of the motion is along it, and the
  // displacement itself does not depend on the direction.
  const Motion m = estimate_motion(prev.view[LEFT], prev.view[RIGHT], cur.view[LEFT],
                                   cur.view[RIGHT], cur.vegetation, *g, TravelParams(), drive);
  const cv::Vec3d off = g->R1 * cv::Vec3d(std::cos(CV_PI / 6), 0, std::sin(CV_PI / 6));
  const Motion b = estimate_motion(prev.view[LEFT], prev.view[RIGHT], cur.view[LEFT],
                                   cur.view[RIGHT], cur.vegetation, *g, TravelParams(), off);
  ASSERT_TRUE(m.found && b.found);
  EXPECT_NEAR(b.travel_mm, truth * std::cos(CV_PI / 6), 0.02 * truth);
  EXPECT_LT(cv::norm(b.displacement_mm - m.displacement_mm), 1e-9);
  EXPECT_NEAR(b.travel_mm, m.displacement_mm.dot(off), 1e-9);
  // What cannot be a row's direction is refused by name.
  for (const cv::Vec3d &bad : {cv::Vec3d(0, 0, 1), cv::Vec3d(2, 0, 0), cv::Vec3d(-1, 0, 0),
                               cv::Vec3d(std::nan(""), 0, 0)})
    EXPECT_THROW(estimate_motion(prev.view[LEFT], prev.view[RIGHT], cur.view[LEFT],
                                 cur.view[RIGHT], cur.vegetation, *g, TravelParams(), bad),
                 BadInput);
}

TEST(EstimateMotion, FramesInReverseAreNegativeTravel)
{
  // The previous frame is the later one: the rig drove towards -x between them.
  for (double speed : {0.5, 2.0}) {
    const StereoGeometry *g = nullptr;
    const Frame &later = frame_of(kVga, speed, 3);
    const Frame &earlier = frame_of(kVga, speed, 2, &g);
    const double truth = -truth_travel(kVga, speed, 3);
    const Motion m = estimate_motion(later.view[LEFT], later.view[RIGHT], earlier.view[LEFT],
                                     earlier.view[RIGHT], earlier.textured, *g);
    ASSERT_TRUE(m.found) << speed << " m/s";
    EXPECT_NEAR(m.travel_mm, truth, std::max(0.02 * std::abs(truth), 3.0)) << speed << " m/s";
  }
}

// A turn between the frames: the previous views as the rig saw them turned by `deg` about its
// vertical axis, the travel unchanged. A turn about the camera's centre moves every pixel by the
// homography K Q K^-1 whatever its depth (the right camera, 50 mm beside it, moves by 50 mm x
// the angle, a fraction of a millimetre: left out). On the straight drive no turn is found; a
// small turn (0.05 degrees) may go unseen, at the cost of a share of the travel within 1 %; a
// turn well above the tracks' noise (0.3 degrees) is found and kept apart from the travel.
TEST(EstimateMotion, ATurnBetweenFramesIsFoundAndTheTravelKeptApart)
{
  for (double speed : {0.5, 2.0})
    for (double deg : {0.0, 0.05, 0.3}) {
      const StereoGeometry *g = nullptr;
      const Frame &prev = frame_of(kFull, speed, 2);
      const Frame &cur = frame_of(kFull, speed, 3, &g);
      const double truth = truth_travel(kFull, speed, 3);
      const cv::Matx33d Q = rotation(cv::Vec3d(0, 1, 0), deg);
      cv::Mat turned[2];
      for (int v = 0; v < 2; ++v) {
        const cv::Matx33d K(g->fx, 0, g->cx[v], 0, g->fy, g->cy, 0, 0, 1);
        cv::warpPerspective(prev.view[v], turned[v], cv::Mat(K * Q * K.inv()), prev.view[v].size(),
                            cv::INTER_LINEAR);
      }
      const Motion m = estimate_motion(turned[LEFT], turned[RIGHT], cur.view[LEFT],
                                       cur.view[RIGHT], cur.vegetation, *g);
      std::printf("%.1f m/s, turn %.2f deg: travel %.2f mm (truth %.2f, error %+.2f mm), rotation "
                  "%.3f deg\n",
                  speed, deg, m.travel_mm, truth, m.travel_mm - truth, m.rotation_deg);
      SCOPED_TRACE(std::to_string(speed) + " m/s, turn " + std::to_string(deg) + " deg");
      ASSERT_TRUE(m.found);
      if (deg == 0) {
        // A spurious turn of 0.05 degrees would take 1.7 mm of the travel at 2 m.
        EXPECT_LT(m.rotation_deg, 0.02);
        EXPECT_NEAR(m.travel_mm, truth, std::max(0.003 * truth, 0.5));
      } else {
        EXPECT_NEAR(m.travel_mm, truth, std::max(0.01 * truth, 1.5));
      }
      if (deg >= 0.3) { // well above what the tracks' noise can hide
        EXPECT_NEAR(m.rotation_deg, deg, 0.05);
      }
    }
}

TEST(EstimateMotion, AStandingRigHasNoTravel)
{
  for (cv::Size size : {kVga, kFull}) {
    const StereoGeometry *g = nullptr;
    const Frame &prev = frame_of(size, 0.0, 0);
    const Frame &cur = frame_of(size, 0.0, 1, &g); // the same scene, other sensor noise
    const Motion m = estimate_motion(prev.view[LEFT], prev.view[RIGHT], cur.view[LEFT],
                                     cur.view[RIGHT], cur.vegetation, *g);
    std::printf("%dx%d standing: travel %+.3f mm, displacement %.3f mm, %zu inliers\n", size.width,
                size.height, m.travel_mm, cv::norm(m.displacement_mm), m.inliers);
    ASSERT_TRUE(m.found);
    EXPECT_LT(std::abs(m.travel_mm), 1.0);
    EXPECT_LT(cv::norm(m.displacement_mm), 2.0);
  }
}

TEST(EstimateMotion, ViewsWithoutTextureAreNotFound)
{
  const StereoGeometry *g = nullptr;
  const Frame &cur = frame_of(kVga, 0.5, 3, &g);
  const cv::Mat black(cur.view[LEFT].size(), cur.view[LEFT].type(), cv::Scalar::all(0));
  const cv::Mat grey(cur.view[LEFT].size(), cur.view[LEFT].type(), cv::Scalar::all(128));
  for (const cv::Mat &flat : {black, grey}) {
    const Motion both = estimate_motion(flat, flat, flat, flat, cur.vegetation, *g);
    EXPECT_FALSE(both.found);
    EXPECT_EQ(both.tracked, 0u);
    // The previous views blank, the current ones the orchard: nothing to track into.
    const Motion prev_blank =
        estimate_motion(flat, flat, cur.view[LEFT], cur.view[RIGHT], cur.vegetation, *g);
    EXPECT_FALSE(prev_blank.found);
  }
  // No points, or only invalid ones.
  std::vector<PixelPoint> invalid = cur.vegetation;
  for (PixelPoint &q : invalid)
    q.p.valid = false;
  const Frame &prev = frame_of(kVga, 0.5, 2);
  EXPECT_FALSE(
      estimate_motion(prev.view[LEFT], prev.view[RIGHT], cur.view[LEFT], cur.view[RIGHT], {}, *g)
          .found);
  EXPECT_FALSE(estimate_motion(prev.view[LEFT], prev.view[RIGHT], cur.view[LEFT], cur.view[RIGHT],
                               invalid, *g)
                   .found);
}

TEST(EstimateMotion, GreyViewsWork)
{
  const StereoGeometry *g = nullptr;
  const Frame &prev = frame_of(kVga, 0.5, 2);
  const Frame &cur = frame_of(kVga, 0.5, 3, &g);
  cv::Mat v[4];
  const cv::Mat *src[4] = {&prev.view[LEFT], &prev.view[RIGHT], &cur.view[LEFT], &cur.view[RIGHT]};
  for (int i = 0; i < 4; ++i)
    cv::cvtColor(*src[i], v[i], cv::COLOR_BGR2GRAY);
  const Motion m = estimate_motion(v[0], v[1], v[2], v[3], cur.vegetation, *g);
  ASSERT_TRUE(m.found);
  const double truth = truth_travel(kVga, 0.5, 3);
  EXPECT_NEAR(m.travel_mm, truth, std::max(0.02 * truth, 3.0));
}

// A view that repeats every 60 px (a brick wall, a trellis, evenly spaced posts), a plane
// 2000 mm away with fx = 1000 px: the view repeats every 120 mm of travel. Moved 150 mm, it
// matches at 30 and -90 mm as well, and the search over the whole range takes a repeat (-90 mm;
// fewer points leave the view there). With the expected travel (the odometer's last step,
// 140 mm) it takes the travel made.
TEST(EstimateMotion, TheExpectedTravelTellsARepeatingViewsRepeatsApart)
{
  const StereoGeometry g = simple_geometry(cv::Size(640, 480), 1000, 100);
  const double z = 2000, travel = 150;
  const int period = 60, shift = 75, disparity = 50; // fx travel / z, fx baseline / z
  // One period of smooth texture, wrapped: blurred over three periods, the middle one kept.
  cv::Mat noise(g.view_size.height, period, CV_8U), wide, tile;
  cv::RNG rng(11);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::hconcat(std::vector<cv::Mat>{noise, noise, noise}, wide);
  cv::GaussianBlur(wide, wide, cv::Size(7, 7), 1.5);
  tile = wide.colRange(period, 2 * period).clone();
  // The view of the texture moved by `offset` px: pixel u shows the texture at u + offset.
  const auto view = [&](int offset) {
    cv::Mat v(g.view_size, CV_8U);
    for (int y = 0; y < v.rows; ++y)
      for (int x = 0; x < v.cols; ++x)
        v.at<uchar>(y, x) = tile.at<uchar>(y, ((x + offset) % period + period) % period);
    return v;
  };
  // A point at left pixel u stood at u + shift in the previous views; its right pixel is
  // u - disparity.
  const cv::Mat left = view(0), right = view(disparity), prev_left = view(-shift),
                prev_right = view(disparity - shift);
  std::vector<PixelPoint> points;
  for (int v = 20; v < g.view_size.height - 20; v += 16)
    for (int u = disparity + 20; u < g.view_size.width - 20; u += 16) {
      PixelPoint q;
      q.px = cv::Point2f(float(u), float(v));
      q.p.x = float((u - g.cx[LEFT]) * z / g.fx);
      q.p.y = float((v - g.cy) * z / g.fy);
      q.p.z = float(z);
      points.push_back(q);
    }
  const Motion whole = estimate_motion(prev_left, prev_right, left, right, points, g);
  const Motion near =
      estimate_motion(prev_left, prev_right, left, right, points, g, TravelParams(),
                      cv::Vec3d(1, 0, 0), 140.0);
  std::printf("repeating view, travel %.0f mm: whole range %s %.2f mm (search %.0f mm), near "
              "140 mm %s %.2f mm (search %.0f mm)\n",
              travel, whole.found ? "found" : "not found", whole.travel_mm, whole.prior_mm,
              near.found ? "found" : "not found", near.travel_mm, near.prior_mm);
  // The whole range's search takes a repeat (the test's view is what it claims to be)...
  EXPECT_GT(std::abs(whole.prior_mm - travel), 50.0);
  // ...and the expected travel the travel made.
  ASSERT_TRUE(near.found);
  EXPECT_NEAR(near.travel_mm, travel, 1.5);
  EXPECT_LT(near.rotation_deg, 0.05);
  // Expected beyond the search's range: its nearer end, not a failure.
  TravelParams short_range;
  short_range.max_travel_mm = 160;
  const Motion beyond = estimate_motion(prev_left, prev_right, left, right, points, g,
                                        short_range, cv::Vec3d(1, 0, 0), 400.0);
  ASSERT_TRUE(beyond.found);
  EXPECT_NEAR(beyond.travel_mm, travel, 1.5);
}

// ---- Odometer: key frames ----

// At 0.5 m/s (71 mm a frame) a 300 mm span measures three frames in four from a key frame; the
// position over the sequence is the renderer's, and every step is the frame's own travel.
TEST(Odometer, MeasuresFramesFromAKeyFrameWithinTheSpan)
{
  const double speed = 0.5;
  OdometerParams p;
  p.travel.scale = 1.0; // VGA is tracked at full size (as treemetrics does)
  Odometer odo(p);
  double position = 0;
  int from_key = 0, found = 0;
  const std::uint64_t first = 2, last = 11;
  for (std::uint64_t k = first; k <= last; ++k) {
    const StereoGeometry *g = nullptr;
    const Frame &f = frame_of(kVga, speed, k, &g);
    const OdometryStep s = odo.add(f.view[LEFT], f.view[RIGHT], f.vegetation, *g);
    if (k == first) {
      EXPECT_FALSE(s.found) << "the first frame has no travel";
      continue;
    }
    ASSERT_TRUE(s.found) << "frame " << k;
    ++found;
    from_key += s.from_key;
    const double truth = truth_travel(kVga, speed, k);
    // A step from a key frame is the difference of two estimates: twice one's error at most.
    EXPECT_NEAR(s.travel_mm, truth, 2 * std::max(0.02 * truth, 3.0)) << "frame " << k;
    position += s.travel_mm;
  }
  SceneRenderer r(orchard(kVga, speed));
  const double truth = r.travel_mm(last) - r.travel_mm(first);
  std::printf("odometer 0.5 m/s: %d of %d frames from a key frame, position %.2f mm (truth "
              "%.2f)\n",
              from_key, found, position, truth);
  EXPECT_GE(from_key, found / 2); // keys at frames 2, 6, 10: 6 of 9 measured from a key
  EXPECT_NEAR(position, truth, 0.01 * truth);
}

// key_span_mm 0: every frame from the previous one; a frame without points (its motion not
// found) is the next frame's key, and the one after measures from it.
TEST(Odometer, NoSpanMeansThePreviousFrameAndALostFrameStartsAKey)
{
  const double speed = 0.5;
  OdometerParams p;
  p.travel.scale = 1.0;
  p.key_span_mm = 0;
  Odometer odo(p);
  for (std::uint64_t k = 2; k <= 4; ++k) {
    const StereoGeometry *g = nullptr;
    const Frame &f = frame_of(kVga, speed, k, &g);
    const OdometryStep s = odo.add(f.view[LEFT], f.view[RIGHT], f.vegetation, *g);
    EXPECT_FALSE(s.from_key) << "frame " << k;
    EXPECT_EQ(s.found, k > 2) << "frame " << k;
  }
  p.key_span_mm = 300;
  Odometer keyed(p);
  const StereoGeometry *g = nullptr;
  const Frame &f2 = frame_of(kVga, speed, 2, &g), &f3 = frame_of(kVga, speed, 3),
              &f4 = frame_of(kVga, speed, 4), &f5 = frame_of(kVga, speed, 5);
  EXPECT_FALSE(keyed.add(f2.view[LEFT], f2.view[RIGHT], f2.vegetation, *g).found);
  EXPECT_TRUE(keyed.add(f3.view[LEFT], f3.view[RIGHT], f3.vegetation, *g).found);
  EXPECT_FALSE(keyed.add(f4.view[LEFT], f4.view[RIGHT], {}, *g).found) << "no points";
  const OdometryStep s = keyed.add(f5.view[LEFT], f5.view[RIGHT], f5.vegetation, *g);
  ASSERT_TRUE(s.found);
  EXPECT_FALSE(s.from_key) << "frame 4 is the key: the previous frame";
  EXPECT_NEAR(s.travel_mm, truth_travel(kVga, speed, 5), 3.0);
  // Another view size: a first frame again.
  const Frame &full = frame_of(kFull, speed, 5, &g);
  EXPECT_FALSE(keyed.add(full.view[LEFT], full.view[RIGHT], full.vegetation, *g).found);
  EXPECT_TRUE(keyed.has_previous());
  keyed.reset();
  EXPECT_FALSE(keyed.has_previous());
  EXPECT_FALSE(keyed.add(f5.view[LEFT], f5.view[RIGHT], f5.vegetation, *g).found);
  EXPECT_TRUE(keyed.has_previous());
}

// A standing rig stays on its first key frame: nothing adds up.
TEST(Odometer, AStandingRigKeepsItsKeyFrame)
{
  const StereoGeometry *g = nullptr;
  const Frame &a = frame_of(kVga, 0.0, 0, &g), &b = frame_of(kVga, 0.0, 1);
  OdometerParams p;
  p.travel.scale = 1.0;
  Odometer odo(p);
  odo.add(a.view[LEFT], a.view[RIGHT], a.vegetation, *g);
  double position = 0;
  for (int i = 0; i < 4; ++i) {
    const Frame &f = i % 2 ? a : b;
    const OdometryStep s = odo.add(f.view[LEFT], f.view[RIGHT], f.vegetation, *g);
    ASSERT_TRUE(s.found);
    EXPECT_EQ(s.from_key, i > 0);
    position += s.travel_mm;
  }
  EXPECT_LT(std::abs(position), 1.0);
}

// Displacements along a row the cameras are yawed 5 degrees against (and tilted 0.5 degrees),
// each with its own error of a few mm across the row: their sum's direction is the row's.
TEST(RowDirection, TheSumOfTheDisplacementsGivesTheRowsDirection)
{
  const double yaw = 5 * CV_PI / 180, tilt = 0.5 * CV_PI / 180;
  const cv::Vec3d truth(std::cos(yaw) * std::cos(tilt), std::sin(tilt), std::sin(yaw));
  RowDirection dir;
  EXPECT_FALSE(dir.measured());
  EXPECT_EQ(dir.direction(), cv::Vec3d(1, 0, 0));
  for (int k = 0; k < 40; ++k) {
    // Driving back along the row for a while is the same direction.
    const double travel = k < 30 ? 143 : -143;
    const cv::Vec3d noise(0.3 * std::sin(1.3 * k), 1.5 * std::cos(2.1 * k), 2.0 * std::sin(0.7 * k));
    dir.add(travel * truth + noise);
    if (k == 0) {
      EXPECT_FALSE(dir.measured()) << "one frame's 143 mm is under the span";
      EXPECT_EQ(dir.direction(), cv::Vec3d(1, 0, 0));
    }
  }
  dir.add(cv::Vec3d(std::nan(""), 0, 0)); // ignored
  RowDirection standing; // a standing rig's tracks: noise of a few mm, ignored
  for (int k = 0; k < 500; ++k)
    standing.add(cv::Vec3d(3 * std::sin(0.37 * k), 3 * std::cos(1.1 * k), 3 * std::sin(2.3 * k)));
  EXPECT_FALSE(standing.measured());
  RowDirection along_z; // displacements along the optical axis: no row across the view
  along_z.add(cv::Vec3d(10, 0, 500));
  EXPECT_FALSE(along_z.measured());
  EXPECT_EQ(along_z.direction(), cv::Vec3d(1, 0, 0));
  ASSERT_TRUE(dir.measured());
  const cv::Vec3d d = dir.direction();
  EXPECT_NEAR(cv::norm(d), 1.0, 1e-12);
  EXPECT_LT(std::acos(std::min(1.0, d.dot(truth))), 0.001); // radians: 2 mm at 2 m
  // The ground plane is not used once measured; before the span, the x axis in the ground
  // plane (what the travel is measured along).
  GroundPlane tilted;
  tilted.found = true;
  tilted.normal = cv::normalize(cv::Vec3d(0.1, -1, 0.1));
  tilted.d = 950;
  EXPECT_EQ(dir.direction(tilted), d);
  const cv::Vec3d x = RowDirection().direction(tilted);
  EXPECT_NEAR(x.dot(tilted.normal), 0.0, 1e-12);
  EXPECT_GT(x[0], 0.99);
  dir.reset();
  EXPECT_FALSE(dir.measured());
  EXPECT_THROW(RowDirection(-1), BadSettings);
  EXPECT_THROW(RowDirection(std::nan("")), BadSettings);
}

// The orchard's rig: rectification turns the cameras, so the rig drives along R1 x, not along
// the rectified x axis (0.2 degrees of yaw, 0.5 of tilt). The motions of consecutive frames
// give that direction.
TEST(RowDirection, TheOrchardRigsDirectionFromItsMotions)
{
  RowDirection dir;
  const StereoGeometry *g = nullptr;
  for (double speed : {0.5, 2.0})
    for (std::uint64_t k : {std::uint64_t(3), std::uint64_t(9)}) {
      const Frame &prev = frame_of(kFull, speed, k - 1);
      const Frame &cur = frame_of(kFull, speed, k, &g);
      const Motion m = estimate_motion(prev.view[LEFT], prev.view[RIGHT], cur.view[LEFT],
                                       cur.view[RIGHT], cur.vegetation, *g);
      ASSERT_TRUE(m.found);
      dir.add(m.displacement_mm);
    }
  ASSERT_TRUE(dir.measured());
  const cv::Vec3d truth = cv::normalize(g->R1 * cv::Vec3d(1, 0, 0));
  const cv::Vec3d d = dir.direction();
  const double err = std::acos(std::min(1.0, d.dot(truth)));
  const double x_axis = std::acos(truth[0]); // what the rectified x axis alone is off by
  std::printf("row direction (%.5f, %.5f, %.5f), truth (%.5f, %.5f, %.5f): %.4f rad off (the x "
              "axis %.4f)\n",
              d[0], d[1], d[2], truth[0], truth[1], truth[2], err, x_axis);
  EXPECT_GT(x_axis, 0.009);
  EXPECT_LT(err, 0.3 * x_axis);
}

TEST(Odometer, BadParametersThrow)
{
  OdometerParams p;
  p.key_span_mm = -1;
  EXPECT_THROW(Odometer{p}, BadSettings);
  p.key_span_mm = p.travel.max_travel_mm + 1;
  try {
    Odometer o(p);
    ADD_FAILURE() << "no exception";
  } catch (const BadSettings &e) {
    EXPECT_NE(std::string(e.what()).find("key_span_mm"), std::string::npos) << e.what();
  }
  p = OdometerParams();
  p.travel.window = 4;
  EXPECT_THROW(Odometer{p}, BadSettings);
}

TEST(EstimateMotion, BadInputAndParametersThrow)
{
  const StereoGeometry *g = nullptr;
  const Frame &prev = frame_of(kVga, 0.5, 2);
  const Frame &cur = frame_of(kVga, 0.5, 3, &g);
  const cv::Mat &pl = prev.view[LEFT], &pr = prev.view[RIGHT], &l = cur.view[LEFT],
                &r = cur.view[RIGHT];
  cv::Mat small, grey, wide;
  cv::resize(l, small, cv::Size(320, 240));
  cv::cvtColor(l, grey, cv::COLOR_BGR2GRAY);
  l.convertTo(wide, CV_16U);
  EXPECT_THROW(estimate_motion(pl, pr, small, r, cur.vegetation, *g), BadInput);
  EXPECT_THROW(estimate_motion(pl, pr, grey, r, cur.vegetation, *g), BadInput);
  EXPECT_THROW(estimate_motion(wide, wide, wide, wide, cur.vegetation, *g), BadInput);
  EXPECT_THROW(estimate_motion(pl, pr, l, r, cur.vegetation, StereoGeometry()), BadInput);

  auto field_named = [&](TravelParams p, const char *field) {
    try {
      estimate_motion(pl, pr, l, r, cur.vegetation, *g, p);
      ADD_FAILURE() << field << ": no exception";
    } catch (const BadSettings &e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  TravelParams p;
  p.max_points = 2;
  field_named(p, "max_points");
  p = TravelParams();
  p.scale = 0;
  field_named(p, "scale");
  p = TravelParams();
  p.window = 14;
  field_named(p, "window");
  p = TravelParams();
  p.levels = -1;
  field_named(p, "levels");
  p = TravelParams();
  p.max_fb_px = 0;
  field_named(p, "max_fb_px");
  p = TravelParams();
  p.max_row_px = -1;
  field_named(p, "max_row_px");
  p = TravelParams();
  p.tol_mm = 0;
  field_named(p, "tol_mm");
  p = TravelParams();
  p.tol_px = std::nan("");
  field_named(p, "tol_px");
  p = TravelParams();
  p.min_inliers = 2;
  field_named(p, "min_inliers");
  p = TravelParams();
  p.ransac_iterations = 0;
  field_named(p, "ransac_iterations");
}

// Time per call on one core at 1296x972 (printed, not asserted: the machine is shared).
TEST(EstimateMotion, TimePerCall)
{
  const StereoGeometry *g = nullptr;
  const Frame &prev = frame_of(kFull, 2.0, 8);
  const Frame &cur = frame_of(kFull, 2.0, 9, &g);
  const int threads = cv::getNumThreads();
  cv::setNumThreads(1);
  std::vector<double> ms;
  for (int i = 0; i < 7; ++i) {
    const std::int64_t t0 = cv::getTickCount();
    const Motion m = estimate_motion(prev.view[LEFT], prev.view[RIGHT], cur.view[LEFT],
                                     cur.view[RIGHT], cur.vegetation, *g);
    ms.push_back(1000.0 * double(cv::getTickCount() - t0) / cv::getTickFrequency());
    EXPECT_TRUE(m.found);
  }
  cv::setNumThreads(threads);
  std::sort(ms.begin(), ms.end());
  std::printf("estimate_motion at 1296x972, one thread: median %.1f ms (min %.1f, max %.1f)\n",
              ms[ms.size() / 2], ms.front(), ms.back());
}
