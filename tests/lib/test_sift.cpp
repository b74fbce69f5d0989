// The project's upright SIFT (lib/core/src/sift.cpp) against OpenCV 4.6's SIFT as the reference: the
// same places and scales, and at angle 0 the same descriptors, on a real photograph (a fixture
// view of the pipeline tests); and a blob found at its sub-pixel centre.
#include "treestereo/sift.hpp"

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <string>

using namespace treestereo;

namespace {

cv::Mat fixture_view()
{
  const std::string path = std::string(TREESTEREO_SOURCE_DIR) + "/tests/fixtures/seq-static/left_0000.jpg";
  cv::Mat img = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (img.empty())
    ADD_FAILURE() << "cannot read " << path;
  return img(cv::Rect(160, 120, 320, 240)).clone(); // the tree, as siftmatch's canopy crop
}

// OpenCV 4.6's SIFT reports every position 0.25 px right of and below the true one (its 2x
// upsampling, see features.cpp); ours are exact.
constexpr float kOpenCVBias = 0.25f;

} // namespace

TEST(Sift, FindsOpenCVsPlacesAndScales)
{
  const cv::Mat img = fixture_view();
  ASSERT_FALSE(img.empty());
  const double contrast = 0.035;
  std::vector<cv::KeyPoint> ref;
  cv::SIFT::create(0, 3, contrast, 10, 1.6)->detect(img, ref);
  SiftPyramid pyr;
  const std::vector<cv::KeyPoint> ours = UprightSift(SiftParams{3, 1.6, contrast, 10}).detect(img, cv::Mat(), pyr);
  ASSERT_GT(ref.size(), 200u);

  // OpenCV repeats a place once per dominant orientation: compare places.
  auto found_in = [](const cv::KeyPoint &k, const std::vector<cv::KeyPoint> &set, float shift) {
    for (const cv::KeyPoint &o : set)
      if (std::hypot(o.pt.x + shift - k.pt.x, o.pt.y + shift - k.pt.y) < 0.02f &&
          std::abs(o.size - k.size) < 0.01f * k.size)
        return true;
    return false;
  };
  int ref_found = 0, ours_found = 0;
  for (const cv::KeyPoint &k : ref)
    ref_found += found_in(k, ours, kOpenCVBias);
  for (const cv::KeyPoint &k : ours)
    ours_found += found_in(k, ref, -kOpenCVBias);
  EXPECT_GE(ref_found, int(0.98 * ref.size())) << ref_found << " of " << ref.size();
  EXPECT_GE(ours_found, int(0.98 * ours.size())) << ours_found << " of " << ours.size();
  for (const cv::KeyPoint &k : ours)
    EXPECT_EQ(k.angle, 0.f);
}

TEST(Sift, DescriptorsAreOpenCVsAtAngleZero)
{
  const cv::Mat img = fixture_view();
  ASSERT_FALSE(img.empty());
  const UprightSift sift(SiftParams{3, 1.6, 0.035, 10});
  SiftPyramid pyr;
  const std::vector<cv::KeyPoint> ours = sift.detect(img, cv::Mat(), pyr);
  ASSERT_GT(ours.size(), 200u);
  const cv::Mat desc = sift.describe(pyr, ours);
  ASSERT_EQ(desc.rows, int(ours.size()));
  ASSERT_EQ(desc.cols, 128);
  ASSERT_EQ(desc.type(), CV_32F);

  // The same keypoints in OpenCV's packing (octave from -1, layer, position with its bias),
  // described by OpenCV at angle 0.
  std::vector<cv::KeyPoint> cv_kps;
  for (const cv::KeyPoint &k : ours) {
    cv::KeyPoint c = k;
    c.pt += cv::Point2f(kOpenCVBias, kOpenCVBias);
    const int octave = (k.octave & 255) - 1, layer = (k.octave >> 8) & 255;
    c.octave = (octave & 255) | (layer << 8) | (128 << 16);
    c.angle = 0;
    cv_kps.push_back(c);
  }
  cv::Mat ref;
  cv::SIFT::create(0, 3, 0.035, 10, 1.6, CV_32F)->compute(img, cv_kps, ref);
  ASSERT_EQ(ref.rows, desc.rows); // OpenCV kept every keypoint, in order

  // Descriptors are bytes on a vector of norm ~512; fast arctangent and rounding differ a little.
  int close = 0;
  double worst = 0;
  for (int i = 0; i < desc.rows; ++i) {
    const double d = cv::norm(desc.row(i), ref.row(i), cv::NORM_L2), n = cv::norm(ref.row(i));
    worst = std::max(worst, d / n);
    close += d < 0.02 * n;
  }
  EXPECT_GE(close, int(0.99 * desc.rows)) << close << " of " << desc.rows << ", worst " << worst;
  EXPECT_LT(worst, 0.02);
}

TEST(Sift, FindsABlobAtItsSubPixelCentreAndScale)
{
  // A dark Gaussian blob of sigma 5 centred at (100.3, 80.6): the scale-normalised Laplacian
  // peaks at the blob's sigma.
  cv::Mat img(160, 200, CV_8U);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const double r2 = (x - 100.3) * (x - 100.3) + (y - 80.6) * (y - 80.6);
      img.at<uchar>(y, x) = cv::saturate_cast<uchar>(220 - 180 * std::exp(-r2 / (2 * 25.0)));
    }
  SiftPyramid pyr;
  const std::vector<cv::KeyPoint> kps = UprightSift().detect(img, cv::Mat(), pyr);
  ASSERT_FALSE(kps.empty());
  const cv::KeyPoint *best = &kps[0];
  for (const cv::KeyPoint &k : kps)
    if (k.response > best->response)
      best = &k;
  EXPECT_NEAR(best->pt.x, 100.3, 0.1);
  EXPECT_NEAR(best->pt.y, 80.6, 0.1);
  EXPECT_NEAR(best->size / 2, 5.0, 1.0); // size is the diameter, 2 sigma
}

TEST(Sift, MaskAndInputChecks)
{
  const cv::Mat img = fixture_view();
  ASSERT_FALSE(img.empty());
  cv::Mat mask = cv::Mat::zeros(img.size(), CV_8U);
  mask(cv::Rect(80, 60, 120, 100)).setTo(255);
  const UprightSift sift;
  SiftPyramid pyr;
  const std::vector<cv::KeyPoint> kps = sift.detect(img, mask, pyr);
  ASSERT_GT(kps.size(), 10u);
  for (const cv::KeyPoint &k : kps)
    EXPECT_EQ(mask.at<uchar>(cvRound(k.pt.y), cvRound(k.pt.x)), 255);
  EXPECT_THROW(sift.detect(cv::Mat(), cv::Mat(), pyr), std::runtime_error);
  EXPECT_THROW(sift.detect(cv::Mat(10, 10, CV_32F), cv::Mat(), pyr), std::runtime_error);
  EXPECT_THROW(sift.detect(img, cv::Mat::zeros(10, 10, CV_8U), pyr), std::runtime_error);
  EXPECT_THROW(UprightSift(SiftParams{0, 1.6, 0.04, 10}), std::runtime_error);
  // A keypoint from another pyramid (an octave this one does not have) is refused.
  SiftPyramid small;
  (void)sift.detect(img(cv::Rect(0, 0, 40, 40)).clone(), cv::Mat(), small);
  cv::KeyPoint far = kps[0];
  far.octave = 7;
  EXPECT_THROW(sift.describe(small, {far}), std::runtime_error);
}
