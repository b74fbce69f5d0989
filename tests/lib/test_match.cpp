#include "treestereo/data_dir.hpp"
#include "treestereo/errors.hpp"
#include "treestereo/features.hpp"
#include "treestereo/match.hpp"
#include "treestereo/middlebury.hpp"
#include "treestereo/presets.hpp"
#include "treestereo/stats.hpp"
#include "typed_error.hpp"
#include "simple_geometry.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iostream>

using namespace treestereo;

namespace {

// Hand-made features: one keypoint per (point, descriptor).
Features make_features(const std::vector<cv::Point2f> &pts, const std::vector<cv::Mat> &desc)
{
  Features f;
  f.descriptors.create(0, 128, CV_32F);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    f.keypoints.emplace_back(pts[i], 4.f);
    f.descriptors.push_back(desc[i]);
  }
  return f;
}

// norm * (cos(theta) e0 + sin(theta) e_axis): a descriptor at a chosen angle from e0.
cv::Mat at_angle(double theta, double norm, int axis)
{
  cv::Mat d = cv::Mat::zeros(1, 128, CV_32F);
  d.at<float>(0, 0) = float(norm * std::cos(theta));
  d.at<float>(0, axis) += float(norm * std::sin(theta));
  return d;
}

cv::Mat random_descriptor(cv::RNG &rng)
{
  cv::Mat d(1, 128, CV_32F);
  rng.fill(d, cv::RNG::UNIFORM, 0.f, 100.f);
  return d;
}

MatcherParams no_constraints(MatchMethod m)
{
  MatcherParams p;
  p.method = m;
  p.ratio = 1.0;
  p.constraints.epipolar_tolerance = -1;
  p.constraints.mutual = false;
  return p;
}

// Smooth random texture (blurred noise stretched to 0..255).
cv::Mat texture(cv::Size size, std::uint64_t seed)
{
  cv::Mat noise(size, CV_32F);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::UNIFORM, 0.f, 1.f);
  cv::GaussianBlur(noise, noise, cv::Size(), 2.0);
  cv::Mat img;
  cv::normalize(noise, noise, 0, 255, cv::NORM_MINMAX);
  noise.convertTo(img, CV_8U);
  return img;
}

// The right view of a pair with a constant disparity d: right(x) = left(x + d).
cv::Mat shift_left(const cv::Mat &img, double d)
{
  cv::Mat out;
  const cv::Matx23d m(1, 0, -d, 0, 1, 0);
  cv::warpAffine(img, out, m, img.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  return out;
}

double median_abs_error(const std::vector<StereoMatch> &m, double d_true)
{
  std::vector<double> e;
  for (const StereoMatch &s : m)
    e.push_back(std::abs(double(s.disparity()) - d_true));
  return median(e);
}

} // namespace

TEST(CosineNorm, PicksSmallestNormDifferenceAmongFiveSmallestAngles)
{
  // The query (500 e0) sits in the RIGHT view, which has more keypoints: it is the reference.
  // Left candidates, (angle, norm): the smallest angle has a far norm; the 6th has the exact
  // norm but is outside the 5 smallest angles; c2 has the exact norm among the 5.
  const double angles[6] = {0.05, 0.10, 0.15, 0.20, 0.25, 0.40};
  const double norms[6] = {300, 450, 500, 420, 380, 500};
  std::vector<cv::Point2f> lp, rp;
  std::vector<cv::Mat> ld, rd;
  for (int k = 0; k < 6; ++k) {
    lp.emplace_back(100.f + 20.f * float(k), 50.f + 3.f * float(k));
    ld.push_back(at_angle(angles[k], norms[k], k + 1));
  }
  rp.emplace_back(30.f, 40.f);
  rd.push_back(at_angle(0.0, 500, 1));
  for (int k = 0; k < 6; ++k) { // fillers, far from every candidate in angle
    rp.emplace_back(300.f + 10.f * float(k), 200.f);
    cv::Mat d = cv::Mat::zeros(1, 128, CV_32F);
    d.at<float>(0, 64 + k) = 400.f;
    rd.push_back(d);
  }
  const Features left = make_features(lp, ld), right = make_features(rp, rd);
  MatchStats st;
  const auto m = CosineNormMatcher(no_constraints(MatchMethod::CosineNorm)).match(left, right, st);
  // Every reference (right) keypoint gets a match: 7, not the left's 6.
  ASSERT_EQ(m.size(), 7u);
  int found = 0;
  for (const StereoMatch &s : m)
    if (s.xr == 30.f && s.yr == 40.f) {
      ++found;
      EXPECT_EQ(s.xl, lp[2].x);
      EXPECT_EQ(s.yl, lp[2].y);
      EXPECT_NEAR(s.score, 0.15, 1e-3); // the chosen angle, not the smallest (0.05)
    }
  EXPECT_EQ(found, 1);
  EXPECT_EQ(st.candidates_tested, 7u * 6u);

  // With a single candidate the norm plays no part: the smallest angle (c0) wins.
  MatcherParams one = no_constraints(MatchMethod::CosineNorm);
  one.candidates = 1; // pure smallest angle: picks c0 for the query
  MatchStats st1;
  const auto m1 = CosineNormMatcher(one).match(left, right, st1);
  for (const StereoMatch &s : m1) {
    if (s.xr == 30.f && s.yr == 40.f) {
      EXPECT_EQ(s.xl, lp[0].x);
    }
  }
}

