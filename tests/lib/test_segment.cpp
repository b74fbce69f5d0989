#include "segment_regions.hpp"
#include "treestereo/data_dir.hpp"
#include "treestereo/segment.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>

using namespace treestereo;

namespace {

// Colours in BGR (OpenCV's order, the default ChannelOrder).
const cv::Scalar kSoil(60, 100, 140);  // brown
const cv::Scalar kSky(200, 170, 150);  // blue-grey
const cv::Scalar kLeaf(50, 130, 60);   // green

// Sky above, soil below, mild sensor noise.
cv::Mat background(cv::Size size, unsigned seed = 1)
{
  cv::Mat img(size, CV_8UC3, kSoil);
  img.rowRange(0, size.height / 3).setTo(kSky);
  cv::Mat noise(size, CV_16SC3);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::NORMAL, 0, 4);
  cv::Mat out;
  cv::add(img, noise, out, cv::noArray(), CV_8U);
  return out;
}

// The exact disc: pixel centres within r of c.
cv::Mat disc_mask(cv::Size size, cv::Point2d c, double r)
{
  cv::Mat m(size, CV_8U);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x)
      m.at<uchar>(y, x) = (x - c.x) * (x - c.x) + (y - c.y) * (y - c.y) <= r * r ? 255 : 0;
  return m;
}

cv::Mat paint(cv::Mat img, const cv::Mat &mask, const cv::Scalar &colour)
{
  cv::Mat layer(img.size(), CV_8UC3, colour), noise(img.size(), CV_16SC3);
  cv::RNG rng(7);
  rng.fill(noise, cv::RNG::NORMAL, 0, 4);
  cv::add(layer, noise, layer, cv::noArray(), CV_8U);
  layer.copyTo(img, mask);
  return img;
}

double iou(const cv::Mat &a, const cv::Mat &b)
{
  const double inter = cv::countNonZero(a & b), uni = cv::countNonZero(a | b);
  return uni > 0 ? inter / uni : 0;
}

void expect_empty(const Silhouette &s)
{
  EXPECT_FALSE(s.present);
  EXPECT_EQ(cv::countNonZero(s.mask), 0);
  EXPECT_EQ(s.area_px, 0);
  EXPECT_EQ(s.perimeter_px, 0);
  EXPECT_EQ(s.complexity, 0);
  EXPECT_EQ(s.centroid, cv::Point2d(0, 0));
  EXPECT_TRUE(s.bbox.empty());
  EXPECT_EQ(s.n_regions, 0);
  EXPECT_TRUE(s.contour.empty());
  EXPECT_FALSE(std::isnan(s.threshold));
}

const cv::Size kSize(400, 300);
const cv::Point2d kCentre(200.3, 150.6);
const double kRadius = 60;

} // namespace

TEST(Segment, DiscOnSoilAndSkyEveryIndex)
{
  const cv::Mat truth = disc_mask(kSize, kCentre, kRadius);
  const cv::Mat img = paint(background(kSize), truth, kLeaf);
  for (VegIndex index : all_veg_indices()) {
    SCOPED_TRACE(veg_index_name(index));
    SegmentParams p;
    p.index = index;
    const Silhouette s = segment_vegetation(img, p);
    ASSERT_TRUE(s.present);
    EXPECT_GE(iou(s.mask, truth), 0.98);
    EXPECT_NEAR(s.centroid.x, kCentre.x, 0.5);
    EXPECT_NEAR(s.centroid.y, kCentre.y, 0.5);
    EXPECT_NEAR(s.area_px / (CV_PI * kRadius * kRadius), 1.0, 0.02);
    EXPECT_NEAR(s.perimeter_px / (2 * CV_PI * kRadius), 1.0, 0.03);
    EXPECT_NEAR(s.complexity, 1.0, 0.04);
    EXPECT_EQ(s.n_regions, 1);
    EXPECT_NEAR(s.bbox.x, kCentre.x - kRadius, 1.5);
    EXPECT_NEAR(s.bbox.width, 2 * kRadius, 2.0);
    EXPECT_GE(s.contour.size(), 8u);
  }
}

