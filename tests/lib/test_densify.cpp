// densify_matches on constructed pairs whose disparity is known at every pixel: a front layer
// with round holes through which a back layer is seen (each layer a smooth random texture shifted
// by its own disparity in the right view, occlusion exact), a flat patch, and bad input.
#include "treestereo/errors.hpp"
#include "treestereo/densify.hpp"
#include "treestereo/features.hpp"
#include "treestereo/stats.hpp"
#include "typed_error.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

using namespace treestereo;

namespace {

cv::Mat texture(cv::Size size, std::uint64_t seed)
{
  cv::Mat noise(size, CV_32F);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::UNIFORM, 0.f, 1.f);
  cv::GaussianBlur(noise, noise, cv::Size(), 1.5);
  cv::normalize(noise, noise, 20, 235, cv::NORM_MINMAX);
  return noise;
}

// `tex` sampled at x + d (cubic): what a surface with disparity d shows in the right view.
cv::Mat shifted(const cv::Mat &tex, double d)
{
  cv::Mat out;
  cv::warpAffine(tex, out, cv::Matx23d(1, 0, d, 0, 1, 0), tex.size(),
                 cv::INTER_CUBIC | cv::WARP_INVERSE_MAP, cv::BORDER_REFLECT);
  return out;
}

// Front layer (disparity df) with holes of radius `r` on a grid, back layer (db) behind.
struct TwoLayers {
  double df = 31.6, db = 26.3; // 5.3 px apart: a 0.6 m deep canopy at 2 m, 1296 px wide
  cv::Mat left, right; // CV_8U
  cv::Mat front;       // CV_8U, left view: 255 where the front layer is seen
  cv::Mat mask;        // the "canopy" in the left view
  double true_d(int x, int y) const { return front.at<uchar>(y, x) ? df : db; }
};

cv::Mat holes_layer(cv::Size size, int r, int spacing)
{
  cv::Mat m(size, CV_8U, cv::Scalar(255));
  for (int y = spacing / 2; y < size.height; y += spacing)
    for (int x = spacing / 2 + (y / spacing % 2) * spacing / 2; x < size.width; x += spacing)
      cv::circle(m, {x, y}, r, cv::Scalar(0), cv::FILLED);
  return m;
}

TwoLayers two_layers()
{
  TwoLayers s;
  const cv::Size size(400, 300);
  const cv::Mat F = texture(size, 3), B = texture(size, 4);
  s.front = holes_layer(size, 14, 44);
  cv::Mat l(size, CV_32F), r(size, CV_32F);
  const cv::Mat Fs = shifted(F, s.df), Bs = shifted(B, s.db);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x) {
      l.at<float>(y, x) = s.front.at<uchar>(y, x) ? F.at<float>(y, x) : B.at<float>(y, x);
      // The right pixel x sees the front layer where that layer's point x + df is solid.
      const int xf = std::min(size.width - 1, int(std::lround(x + s.df)));
      r.at<float>(y, x) = s.front.at<uchar>(y, xf) ? Fs.at<float>(y, x) : Bs.at<float>(y, x);
    }
  l.convertTo(s.left, CV_8U);
  r.convertTo(s.right, CV_8U);
  s.mask = cv::Mat::zeros(size, CV_8U);
  s.mask(cv::Rect(60, 30, 320, 240)).setTo(255);
  return s;
}

std::vector<StereoMatch> seeds_at(const std::vector<double> &disparities, int n)
{
  std::vector<StereoMatch> seeds;
  for (int i = 0; i < n; ++i) {
    const float x = float(100 + 7 * i), y = float(50 + 5 * i);
    const double d = disparities[std::size_t(i) % disparities.size()];
    seeds.push_back({x, y, float(x - d), y, 0.1f});
  }
  return seeds;
}

// True when the back layer's point seen at left pixel (x, y) is hidden by the front layer in
// the right view.
bool occluded_in_right(const TwoLayers &s, int x, int y)
{
  const int xf = int(std::lround(x - s.db + s.df));
  return !s.front.at<uchar>(y, x) && xf < s.front.cols && s.front.at<uchar>(y, xf);
}

// True when the (2h+1)^2 window around (x, y) lies on one layer and every pixel of it is seen
// by both views: such a window has exactly one correct match. (One pixel of margin: the right
// view's hole rims are placed to the nearest pixel.)
bool window_on_one_layer(const TwoLayers &s, int x, int y, int half_window)
{
  const int h = half_window + 1;
  const cv::Mat w = s.front(cv::Rect(x - h, y - h, 2 * h + 1, 2 * h + 1));
  const int n = cv::countNonZero(w);
  if (n != 0 && n != w.rows * w.cols)
    return false;
  for (int v = y - h; v <= y + h; ++v)
    for (int u = x - h; u <= x + h; ++u)
      if (occluded_in_right(s, u, v))
        return false;
  return true;
}

} // namespace