TEST(CosineNorm, ReferenceIsTheViewWithMoreKeypoints)
{
  cv::RNG rng(3);
  std::vector<cv::Point2f> lp, rp;
  std::vector<cv::Mat> ld, rd;
  for (int k = 0; k < 9; ++k) {
    lp.emplace_back(float(10 * k), 5.f);
    ld.push_back(random_descriptor(rng));
  }
  for (int k = 0; k < 4; ++k) {
    rp.emplace_back(float(10 * k), 5.f);
    rd.push_back(random_descriptor(rng));
  }
  MatchStats a, b;
  const MatcherParams p = no_constraints(MatchMethod::CosineNorm);
  // Without any rejection, one match per reference keypoint: the larger view's count.
  EXPECT_EQ(CosineNormMatcher(p).match(make_features(lp, ld), make_features(rp, rd), a).size(), 9u);
  EXPECT_EQ(CosineNormMatcher(p).match(make_features(rp, rd), make_features(lp, ld), b).size(), 9u);
  // Euclidean keeps the left as the reference.
  MatchStats c;
  EXPECT_EQ(EuclideanMatcher(no_constraints(MatchMethod::Euclidean))
                .match(make_features(rp, rd), make_features(lp, ld), c)
                .size(),
            4u);
}

class Constraints : public ::testing::TestWithParam<MatchMethod> {};

TEST_P(Constraints, EpipolarBandRejectsOffRowMatch)
{
  cv::RNG rng(1);
  const cv::Mat d = random_descriptor(rng);
  const Features left = make_features({{100.f, 50.f}}, {d});
  const Features right = make_features({{80.f, 60.f}}, {d.clone()}); // 10 rows off
  MatcherParams p = no_constraints(GetParam());
  MatchStats off;
  EXPECT_EQ(make_matcher(p)->match(left, right, off).size(), 1u);
  p.constraints.epipolar_tolerance = 2.0;
  MatchStats on;
  EXPECT_TRUE(make_matcher(p)->match(left, right, on).empty());
  EXPECT_EQ(on.rejected_epipolar, 1u);
  EXPECT_EQ(on.candidates_tested, 0u);
  p.constraints.epipolar_tolerance = 10.5;
  MatchStats wide;
  EXPECT_EQ(make_matcher(p)->match(left, right, wide).size(), 1u);
}

TEST_P(Constraints, DisparityRangeRejectsOutOfRange)
{
  cv::RNG rng(2);
  const cv::Mat d = random_descriptor(rng);
  const Features left = make_features({{100.f, 50.f}}, {d});
  const Features right = make_features({{20.f, 50.5f}}, {d.clone()}); // d = 80
  MatcherParams p = no_constraints(GetParam());
  p.constraints.epipolar_tolerance = 1.0;
  p.constraints.min_disparity = 0;
  p.constraints.max_disparity = 64;
  MatchStats st;
  EXPECT_TRUE(make_matcher(p)->match(left, right, st).empty());
  EXPECT_EQ(st.rejected_disparity, 1u);
  p.constraints.max_disparity = 100;
  MatchStats ok;
  const auto m = make_matcher(p)->match(left, right, ok);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_FLOAT_EQ(m[0].disparity(), 80.f);
}

TEST_P(Constraints, MutualCheckRejectsOneSidedMatch)
{
  // Both left keypoints' only candidate is B; B prefers A1 (the nearer descriptor).
  cv::RNG rng(5);
  const cv::Mat v = random_descriptor(rng);
  cv::Mat a1 = v.clone(), a2 = v.clone();
  a1.at<float>(0, 3) += 5.f;
  a2.at<float>(0, 7) += 60.f;
  a2.at<float>(0, 9) -= 60.f;
  const Features left = make_features({{100.f, 50.f}, {140.f, 50.f}}, {a1, a2});
  const Features right = make_features({{90.f, 50.f}}, {v});
  MatcherParams p = no_constraints(GetParam());
  p.candidates = 1; // cosine-norm: the angle alone decides which left keypoint B takes
  MatchStats one_sided;
  EXPECT_EQ(make_matcher(p)->match(left, right, one_sided).size(), 2u);
  p.constraints.mutual = true;
  MatchStats st;
  const auto m = make_matcher(p)->match(left, right, st);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].xl, 100.f);
  EXPECT_EQ(st.rejected_mutual, 1u);
}

INSTANTIATE_TEST_SUITE_P(BothMatchers, Constraints,
                         ::testing::Values(MatchMethod::Euclidean, MatchMethod::CosineNorm),
                         [](const auto &info) {
                           return std::string(info.param == MatchMethod::Euclidean ? "euclidean"
                                                                                    : "cosine_norm");
                         });

TEST(Euclidean, RatioTestRejectsAmbiguousMatch)
{
  cv::RNG rng(9);
  const cv::Mat v = random_descriptor(rng);
  cv::Mat b1 = v.clone(), b2 = v.clone();
  b1.at<float>(0, 1) += 10.f;
  b2.at<float>(0, 2) += 10.5f; // nearly as close as b1
  const Features left = make_features({{100.f, 50.f}}, {v});
  const Features right = make_features({{90.f, 50.f}, {60.f, 50.f}}, {b1, b2});
  MatcherParams p = no_constraints(MatchMethod::Euclidean);
  p.ratio = 0.8;
  MatchStats st;
  EXPECT_TRUE(EuclideanMatcher(p).match(left, right, st).empty());
  EXPECT_EQ(st.rejected_ratio, 1u);
}

TEST(Features, ScaledDetectionMapsKeypointsBackToFullResolution)
{
  // A dark Gaussian blob centred on pixel (100, 80): SIFT finds its centre.
  cv::Mat img(160, 200, CV_8U);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const double r2 = (x - 100.0) * (x - 100.0) + (y - 80.0) * (y - 80.0);
      img.at<std::uint8_t>(y, x) = cv::saturate_cast<std::uint8_t>(220 - 180 * std::exp(-r2 / (2 * 36.0)));
    }
  for (SiftEngine engine : {SiftEngine::OpenCV, SiftEngine::Upright})
    for (double scale : {1.0, 0.5}) {
      DetectParams p;
      p.engine = engine;
      p.scale = scale;
      const Features f = detect_features(img, cv::Mat(), p);
      double best = 1e9;
      for (const cv::KeyPoint &k : f.keypoints)
        best = std::min(best, std::hypot(k.pt.x - 100.0, k.pt.y - 80.0));
      EXPECT_LT(best, 0.2) << "scale " << scale << ", upright " << (engine == SiftEngine::Upright);
    }
}

