// select_canopy on constructed scenes ray-cast in both views of a rectified rig: spheres of
// leaves (canopies), a green wall behind them, a green ground plane under them. Every surface is
// "vegetation" to colour; the truth of which pixels are the canopy in front is exact.
#include "treestereo/errors.hpp"
#include "treestereo/canopy.hpp"
#include "treestereo/rowtrack.hpp"
#include "typed_error.hpp"
#include "simple_geometry.hpp"

#include "../../lib/core/src/mask_strips.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

using namespace treestereo;

namespace {

struct Sphere {
  cv::Vec3d c;
  double r;
};

// A rectified rig, 640x480, fx 800 px, baseline 60 mm; the scene in the left camera's frame (mm).
struct Scene {
  std::vector<Sphere> spheres;
  double wall_z = 0;     // 0: none
  double ground_y = 0;   // 0: none (the plane y = ground_y, y down)
  // The ground as mown grass: no texture of its own, only a shade that darkens with the
  // distance (so along the view's columns) instead of the leafy texture.
  bool smooth_ground = false;
  StereoGeometry g = simple_geometry(cv::Size(640, 480), 800, 60);

  // First hit along the ray from `o` through normalised (u, v): the object (0..n-1 sphere,
  // -1 wall, -2 ground, -3 nothing) and the point.
  int trace(const cv::Vec3d &o, double u, double v, cv::Vec3d &hit) const
  {
    const cv::Vec3d d(u, v, 1.0);
    double best = std::numeric_limits<double>::infinity();
    int what = -3;
    for (std::size_t i = 0; i < spheres.size(); ++i) {
      const cv::Vec3d oc = o - spheres[i].c;
      const double b = oc.dot(d), a = d.dot(d), c = oc.dot(oc) - spheres[i].r * spheres[i].r;
      const double disc = b * b - a * c;
      if (disc < 0)
        continue;
      const double t = (-b - std::sqrt(disc)) / a;
      if (t > 0 && t < best) {
        best = t;
        what = int(i);
      }
    }
    if (wall_z > 0) {
      const double t = (wall_z - o[2]) / d[2];
      if (t > 0 && t < best) {
        best = t;
        what = -1;
      }
    }
    if (ground_y > 0 && d[1] > 0) {
      const double t = (ground_y - o[1]) / d[1];
      if (t > 0 && t < best) {
        best = t;
        what = -2;
      }
    }
    hit = o + best * d;
    return what;
  }

  // A leafy texture as a function of the 3D point (both views see the same).
  static double texture(const cv::Vec3d &p)
  {
    auto h = [](std::int64_t x, std::int64_t y, std::int64_t z) {
      std::uint64_t k = std::uint64_t(x * 73856093LL ^ y * 19349663LL ^ z * 83492791LL);
      k ^= k >> 33;
      k *= 0xff51afd7ed558ccdULL;
      k ^= k >> 33;
      return double(k % 1000) / 1000.0;
    };
    const double s = 7.0; // mm cells, trilinear
    const double fx = p[0] / s, fy = p[1] / s, fz = p[2] / s;
    const std::int64_t x0 = std::int64_t(std::floor(fx)), y0 = std::int64_t(std::floor(fy)),
                       z0 = std::int64_t(std::floor(fz));
    const double ax = fx - x0, ay = fy - y0, az = fz - z0;
    double v = 0;
    for (int k = 0; k < 8; ++k) {
      const int i = k & 1, j = (k >> 1) & 1, l = k >> 2;
      v += (i ? ax : 1 - ax) * (j ? ay : 1 - ay) * (l ? az : 1 - az) * h(x0 + i, y0 + j, z0 + l);
    }
    return 30 + 190 * v;
  }

  // Left and right grey views, the left view's object map and 3D points.
  void render(cv::Mat &left, cv::Mat &right, cv::Mat &objects, cv::Mat &points) const
  {
    const cv::Size s = g.view_size;
    left.create(s, CV_8U);
    right.create(s, CV_8U);
    objects.create(s, CV_32S);
    points.create(s, CV_64FC3);
    for (int view = 0; view < 2; ++view) {
      const cv::Vec3d o(view == 0 ? 0 : g.baseline_mm, 0, 0);
      for (int y = 0; y < s.height; ++y)
        for (int x = 0; x < s.width; ++x) {
          cv::Vec3d hit;
          const int what = trace(o, (x - g.cx[view]) / g.fx, (y - g.cy) / g.fy, hit);
          // (the sky's hit lies at infinity: no texture there)
          const double v_hit = what == -3                       ? 250
                               : what == -2 && smooth_ground ? 60 + 120 * std::exp(-hit[2] / 5000.0)
                                                             : texture(hit);
          const uchar v = cv::saturate_cast<uchar>(v_hit);
          (view == 0 ? left : right).at<uchar>(y, x) = v;
          if (view == 0) {
            objects.at<int>(y, x) = what;
            points.at<cv::Vec3d>(y, x) = hit;
          }
        }
    }
  }
};

// Grid samples of the left view (every `step` px) with their exact 3D points.
std::vector<PixelPoint> grid_points(const cv::Mat &objects, const cv::Mat &points, int step)
{
  std::vector<PixelPoint> out;
  for (int y = step / 2; y < objects.rows; y += step)
    for (int x = step / 2; x < objects.cols; x += step) {
      if (objects.at<int>(y, x) == -3)
        continue;
      const cv::Vec3d p = points.at<cv::Vec3d>(y, x);
      PixelPoint q;
      q.px = cv::Point2f(float(x), float(y));
      q.p.x = float(p[0]);
      q.p.y = float(p[1]);
      q.p.z = float(p[2]);
      out.push_back(q);
    }
  return out;
}

double iou(const cv::Mat &a, const cv::Mat &b)
{
  cv::Mat i, u;
  cv::bitwise_and(a, b, i);
  cv::bitwise_or(a, b, u);
  return double(cv::countNonZero(i)) / std::max(1, cv::countNonZero(u));
}

cv::Mat object_mask(const cv::Mat &objects, int which)
{
  cv::Mat m;
  cv::compare(objects, which, m, cv::CMP_EQ);
  return m;
}

struct Rendered {
  cv::Mat left, right, objects, points, vegetation;
};

Rendered render(const Scene &s)
{
  Rendered r;
  s.render(r.left, r.right, r.objects, r.points);
  cv::compare(r.objects, -3, r.vegetation, cv::CMP_NE); // everything but the sky is green
  return r;
}

} // namespace

