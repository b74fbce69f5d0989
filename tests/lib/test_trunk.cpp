// find_trunk() on constructed pairs: a crown's mask above, textured ground below it seen at the
// ground's own disparity, and bare bars (trunks, posts, a patch of soil) at chosen depths.

#include "treestereo/canopy.hpp"
#include "treestereo/errors.hpp"
#include "typed_error.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <vector>

using namespace treestereo;

namespace {

constexpr double kCameraHeightMm = 1200; // the ground is the plane y = 1200 (y down)

// A bare bar from column `u0` on, `width` px wide, below the crown, at depth `z_mm`; `textured`
// false: the ground's own texture at the ground's depth (a patch of soil), only not plant.
struct Bar {
  int u0, width;
  double z_mm;
  bool textured = true;
};

struct Pair {
  StereoGeometry g;
  cv::Mat left, right, vegetation, canopy;
  RowSegment segment;
  GroundPlane ground;
};

// 640x480, fx 800 px, baseline 120 mm. The crown: an ellipse over columns 53-587, rows 100-300,
// its segment -600..600 mm with its front at 1800 mm. Below it the ground, plant everywhere but
// on the bars.
Pair make_pair(const std::vector<Bar> &bars)
{
  Pair p;
  p.g.view_size = cv::Size(640, 480);
  p.g.fx = p.g.fy = 800;
  p.g.cx[0] = p.g.cx[1] = 320;
  p.g.cy = 240;
  p.g.baseline_mm = 120;
  const cv::Size size = p.g.view_size;
  cv::RNG rng(7);
  cv::Mat texture(size.height, size.width + 200, CV_8U);
  rng.fill(texture, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(texture, texture, cv::Size(0, 0), 1.2);
  cv::normalize(texture, texture, 30, 220, cv::NORM_MINMAX);
  p.left.create(size, CV_8U);
  p.right.create(size, CV_8U);
  // Rows below the horizon: the ground at its depth; above it, anything at 5 m.
  for (int v = 0; v < size.height; ++v) {
    const double z = v > p.g.cy + 1 ? p.g.fy * kCameraHeightMm / (v - p.g.cy) : 5000.0;
    const int d = int(std::lround(p.g.fx * p.g.baseline_mm / z));
    for (int u = 0; u < size.width; ++u) {
      p.left.at<uchar>(v, u) = texture.at<uchar>(v, u + 100);
      p.right.at<uchar>(v, u) = texture.at<uchar>(v, u + 100 + d);
    }
  }
  p.vegetation = cv::Mat(size, CV_8U, cv::Scalar(255));
  p.canopy = cv::Mat::zeros(size, CV_8U);
  cv::ellipse(p.canopy, cv::Point(320, 200), cv::Size(267, 100), 0, 0, 360, cv::Scalar(255),
              cv::FILLED);
  cv::Mat bark(size, CV_8U);
  rng.fill(bark, cv::RNG::UNIFORM, 0, 255);
  cv::blur(bark, bark, cv::Size(1, 9)); // streaks along the trunk
  cv::normalize(bark, bark, 20, 120, cv::NORM_MINMAX);
  for (const Bar &b : bars) {
    const int d = int(std::lround(p.g.fx * p.g.baseline_mm / b.z_mm));
    for (int v = 301; v < size.height; ++v)
      for (int u = b.u0; u < b.u0 + b.width; ++u) {
        p.vegetation.at<uchar>(v, u) = 0;
        if (b.textured) {
          p.left.at<uchar>(v, u) = bark.at<uchar>(v, u);
          p.right.at<uchar>(v, u - d) = bark.at<uchar>(v, u);
        }
      }
  }
  p.segment.lo_mm = -600;
  p.segment.hi_mm = 600;
  p.segment.near_mm = 1800;
  p.segment.selected = true;
  p.ground.found = true;
  p.ground.normal = cv::Vec3d(0, -1, 0);
  p.ground.d = kCameraHeightMm;
  return p;
}

double trunk(const Pair &p)
{
  return find_trunk(p.left, p.right, p.vegetation, p.canopy, p.segment, p.ground, p.g);
}

// Where a bar's axis stands: its front matched at z_mm, the axis half its width behind.
double axis_x(const Pair &p, const Bar &b)
{
  const double u = b.u0 + 0.5 * (b.width - 1);
  const double z = b.z_mm * (1 + 0.5 * b.width / p.g.fx);
  return (u - p.g.cx[0]) * z / p.g.fx;
}

} // namespace

// A trunk 60 px wide (150 mm at 2 m) under the crown's right half, and a patch of bare soil as
// wide under its left: the trunk's axis, not the soil (which matches at the ground's depth).
TEST(Trunk, TheBareColumnsThatMatchAtTheCrownsDepth)
{
  const Bar bar{400, 60, 2000};
  const Pair p = make_pair({bar, Bar{120, 60, 0, false}});
  const double pixel_mm = bar.z_mm / p.g.fx;
  EXPECT_NEAR(trunk(p), axis_x(p, bar), pixel_mm);
  // Read in the rows from two below the crown's bottom (row 300) two thirds of the way down to
  // the ground under the crown's middle (2400 mm deep: below the view, so its bottom row): rows
  // 302-419, the middle 360.5. Its Y, at the axis' depth, is what places it along a row the view
  // is rolled against.
  double y_mm = 0;
  find_trunk(p.left, p.right, p.vegetation, p.canopy, p.segment, p.ground, p.g, &y_mm);
  const double z_axis = bar.z_mm * (1 + 0.5 * bar.width / p.g.fx);
  EXPECT_NEAR(y_mm, (360.5 - p.g.cy) * z_axis / p.g.fy, z_axis / p.g.fy);
  // Off the crown's side of the view, and with the image's bottom for the ground.
  const Bar left{150, 50, 2400};
  Pair q = make_pair({left});
  q.ground.found = false;
  EXPECT_NEAR(trunk(q), axis_x(q, left), left.z_mm / q.g.fx);
}

// A trunk standing in a strip of bare soil (a path, a herbicide strip): the soil on both sides is
// as bare as the trunk, so every column from the strip's one end to the other is bare. The soil
// lies at the ground's own depth, deeper than the crown, and does not join the trunk's columns.
// Its edges are then where the match holds, not where the colour mask ends: within a pixel and a
// half.
TEST(Trunk, ATrunkInAStripOfBareSoil)
{
  const Bar bar{380, 40, 2000};
  const Pair p = make_pair({Bar{230, 340, 0, false}, bar});
  EXPECT_NEAR(trunk(p), axis_x(p, bar), 1.5 * bar.z_mm / p.g.fx);
  // The strip's soil on one side only, and the trunk at the strip's edge.
  const Bar edge{230, 40, 2300};
  const Pair q = make_pair({Bar{230, 300, 0, false}, edge});
  EXPECT_NEAR(trunk(q), axis_x(q, edge), 1.5 * edge.z_mm / q.g.fx);
}

TEST(Trunk, NoneWhereNoTrunkCanBeTold)
{
  // The next row's trunk (6 m) under the crown: deeper than the crown can be.
  EXPECT_TRUE(std::isnan(trunk(make_pair({Bar{400, 30, 6000}}))));
  // Two trunks (or a trunk and a post) as wide: no telling which.
  EXPECT_TRUE(std::isnan(trunk(make_pair({Bar{200, 50, 2000}, Bar{400, 50, 2000}}))));
  // A bare stretch half the crown across: ground or a wall, no trunk.
  EXPECT_TRUE(std::isnan(trunk(make_pair({Bar{150, 300, 2000}}))));
  // The crown down to the image's bottom: no rows below it.
  Pair low = make_pair({Bar{400, 60, 2000}});
  low.canopy.rowRange(300, 480).setTo(255);
  EXPECT_TRUE(std::isnan(trunk(low)));
  // Nothing of the crown in its columns, or no depth.
  Pair none = make_pair({Bar{400, 60, 2000}});
  none.canopy.setTo(0);
  EXPECT_TRUE(std::isnan(trunk(none)));
  none = make_pair({Bar{400, 60, 2000}});
  none.segment.near_mm = 0;
  EXPECT_TRUE(std::isnan(trunk(none)));
  // A segment of an absurd depth and extent: nothing to tell, and no pixel out of range.
  none.segment.near_mm = 1e-9;
  none.segment.lo_mm = -1e12;
  none.segment.hi_mm = 1e12;
  EXPECT_TRUE(std::isnan(trunk(none)));
}

TEST(Trunk, ErrorsAreTypedAndNameTheProblem)
{
  Pair p = make_pair({});
  p.canopy = cv::Mat::zeros(10, 10, CV_8U);
  expect_typed_error<BadInput>([&] { trunk(p); }, "8-bit masks");
  p = make_pair({});
  p.g.fx = 0;
  expect_typed_error<BadInput>([&] { trunk(p); }, "stereo geometry");
}