TEST(Segment, NormalisedIndicesFollowBrightness)
{
  const cv::Mat truth = disc_mask(kSize, kCentre, kRadius);
  const cv::Mat img = paint(background(kSize), truth, kLeaf);
  for (VegIndex index : {VegIndex::ExgNorm, VegIndex::ExgExrNorm})
    for (double gain : {0.7, 1.3}) {
      SCOPED_TRACE(std::string(veg_index_name(index)) + " x" + std::to_string(gain));
      cv::Mat lit;
      img.convertTo(lit, CV_8U, gain);
      SegmentParams p;
      p.index = index;
      const Silhouette s = segment_vegetation(lit, p);
      ASSERT_TRUE(s.present);
      EXPECT_GE(iou(s.mask, truth), 0.98);
      EXPECT_NEAR(s.centroid.x, kCentre.x, 0.5);
      EXPECT_NEAR(s.centroid.y, kCentre.y, 0.5);
      EXPECT_NEAR(s.complexity, 1.0, 0.04);
    }
}

TEST(Segment, ChannelOrderAndRoiOfSideBySideFrame)
{
  const cv::Mat truth = disc_mask(kSize, kCentre, kRadius);
  const cv::Mat bgr = paint(background(kSize), truth, kLeaf);
  // xRGB side-by-side frame, the view is its right half: a ROI with the frame's stride.
  cv::Mat xrgb;
  cv::cvtColor(bgr, xrgb, cv::COLOR_BGR2RGBA); // R G B A
  const int shift[] = {3, 0, 1, 2};            // -> A R G B
  cv::Mat frame(kSize.height, 2 * kSize.width, CV_8UC4, cv::Scalar::all(0));
  cv::Mat view = frame(cv::Rect(kSize.width, 0, kSize.width, kSize.height));
  cv::mixChannels(&xrgb, 1, &view, 1, std::vector<int>{shift[0], 0, shift[1], 1, shift[2], 2,
                                                       shift[3], 3}.data(), 4);
  SegmentParams p;
  p.order = channel_order_from_name("xRGB");
  EXPECT_EQ(p.order.r, 1);
  EXPECT_EQ(p.order.b, 3);
  const Silhouette s4 = segment_vegetation(view, p);
  const Silhouette s3 = segment_vegetation(bgr, SegmentParams());
  ASSERT_TRUE(s4.present);
  EXPECT_EQ(cv::countNonZero(s4.mask != s3.mask), 0);
  // With the wrong order (R and B swapped does not matter for ExG; G swapped does).
  p.order = channel_order_from_name("RGBx"); // reads A as B, R as G: no green disc
  const Silhouette wrong = segment_vegetation(view, p);
  EXPECT_LT(iou(wrong.mask, truth), 0.5);
}

TEST(Segment, PreallocatedMaskIsReused)
{
  const cv::Mat truth = disc_mask(kSize, kCentre, kRadius);
  const cv::Mat img = paint(background(kSize), truth, kLeaf);
  std::vector<uchar> memory(std::size_t(kSize.area()), 7);
  Silhouette s;
  s.mask = cv::Mat(kSize, CV_8U, memory.data());
  VegetationSegmenter seg;
  seg.run(img, s);
  EXPECT_EQ(s.mask.data, memory.data());
  EXPECT_GE(iou(s.mask, truth), 0.98);
  seg.run(background(kSize), s); // nothing green: the caller's memory is cleared
  EXPECT_EQ(s.mask.data, memory.data());
  expect_empty(s);
}

TEST(Segment, SquareComplexityIsFourOverPi)
{
  cv::Mat truth(kSize, CV_8U, cv::Scalar(0));
  truth(cv::Rect(150, 100, 90, 90)).setTo(255);
  const Silhouette s = segment_vegetation(paint(background(kSize), truth, kLeaf));
  ASSERT_TRUE(s.present);
  EXPECT_NEAR(s.area_px, 90 * 90, 90 * 90 * 0.005); // opening rounds the corners a little
  EXPECT_NEAR(s.perimeter_px, 4 * 90, 4 * 90 * 0.02);
  EXPECT_NEAR(s.complexity, 4 / CV_PI, 4 / CV_PI * 0.03);
  EXPECT_EQ(s.bbox, cv::Rect(150, 100, 90, 90));
  EXPECT_NEAR(s.centroid.x, 194.5, 1e-9);
}