TEST(Densify, EvenGridWithTheTrueDisparityOfBothLayers)
{
  const TwoLayers s = two_layers();
  DensifyParams p;
  p.step = 4;
  p.edge_band = 0; // the even grid alone (EdgeBandsSampleTheExtremesFiner below)
  DensifyStats st;
  const std::vector<StereoMatch> m =
      densify_matches(s.left, s.right, s.mask, seeds_at({s.df, s.db}, 40), p, &st);
  EXPECT_EQ(st.step, 4);
  // The window spans the seeds' disparities plus the margin.
  EXPECT_EQ(st.min_disparity, int(std::floor(s.db - p.search_margin_px)));
  EXPECT_EQ(st.max_disparity, int(std::ceil(s.df + p.search_margin_px)));
  // Every mask pixel on the step-4 grid (phase 2) is tried: 320/4 x 240/4.
  EXPECT_EQ(st.grid, std::size_t(80 * 60));
  EXPECT_EQ(st.kept + st.flat + st.weak + st.ambiguous + st.inconsistent, st.grid);
  EXPECT_EQ(st.kept, m.size());

  std::size_t interior = 0, interior_kept = 0, wrong = 0, back_kept = 0, back_interior = 0;
  for (int y = 30; y < 270; ++y)
    for (int x = 60; x < 380; ++x)
      if (x % 4 == 2 && y % 4 == 2 && window_on_one_layer(s, x, y, p.half_window)) {
        ++interior;
        back_interior += s.front.at<uchar>(y, x) == 0;
      }
  std::vector<double> interior_err;
  for (const StereoMatch &g : m) {
    const int x = int(g.xl), y = int(g.yl);
    ASSERT_EQ(float(x), g.xl);
    ASSERT_EQ(x % 4, 2);
    ASSERT_EQ(y % 4, 2);
    ASSERT_TRUE(s.mask.at<uchar>(y, x));
    EXPECT_EQ(g.yr, g.yl);
    EXPECT_NEAR(g.score, 0.0, 1.0 - p.min_zncc + 1e-6);
    const double err = std::abs(g.disparity() - s.true_d(x, y));
    if (window_on_one_layer(s, x, y, p.half_window)) {
      ++interior_kept;
      interior_err.push_back(err);
      back_kept += s.front.at<uchar>(y, x) == 0;
    }
    wrong += err > 0.5;
  }
  // A window on one textured layer has one clear peak: (nearly) all of them are matched, to a
  // few hundredths of a pixel (as refine_matches). Windows across a hole's rim may be lost or
  // take the layer that dominates them; few are matched to a wrong disparity.
  ASSERT_FALSE(interior_err.empty());
  EXPECT_LT(median(interior_err), 0.03);
  EXPECT_LT(*std::max_element(interior_err.begin(), interior_err.end()), 0.2);
  EXPECT_GE(interior_kept, std::size_t(0.95 * double(interior)));
  EXPECT_GE(back_kept, std::size_t(0.95 * double(back_interior)));
  EXPECT_LE(wrong, m.size() / 10);
}

TEST(Densify, DisparitiesOutsideTheSeedsWindowAreNotMatched)
{
  const TwoLayers s = two_layers();
  DensifyParams p;
  p.step = 4;
  p.search_margin_px = 1.0;
  DensifyStats st;
  // Seeds only on the front layer: the window is [df - 1, df + 1], the back layer 4.3 px
  // beyond its end.
  const std::vector<StereoMatch> m =
      densify_matches(s.left, s.right, s.mask, seeds_at({s.df}, 30), p, &st);
  EXPECT_EQ(st.min_disparity, int(std::floor(s.df - p.search_margin_px)));
  EXPECT_GT(st.kept, st.grid / 2);
  std::size_t back_interior = 0, back_matched = 0;
  for (int y = 30; y < 270; ++y)
    for (int x = 60; x < 380; ++x)
      if (x % 4 == 2 && y % 4 == 2 && !s.front.at<uchar>(y, x) &&
          window_on_one_layer(s, x, y, p.half_window))
        ++back_interior;
  std::vector<double> front_err;
  for (const StereoMatch &g : m) {
    const int x = int(g.xl), y = int(g.yl);
    if (!window_on_one_layer(s, x, y, p.half_window))
      continue; // a window across a rim: either layer or in between
    if (s.front.at<uchar>(y, x))
      front_err.push_back(std::abs(g.disparity() - s.df));
    else
      ++back_matched; // only a chance correlation can match it inside the window
  }
  ASSERT_GT(back_interior, 50u);
  EXPECT_LE(back_matched, back_interior / 20);
  ASSERT_FALSE(front_err.empty());
  EXPECT_LT(median(front_err), 0.03);
}

