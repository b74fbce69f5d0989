// lib's internal correlation (lib/core/src/zncc.hpp), shared by refinement and densification: the
// ZNCC against its definition, the same with and without the vector loop, and its limits.
#include "../../lib/core/src/zncc.hpp"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include <cmath>

using treestereo::detail::Patch;
using treestereo::detail::centred_patch;
using treestereo::detail::zncc;

namespace {

// The definition, in doubles: sum (l - ml)(r - mr) / sqrt(sum (l - ml)^2 sum (r - mr)^2).
double reference(const cv::Mat &a, int ax, int ay, const cv::Mat &b, int bx, int by, int h)
{
  const int n = 2 * h + 1;
  double ml = 0, mr = 0;
  for (int y = -h; y <= h; ++y)
    for (int x = -h; x <= h; ++x) {
      ml += a.at<uchar>(ay + y, ax + x);
      mr += b.at<uchar>(by + y, bx + x);
    }
  ml /= n * n;
  mr /= n * n;
  double c = 0, vl = 0, vr = 0;
  for (int y = -h; y <= h; ++y)
    for (int x = -h; x <= h; ++x) {
      const double l = a.at<uchar>(ay + y, ax + x) - ml, r = b.at<uchar>(by + y, bx + x) - mr;
      c += l * r;
      vl += l * l;
      vr += r * r;
    }
  return c / std::sqrt(vl * vr);
}

} // namespace

TEST(Zncc, MatchesItsDefinitionForEveryPatchSize)
{
  cv::Mat a(60, 90, CV_8U), b(60, 90, CV_8U);
  cv::randu(a, 0, 256);
  b = a * 0.5 + 40; // correlated, then noise
  cv::Mat noise(b.size(), CV_8U);
  cv::randu(noise, 0, 60);
  b += noise;
  // h = 1, 3: one 8-lane chunk a row; 5: two; 10: three (21 px). The right patch at every
  // column up to the image's edge, where the vector loop would read past it (the scalar path).
  for (int h : {1, 3, 5, 10}) {
    Patch p;
    ASSERT_TRUE(centred_patch(a, 30, 30, h, p));
    for (int cx = h; cx < b.cols - h; ++cx) {
      const double z = zncc(p, b, cx, 30);
      EXPECT_NEAR(z, reference(a, 30, 30, b, cx, 30, h), 1e-12) << "h " << h << ", cx " << cx;
    }
    // against itself: 1
    EXPECT_NEAR(zncc(p, a, 30, 30), 1.0, 1e-12) << "h " << h;
  }
}

TEST(Zncc, TheSameWithAndWithoutTheVectorLoop)
{
  // The same content with the patch against the right edge of a narrow image (the padded 8-lane
  // rows would read past it: the scalar path) and inside a wider one (the vector path):
  // whole-number sums, equal scores.
  cv::Mat wide(30, 40, CV_8U);
  cv::randu(wide, 0, 256);
  const cv::Mat narrow = wide.colRange(0, 24).clone(); // column 23 is the last
  for (int h : {3, 5}) {
    Patch p;
    ASSERT_TRUE(centred_patch(wide, 12, 12, h, p));
    const int cx = 23 - h; // the patch's last column is the image's
    ASSERT_GT(cx - h + p.stride(), narrow.cols);
    ASSERT_LE(cx - h + p.stride(), wide.cols);
    EXPECT_EQ(zncc(p, narrow, cx, 12), zncc(p, wide, cx, 12)) << "h " << h;
    EXPECT_NEAR(zncc(p, narrow, cx, 12), reference(wide, 12, 12, wide, cx, 12, h), 1e-12);
  }
}

TEST(Zncc, FlatPatchesAndInvertedContrast)
{
  cv::Mat a(20, 20, CV_8U);
  cv::randu(a, 0, 256);
  Patch p;
  ASSERT_TRUE(centred_patch(a, 10, 10, 3, p));
  const cv::Mat flat(20, 20, CV_8U, cv::Scalar(77));
  EXPECT_EQ(zncc(p, flat, 10, 10), -1.0); // no texture to correlate with
  Patch q;
  EXPECT_FALSE(centred_patch(flat, 10, 10, 3, q));
  const cv::Mat inverted = 255 - a;
  EXPECT_NEAR(zncc(p, inverted, 10, 10), -1.0, 1e-12);
}