TEST(Segment, KeepLargestOrAllAndMinArea)
{
  const cv::Mat big = disc_mask(kSize, {120, 150}, 50), small = disc_mask(kSize, {300, 150}, 25);
  cv::Mat truth = big | small;
  for (int i = 0; i < 5; ++i) // 3x3 specks: 9 px each
    truth(cv::Rect(40 + 70 * i, 260, 3, 3)).setTo(255);
  const cv::Mat img = paint(background(kSize), truth, kLeaf);
  SegmentParams p;
  p.morph_size = 0; // the specks survive thresholding; only min_area removes them
  p.min_area = 50;
  EXPECT_EQ(p.keep, KeepMode::All); // the default: all the vegetation, depth picks the canopy
  p.keep = KeepMode::Largest;
  Silhouette s = segment_vegetation(img, p);
  EXPECT_EQ(s.n_regions, 1);
  EXPECT_GE(iou(s.mask, big), 0.98);
  EXPECT_NEAR(s.centroid.x, 120, 0.5);
  p.keep = KeepMode::All;
  s = segment_vegetation(img, p);
  EXPECT_EQ(s.n_regions, 2);
  EXPECT_GE(iou(s.mask, big | small), 0.98);
  const double ab = cv::countNonZero(big), as = cv::countNonZero(small);
  EXPECT_NEAR(s.area_px, ab + as, 0.02 * (ab + as));
  EXPECT_NEAR(s.centroid.x, (120 * ab + 300 * as) / (ab + as), 0.5);
  EXPECT_NEAR(s.perimeter_px, 2 * CV_PI * 75, 2 * CV_PI * 75 * 0.03); // both outer contours
  EXPECT_NEAR(s.contour.front().x, 120, 51);                           // the big one's contour
  p.min_area = 0;
  s = segment_vegetation(img, p);
  EXPECT_EQ(s.n_regions, 7);
}

TEST(Segment, MorphologyRemovesSaltNoise)
{
  const cv::Mat truth = disc_mask(kSize, kCentre, kRadius);
  cv::Mat salt(kSize, CV_8U, cv::Scalar(0));
  cv::RNG rng(3);
  for (int i = 0; i < 1500; ++i)
    salt.at<uchar>(rng.uniform(0, kSize.height), rng.uniform(0, kSize.width)) = 255;
  const cv::Mat img = paint(paint(background(kSize), truth, kLeaf), salt, kLeaf);
  SegmentParams p;
  p.keep = KeepMode::All;
  p.min_area = 0;
  p.morph_size = 0;
  EXPECT_GT(segment_vegetation(img, p).n_regions, 500); // the noise is there
  p.morph_size = 5;
  const Silhouette s = segment_vegetation(img, p);
  EXPECT_EQ(s.n_regions, 1);
  EXPECT_GE(iou(s.mask, truth), 0.98);
}