TEST(Features, MaskAndRegionLimitDetection)
{
  const cv::Mat img = texture(cv::Size(320, 240), 11);
  cv::Mat mask = cv::Mat::zeros(img.size(), CV_8U);
  mask(cv::Rect(100, 60, 80, 70)).setTo(255);
  for (SiftEngine engine : {SiftEngine::OpenCV, SiftEngine::Upright}) {
    DetectParams p;
    p.engine = engine;
    const Features f = detect_features(img, mask, p);
    ASSERT_GT(f.size(), 10u);
    EXPECT_EQ(f.descriptors.rows, int(f.size()));
    EXPECT_EQ(f.region, cv::Rect(100 - 16, 60 - 16, 80 + 32, 70 + 32));
    // OpenCV's SIFT tests the mask 0.25 px off the position it reports (features.cpp)
    const float bias = engine == SiftEngine::OpenCV ? 0.25f : 0.f;
    for (const cv::KeyPoint &k : f.keypoints)
      EXPECT_EQ(mask.at<std::uint8_t>(cvRound(k.pt.y + bias), cvRound(k.pt.x + bias)), 255);
    EXPECT_EQ(detect_features(img, cv::Mat::zeros(img.size(), CV_8U), p).size(), 0u);
  }
  DetectParams p;
  EXPECT_THROW(detect_features(img, cv::Mat::zeros(10, 10, CV_8U), p), BadInput);
  EXPECT_THROW(detect_features(cv::Mat(10, 10, CV_32F), cv::Mat(), p), BadInput);
}