TEST(Densify, AutomaticStepGivesAboutTheTargetCount)
{
  const TwoLayers s = two_layers();
  DensifyParams p;
  p.target_points = 1200; // mask area 76800 px: step sqrt(64) = 8
  p.edge_band = 0;
  DensifyStats st;
  densify_matches(s.left, s.right, s.mask, seeds_at({s.df, s.db}, 20), p, &st);
  EXPECT_EQ(st.step, 8);
  EXPECT_EQ(st.grid, std::size_t(40 * 30));
}

// The edge bands: every mask pixel on the fine grid (edge_step, phase edge_step / 2 from the
// view's origin) within edge_band of the box's height (width) of its top and bottom rows (left
// and right columns) is tried as well as the even grid, and matched as well.
TEST(Densify, EdgeBandsSampleTheExtremesFiner)
{
  const TwoLayers s = two_layers(); // mask: x 60..379, y 30..269
  DensifyParams p;
  p.step = 8;
  p.edge_band = 0.1; // 24 rows at the top and bottom, 32 columns at the left and right
  p.edge_step = 2;
  DensifyStats st;
  const std::vector<StereoMatch> m =
      densify_matches(s.left, s.right, s.mask, seeds_at({s.df, s.db}, 40), p, &st);
  EXPECT_EQ(st.edge_step, 2);
  const auto in_band = [](int x, int y) {
    return y < 30 + 24 || y >= 270 - 24 || x < 60 + 32 || x >= 380 - 32;
  };
  // The grid points expected, counted here from the definition.
  std::size_t coarse = 0, band = 0;
  for (int y = 30; y < 270; ++y)
    for (int x = 60; x < 380; ++x) {
      const bool c = x % 8 == 4 && y % 8 == 4, f = x % 2 == 1 && y % 2 == 1 && in_band(x, y);
      coarse += c;
      band += f && !c;
    }
  EXPECT_EQ(coarse, std::size_t(40 * 30));
  EXPECT_EQ(st.grid, coarse + band);
  EXPECT_EQ(st.kept, m.size());

  std::vector<double> band_err;
  std::size_t band_interior = 0;
  for (int y = 30; y < 270; ++y)
    for (int x = 60; x < 380; ++x)
      if (x % 2 == 1 && y % 2 == 1 && in_band(x, y) && window_on_one_layer(s, x, y, p.half_window))
        ++band_interior;
  for (const StereoMatch &g : m) {
    const int x = int(g.xl), y = int(g.yl);
    const bool c = x % 8 == 4 && y % 8 == 4, f = x % 2 == 1 && y % 2 == 1 && in_band(x, y);
    ASSERT_TRUE(c || f) << "(" << x << ", " << y << ") on neither grid";
    if (f && window_on_one_layer(s, x, y, p.half_window))
      band_err.push_back(std::abs(g.disparity() - s.true_d(x, y)));
  }
  ASSERT_GT(band_interior, 1000u);
  EXPECT_GE(band_err.size(), std::size_t(0.95 * double(band_interior)));
  EXPECT_LT(median(band_err), 0.03);

  // Automatic: the view's width / 648 (here 400 px: 0.6), but at least 2 px.
  p.edge_step = 0;
  densify_matches(s.left, s.right, s.mask, seeds_at({s.df, s.db}, 40), p, &st);
  EXPECT_EQ(st.edge_step, 2);

  // Off: the even grid alone.
  p.edge_band = 0;
  densify_matches(s.left, s.right, s.mask, seeds_at({s.df, s.db}, 40), p, &st);
  EXPECT_EQ(st.grid, coarse);
  EXPECT_EQ(st.edge_step, 0);

  p.edge_band = 0.6;
  EXPECT_THROW(densify_matches(s.left, s.right, s.mask, seeds_at({s.df}, 20), p),
               BadSettings);
  p.edge_band = 0.1;
  p.edge_step = -1;
  EXPECT_THROW(densify_matches(s.left, s.right, s.mask, seeds_at({s.df}, 20), p),
               BadSettings);
}