TEST(Canopy, GreenWallTwoMetresBehind)
{
  Scene s;
  s.spheres.push_back({cv::Vec3d(0, 0, 2000), 350});
  s.wall_z = 4000;
  const Rendered r = render(s);
  const cv::Mat truth = object_mask(r.objects, 0);
  const auto pts = grid_points(r.objects, r.points, 8);

  // Colour alone: the whole view.
  EXPECT_LT(iou(r.vegetation, truth), 0.5);

  CanopyParams p;
  const CanopyResult nearest = select_canopy(r.vegetation, pts, s.g, p); // no seam test
  ASSERT_TRUE(nearest.present);
  EXPECT_GT(iou(nearest.silhouette.mask, truth), 0.95);
  EXPECT_LT(nearest.near_mm, 1650);
  EXPECT_GT(nearest.far_mm, 2000);
  EXPECT_LT(nearest.far_mm, 4000);
  EXPECT_TRUE(nearest.zone_from_data);

  const CanopyResult seam = select_canopy(r.vegetation, pts, s.g, p, r.left, r.right);
  ASSERT_TRUE(seam.present);
  EXPECT_GT(seam.n_seam_pixels, 0u);
  EXPECT_GT(iou(seam.silhouette.mask, truth), 0.975);
  EXPECT_GT(iou(seam.silhouette.mask, truth), iou(nearest.silhouette.mask, truth));
  // The silhouette's box within 2 px of the truth's.
  const cv::Rect tb = cv::boundingRect(truth), sb = seam.silhouette.bbox;
  EXPECT_LE(std::abs(tb.x - sb.x), 2);
  EXPECT_LE(std::abs(tb.br().x - sb.br().x), 2);
  EXPECT_LE(std::abs(tb.y - sb.y), 2);
  EXPECT_LE(std::abs(tb.br().y - sb.br().y), 2);
  // Every point is classified: the sphere's as canopy, the wall's as behind.
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const int obj = r.objects.at<int>(cv::Point(pts[i].px));
    EXPECT_EQ(seam.classes[i], obj == 0 ? PointClass::Canopy : PointClass::Behind) << i;
  }

  // The user's spray zone instead of the data's.
  p.near_mm = 1000;
  p.far_mm = 3000;
  const CanopyResult zone = select_canopy(r.vegetation, pts, s.g, p);
  EXPECT_FALSE(zone.zone_from_data);
  EXPECT_GT(iou(zone.silhouette.mask, truth), 0.95);
  p.near_mm = 2500; // a zone with nothing in it: no canopy, said so
  p.far_mm = 3500;
  EXPECT_FALSE(select_canopy(r.vegetation, pts, s.g, p).present);
}