// mask_inset keeps keypoints off the canopy's edge by that many px of the detection image, not
// off the view's border, and nowhere else.
TEST(Features, MaskInsetKeepsKeypointsOffTheCanopysEdge)
{
  const cv::Mat img = texture(cv::Size(320, 240), 12);
  // The canopy: a disc in the middle, and a block touching the view's left border.
  cv::Mat mask = cv::Mat::zeros(img.size(), CV_8U);
  cv::circle(mask, cv::Point(200, 120), 70, cv::Scalar(255), cv::FILLED);
  mask(cv::Rect(0, 40, 60, 160)).setTo(255);
  // Distance of each pixel to the nearest non-canopy pixel, the view's border not counting.
  cv::Mat padded, dist;
  cv::copyMakeBorder(mask, padded, 1, 1, 1, 1, cv::BORDER_REPLICATE);
  cv::distanceTransform(padded, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  dist = dist(cv::Rect(1, 1, img.cols, img.rows));
  auto edge_distance = [&](const cv::KeyPoint &k) {
    return dist.at<float>(cvRound(k.pt.y), cvRound(k.pt.x));
  };
  for (double scale : {1.0, 0.5}) {
    DetectParams p;
    p.scale = scale;
    const Features all = detect_features(img, mask, p);
    p.mask_inset = 4;
    const Features inset = detect_features(img, mask, p);
    // Reach of 4 detection px at full resolution, less the rounding of the keypoint to the
    // detection grid (SIFT tests the mask at its own rounded position, 0.25 px off ours).
    const double reach = 4.0 / scale - 1.0 / scale;
    std::size_t near_edge = 0, near_border = 0;
    for (const cv::KeyPoint &k : all.keypoints) {
      const float d = edge_distance(k);
      near_edge += d < reach;
      near_border += k.pt.x < 8.0 / scale && d >= 6.0 / scale;
    }
    ASSERT_GT(near_edge, 5u) << "scale " << scale << ": the test needs keypoints at the edge";
    ASSERT_GT(near_border, 2u) << "scale " << scale << ": ... and at the view's border";
    std::size_t inset_near_border = 0;
    for (const cv::KeyPoint &k : inset.keypoints) {
      EXPECT_GE(edge_distance(k), reach)
          << "scale " << scale << ": keypoint at (" << k.pt.x << ", " << k.pt.y << ")";
      inset_near_border += k.pt.x < 8.0 / scale && edge_distance(k) >= 6.0 / scale;
    }
    // Inside, nothing else changes: the inset view keeps every keypoint away from the edge.
    std::size_t far_from_edge = 0;
    for (const cv::KeyPoint &k : all.keypoints)
      far_from_edge += edge_distance(k) >= 5.0 / scale;
    EXPECT_GE(inset.size(), far_from_edge) << "scale " << scale;
    EXPECT_LT(inset.size(), all.size()) << "scale " << scale;
    EXPECT_EQ(inset_near_border, near_border) << "scale " << scale << ": the border eroded";
  }
  DetectParams bad;
  bad.mask_inset = -1;
  EXPECT_THROW(FeatureDetector{bad}, BadSettings);
}

// The upright engine in two steps: describe() computes the flagged keypoints' descriptors, the
// same as describing all, and leaves the others at zero.
TEST(Features, UprightDescribesOnlyTheKeypointsItIsAskedFor)
{
  const cv::Mat img = texture(cv::Size(320, 240), 5);
  DetectParams p;
  p.engine = SiftEngine::Upright;
  const FeatureDetector det(p);
  const Features all = det.detect(img);
  ASSERT_GT(all.size(), 20u);
  LocatedFeatures located = det.locate(img);
  ASSERT_EQ(located.features.size(), all.size());
  std::vector<char> needed(all.size(), 0);
  for (std::size_t i = 0; i < needed.size(); i += 3)
    needed[i] = 1;
  const Features some = det.describe(std::move(located), needed);
  ASSERT_EQ(some.descriptors.rows, all.descriptors.rows);
  for (int i = 0; i < all.descriptors.rows; ++i) {
    EXPECT_EQ(some.keypoints[std::size_t(i)].pt, all.keypoints[std::size_t(i)].pt);
    if (needed[std::size_t(i)])
      EXPECT_EQ(cv::norm(some.descriptors.row(i), all.descriptors.row(i), cv::NORM_INF), 0.0);
    else
      EXPECT_EQ(cv::countNonZero(some.descriptors.row(i)), 0);
  }
  EXPECT_THROW(det.describe(det.locate(img), std::vector<char>(3, 1)), BadInput);
}

// StereoMatcher with the upright engine describes only keypoints that have a candidate in the
// other view (the relation is symmetric: the others are nobody's candidate). The matches are
// those of describing every keypoint, on a pair where many keypoints have no candidate.
TEST(StereoMatcher, UprightPruningChangesNoMatch)
{
  const double d_true = 9.4;
  const cv::Mat left = texture(cv::Size(480, 360), 41);
  cv::Mat right = shift_left(left, d_true);
  right(cv::Rect(0, 0, 480, 150)).setTo(128); // the left view's top has no partner
  for (MatchMethod method : {MatchMethod::Euclidean, MatchMethod::CosineNorm}) {
    MatchParams p;
    p.detect.engine = SiftEngine::Upright;
    p.matcher.method = method;
    p.matcher.constraints.min_disparity = 5;
    p.matcher.constraints.max_disparity = 14;
    p.refine = false;
    const StereoMatchResult r = StereoMatcher(p).run(left, right, cv::Mat(), cv::Mat());
    const FeatureDetector det(p.detect);
    const Features fl = det.detect(left), fr = det.detect(right);
    MatchStats st;
    const std::vector<StereoMatch> ref = make_matcher(p.matcher)->match(fl, fr, st);
    EXPECT_EQ(r.stats.keypoints[0], fl.size());
    EXPECT_EQ(r.stats.keypoints[1], fr.size());
    EXPECT_GT(st.rejected_epipolar + st.rejected_disparity, fl.size() / 4); // pruned in r
    EXPECT_EQ(r.stats.rejected_epipolar, st.rejected_epipolar);
    EXPECT_EQ(r.stats.rejected_disparity, st.rejected_disparity);
    ASSERT_EQ(r.matches.size(), ref.size());
    ASSERT_GT(ref.size(), 50u);
    for (std::size_t i = 0; i < ref.size(); ++i) {
      EXPECT_EQ(r.matches[i].xl, ref[i].xl);
      EXPECT_EQ(r.matches[i].yl, ref[i].yl);
      EXPECT_EQ(r.matches[i].xr, ref[i].xr);
      EXPECT_EQ(r.matches[i].yr, ref[i].yr);
    }
  }
}

TEST(Refine, RecoversSubPixelShift)
{
  const double d_true = 12.37;
  const cv::Mat left = texture(cv::Size(480, 360), 21);
  const cv::Mat right = shift_left(left, d_true);
  for (SiftEngine engine : {SiftEngine::OpenCV, SiftEngine::Upright}) {
    MatchParams p;
    p.detect.engine = engine;
    p.matcher.method = MatchMethod::Euclidean;
    p.matcher.constraints.min_disparity = 0;
    p.matcher.constraints.max_disparity = 40;
    p.refine = false;
    const StereoMatchResult raw = match_stereo(left, right, cv::Mat(), cv::Mat(), p);
    p.refine = true;
    const StereoMatchResult r = match_stereo(left, right, cv::Mat(), cv::Mat(), p);
    ASSERT_GT(r.matches.size(), 100u);
    const double err = median_abs_error(r.matches, d_true);
    std::cout << "refined (upright " << (engine == SiftEngine::Upright) << "): " << r.matches.size()
              << " matches, median |error| " << err << " px (unrefined "
              << median_abs_error(raw.matches, d_true) << " px), rejected "
              << r.stats.rejected_refine << "\n";
    EXPECT_LT(err, 0.1);
    for (const StereoMatch &m : r.matches)
      EXPECT_EQ(m.yr, m.yl);
  }
}

TEST(Refine, HalfScaleDetectionKeepsFullResolutionPrecision)
{
  const double d_true = 17.62;
  const cv::Mat left = texture(cv::Size(640, 480), 31);
  const cv::Mat right = shift_left(left, d_true);
  MatchParams p;
  p.detect.scale = 0.5;
  p.matcher.constraints.min_disparity = 0;
  p.matcher.constraints.max_disparity = 40;
  const StereoMatchResult r = match_stereo(left, right, cv::Mat(), cv::Mat(), p);
  ASSERT_GT(r.matches.size(), 50u);
  const double err = median_abs_error(r.matches, d_true);
  std::cout << "scale 0.5: " << r.matches.size() << " matches, median |error| " << err << " px\n";
  EXPECT_LT(err, 0.1);
}

TEST(Refine, RejectsMatchWithoutCorrelationPeak)
{
  const cv::Mat left = texture(cv::Size(200, 100), 41);
  const cv::Mat right = texture(cv::Size(200, 100), 42); // unrelated content
  std::vector<StereoMatch> m{{100.f, 50.f, 90.f, 50.f, 0.f}};
  EXPECT_EQ(refine_matches(left, right, m, RefineParams{}), 1u);
  EXPECT_TRUE(m.empty());
}

// A two-layer pair: a weakly textured background at disparity 10 and a strongly textured
// vertical band (x in [100, 140) of the left view) at disparity 16 in front of it; each layer's
// texture is attached to its surface, so the right view shows the band shifted by 16 px over the
// background shifted by 10 px (the band hides part of the background, as in a real scene).
struct TwoLayers {
  static constexpr int kBand0 = 100, kBand1 = 140;
  static constexpr double kBack = 10, kFront = 16;
  cv::Mat left, right;
  TwoLayers()
  {
    const cv::Size size(240, 120);
    cv::Mat back = texture(cv::Size(size.width + 40, size.height), 51);
    back.convertTo(back, -1, 0.12, 60); // a dim, low-contrast leaf in shadow
    const cv::Mat front = texture(cv::Size(size.width + 40, size.height), 52);
    left.create(size, CV_8U);
    right.create(size, CV_8U);
    for (int y = 0; y < size.height; ++y)
      for (int x = 0; x < size.width; ++x) {
        left.at<std::uint8_t>(y, x) = (x >= kBand0 && x < kBand1) ? front.at<std::uint8_t>(y, x)
                                                                  : back.at<std::uint8_t>(y, x);
        // Right pixel x sees the band point x + kFront when that lies in the band, else the
        // background point x + kBack.
        const int xf = x + int(kFront);
        right.at<std::uint8_t>(y, x) = (xf >= kBand0 && xf < kBand1)
                                           ? front.at<std::uint8_t>(y, xf)
                                           : back.at<std::uint8_t>(y, x + int(kBack));
      }
  }
  // A background pixel at bad_x matched at the band's disparity, then good ones: the band's
  // middle and the background far from the band, each at its own disparity.
  static std::vector<StereoMatch> matches(float bad_x, float y)
  {
    return {
        {bad_x, y, bad_x - float(kFront), y, 0.f},
        {120.f, y, 120.f - float(kFront), y, 0.f},
        {40.f, y, 40.f - float(kBack), y, 0.f},
        {200.f, y, 200.f - float(kBack), y, 0.f},
    };
  }
};

TEST(Refine, TwoLayerTestRejectsBackgroundPixelGivenTheForegroundDisparity)
{
  const TwoLayers s;
  const float y = 60;
  // Known bad: the background pixel just right of the band's edge, matched at the band's
  // disparity (the band's texture dominates its 7x7 patch). Good: the band's middle and the
  // background far from the band, each at its own disparity.
  const float bad_x = float(TwoLayers::kBand1) + 1;
  const std::vector<StereoMatch> input = TwoLayers::matches(bad_x, y);
  RefineParams off;
  std::vector<StereoMatch> m = input;
  refine_matches(s.left, s.right, m, off);
  // Without the test the bad match survives refinement at the foreground's disparity: the case
  // the test exists for.
  ASSERT_EQ(m.size(), 4u);
  EXPECT_NEAR(m[0].disparity(), TwoLayers::kFront, 1.0);

  RefineParams on;
  on.layer_tolerance = 0.5;
  m = input;
  EXPECT_EQ(refine_matches(s.left, s.right, m, on), 1u);
  ASSERT_EQ(m.size(), 3u);
  const double want[3] = {TwoLayers::kFront, TwoLayers::kBack, TwoLayers::kBack};
  for (int i = 0; i < 3; ++i) {
    EXPECT_NE(m[std::size_t(i)].xl, bad_x);
    EXPECT_NEAR(m[std::size_t(i)].disparity(), want[i], 0.1);
  }

  on.layer_search = 0;
  EXPECT_THROW(refine_matches(s.left, s.right, m, on), BadSettings);
}

// Relocation: a background pixel beside the band, matched at the band's disparity (its 7x7 patch
// is dominated by the band's texture), moves onto the band, keeping the disparity; matches on one
// surface stay where they are.
TEST(Refine, RelocationMovesABackgroundPixelOntoTheLayerItsDisparityBelongsTo)
{
  const TwoLayers s;
  const float y = 60;
  for (const int r : {1, 2}) {
    // the first background column with relocate 1, the second with 2: each within reach
    const float bad_x = float(TwoLayers::kBand1 - 1 + r);
    const std::vector<StereoMatch> input = TwoLayers::matches(bad_x, y);
    RefineParams p;
    std::vector<StereoMatch> m = input;
    refine_matches(s.left, s.right, m, p); // relocate = 0: lib's default
    ASSERT_EQ(m.size(), 4u);
    EXPECT_EQ(m[0].xl, bad_x);
    EXPECT_NEAR(m[0].disparity(), TwoLayers::kFront, 1.0);

    p.relocate = r;
    m = input;
    EXPECT_EQ(refine_matches(s.left, s.right, m, p), 0u);
    ASSERT_EQ(m.size(), 4u);
    EXPECT_LT(m[0].xl, float(TwoLayers::kBand1)) << "relocate " << r; // on the band now
    EXPECT_GE(m[0].xl, bad_x - float(r));
    EXPECT_LE(std::abs(m[0].yl - y), float(r));
    EXPECT_NEAR(m[0].disparity(), TwoLayers::kFront, 1.0); // the disparity is kept
    EXPECT_EQ(m[0].yr, m[0].yl);
    EXPECT_FLOAT_EQ(m[0].xl - m[0].xr, float(m[0].disparity()));
    for (std::size_t i = 1; i < 4; ++i) { // inside one surface: nothing to move to
      EXPECT_EQ(m[i].xl, input[i].xl) << "match " << i << ", relocate " << r;
      EXPECT_EQ(m[i].yl, input[i].yl) << "match " << i << ", relocate " << r;
    }
  }
}

// A foreground rectangle at disparity `front` over a background at `back`, each with its own
// texture attached to its surface (background contrast scaled by `back_contrast`): the right
// pixel x sees the rectangle's point x + front when that lies in the rectangle, else the
// background's point x + back. Left pixels of the background just left of the rectangle are
// hidden in the right view (occluded) when front > back.
struct Rectangle {
  cv::Mat left, right;
  Rectangle(cv::Rect rect, double front, double back, double back_contrast)
  {
    const cv::Size size(240, 120);
    const int pad = int(std::ceil(std::max(front, back))) + 2;
    cv::Mat bg = texture(cv::Size(size.width + pad, size.height), 61);
    bg.convertTo(bg, -1, back_contrast, 128 * (1 - back_contrast));
    const cv::Mat fg = texture(cv::Size(size.width + pad, size.height), 62);
    left.create(size, CV_8U);
    right.create(size, CV_8U);
    const auto in_rect = [&](double x, int y) {
      return y >= rect.y && y < rect.y + rect.height && x >= rect.x && x < rect.x + rect.width;
    };
    // The background's and the rectangle's points at a left x (sub-pixel: linear interpolation).
    const auto at = [](const cv::Mat &m, double x, int y) {
      const int i = int(std::floor(x));
      const double f = x - i;
      return (1 - f) * m.at<std::uint8_t>(y, i) + f * m.at<std::uint8_t>(y, i + 1);
    };
    for (int y = 0; y < size.height; ++y)
      for (int x = 0; x < size.width; ++x) {
        left.at<std::uint8_t>(y, x) =
            in_rect(x, y) ? fg.at<std::uint8_t>(y, x) : bg.at<std::uint8_t>(y, x);
        const double xf = x + front;
        right.at<std::uint8_t>(y, x) =
            cv::saturate_cast<std::uint8_t>(in_rect(xf, y) ? at(fg, xf, y) : at(bg, x + back, y));
      }
  }
};

TEST(Refine, LayerMinZnccRejectsOccludedBackgroundBesideForeground)
{
  // A strongly textured square at disparity 16 over a weakly textured background at 10. The
  // background pixel 1 px left of the square's left edge is hidden in the right view; its 7x7
  // patch is dominated by the square's texture and refines to the square's disparity. Its left
  // quadrants, all background, then compare background with unrelated background 6 px away
  // (the blurred texture decorrelates within a few px): a low ZNCC at the refined position.
  const cv::Rect square(100, 30, 60, 60);
  const double front = 16, back = 10;
  const Rectangle s(square, front, back, 0.12);
  const float y = 60, bad_x = float(square.x) - 1;
  const std::vector<StereoMatch> input{
      {bad_x, y, bad_x - float(front), y, 0.f},
      {130.f, y, 130.f - float(front), y, 0.f},
      {40.f, y, 40.f - float(back), y, 0.f},
  };
  // Peaks ignored (tolerances beyond the search range): only the ZNCC minimum can reject.
  RefineParams p;
  p.layer_tolerance = 100;
  p.layer_centre_tolerance = 100;
  std::vector<StereoMatch> m = input;
  refine_matches(s.left, s.right, m, p);
  ASSERT_EQ(m.size(), 3u); // the occluded pixel survives refinement at the square's disparity
  EXPECT_NEAR(m[0].disparity(), front, 1.0);

  p.layer_min_zncc = 0.7;
  m = input;
  EXPECT_EQ(refine_matches(s.left, s.right, m, p), 1u);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0].xl, 130.f);
  EXPECT_NEAR(m[0].disparity(), front, 0.1);
  EXPECT_EQ(m[1].xl, 40.f);
  EXPECT_NEAR(m[1].disparity(), back, 0.1);
}

