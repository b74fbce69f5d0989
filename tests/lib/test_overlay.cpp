// Overlay drawing: every layer lands where its item is, in the item's colour, in any channel
// order, and nothing is drawn elsewhere.
#include "treestereo/overlay.hpp"
#include "simple_geometry.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>

using namespace treestereo;

namespace {

constexpr int W = 320, H = 240; // one view
const cv::Vec3b kBackground(40, 90, 60);

cv::Mat background(int views, int channels = 3)
{
  cv::Mat m(H, W * views, CV_8UC(channels), cv::Scalar(40, 90, 60, 200));
  return m;
}

// The colour of pixel (x, y) as RGB, read through the channel order.
Rgb rgb_at(const cv::Mat &img, const ChannelOrder &o, int x, int y)
{
  const uchar *px = img.ptr<uchar>(y) + x * o.channels;
  return {px[o.r], px[o.g], px[o.b]};
}

// A square contour around (cx, cy) of half side r, every pixel of its outline listed.
std::vector<cv::Point> square(int cx, int cy, int r)
{
  return {{cx - r, cy - r}, {cx + r, cy - r}, {cx + r, cy + r}, {cx - r, cy + r}};
}

Silhouette silhouette_square(int cx, int cy, int r)
{
  Silhouette s;
  s.present = true;
  s.contour = square(cx, cy, r);
  s.bbox = cv::Rect(cx - r - 6, cy - r - 6, 2 * r + 13, 2 * r + 13);
  return s;
}

OverlayStyle only(bool contour, bool box, bool matches, bool bands, bool text)
{
  OverlayStyle s;
  s.contour = contour;
  s.box = box;
  s.matches = matches;
  s.bands = bands;
  s.text = text;
  return s;
}

// Pixels that differ between a and b.
cv::Mat changed(const cv::Mat &a, const cv::Mat &b)
{
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  std::vector<cv::Mat> ch;
  cv::split(diff, ch);
  cv::Mat any = cv::Mat::zeros(a.size(), CV_8U);
  for (const cv::Mat &c : ch)
    any |= c > 0;
  return any;
}

// Pixels farther than `margin` from every point of `near`.
cv::Mat far_from(cv::Size size, const std::vector<cv::Point> &near, int margin)
{
  cv::Mat mask(size, CV_8U, cv::Scalar(255));
  for (const cv::Point &p : near)
    cv::circle(mask, p, margin, cv::Scalar(0), cv::FILLED);
  return mask;
}

// Every pixel on the segments between consecutive points (closed).
std::vector<cv::Point> outline(const std::vector<cv::Point> &poly, cv::Point offset = {})
{
  std::vector<cv::Point> out;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    cv::LineIterator it(poly[i] + offset, poly[(i + 1) % poly.size()] + offset, 8);
    for (int k = 0; k < it.count; ++k, ++it)
      out.push_back(it.pos());
  }
  return out;
}

} // namespace

TEST(OverlayColor, DepthMapRunsFromWarmNearToCoolFar)
{
  EXPECT_EQ(depth_color(0.0), (Rgb{255, 0, 0}));
  EXPECT_EQ(depth_color(1.0), (Rgb{0, 85, 255}));
  EXPECT_EQ(depth_color(-3.0), depth_color(0.0)); // clamped
  EXPECT_EQ(depth_color(NAN), depth_color(0.0));
  // Warmth (red minus blue, minus green towards azure) falls strictly as the depth grows;
  // green stays low (the colours must stand out on foliage).
  int last = 1000;
  for (int i = 0; i <= 20; ++i) {
    const Rgb c = depth_color(i / 20.0);
    const int warmth = int(c.r) - int(c.b) - int(c.g);
    EXPECT_LT(warmth, last) << i;
    last = warmth;
    EXPECT_LE(c.g, 85) << i;
  }
}