TEST(Canopy, ALeafClusterPeekingOutBehindTheFrontOneIsCanopy)
{
  // A crown of three clusters before a wall 4.5 m away: the front one (1.65 m at its front), and
  // two 0.5 m behind it, one out to the left and one peeking out on the right by a sliver. Seen
  // from the side, that sliver is where the crown reaches farthest. No sample lies on it (it is
  // a few samples' spacing wide, and matches are sparse there): its nearest canopy sample is
  // the front cluster's, whose disparity misses it by 4 px and more; the wall's by about 9.
  Scene s;
  s.wall_z = 4500;
  s.spheres.push_back({cv::Vec3d(0, 0, 2000), 350});
  s.spheres.push_back({cv::Vec3d(172, 40, 2450), 300});
  s.spheres.push_back({cv::Vec3d(-420, -60, 2450), 300});
  const Rendered r = render(s);
  const cv::Mat sliver = object_mask(r.objects, 1);
  std::vector<PixelPoint> pts;
  for (const PixelPoint &q : grid_points(r.objects, r.points, 8))
    if (r.objects.at<int>(cv::Point(q.px)) != 1)
      pts.push_back(q);
  const int n_sliver = cv::countNonZero(sliver);
  ASSERT_GT(n_sliver, 800);
  // The sliver's widest row is at least two sample spacings wide.
  int widest = 0;
  for (int y = 0; y < sliver.rows; ++y)
    widest = std::max(widest, cv::countNonZero(sliver.row(y)));
  ASSERT_GE(widest, 16);

  CanopyParams p;
  const CanopyResult c = select_canopy(r.vegetation, pts, s.g, p, r.left, r.right);
  ASSERT_TRUE(c.present);
  // Most of the sliver is taken (not its outer rim, where the seam test's windows reach over
  // the wall), and the wall stays out.
  EXPECT_GT(cv::countNonZero(c.silhouette.mask & sliver), 0.55 * n_sliver);
  const cv::Mat wall = object_mask(r.objects, -1);
  cv::Mat crown = ~wall & r.vegetation, beside;
  cv::dilate(crown, beside, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(7, 7)));
  EXPECT_LT(cv::countNonZero(c.silhouette.mask & wall & ~beside), 0.002 * cv::countNonZero(crown));
  // The crown's right edge within 5 px of the truth's (16 px short without the sliver).
  EXPECT_LE(std::abs(cv::boundingRect(crown).br().x - c.silhouette.bbox.br().x), 5);
}

TEST(Canopy, AFewSamplesOnADeepClusterBelowTheCrownAreCanopy)
{
  // A crown (1.65 m at its front, its limbs about 1.94 m) before a wall 4.5 m away, and a leaf
  // cluster 0.4 m deeper, low near the trunk, that reaches below the crown's outline. Its
  // surface gives a few samples only (dark leaves: every third grid point matched), too few to
  // make a layer of their own in the depth histogram. They lie in the empty stretch between the
  // crown and the wall, much nearer the crown: they are the crown's, and so is the cluster.
  Scene s;
  s.wall_z = 4500;
  s.spheres.push_back({cv::Vec3d(0, 0, 2000), 350});
  s.spheres.push_back({cv::Vec3d(0, 330, 2150), 90});
  const Rendered r = render(s);
  const cv::Mat deep = object_mask(r.objects, 1), crown = deep | object_mask(r.objects, 0);
  std::vector<PixelPoint> pts;
  std::vector<std::size_t> on_deep;
  int k = 0;
  for (const PixelPoint &q : grid_points(r.objects, r.points, 8)) {
    if (r.objects.at<int>(cv::Point(q.px)) == 1) {
      if (k++ % 3)
        continue;
      on_deep.push_back(pts.size());
    }
    pts.push_back(q);
  }
  ASSERT_GE(on_deep.size(), 2u);
  // The cluster reaches below the crown's outline by more than a sample spacing.
  const cv::Rect whole = cv::boundingRect(crown), front = cv::boundingRect(object_mask(r.objects, 0));
  ASSERT_GT(whole.br().y - front.br().y, 10);

  const CanopyResult c = select_canopy(r.vegetation, pts, s.g, CanopyParams{}, r.left, r.right);
  ASSERT_TRUE(c.present);
  for (std::size_t i : on_deep)
    EXPECT_EQ(c.classes[i], PointClass::Canopy) << pts[i].p.z;
  EXPECT_LT(c.far_mm, 4000);
  // The canopy reaches the cluster's bottom, and the wall stays out.
  EXPECT_LE(std::abs(whole.br().y - c.silhouette.bbox.br().y), 2);
  EXPECT_GT(cv::countNonZero(c.silhouette.mask & deep), 0.8 * cv::countNonZero(deep));
  EXPECT_GT(iou(c.silhouette.mask, crown), 0.97);
}

TEST(Canopy, StandingOnAGreenGroundPlane)
{
  Scene s;
  // Camera 0.7 m above the grass, which is in view from 2.3 m on; a crown of 0.6 m at 2.4 m
  // whose bottom is 0.4 m above the grass.
  s.ground_y = 700;
  s.spheres.push_back({cv::Vec3d(0, 0, 2400), 300});
  const Rendered r = render(s);
  const cv::Mat truth = object_mask(r.objects, 0);
  const auto pts = grid_points(r.objects, r.points, 8);
  ASSERT_GT(cv::countNonZero(object_mask(r.objects, -2)), 10000); // the grass is in view

  CanopyParams p;
  const CanopyResult c = select_canopy(r.vegetation, pts, s.g, p, r.left, r.right);
  ASSERT_TRUE(c.present);
  ASSERT_TRUE(c.ground.found);
  EXPECT_NEAR(c.ground.normal[1], -1.0, 1e-3);
  EXPECT_NEAR(c.ground.d, 700, 5); // height of the camera above the plane
  EXPECT_GT(iou(c.silhouette.mask, truth), 0.97);
  std::size_t grass = 0, grass_as_ground = 0;
  for (std::size_t i = 0; i < pts.size(); ++i)
    if (r.objects.at<int>(cv::Point(pts[i].px)) == -2) {
      ++grass;
      grass_as_ground += c.classes[i] == PointClass::Ground || c.classes[i] == PointClass::Behind;
    }
  EXPECT_EQ(grass_as_ground, grass);

  // The rig's height instead of a fit gives the same.
  p.ground = GroundModel::Rig;
  p.camera_height_mm = 700;
  const CanopyResult rig = select_canopy(r.vegetation, pts, s.g, p, r.left, r.right);
  EXPECT_GT(iou(rig.silhouette.mask, truth), 0.97);

  // Without the ground the grass at the crown's depth is taken for canopy.
  p.ground = GroundModel::Off;
  const CanopyResult off = select_canopy(r.vegetation, pts, s.g, p, r.left, r.right);
  EXPECT_LT(iou(off.silhouette.mask, truth), 0.9);
}