TEST(Refine, LayerCentreTestJudgesTheCentreOnItsOwn)
{
  // A fine texture at disparity 10 everywhere but the 3x3 block around the left pixel (60, 60),
  // which the right view shows at disparity 12 (right pixels 47..49 of rows 59..61 show left
  // pixels 59..61). The 7x7 patch and the quadrants (4 of whose 36 pixels are in the block)
  // take disparity 10; the 3x3 centre alone peaks at 12, and at 10 it meets texture 2 px away,
  // which a fine texture no longer resembles.
  const cv::Size size(240, 120);
  cv::Mat noise(size, CV_32F);
  cv::RNG rng(91);
  rng.fill(noise, cv::RNG::UNIFORM, 0.f, 255.f);
  cv::GaussianBlur(noise, noise, cv::Size(), 0.8);
  cv::Mat left;
  noise.convertTo(left, CV_8U);
  cv::Mat right = shift_left(left, 10);
  for (int y = 59; y <= 61; ++y)
    for (int x = 47; x <= 49; ++x)
      right.at<std::uint8_t>(y, x) = left.at<std::uint8_t>(y, x + 12);
  const std::vector<StereoMatch> input{{60.f, 60.f, 50.f, 60.f, 0.f},
                                       {150.f, 60.f, 140.f, 60.f, 0.f}};
  RefineParams p;
  p.min_zncc = 0.5; // the block's 9 pixels lower the 7x7 patch's peak
  p.layer_tolerance = 0.5;
  p.layer_centre_tolerance = 3; // the centre's peak 2 px away does not matter
  std::vector<StereoMatch> m = input;
  EXPECT_EQ(refine_matches(left, right, m, p), 0u);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_NEAR(m[0].disparity(), 10, 0.5); // the block pulls the 7x7 patch a little

  p.layer_centre_tolerance = 0.7;
  m = input;
  EXPECT_EQ(refine_matches(left, right, m, p), 1u);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].xl, 150.f);

  p.layer_centre_tolerance = -1; // = layer_tolerance
  m = input;
  EXPECT_EQ(refine_matches(left, right, m, p), 1u);

  p.layer_centre_tolerance = 3;
  p.layer_centre_min_zncc = 0.6;
  m = input;
  EXPECT_EQ(refine_matches(left, right, m, p), 1u);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].xl, 150.f);
}