TEST(OverlayDraw, ContourAndBoxInTheirColoursInBothViews)
{
  cv::Mat img = background(2);
  const cv::Mat before = img.clone();
  OverlayScene scene;
  scene.views[LEFT] = silhouette_square(120, 110, 40);
  scene.views[RIGHT] = silhouette_square(100, 110, 40);
  const ChannelOrder rgb{0, 1, 2, 3};
  draw_overlay(img, rgb, scene, only(true, true, false, false, false));

  std::vector<cv::Point> drawn;
  for (const cv::Point &p : outline(scene.views[LEFT].contour)) {
    EXPECT_EQ(rgb_at(img, rgb, p.x, p.y), kContourColor) << p;
    drawn.push_back(p);
  }
  for (const cv::Point &p : outline(scene.views[RIGHT].contour, {W, 0})) {
    EXPECT_EQ(rgb_at(img, rgb, p.x, p.y), kContourColor) << p;
    drawn.push_back(p);
  }
  const cv::Rect box = scene.views[LEFT].bbox;
  const std::vector<cv::Point> corners = {box.tl(), {box.br().x - 1, box.y},
                                          {box.br().x - 1, box.br().y - 1}, {box.x, box.br().y - 1}};
  for (const cv::Point &p : outline(corners)) {
    EXPECT_EQ(rgb_at(img, rgb, p.x, p.y), kBoxColor) << p;
    drawn.push_back(p);
  }
  for (const cv::Point &p : outline(corners, {W + scene.views[RIGHT].bbox.x - box.x, 0}))
    drawn.push_back(p);
  // The inside of the square and everything a few pixels away from the lines is untouched.
  const cv::Mat far = far_from(img.size(), drawn, 3);
  EXPECT_EQ(cv::countNonZero(changed(img, before) & far), 0);
  EXPECT_EQ(cv::Vec3b(img.at<cv::Vec3b>(110, 120)), kBackground);
}

TEST(OverlayDraw, MatchDotsColouredByDepthNearWarmFarCool)
{
  cv::Mat img = background(2);
  const cv::Mat before = img.clone();
  OverlayScene scene;
  scene.matches = {{60, 50, 40, 50, 0}, {200, 150, 190, 150, 0}, {250, 200, 245, 200, 0}};
  scene.match_depth_m = {1.5, 3.0, -1.0}; // near, far, unknown
  const ChannelOrder rgb{0, 1, 2, 3};
  OverlayStyle style = only(false, false, true, false, false);
  style.depth_near_m = 1.5;
  style.depth_far_m = 3.0;
  draw_overlay(img, rgb, scene, style);

  EXPECT_EQ(rgb_at(img, rgb, 60, 50), depth_color(0.0));
  EXPECT_EQ(rgb_at(img, rgb, W + 40, 50), depth_color(0.0));
  EXPECT_EQ(rgb_at(img, rgb, 200, 150), depth_color(1.0));
  EXPECT_EQ(rgb_at(img, rgb, W + 190, 150), depth_color(1.0));
  EXPECT_EQ(rgb_at(img, rgb, 250, 200), kUnknownDepthColor);
  const Rgb near = rgb_at(img, rgb, 60, 50), far = rgb_at(img, rgb, 200, 150);
  EXPECT_GT(int(near.r) - int(near.b), int(far.r) - int(far.b));

  const std::vector<cv::Point> at = {{60, 50}, {W + 40, 50}, {200, 150}, {W + 190, 150},
                                     {250, 200}, {W + 245, 200}};
  const int r = overlay_scale({W, H}).dot + 2;
  EXPECT_EQ(cv::countNonZero(changed(img, before) & far_from(img.size(), at, r)), 0);
  EXPECT_GT(cv::countNonZero(changed(img, before)), 6 * 9); // dots, not single pixels
}

TEST(OverlayDraw, MatchLinesJoinTheViewsOrShowDisparityOnOneView)
{
  const ChannelOrder rgb{0, 1, 2, 3};
  OverlayScene scene;
  scene.matches = {{100, 60, 80, 60, 0}};
  scene.match_depth_m = {2.0};
  OverlayStyle style = only(false, false, true, false, false);
  style.match_style = MatchStyle::kLines;
  style.depth_near_m = 1.0;
  style.depth_far_m = 3.0;
  const Rgb c = depth_color(0.5);

  cv::Mat both = background(2);
  draw_overlay(both, rgb, scene, style);
  for (int x : {100, 200, 300, W + 10, W + 80}) // the line crosses the middle of the frame
    EXPECT_EQ(rgb_at(both, rgb, x, 60), c) << x;
  EXPECT_EQ(cv::Vec3b(both.at<cv::Vec3b>(90, 200)), kBackground);

  scene.n_views = 1;
  cv::Mat left = background(1);
  const cv::Mat before = left.clone();
  draw_overlay(left, rgb, scene, style);
  for (int x = 80; x <= 100; ++x)
    EXPECT_EQ(rgb_at(left, rgb, x, 60), c) << x;
  EXPECT_EQ(cv::countNonZero(changed(left, before) &
                             far_from(left.size(), {{80, 60}, {90, 60}, {100, 60}}, 6)),
            0);
}