TEST(Canopy, GrassWithoutTextureIsNotTakenWithTheCrown)
{
  // The crown stands in the grass's colour region, and the grass gives no sample at all (mown
  // grass without texture: no match). The crown's samples must not speak for the lawn around
  // it. A second crown runs off the left border, into the strip the right camera does not see:
  // no sample can lie there, and the samples beside it speak for it.
  Scene s;
  s.ground_y = 700;
  s.spheres.push_back({cv::Vec3d(0, 0, 2400), 300});
  s.spheres.push_back({cv::Vec3d(-900, 0, 2400), 300});
  const Rendered r = render(s);
  const cv::Mat crown = object_mask(r.objects, 0), cut = object_mask(r.objects, 1);
  const double strip = s.g.fx * s.g.baseline_mm / 2100.0; // disparity of the crowns' front
  std::vector<PixelPoint> pts;
  for (const PixelPoint &q : grid_points(r.objects, r.points, 8)) {
    const int obj = r.objects.at<int>(cv::Point(q.px));
    if (obj >= 0 && q.px.x >= strip)
      pts.push_back(q);
  }
  ASSERT_GT(cv::countNonZero(cut(cv::Rect(0, 0, int(strip), 480))), 500);

  CanopyParams p;
  p.mode = CanopyMode::Row;
  const CanopyResult c = select_canopy(r.vegetation, pts, s.g, p, r.left, r.right);
  ASSERT_TRUE(c.present);
  EXPECT_FALSE(c.ground.found); // nothing to fit it to
  const cv::Mat both = crown | cut;
  EXPECT_GT(iou(c.silhouette.mask, both), 0.93);
  // Hardly any lawn farther than two sample spacings (16 px) from a crown (where the lawn
  // borders a crown at the crown's depth, a crown's sample may speak for it; slivers remain
  // along the horizon). Taken whole, the region would bring all of it.
  cv::Mat near_crown;
  cv::dilate(both, near_crown, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(33, 33)));
  const cv::Mat far_lawn = object_mask(r.objects, -2) & ~near_crown;
  ASSERT_GT(cv::countNonZero(far_lawn), 50000);
  EXPECT_LT(cv::countNonZero(c.silhouette.mask & far_lawn), 0.01 * cv::countNonZero(far_lawn));
  // The crown in the one-view strip is kept.
  const cv::Rect sr(0, 0, int(strip), 480);
  EXPECT_GT(cv::countNonZero(c.silhouette.mask(sr) & cut(sr)), 0.9 * cv::countNonZero(cut(sr)));
}