TEST(Refine, MinZnccDropRejectsPatchWithoutHorizontalStructure)
{
  // Top half: a horizontal edge (grey 60 above row 50, 190 below) with a faint texture; bottom
  // half: full texture. Shifted by 12.4 px. On the edge every position along the row correlates
  // almost equally well (the aperture problem): the faint texture alone places the peak.
  const double d = 12.4;
  const cv::Size size(240, 160);
  cv::Mat left = texture(size, 71);
  cv::Mat faint = texture(size, 72);
  for (int y = 0; y < 100; ++y)
    for (int x = 0; x < size.width; ++x)
      left.at<std::uint8_t>(y, x) =
          cv::saturate_cast<std::uint8_t>((y < 50 ? 60 : 190) + 0.08 * faint.at<std::uint8_t>(y, x));
  const cv::Mat right = shift_left(left, d);
  const std::vector<StereoMatch> input{{100.f, 50.f, 88.f, 50.f, 0.f},
                                       {100.f, 130.f, 88.f, 130.f, 0.f}};
  RefineParams p;
  std::vector<StereoMatch> m = input;
  EXPECT_EQ(refine_matches(left, right, m, p), 0u); // no drop required: both kept

  p.min_zncc_drop = 0.05;
  m = input;
  EXPECT_EQ(refine_matches(left, right, m, p), 1u);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].yl, 130.f);
  EXPECT_NEAR(m[0].disparity(), d, 0.1);
}