TEST(OverlayDraw, TextPanelChangesOnlyItsCornerAndScalesWithTheFrame)
{
  const ChannelOrder rgb{0, 1, 2, 3};
  OverlayScene scene;
  scene.text = {"distance 2.03 m", "height 1.20 m"};
  cv::Mat img(480, 2 * 640, CV_8UC3, cv::Scalar(40, 90, 60));
  const cv::Mat before = img.clone();
  draw_overlay(img, rgb, scene, only(false, false, false, false, true));
  const cv::Mat diff = changed(img, before);
  const cv::Rect where = cv::boundingRect(diff);
  EXPECT_GT(cv::countNonZero(diff), 1000);
  EXPECT_LT(where.br().x, 640);    // in the left view
  EXPECT_LT(where.br().y, 240);    // at the top
  EXPECT_GT(where.width, 80);      // wide enough to hold the text
  // the panel is darker than the frame, the text in it white
  const cv::Vec3b dim = img.at<cv::Vec3b>(where.y + 1, where.x + 1);
  EXPECT_LT(dim[1], kBackground[1]);
  cv::Mat white;
  cv::inRange(img, cv::Scalar(200, 200, 200), cv::Scalar(255, 255, 255), white);
  EXPECT_GT(cv::countNonZero(white), 50);

  // The same text at the sensor's full size: the panel grows with the frame (readable).
  cv::Mat big(1944, 2 * 2592, CV_8UC3, cv::Scalar(40, 90, 60));
  const cv::Mat big_before = big.clone();
  draw_overlay(big, rgb, scene, only(false, false, false, false, true));
  const cv::Rect big_where = cv::boundingRect(changed(big, big_before));
  const double ratio = double(big_where.height) / where.height;
  EXPECT_GT(ratio, 4.0 * 0.8);
  EXPECT_LT(ratio, 4.0 * 1.6);
  EXPECT_GE(overlay_scale({2592, 1944}).line, 5);
  EXPECT_EQ(overlay_scale({640, 480}).line, 2);
}

TEST(OverlayDraw, TextPanelGivesWayToATreeInFrontAtTheLeftEdge)
{
  const ChannelOrder rgb{0, 1, 2, 3};
  OverlayScene scene;
  scene.text = {"distance 2.03 m", "height 1.20 m", "width 0.70 m"};
  const auto panel_at = [&](const Silhouette &front) {
    scene.views[LEFT] = front;
    cv::Mat img(480, 2 * 640, CV_8UC3, cv::Scalar(40, 90, 60));
    const cv::Mat before = img.clone();
    draw_overlay(img, rgb, scene, only(false, false, false, false, true));
    return cv::boundingRect(changed(img, before));
  };
  // No tree, or a tree in the middle: the top left corner.
  EXPECT_LT(panel_at(Silhouette{}).x, 40);
  EXPECT_LT(panel_at(silhouette_square(320, 240, 100)).x, 40);
  // A tree at the left edge: the top right corner of the left view, clear of the tree.
  const Silhouette left_edge = silhouette_square(150, 200, 140);
  const cv::Rect moved = panel_at(left_edge);
  EXPECT_LE(moved.br().x, 640);
  EXPECT_GT(moved.x, 320);
  EXPECT_EQ((moved & left_edge.bbox).area(), 0);
  // A tree that fills the view: the corner stays the top left (no better place).
  EXPECT_LT(panel_at(silhouette_square(320, 240, 320)).x, 40);
}