TEST(Canopy, TheGrassTheRightCameraCannotSeeBesideTheCrownIsNotCanopy)
{
  // A crown 0.5 m above mown grass, the camera 0.95 m over it (the drive-by rig's height). The
  // grass's shade changes only down the view, so along a row it correlates with itself at any
  // disparity. Beside the crown's left limb lies a strip of grass (the disparities' difference
  // wide, 15-21 px here) that the right camera does not see: it shows the crown there. At the
  // crown's disparity the strip finds more grass a strip further on, and took the crown's side.
  // The grass gives samples only away from the crown (a few matched grass blades), as in the
  // chain.
  Scene s;
  s.ground_y = 950;
  s.smooth_ground = true;
  s.spheres.push_back({cv::Vec3d(0, 150, 2000), 300});
  const Rendered r = render(s);
  const cv::Mat crown = object_mask(r.objects, 0), grass = object_mask(r.objects, -2);
  cv::Mat near_crown;
  cv::dilate(crown, near_crown, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(81, 81)));
  std::vector<PixelPoint> pts;
  for (const PixelPoint &q : grid_points(r.objects, r.points, 8)) {
    const cv::Point px(q.px);
    const int obj = r.objects.at<int>(px);
    if (obj == 0 || (obj == -2 && !near_crown.at<uchar>(px) && px.x % 24 == 4 && px.y % 24 == 4))
      pts.push_back(q);
  }

  CanopyParams p;
  const CanopyResult c = select_canopy(r.vegetation, pts, s.g, p, r.left, r.right);
  ASSERT_TRUE(c.present);
  ASSERT_TRUE(c.ground.found);
  EXPECT_NEAR(c.ground.d, 950, 20);
  // On the rows where the crown's left limb stands against the grass and runs steeply (within
  // 0.7 of the radius of the crown's middle row), the canopy's leftmost pixel within 6 px of the
  // crown's (the seam test's window reaches 3 px across the edge, and more along the horizon,
  // where the grass's shade is flat), and the leftmost of all, which sets the crown's width,
  // within 3 px.
  const int mid = int(std::lround(s.g.cy + s.g.fy * 150 / 2000));
  const int radius = int(s.g.fy * 300 / 2000);
  int rows = 0, worst = 0, left_truth = r.objects.cols, left_mask = r.objects.cols;
  for (int y = mid - 7 * radius / 10; y <= mid + 7 * radius / 10; ++y) {
    const uchar *t = crown.ptr<uchar>(y), *m = c.silhouette.mask.ptr<uchar>(y);
    int xt = -1, xm = -1;
    for (int x = 0; x < r.objects.cols && (xt < 0 || xm < 0); ++x) {
      if (xt < 0 && t[x])
        xt = x;
      if (xm < 0 && m[x])
        xm = x;
    }
    if (xt < 20 || !grass.at<uchar>(y, xt - 20))
      continue;
    ++rows;
    worst = std::max(worst, xt - (xm < 0 ? xt : xm));
    left_truth = std::min(left_truth, xt);
    left_mask = std::min(left_mask, xm < 0 ? xt : xm);
  }
  ASSERT_GT(rows, 100);
  EXPECT_LE(worst, 6);
  EXPECT_LE(left_truth - left_mask, 3);
  // Hardly any grass more than 4 px from the crown is taken.
  cv::Mat beside;
  cv::dilate(crown, beside, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(9, 9)));
  const cv::Mat grass_taken = c.silhouette.mask & grass & ~beside;
  EXPECT_LT(cv::countNonZero(grass_taken), 0.002 * cv::countNonZero(crown));
  EXPECT_GT(iou(c.silhouette.mask, crown), 0.96);
}

// The split's last step (lib/core/src/mask_strips.hpp): a crown's disc with, out of its left
// limb, a strip 7 px tall running 35 px out (the grass's top rows where the grass meets the
// wall behind), out of its right limb a leaf 3 px out and 6 px tall, and a trunk 4 px wide
// under it. Only the strip goes, all but its first 3 px.
TEST(Canopy, AThinStripRunningOutOfTheCrownIsCutOff)
{
  cv::Mat mask(240, 320, CV_8U, cv::Scalar(0));
  cv::circle(mask, cv::Point(160, 100), 60, cv::Scalar(255), cv::FILLED);
  const cv::Mat crown = mask.clone();
  const cv::Rect strip(65, 110, 40, 7); // on into the limb
  const cv::Rect leaf(219, 97, 4, 6);   // to x = 222, the disc's edge at 220
  const cv::Rect trunk(158, 150, 4, 60);
  for (const cv::Rect &r : {strip, leaf, trunk})
    cv::rectangle(mask, r, cv::Scalar(255), cv::FILLED);
  const cv::Mat before = mask.clone();
  ASSERT_EQ(cv::boundingRect(mask).x, 65);

  detail::cut_thin_strips(mask, 11, 3);
  EXPECT_EQ(cv::countNonZero(crown & ~mask), 0); // the crown whole
  EXPECT_EQ(cv::countNonZero(before(leaf) & ~mask(leaf)), 0);
  EXPECT_EQ(cv::countNonZero(before(trunk) & ~mask(trunk)), 0);
  const cv::Rect box = cv::boundingRect(mask);
  // The limb at y 110-116 lies at x 160 - sqrt(60^2 - 16^2) = 102.2 at most: the strip keeps 3 px
  // out of it, the disc reaches x = 100.
  EXPECT_GE(box.x, 98);
  EXPECT_LE(box.x, 100);
  EXPECT_EQ(box.br().x, 223); // the leaf
  EXPECT_EQ(cv::countNonZero(mask(cv::Rect(65, 110, 30, 7))), 0);
}