TEST(Refine, RejectsInvalidFilterParameters)
{
  const cv::Mat img = texture(cv::Size(64, 64), 81);
  std::vector<StereoMatch> m;
  const auto bad = [&](auto set) {
    RefineParams p;
    set(p);
    EXPECT_THROW(refine_matches(img, img, m, p), BadSettings);
  };
  bad([](RefineParams &p) { p.layer_centre_tolerance = std::nan(""); });
  bad([](RefineParams &p) { p.layer_min_zncc = 1.5; });
  bad([](RefineParams &p) { p.layer_centre_min_zncc = std::nan(""); });
  bad([](RefineParams &p) { p.min_zncc_drop = -0.1; });
  bad([](RefineParams &p) { p.min_zncc_drop = std::nan(""); });
  bad([](RefineParams &p) { p.relocate = -1; });
  bad([](RefineParams &p) { p.relocate = 4; });
}

TEST(FeaturesMatchRefine, ErrorsAreTypedAndNameTheProblem)
{
  // features
  expect_typed_error<BadInput>(
      [] { detect_features(cv::Mat(10, 10, CV_32F), cv::Mat(), DetectParams()); }, "8-bit");
  DetectParams detect;
  detect.scale = 2;
  expect_typed_error<BadSettings>([&] { FeatureDetector d{detect}; }, "scale");
  // match
  expect_typed_error<BadSettings>([] { parse_match_method("hamming"); }, "'hamming'");
  expect_typed_error<BadInput>([] { disparity_range_for_depth(StereoGeometry(), 1000, 2000); },
                               "baseline");
  // refine
  const cv::Mat a = texture(cv::Size(64, 64), 81), b = texture(cv::Size(32, 64), 82);
  std::vector<StereoMatch> m;
  expect_typed_error<BadInput>([&] { refine_matches(a, b, m, RefineParams()); }, "differ in size");
  RefineParams refine;
  refine.relocate = 4;
  expect_typed_error<BadSettings>([&] { refine_matches(a, a, m, refine); }, "relocate");
}

// The refinement windows follow the detection scale below 0.5 (a 2592 px wide view detected at
// 0.25 gets the windows a 1296 px view has at 0.5, in full-resolution pixels: twice as wide).
TEST(Refine, WindowsGrowBelowDetectionScaleOneHalf)
{
  RefineParams p;
  p.half_window = 3;
  p.layer_half_window = 5;
  p.search = 2;
  p.layer_tolerance = 0.5;
  for (double s : {1.0, 0.5}) {
    const RefineParams q = refine_params_for_scale(p, s);
    EXPECT_EQ(q.half_window, 3);
    EXPECT_EQ(q.layer_half_window, 5);
  }
  const RefineParams q = refine_params_for_scale(p, 0.25);
  EXPECT_EQ(q.half_window, 6);
  EXPECT_EQ(q.layer_half_window, 10);
  EXPECT_EQ(q.search, 2);              // the search and the tolerances stay
  EXPECT_EQ(q.layer_tolerance, 0.5);
  EXPECT_EQ(refine_params_for_scale(p, 0.125).half_window, 12);
}