TEST(OverlayDraw, NothingToDrawLeavesTheFrameAlone)
{
  cv::Mat img = background(2);
  const cv::Mat before = img.clone();
  OverlayScene scene;
  draw_overlay(img, ChannelOrder{0, 1, 2, 3}, scene, OverlayStyle());
  EXPECT_EQ(cv::countNonZero(changed(img, before)), 0);

  // Layers switched off draw nothing even with items.
  scene.views[LEFT] = silhouette_square(100, 100, 30);
  scene.matches = {{50, 50, 40, 50, 0}};
  scene.text = {"no tree"};
  draw_overlay(img, ChannelOrder{0, 1, 2, 3}, scene, only(false, false, false, false, false));
  EXPECT_EQ(cv::countNonZero(changed(img, before)), 0);
}

TEST(OverlayDraw, ChannelOrdersGiveTheSamePicture)
{
  OverlayScene scene;
  scene.views[LEFT] = silhouette_square(120, 110, 40);
  scene.views[RIGHT] = silhouette_square(100, 110, 40);
  scene.matches = {{120, 110, 100, 110, 0}, {90, 90, 72, 90, 0}};
  scene.match_depth_m = {2.0, 2.6};
  scene.text = {"distance 2.03 m"};

  cv::Mat rgb_img = background(2);
  draw_overlay(rgb_img, ChannelOrder{0, 1, 2, 3}, scene, OverlayStyle());

  cv::Mat bgr_img;
  cv::cvtColor(background(2), bgr_img, cv::COLOR_RGB2BGR);
  draw_overlay(bgr_img, ChannelOrder{2, 1, 0, 3}, scene, OverlayStyle());
  cv::Mat back;
  cv::cvtColor(bgr_img, back, cv::COLOR_BGR2RGB);
  EXPECT_EQ(cv::countNonZero(changed(rgb_img, back)), 0);

  // BGRx: 4 bytes, padding written opaque where drawn, the colours as in RGB.
  cv::Mat bgrx;
  cv::cvtColor(background(2), bgrx, cv::COLOR_RGB2BGRA);
  bgrx.setTo(cv::Scalar(60, 90, 40, 7));
  draw_overlay(bgrx, ChannelOrder{2, 1, 0, 4}, scene, OverlayStyle());
  cv::Mat as_rgb;
  cv::cvtColor(bgrx, as_rgb, cv::COLOR_BGRA2RGB);
  EXPECT_EQ(cv::countNonZero(changed(rgb_img, as_rgb)), 0);
  EXPECT_EQ(bgrx.at<cv::Vec4b>(70, 120)[3], 255); // on the contour
  EXPECT_EQ(bgrx.at<cv::Vec4b>(230, 300)[3], 7);  // far from everything
}

TEST(OverlayBands, SegmentIsThePinholeProjection)
{
  StereoGeometry g;
  g.view_size = {640, 480};
  g.fx = g.fy = 1000;
  g.cx[0] = 320;
  g.cx[1] = 310;
  g.cy = 240;
  g.baseline_mm = 50;
  Band b;
  b.present = true;
  b.left_m = -0.2;
  b.right_m = 0.3;
  b.top_m = -0.1;
  b.bottom_m = 0.05;
  const BandSegment s = band_segment(b, g, 2.0);
  EXPECT_DOUBLE_EQ(s.x_left, 220.0);
  EXPECT_DOUBLE_EQ(s.x_right, 470.0);
  EXPECT_DOUBLE_EQ(s.y_top, 190.0);
  EXPECT_DOUBLE_EQ(s.y_bottom, 265.0);
  EXPECT_THROW(band_segment(b, g, 0.0), std::runtime_error);
  EXPECT_THROW(band_segment(b, StereoGeometry(), 2.0), std::runtime_error);
}