TEST(Canopy, TwoCanopiesThirtyCentimetresApart)
{
  Scene s;
  s.spheres.push_back({cv::Vec3d(-100, 0, 2200), 330});
  s.spheres.push_back({cv::Vec3d(-100 + 330 + 300 + 330, 0, 2200), 330}); // gap 0.3 m
  s.spheres.push_back({cv::Vec3d(-100 - 330 - 300 - 330, 0, 2200), 330});
  s.wall_z = 5500;
  const Rendered r = render(s);
  const auto pts = grid_points(r.objects, r.points, 8);
  const cv::Mat truth = object_mask(r.objects, 0);
  cv::Mat row = truth | object_mask(r.objects, 1) | object_mask(r.objects, 2);

  CanopyParams p;
  const CanopyResult tree = select_canopy(r.vegetation, pts, s.g, p, r.left, r.right);
  ASSERT_TRUE(tree.present);
  EXPECT_EQ(tree.n_segments, 3);
  EXPECT_GT(iou(tree.silhouette.mask, truth), 0.98);
  EXPECT_NEAR(tree.left_mm, -100 - 330, 25);
  EXPECT_NEAR(tree.right_mm, -100 + 330, 25);
  // The segments along the row, left to right; the middle one is the tree in front.
  ASSERT_EQ(tree.segments.size(), 3u);
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(tree.segments[k].selected, k == 1);
    EXPECT_GT(tree.segments[k].n_points, 0u);
    if (k > 0) {
      EXPECT_GT(tree.segments[k].lo_mm - tree.segments[k - 1].hi_mm, 250);
    }
  }
  EXPECT_NEAR(tree.segments[1].lo_mm, tree.left_mm, 1e-9);
  EXPECT_NEAR(tree.segments[1].hi_mm, tree.right_mm, 1e-9);
  EXPECT_NEAR(tree.segments[1].near_mm, 2200 - 330, 40);
  EXPECT_NEAR(tree.segments[2].lo_mm, -100 + 330 + 300, 25);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const int obj = r.objects.at<int>(cv::Point(pts[i].px));
    if (obj == 1 || obj == 2) {
      EXPECT_EQ(tree.classes[i], PointClass::Neighbour);
    }
  }

  p.mode = CanopyMode::Row;
  const CanopyResult wall = select_canopy(r.vegetation, pts, s.g, p, r.left, r.right);
  ASSERT_TRUE(wall.present);
  EXPECT_GT(iou(wall.silhouette.mask, row), 0.97);
  ASSERT_EQ(wall.segments.size(), 3u);
  for (const auto &seg : wall.segments) {
    EXPECT_TRUE(seg.selected);
  }
}

// How far inside the stereo view's edges a segment's points keep. The points are the exact grid
// of the left view, less those within kReach px of the right view's left border (as stereo
// points stop there: the right view's black border after rectification, the match's patch).
//  - A crown wholly in view: its clearance is the sphere's, the least x - (s z + o) over it
//    (edge ray x = s z + o), cx - s cz - o - r sqrt(1 + s^2), and likewise on the right.
//  - A crown the left edge cuts: its points stop kReach px inside the right view, whose edge
//    ray is the view's; the front ones come nearest, and its clearance is (kReach + 0.5) px at
//    the front's depth. Its extreme point lies deeper, further out on the ray: tested alone, it
//    would seem clear of the edge by more.
TEST(Canopy, SegmentsKnowHowFarInsideTheViewTheirPointsKeep)
{
  Scene s;
  s.spheres.push_back({cv::Vec3d(-700, 0, 2200), 330}); // x -1030..-370, the edge at -821
  s.spheres.push_back({cv::Vec3d(150, 0, 2200), 300});  // x -150..450
  s.wall_z = 5500;
  const Rendered r = render(s);
  constexpr double kReach = 16;
  std::vector<PixelPoint> pts;
  for (const PixelPoint &q : grid_points(r.objects, r.points, 4)) {
    const double xr = q.px.x - s.g.fx * s.g.baseline_mm / q.p.z;
    if (xr >= kReach)
      pts.push_back(q);
  }
  const CanopyResult res = select_canopy(r.vegetation, pts, s.g, CanopyParams(), r.left, r.right);
  ASSERT_EQ(res.segments.size(), 2u);
  double ls = 0, rs = 0, lo_off = 0;
  view_slopes(s.g, ls, rs, lo_off);
  const RowSegment &cut = res.segments[0], &whole = res.segments[1];

  const double spacing = 4 * 2200 / s.g.fx; // the grid's, at the crowns' depth (11 mm)
  const Sphere &b = s.spheres[1];
  EXPECT_NEAR(whole.lo_clear_mm,
              b.c[0] - ls * b.c[2] - lo_off - b.r * std::sqrt(1 + ls * ls), spacing);
  EXPECT_NEAR(whole.hi_clear_mm, rs * b.c[2] - b.c[0] - b.r * std::sqrt(1 + rs * rs), spacing);

  // The cut crown's front (the sphere's front at the edge ray lies near z = 1.95 m).
  EXPECT_NEAR(cut.lo_clear_mm, (kReach + 0.5) * cut.near_mm / s.g.fx, spacing);
  EXPECT_LT(cut.lo_clear_mm + 5, cut.lo_mm - (ls * cut.lo_z_mm + lo_off));
  // Its right end, far inside the view.
  EXPECT_GT(cut.hi_clear_mm, 500);
}