TEST(Segment, OpeningByReconstructionRestoresTipsNotSpecks)
{
  // A disc with thin spikes (1 px straight, 1 px diagonal, 2 and 3 px wide: all narrower than
  // the 5 px opening) and isolated specks (3x3 and single pixels), one of them 3 px from the
  // disc's edge, which the close would join to the disc if it survived the opening.
  const cv::Mat disc = disc_mask(kSize, kCentre, kRadius);
  cv::Mat spikes(kSize, CV_8U, cv::Scalar(0));
  const int cx = int(kCentre.x), cy = int(kCentre.y), r = int(kRadius);
  spikes(cv::Rect(cx, cy - r - 30, 1, 40)).setTo(255);      // up, 1 px wide
  spikes(cv::Rect(cx + r - 10, cy, 45, 2)).setTo(255);      // right, 2 px wide
  spikes(cv::Rect(cx - 2, cy + r - 10, 3, 35)).setTo(255);  // down, 3 px wide
  for (int i = 0; i < 35; ++i)                              // up-left, 1 px diagonal
    spikes.at<uchar>(cy - 30 - i, cx - 30 - i) = 255;
  spikes &= ~disc;
  cv::Mat specks(kSize, CV_8U, cv::Scalar(0));
  specks(cv::Rect(30, 30, 3, 3)).setTo(255);
  specks(cv::Rect(340, 250, 3, 3)).setTo(255);
  specks(cv::Rect(cx - r - 5, cy - 1, 3, 3)).setTo(255); // 3 px left of the disc
  specks.at<uchar>(200, 60) = 255;
  specks.at<uchar>(40, 370) = 255;
  const cv::Mat shape = disc | spikes;
  const cv::Mat img = paint(background(kSize), shape | specks, kLeaf);

  SegmentParams p;
  p.keep = KeepMode::All;
  p.min_area = 0; // nothing but the morphology removes the specks
  p.unmix_edges = false; // it would give back the corners the close fills (background colour)
  ASSERT_TRUE(p.reconstruct);
  const Silhouette s = segment_vegetation(img, p);
  ASSERT_TRUE(s.present);
  EXPECT_EQ(s.n_regions, 1);
  // Exactly the shape after the close step (which only fills the corners where the spikes
  // meet the disc): the opening took nothing of it, and no speck came back.
  cv::Mat expected;
  cv::morphologyEx(shape, expected, cv::MORPH_CLOSE,
                   cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
  EXPECT_EQ(cv::countNonZero(s.mask != expected), 0);
  EXPECT_EQ(cv::countNonZero(s.mask & spikes), cv::countNonZero(spikes));
  EXPECT_EQ(cv::countNonZero(s.mask & specks), 0);
  EXPECT_EQ(s.bbox.y, cy - r - 30); // the top spike's tip

  // The plain opening shaves the spikes off (what reconstruct gives back).
  p.reconstruct = false;
  const Silhouette plain = segment_vegetation(img, p);
  EXPECT_LT(cv::countNonZero(plain.mask & spikes), cv::countNonZero(spikes) / 5);
  EXPECT_EQ(cv::countNonZero(plain.mask & specks), 0);
  EXPECT_GT(plain.bbox.y, cy - r - 5);
}

TEST(Segment, UnmixedEdgesFollowLeafCoverage)
{
  // A leaf disc against bright sky, each pixel the area average of 8x8 sub-pixels (a lens and
  // sensor integrate light over the pixel), so every pixel's leaf coverage is known. The ideal
  // mask is the pixels at least half leaf: about pi r^2 pixels, edge within a pixel everywhere.
  const int ss = 8;
  const cv::Size big = kSize * ss;
  const cv::Scalar sky(235, 215, 200), leaf(40, 120, 50); // BGR
  cv::Mat hi(big, CV_8UC3, sky), cover_hi(big, CV_32F, cv::Scalar(0));
  cv::circle(cover_hi, cv::Point(cvRound((kCentre.x + 0.5) * ss - 0.5), cvRound((kCentre.y + 0.5) * ss - 0.5)),
             int(kRadius * ss), cv::Scalar(1), cv::FILLED);
  hi.setTo(leaf, cover_hi > 0.5f);
  cv::Mat img, cover;
  cv::resize(hi, img, kSize, 0, 0, cv::INTER_AREA);
  cv::resize(cover_hi, cover, kSize, 0, 0, cv::INTER_AREA);
  const cv::Mat ideal = cover >= 0.5f;
  const double ideal_area = cv::countNonZero(ideal);

  // Where the threshold puts the edge depends on the threshold (leaf ExG-norm 0.71, sky's
  // about 0): a high one loses the mixed ring, a low one takes pixels that are mostly sky.
  // Unmixed, the edge is where the leaf covers half the pixel, whatever the threshold.
  const double r_ideal = std::sqrt(ideal_area / CV_PI);
  const cv::Rect ib = cv::boundingRect(ideal);
  SegmentParams p;
  ASSERT_TRUE(p.unmix_edges);
  Silhouette t;
  for (double thr : {0.06, 0.35, 0.55}) {
    SCOPED_TRACE(thr);
    p.threshold = thr;
    p.unmix_edges = false;
    t = segment_vegetation(img, p);
    p.unmix_edges = true;
    const Silhouette s = segment_vegetation(img, p);
    ASSERT_TRUE(s.present && t.present);
    const double r_thr = std::sqrt(t.area_px / CV_PI), r_mix = std::sqrt(s.area_px / CV_PI);
    if (thr > 0.5) {
      EXPECT_LT(r_thr, r_ideal - 0.3);
    }
    if (thr < 0.2) {
      EXPECT_GT(r_thr, r_ideal + 0.15);
    }
    // The pixels more than half leaf, to within a few pixels of the whole ring; those that
    // differ are close to half (the 5x5 mean colours carry the neighbours' coverage).
    const cv::Mat differ = s.mask != ideal;
    EXPECT_LT(cv::countNonZero(differ), 8) << "radius " << r_mix << " ideal " << r_ideal;
    for (int y = 0; y < kSize.height; ++y)
      for (int x = 0; x < kSize.width; ++x)
        if (differ.at<uchar>(y, x)) {
          EXPECT_NEAR(cover.at<float>(y, x), 0.5, 0.15) << "at " << x << "," << y;
        }
    EXPECT_LE(std::abs(s.bbox.y - ib.y) + std::abs(s.bbox.br().y - ib.br().y), 1);
    EXPECT_LE(std::abs(s.bbox.x - ib.x) + std::abs(s.bbox.br().x - ib.br().x), 1);
  }

  // On a background of about the leaf's colour nothing is unmixed: the threshold stands.
  p.unmix_edges = true;
  p.unmix_min_contrast = 442;
  const Silhouette u = segment_vegetation(img, p);
  EXPECT_EQ(cv::countNonZero(u.mask != t.mask), 0);
}

TEST(Segment, NothingGreenOrDegenerateFramesFindNothing)
{
  const cv::Mat soil_sky = background(kSize, 5);
  const cv::Mat black(kSize, CV_8UC3, cv::Scalar::all(0));
  const cv::Mat white(kSize, CV_8UC3, cv::Scalar::all(255));
  cv::Mat luminance(kSize, CV_8U), grey_noise; // neutral grey with luminance noise only
  cv::RNG(9).fill(luminance, cv::RNG::NORMAL, 128, 3);
  cv::cvtColor(luminance, grey_noise, cv::COLOR_GRAY2BGR);
  for (VegIndex index : all_veg_indices())
    for (const cv::Mat *img : {&soil_sky, &black, &white, (const cv::Mat *)&grey_noise}) {
      SCOPED_TRACE(veg_index_name(index));
      SegmentParams p;
      p.index = index;
      expect_empty(segment_vegetation(*img, p));
    }
}

TEST(Segment, FixedThresholdInIndexUnits)
{
  const cv::Mat truth = disc_mask(kSize, kCentre, kRadius);
  const cv::Mat img = paint(background(kSize), truth, kLeaf);
  SegmentParams p;
  p.index = VegIndex::ExgExr; // leaf 3*130-2.4*60-50 = 196, soil -80, sky -200
  p.threshold = 0;
  Silhouette s = segment_vegetation(img, p);
  EXPECT_EQ(s.threshold, 0);
  EXPECT_GE(iou(s.mask, truth), 0.98);
  p.threshold = 250; // above the leaf: nothing
  expect_empty(segment_vegetation(img, p));
  p.index = VegIndex::Exg; // leaf 2*130-60-50 = 150
  p.threshold = 115; // 3.5 sigma of the noise below the leaf
  EXPECT_GE(iou(segment_vegetation(img, p).mask, truth), 0.98);
  p.threshold = 200;
  EXPECT_FALSE(segment_vegetation(img, p).present);
}

TEST(Segment, DownscaledWorkKeepsFullSizeAccuracy)
{
  const cv::Size big(1800, 1350);
  const cv::Point2d c(900.4, 640.7);
  const double r = 420;
  const cv::Mat truth = disc_mask(big, c, r);
  const cv::Mat img = paint(background(big), truth, kLeaf);
  for (int f : {1, 2, 3}) {
    SCOPED_TRACE(f);
    SegmentParams p;
    p.work_scale = f;
    const Silhouette s = segment_vegetation(img, p);
    ASSERT_TRUE(s.present);
    EXPECT_GE(iou(s.mask, truth), 0.995);
    EXPECT_NEAR(s.centroid.x, c.x, 0.5);
    EXPECT_NEAR(s.centroid.y, c.y, 0.5);
    EXPECT_NEAR(s.area_px / (CV_PI * r * r), 1.0, 0.005);
    EXPECT_NEAR(s.complexity, 1.0, 0.03);
  }
}

TEST(Segment, OtsuOnHistogram)
{
  std::vector<int> h(1000, 0);
  h[100] = 500;
  h[700] = 200;
  EXPECT_NEAR(otsu_bin(h), 400, 1); // middle of the empty gap between two spikes
  std::vector<int> one(10, 0);
  one[3] = 99;
  EXPECT_EQ(otsu_bin(one), -1);
  EXPECT_EQ(otsu_bin(std::vector<int>(5, 0)), -1);
  // Two Gaussian-like humps of different size: the cut lies between them.
  std::vector<int> g(600, 0);
  for (int i = 0; i < 600; ++i)
    g[std::size_t(i)] = int(1000 * std::exp(-0.5 * std::pow((i - 150) / 30.0, 2)) +
                            300 * std::exp(-0.5 * std::pow((i - 450) / 30.0, 2)));
  EXPECT_GT(otsu_bin(g), 250);
  EXPECT_LT(otsu_bin(g), 350);
}

TEST(Segment, BadInputThrowsWithReason)
{
  const cv::Mat gray(10, 10, CV_8U, cv::Scalar(0));
  EXPECT_THROW(segment_vegetation(gray), std::runtime_error);
  EXPECT_THROW(segment_vegetation(cv::Mat()), std::runtime_error);
  EXPECT_THROW(segment_vegetation(cv::Mat(10, 10, CV_16UC3)), std::runtime_error);
  SegmentParams p;
  p.order = {0, 0, 2};
  EXPECT_THROW(VegetationSegmenter{p}, std::runtime_error);
  p = SegmentParams();
  p.order = {3, 1, 0}; // valid for 4 channels, not for a 3-channel view
  EXPECT_THROW(segment_vegetation(cv::Mat(10, 10, CV_8UC3), p), std::runtime_error);
  EXPECT_THROW(veg_index_from_name("ndvi"), std::runtime_error);
  EXPECT_THROW(keep_mode_from_name("biggest"), std::runtime_error);
  EXPECT_THROW(channel_order_from_name("YUY2"), std::runtime_error);
  EXPECT_EQ(veg_index_from_name("exg-exr-norm"), VegIndex::ExgExrNorm);
  EXPECT_EQ(keep_mode_from_name("all"), KeepMode::All);
  try {
    segment_vegetation(gray);
  } catch (const std::runtime_error &e) {
    EXPECT_NE(std::string(e.what()).find("colour"), std::string::npos);
  }
}

// Real images against hand-marked regions (tests/lib/segment_regions.hpp).
TEST(Segment, RealImagesHandMarkedRegions)
{
  const std::string dir = data_dir();
  // Required per image with the default index (exg-norm), keep=all: mean foliage covered,
  // mean other covered. Measured values are in docs/segmentation.md.
  struct Need {
    double foliage_min, other_max;
  };
  const Need need[] = {{0.75, 0.06}, {0.50, 0.15}, {0.95, 0.06}};
  int i = 0, found = 0;
  for (const auto &m : segment_truth::marked_images()) {
    const Need n = need[i++];
    const cv::Mat img = cv::imread(dir + "/" + m.path);
    if (img.empty())
      continue;
    ++found;
    SCOPED_TRACE(m.name);
    SegmentParams p;
    p.keep = KeepMode::All;
    const Silhouette s = segment_vegetation(img, p);
    ASSERT_TRUE(s.present);
    double f = 0, o = 0;
    for (const auto &r : m.foliage)
      f += segment_truth::covered(s.mask, r.rect) / double(m.foliage.size());
    for (const auto &r : m.other)
      o += segment_truth::covered(s.mask, r.rect) / double(m.other.size());
    EXPECT_GE(f, n.foliage_min);
    EXPECT_LE(o, n.other_max);
  }
  if (found == 0)
    GTEST_SKIP() << "real images not found under " << dir
                 << " (set TREESTEREO_DATA_DIR to the shared data directory)";
}