// treemetrics' bands projected at its centroid depth land on the silhouette's edges: a disc
// canopy whose front is 2 m away, the round-canopy model.
TEST(OverlayBands, TreemetricsBandsProjectOntoTheSilhouette)
{
  const StereoGeometry g = simple_geometry(cv::Size(640, 480), 800, 50);
  Silhouette s;
  s.present = true;
  s.mask = cv::Mat::zeros(480, 640, CV_8U);
  const cv::Point centre(360, 230);
  const int radius = 120;
  cv::circle(s.mask, centre, radius, cv::Scalar(255), cv::FILLED);
  std::vector<Point3> pts;
  for (int y = centre.y - radius + 5; y < centre.y + radius - 5; y += 8)
    for (int x = centre.x - radius + 5; x < centre.x + radius - 5; x += 8)
      if (s.mask.at<uchar>(y, x)) {
        const float z = 2000;
        pts.push_back({float((x - g.cx[0]) * z / g.fx), float((y - g.cy) * z / g.fy), z, 0, true});
      }
  MetricsParams params;
  params.n_bands = 5;
  params.extent_depth = ExtentDepth::kRoundCanopy;
  const TreeMetrics m = compute_tree_metrics(s, pts, g, params);
  ASSERT_TRUE(m.tree_present);
  ASSERT_EQ(m.bands.size(), 5u);
  const double z = m.centroid_m.z;
  ASSERT_GT(z, 2.0);
  for (const Band &b : m.bands) {
    ASSERT_TRUE(b.present);
    const BandSegment seg = band_segment(b, g, z);
    // The silhouette's extent over the band's rows (its outer pixel edges).
    int xl = 640, xr = -1;
    for (int y = int(std::ceil(seg.y_top)); y < seg.y_bottom; ++y)
      for (int x = 0; x < 640; ++x)
        if (s.mask.at<uchar>(y, x)) {
          xl = std::min(xl, x);
          xr = std::max(xr, x);
        }
    // The band's edge is the canopy's widest point, which the tangent ray (the silhouette's
    // edge) passes outside of by about fx * t^3 / 2 px at slope t off the axis.
    const auto tol = [&](double x) { return 1.0 + g.fx * std::pow(std::abs(x - g.cx[0]) / g.fx, 3); };
    EXPECT_NEAR(seg.x_left, xl - 0.5, tol(xl));
    EXPECT_NEAR(seg.x_right, xr + 0.5, tol(xr));
  }
  EXPECT_NEAR(band_segment(m.bands.front(), g, z).y_top, centre.y - radius - 0.5, 2.0);
  EXPECT_NEAR(band_segment(m.bands.back(), g, z).y_bottom, centre.y + radius + 0.5, 2.0);
}

TEST(OverlayBands, DrawnAtTheirRowsInTheirDepthColour)
{
  const StereoGeometry g = simple_geometry(cv::Size(W, H), 400, 50);
  Band b;
  b.present = true;
  b.left_m = -0.5;
  b.right_m = 0.25;
  b.top_m = -0.2;
  b.bottom_m = 0.0;
  b.width_m = 0.75;
  b.depth_m = 1.8;
  OverlayScene scene;
  scene.bands = {b};
  scene.geometry = g;
  scene.band_depth_m = 2.0;
  OverlayStyle style = only(false, false, false, true, false);
  style.depth_near_m = 1.8;
  style.depth_far_m = 2.8;
  const ChannelOrder rgb{0, 1, 2, 3};
  cv::Mat img = background(2);
  draw_overlay(img, rgb, scene, style);
  // x 60..210 at y (80 + 120)/2 = 100, ticks at x 60 and 210 over rows 80..120
  for (int x : {60, 100, 150, 210})
    EXPECT_EQ(rgb_at(img, rgb, x, 100), depth_color(0.0)) << x;
  for (int y : {82, 118})
    EXPECT_EQ(rgb_at(img, rgb, 60, y), depth_color(0.0)) << y;
  EXPECT_EQ(cv::Vec3b(img.at<cv::Vec3b>(110, 130)), kBackground); // inside the band, off the lines
  EXPECT_EQ(cv::Vec3b(img.at<cv::Vec3b>(100, W + 100)), kBackground); // right view untouched

  scene.band_depth_m = 0; // no projection depth: bands are not placed anywhere
  cv::Mat none = background(2);
  draw_overlay(none, rgb, scene, style);
  EXPECT_EQ(cv::countNonZero(changed(none, background(2))), 0);
}