TEST(Densify, ColourViewsAsTheirGreyAndFlatPatchesAreSkipped)
{
  const TwoLayers s = two_layers();
  DensifyParams p;
  p.step = 6;
  const std::vector<StereoMatch> seeds = seeds_at({s.df, s.db}, 20);
  const std::vector<StereoMatch> grey = densify_matches(s.left, s.right, s.mask, seeds, p);
  // The same pair as RGB (R = G = B): the grey conversion gives the grey views back.
  cv::Mat lc, rc;
  cv::cvtColor(s.left, lc, cv::COLOR_GRAY2RGB);
  cv::cvtColor(s.right, rc, cv::COLOR_GRAY2RGB);
  p.order = ChannelOrder{0, 1, 2, 3};
  const std::vector<StereoMatch> colour = densify_matches(lc, rc, s.mask, seeds, p);
  ASSERT_EQ(grey.size(), colour.size());
  for (std::size_t i = 0; i < grey.size(); ++i)
    EXPECT_NEAR(grey[i].xr, colour[i].xr, 1e-3);

  // A uniform patch in both views: no texture, no match.
  cv::Mat l = s.left.clone(), r = s.right.clone();
  l(cv::Rect(100, 100, 60, 60)).setTo(128);
  r.setTo(128);
  DensifyStats st;
  p.order = ChannelOrder{};
  const std::vector<StereoMatch> flat = densify_matches(l, r, s.mask, seeds, p, &st);
  EXPECT_GT(st.flat, 0u);
  for (const StereoMatch &g : flat)
    EXPECT_FALSE(g.xl >= 100 + p.half_window && g.xl < 160 - p.half_window &&
                 g.yl >= 100 + p.half_window && g.yl < 160 - p.half_window);
}

TEST(Densify, TooFewSeedsOrBadInput)
{
  const TwoLayers s = two_layers();
  DensifyParams p;
  DensifyStats st;
  st.grid = 99;
  EXPECT_TRUE(densify_matches(s.left, s.right, s.mask, seeds_at({s.df}, p.min_seeds - 1), p, &st)
                  .empty());
  EXPECT_EQ(st.grid, 0u);
  EXPECT_EQ(st.kept, 0u);
  const std::vector<StereoMatch> seeds = seeds_at({s.df}, 20);
  // An empty mask: no canopy, nothing to sample.
  EXPECT_TRUE(densify_matches(s.left, s.right, cv::Mat::zeros(s.mask.size(), CV_8U), seeds, p, &st)
                  .empty());
  EXPECT_EQ(st.grid, 0u);
  EXPECT_THROW(densify_matches(s.left, s.right(cv::Rect(0, 0, 100, 100)), s.mask, seeds, p),
               BadInput);
  EXPECT_THROW(densify_matches(s.left, s.right, s.mask(cv::Rect(0, 0, 100, 100)), seeds, p),
               BadInput);
  cv::Mat rc;
  cv::cvtColor(s.right, rc, cv::COLOR_GRAY2BGR);
  EXPECT_THROW(densify_matches(s.left, rc, s.mask, seeds, p), BadInput);
  p.step = -1;
  EXPECT_THROW(densify_matches(s.left, s.right, s.mask, seeds, p), BadSettings);
  p.step = 0;
  p.half_window = 0;
  EXPECT_THROW(densify_matches(s.left, s.right, s.mask, seeds, p), BadSettings);
}

TEST(Densify, ErrorsAreTypedAndNameTheProblem)
{
  const TwoLayers s = two_layers();
  const std::vector<StereoMatch> seeds = seeds_at({s.df}, 20);
  expect_typed_error<BadInput>(
      [&] { densify_matches(s.left, s.right, s.mask(cv::Rect(0, 0, 100, 100)), seeds, {}); },
      "mask does not fit");
  DensifyParams p;
  p.min_seeds = 0;
  expect_typed_error<BadSettings>([&] { densify_matches(s.left, s.right, s.mask, seeds, p); },
                                  "min seeds");
}

TEST(Densify, GreyConversionFollowsTheChannelOrder)
{
  // One xRGB pixel: padding first, then R = 200, G = 100, B = 50.
  const cv::Mat px(1, 1, CV_8UC4, cv::Scalar(7, 200, 100, 50));
  const cv::Mat g = to_gray8(px, ChannelOrder{1, 2, 3, 4});
  EXPECT_EQ(int(g.at<uchar>(0, 0)), int(std::lround(0.299 * 200 + 0.587 * 100 + 0.114 * 50)));
  EXPECT_THROW(to_gray8(px, ChannelOrder{2, 1, 0, 3}), BadInput);
}