// Two round crowns grown 40 mm into each other: no gap along the row, but a notch in their top
// line where they meet. In mode Tree they are two trees, cut at the notch; one crown of two
// lobes (260 mm into each other) has a shallow notch and stays one.
TEST(Canopy, TouchingCrownsAreCutWhereTheirTopLineDips)
{
  Scene s;
  s.spheres.push_back({cv::Vec3d(-150, 0, 2200), 330});             // in front: x -480..180
  s.spheres.push_back({cv::Vec3d(-150 + 660 - 40, 0, 2200), 330});  // x 140..800
  s.wall_z = 5500;
  const Rendered r = render(s);
  const auto pts = grid_points(r.objects, r.points, 8);
  const cv::Mat front = object_mask(r.objects, 0);

  CanopyParams p;
  const CanopyResult tree = select_canopy(r.vegetation, pts, s.g, p, r.left, r.right);
  ASSERT_TRUE(tree.present);
  ASSERT_EQ(tree.n_segments, 2);
  ASSERT_EQ(tree.segments.size(), 2u);
  EXPECT_TRUE(tree.segments[0].selected);
  EXPECT_FALSE(tree.segments[1].selected);
  // The cut falls where the crowns meet (x = 160), within a bin and the points' spacing.
  EXPECT_NEAR(tree.segments[0].hi_mm, 160, 40);
  EXPECT_NEAR(tree.segments[1].lo_mm, 160, 40);
  EXPECT_NEAR(tree.left_mm, -480, 40);
  EXPECT_NEAR(tree.right_mm, 160, 40);
  EXPECT_GT(iou(tree.silhouette.mask, front), 0.9);

  // Off, or mode Row: one stretch of canopy.
  CanopyParams off = p;
  off.valley_share = 0;
  EXPECT_EQ(select_canopy(r.vegetation, pts, s.g, off, r.left, r.right).n_segments, 1);
  CanopyParams row = p;
  row.mode = CanopyMode::Row;
  EXPECT_EQ(select_canopy(r.vegetation, pts, s.g, row, r.left, r.right).n_segments, 1);

  // A low crown grown into a taller one (their bottoms level): the top line is lowest on the
  // low crown's shoulder; the cut still falls where they meet (x 90..130).
  Scene uneven;
  uneven.spheres.push_back({cv::Vec3d(-150, 50, 2200), 280});  // x -430..130
  uneven.spheres.push_back({cv::Vec3d(440, -20, 2200), 350});  // x 90..790
  uneven.wall_z = 5500;
  const Rendered ru = render(uneven);
  const auto upts = grid_points(ru.objects, ru.points, 8);
  const CanopyResult two = select_canopy(ru.vegetation, upts, uneven.g, p, ru.left, ru.right);
  ASSERT_EQ(two.segments.size(), 2u);
  EXPECT_TRUE(two.segments[0].joined_hi);
  EXPECT_TRUE(two.segments[1].joined_lo);
  EXPECT_FALSE(two.segments[0].joined_lo);
  EXPECT_NEAR(two.segments[0].hi_mm, 110, 40);
  EXPECT_NEAR(two.segments[1].lo_mm, 110, 40);
  // The outer ends' depths are their limbs', near the spheres' centres (2.2 m), well behind
  // the crowns' fronts (1.92 and 1.85 m).
  EXPECT_GT(two.segments[0].lo_z_mm, two.segments[0].near_mm + 100);
  EXPECT_LT(two.segments[0].lo_z_mm, 2250);
  EXPECT_GT(two.segments[1].hi_z_mm, two.segments[1].near_mm + 100);
  EXPECT_LT(two.segments[1].hi_z_mm, 2250);

  // One crown of two lobes: its top line dips by about a tenth of its height.
  Scene lobes;
  lobes.spheres.push_back({cv::Vec3d(-200, 0, 2200), 330});
  lobes.spheres.push_back({cv::Vec3d(200, 0, 2200), 330});
  lobes.wall_z = 5500;
  const Rendered rl = render(lobes);
  const auto lpts = grid_points(rl.objects, rl.points, 8);
  const CanopyResult one = select_canopy(rl.vegetation, lpts, lobes.g, p, rl.left, rl.right);
  ASSERT_TRUE(one.present);
  EXPECT_EQ(one.n_segments, 1);
  EXPECT_NEAR(one.left_mm, -530, 25);
  EXPECT_NEAR(one.right_mm, 530, 25);

  CanopyParams bad;
  bad.valley_share = 1;
  EXPECT_THROW(validate(bad), BadSettings);
  bad = CanopyParams();
  bad.min_crown_mm = -1;
  EXPECT_THROW(validate(bad), BadSettings);
}

// Points of a plane through the rig's view, as select_canopy takes them: x across, z in depth,
// y from the plane (y down), each at its left pixel.
std::vector<PixelPoint> plane_points(const StereoGeometry &g, double x0, double x1, double z0,
                                     double z1, int n, const std::function<double(double, double)> &y)
{
  std::vector<PixelPoint> out;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double x = x0 + (x1 - x0) * i / (n - 1), z = z0 + (z1 - z0) * j / (n - 1);
      PixelPoint q;
      q.p = Point3{float(x), float(y(x, z)), float(z), true};
      q.px = cv::Point2f(float(g.fx * x / z + g.cx[0]), float(g.fy * q.p.y / z + g.cy));
      if (q.px.x >= 0 && q.px.y >= 0 && q.px.x < g.view_size.width && q.px.y < g.view_size.height)
        out.push_back(q);
    }
  return out;
}