TEST(OverlayText, MetricsLines)
{
  TreeMetrics m;
  EXPECT_EQ(metrics_text(m, nullptr), std::vector<std::string>{"no tree"});
  m.tree_present = true;
  m.distance_m = 2.034;
  m.height_m = 1.2;
  m.width_m = 0.95;
  m.thickness_m = 0.42;
  m.points = 120;
  m.matches = 150;
  m.clipped.top = true;
  TreeMetrics sm = m;
  sm.distance_m = 2.011;
  sm.width_m = 0.951; // reads the same: not repeated
  const std::vector<std::string> lines = metrics_text(m, &sm);
  ASSERT_EQ(lines.size(), 5u);
  EXPECT_EQ(lines[0], "distance 2.03 m (smoothed 2.01)");
  EXPECT_EQ(lines[1], "height >= 1.20 m");
  EXPECT_EQ(lines[2], "width 0.95 m");
  EXPECT_EQ(lines[3], "thickness 0.42 m");
  EXPECT_EQ(lines[4], "points 120, matches 150");
  m.clipped = Clipped();
  m.clipped.right = true;
  EXPECT_EQ(metrics_text(m, nullptr)[2], "width >= 0.95 m");
  EXPECT_EQ(metrics_text(m, nullptr)[1], "height 1.20 m");
  m.confidence = 0.934;
  const std::vector<std::string> with = metrics_text(m, nullptr, true);
  ASSERT_EQ(with.size(), 6u);
  EXPECT_EQ(with[5], "conf 0.93");
  EXPECT_EQ(metrics_text(TreeMetrics{}, nullptr, true), std::vector<std::string>{"no tree"});
}

TEST(OverlayDraw, RejectedVegetationIsTintedAndCanopyIsNot)
{
  cv::Mat veg = cv::Mat::zeros(40, 60, CV_8U), canopy = cv::Mat::zeros(40, 60, CV_8U);
  veg(cv::Rect(10, 10, 40, 20)).setTo(255);
  canopy(cv::Rect(10, 10, 20, 20)).setTo(255);
  const cv::Mat rejected = rejected_vegetation(veg, canopy);
  EXPECT_EQ(cv::countNonZero(rejected), 20 * 20);
  EXPECT_EQ(rejected.at<uchar>(15, 40), 255);
  EXPECT_EQ(rejected.at<uchar>(15, 20), 0);
  EXPECT_EQ(cv::countNonZero(rejected_vegetation(veg, cv::Mat())), 40 * 20);

  // a BGR side-by-side frame: the tint is the mean with kRejectedColor, in the left view only
  cv::Mat image(40, 120, CV_8UC3, cv::Scalar(60, 90, 40)); // B, G, R
  const ChannelOrder bgr{2, 1, 0, 3};
  OverlayScene scene;
  scene.rejected = rejected;
  draw_overlay(image, bgr, scene, OverlayStyle{});
  const cv::Vec3b t = image.at<cv::Vec3b>(15, 40), c = image.at<cv::Vec3b>(15, 20);
  EXPECT_EQ(t, cv::Vec3b((60 + kRejectedColor.b + 1) / 2, (90 + kRejectedColor.g + 1) / 2,
                         (40 + kRejectedColor.r + 1) / 2));
  EXPECT_EQ(c, cv::Vec3b(60, 90, 40));
  EXPECT_EQ(image.at<cv::Vec3b>(15, 60 + 40), cv::Vec3b(60, 90, 40));
  OverlayStyle off;
  off.rejected = false;
  cv::Mat plain(40, 120, CV_8UC3, cv::Scalar(60, 90, 40));
  draw_overlay(plain, bgr, scene, off);
  EXPECT_EQ(plain.at<cv::Vec3b>(15, 40), cv::Vec3b(60, 90, 40));
  // a mask of another size is an error, not a guess
  scene.rejected = cv::Mat::zeros(10, 10, CV_8U);
  EXPECT_THROW(draw_overlay(image, bgr, scene, OverlayStyle{}), std::runtime_error);
}

TEST(OverlayDraw, RejectsImagesItCannotDrawOn)
{
  OverlayScene scene;
  cv::Mat gray(H, 2 * W, CV_8UC1);
  EXPECT_THROW(draw_overlay(gray, ChannelOrder{0, 1, 2, 3}, scene, OverlayStyle()),
               std::runtime_error);
  cv::Mat odd(H, 2 * W + 1, CV_8UC3);
  EXPECT_THROW(draw_overlay(odd, ChannelOrder{0, 1, 2, 3}, scene, OverlayStyle()),
               std::runtime_error);
  cv::Mat ok(H, 2 * W, CV_8UC3);
  EXPECT_THROW(draw_overlay(ok, ChannelOrder{0, 1, 5, 3}, scene, OverlayStyle()),
               std::runtime_error);
}