TEST(Middlebury, PfmAndCalibRoundTrip)
{
  const std::string dir = ::testing::TempDir();
  // A 3x2 little-endian PFM, bottom row first: the top row must come out as {1, 2, inf}.
  {
    std::ofstream f(dir + "/t.pfm", std::ios::binary);
    f << "Pf\n3 2\n-1.0\n";
    const float rows[6] = {4, 5, 6, 1, 2, std::numeric_limits<float>::infinity()};
    f.write(reinterpret_cast<const char *>(rows), sizeof rows);
  }
  const cv::Mat d = read_pfm(dir + "/t.pfm");
  ASSERT_EQ(d.size(), cv::Size(3, 2));
  EXPECT_EQ(d.at<float>(0, 0), 1.f);
  EXPECT_EQ(d.at<float>(1, 2), 6.f);
  EXPECT_TRUE(std::isinf(d.at<float>(0, 2)));
  {
    std::ofstream f(dir + "/c.txt");
    f << "cam0=[1000 0 300; 0 1000 200; 0 0 1]\ncam1=[1000 0 350; 0 1000 200; 0 0 1]\n"
         "doffs=50\nbaseline=100\nwidth=640\nheight=480\nndisp=64\n";
  }
  const MiddleburyCalib c = read_middlebury_calib(dir + "/c.txt");
  const StereoGeometry g = c.geometry();
  EXPECT_DOUBLE_EQ(g.doffs(), -50.0);
  // Z = b f / (d + doffs): d = 50 -> Z = 1000 mm, through Q as well.
  const cv::Vec4d X = g.Q * cv::Vec4d(320, 200, 50, 1);
  EXPECT_NEAR(X[2] / X[3], 1000.0, 1e-9);
  const DisparityRange r = disparity_range_for_depth(g, 1000, 2000);
  EXPECT_DOUBLE_EQ(r.min, 0.0);
  EXPECT_DOUBLE_EQ(r.max, 50.0);
  EXPECT_THROW(read_pfm(dir + "/missing.pfm"), std::runtime_error);
  EXPECT_THROW(read_middlebury_calib(dir + "/t.pfm"), std::runtime_error);
}

TEST(Middlebury, JadeplantCorrectRate)
{
  const std::string dir = data_dir() + "/middlebury2014-quarter/Jadeplant";
  if (!std::ifstream(dir + "/disp0GT.pfm").good())
    GTEST_SKIP() << "Middlebury Jadeplant not found in " << dir
                 << " (set TREESTEREO_DATA_DIR to the shared data directory)";
  const MiddleburyScene s = load_middlebury_scene(dir);
  const FeatureDetector det{DetectParams{}};
  const Features fl = det.detect(s.left), fr = det.detect(s.right);
  // Ground-truth depth spans about 2.0-3.3 m.
  const DisparityRange range = disparity_range_for_depth(s.calib.geometry(), 1800, 3600);
  for (MatchMethod method : {MatchMethod::Euclidean, MatchMethod::CosineNorm}) {
    double plain_rate = 0;
    for (bool constrained : {false, true}) {
      MatcherParams p;
      p.method = method;
      if (!constrained) {
        p.constraints.epipolar_tolerance = -1;
        p.constraints.mutual = false;
      } else {
        p.constraints.epipolar_tolerance = 1.0;
        p.constraints.min_disparity = range.min;
        p.constraints.max_disparity = range.max;
      }
      MatchStats st;
      std::vector<StereoMatch> m = make_matcher(p)->match(fl, fr, st);
      if (constrained)
        refine_matches(s.left, s.right, m, RefineParams{});
      const MatchAccuracy acc = evaluate_matches(m, s.disp_gt, s.mask_nocc, 1.0);
      std::cout << match_method_name(method) << (constrained ? " +constraints" : " plain")
                << ": keypoints " << fl.size() << "/" << fr.size() << ", matches " << m.size()
                << ", evaluated " << acc.evaluated << ", wrong " << acc.wrong() << ", correct "
                << 100.0 * acc.correct_rate() << "%\n";
      if (constrained) {
        EXPECT_GT(acc.evaluated, 50u);
        // The target is 98%; Jadeplant's thin branches in front of a far wall keep it
        // lower: nearly all remaining errors are keypoints centred on the wall beside a branch
        // whose descriptor and patch are dominated by the branch (see docs/results-matching.md).
        EXPECT_GE(acc.correct_rate(), 0.85) << match_method_name(method);
        EXPECT_GT(acc.correct_rate(), plain_rate + 0.05) << match_method_name(method);
      } else {
        plain_rate = acc.correct_rate();
      }
    }
  }
}

// siftmatch's automatic scale: the largest power of two that brings the view to 648 px or less.
TEST(SiftmatchPreset, AutoScaleBringsTheViewTo648PxOrLess)
{
  EXPECT_EQ(SiftmatchPreset::auto_scale(640), 1.0);
  EXPECT_EQ(SiftmatchPreset::auto_scale(648), 1.0);
  EXPECT_EQ(SiftmatchPreset::auto_scale(649), 0.5);
  EXPECT_EQ(SiftmatchPreset::auto_scale(1296), 0.5);
  EXPECT_EQ(SiftmatchPreset::auto_scale(2592), 0.25);
  EXPECT_EQ(SiftmatchPreset::auto_scale(4000), 0.125);
}

// The preset is siftmatch's configuration, not lib's: the upright engine, the lower contrast
// threshold with its inset, and the two-layer test with its refinements and relocation.
TEST(SiftmatchPreset, HoldsTheElementsDefaults)
{
  const MatchParams p = SiftmatchPreset::params();
  EXPECT_EQ(p.detect.engine, SiftEngine::Upright);
  EXPECT_EQ(p.detect.contrast_threshold, 0.02);
  EXPECT_EQ(p.detect.mask_inset, 4);
  EXPECT_EQ(p.matcher.method, MatchMethod::Euclidean);
  EXPECT_EQ(p.matcher.constraints.epipolar_tolerance, 2.0);
  EXPECT_EQ(p.refine_params.layer_tolerance, 0.5);
  EXPECT_EQ(p.refine_params.min_zncc, 0.9);
  EXPECT_EQ(p.refine_params.relocate, 1);
  EXPECT_NO_THROW(check_refine_params(p.refine_params));

  const StereoGeometry g = simple_geometry(cv::Size(1296, 972), 1100, 50);
  const MatchParams v = SiftmatchPreset::for_view(g, g.view_size.width);
  EXPECT_EQ(v.detect.scale, 0.5);
  EXPECT_NEAR(v.matcher.constraints.min_disparity, 1100.0 * 50 / 10000, 1e-9);
  EXPECT_NEAR(v.matcher.constraints.max_disparity, 1100.0 * 50 / 500, 1e-9);
}