TEST(Canopy, TheGroundStaysNearTheFramesBefore)
{
  // A slope of leaves (the underside of crowns, a bank of the next row) tilted 15 degrees, and
  // no grass in view: a plane the fit takes for the ground when nothing says where the ground
  // was. With the ground of the frames before as the prior (the grass 0.7 m below the camera),
  // the slope is refused and the prior held.
  Scene s;
  const cv::Mat all(s.g.view_size, CV_8U, cv::Scalar(255));
  const double tilt = std::tan(15 * 3.14159265358979 / 180);
  const auto slope = plane_points(s.g, -1000, 1000, 1400, 3000, 30,
                                  [&](double, double z) { return 150 - tilt * (z - 2000); });
  CanopyParams p;
  const CanopyResult free_fit = select_canopy(all, slope, s.g, p);
  ASSERT_TRUE(free_fit.ground.found);
  EXPECT_FALSE(free_fit.ground.held);
  EXPECT_LT(free_fit.ground.normal[1], -0.95); // taken, though 15 degrees off level
  EXPECT_GT(std::abs(free_fit.ground.normal[2]), 0.2);

  GroundPlane grass;
  grass.found = true;
  grass.normal = cv::Vec3d(0, -1, 0);
  grass.d = 700;
  p.ground_prior = grass;
  const CanopyResult held = select_canopy(all, slope, s.g, p);
  ASSERT_TRUE(held.ground.found);
  EXPECT_TRUE(held.ground.held);
  EXPECT_EQ(held.ground.inliers, 0u);
  EXPECT_NEAR(held.ground.d, 700, 1e-9);
  EXPECT_NEAR(held.ground.normal[1], -1, 1e-9);

  // The grass in view, 20 mm lower than the prior (the rig bounced): this frame's own plane.
  auto both = slope;
  const auto lawn = plane_points(s.g, -1500, 1500, 1500, 4000, 16,
                                 [](double, double) { return 720.0; });
  both.insert(both.end(), lawn.begin(), lawn.end());
  const CanopyResult fitted = select_canopy(all, both, s.g, p);
  ASSERT_TRUE(fitted.ground.found);
  EXPECT_FALSE(fitted.ground.held);
  EXPECT_NEAR(fitted.ground.d, 720, 3);
  EXPECT_NEAR(fitted.ground.normal[1], -1, 1e-3);
}

TEST(Canopy, GroundTrackerHoldsThePriorForAWhile)
{
  GroundTracker t(3);
  EXPECT_FALSE(t.prior().found);
  GroundPlane g;
  g.found = true;
  g.d = 950;
  t.update(g);
  ASSERT_TRUE(t.prior().found);
  EXPECT_EQ(t.prior().d, 950);
  GroundPlane held = g;
  held.held = true;
  held.d = 0; // a held plane never becomes the prior
  for (int i = 0; i < 3; ++i) {
    t.update(i == 1 ? GroundPlane() : held); // held, or none at all
    ASSERT_TRUE(t.prior().found) << i;
    EXPECT_EQ(t.prior().d, 950);
  }
  t.update(held); // the fourth frame in a row without a plane of its own: the prior goes
  EXPECT_FALSE(t.prior().found);
  t.update(g);
  EXPECT_TRUE(t.prior().found);
  t.reset();
  EXPECT_FALSE(t.prior().found);
}

TEST(Canopy, NothingToDecide)
{
  Scene s;
  const StereoGeometry g = s.g;
  const cv::Mat veg(g.view_size, CV_8U, cv::Scalar(0));
  const CanopyResult r = select_canopy(veg, {}, g, CanopyParams());
  EXPECT_FALSE(r.present);
  EXPECT_EQ(cv::countNonZero(r.silhouette.mask), 0);
  CanopyParams bad;
  bad.far_mm = 100;
  bad.near_mm = 200;
  EXPECT_THROW(select_canopy(veg, {}, g, bad), BadSettings);
  EXPECT_THROW(select_canopy(cv::Mat(10, 10, CV_8U), {}, g, CanopyParams()), BadInput);
}

TEST(Canopy, ErrorsAreTypedAndNameTheProblem)
{
  expect_typed_error<BadSettings>([] { canopy_mode_from_name("hedge"); }, "'hedge'");
  CanopyParams bad;
  bad.min_crown_mm = -1;
  expect_typed_error<BadSettings>([&] { validate(bad); }, "min_crown_mm");
  Scene s;
  expect_typed_error<BadInput>(
      [&] { select_canopy(cv::Mat(10, 10, CV_8U), {}, s.g, CanopyParams()); }, "vegetation mask");
  expect_typed_error<BadInput>([] { depth_support(cv::Mat(10, 10, CV_32F), {}, 3); }, "8-bit");
}

TEST(Canopy, DepthSupport)
{
  cv::Mat mask(100, 100, CV_8U, cv::Scalar(0));
  mask(cv::Rect(0, 0, 100, 50)).setTo(255);
  EXPECT_EQ(depth_support(mask, {}, 5), 0.0);
  std::vector<cv::Point2f> px;
  for (int y = 0; y < 50; y += 4)
    for (int x = 0; x < 50; x += 4)
      px.emplace_back(float(x), float(y));
  EXPECT_NEAR(depth_support(mask, px, 3), 0.5, 0.03);
  EXPECT_EQ(depth_support(cv::Mat(10, 10, CV_8U, cv::Scalar(0)), px, 3), 0.0);
}
