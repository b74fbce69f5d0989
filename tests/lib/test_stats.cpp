#include "treestereo/stats.hpp"

#include <gtest/gtest.h>

using namespace treestereo;

TEST(Stats, PercentileInterpolatesLikeNumpy)
{
  std::vector<double> v{4, 1, 3, 2, 5};
  EXPECT_DOUBLE_EQ(percentile(v, 0), 1.0);
  EXPECT_DOUBLE_EQ(percentile(v, 100), 5.0);
  EXPECT_DOUBLE_EQ(percentile(v, 50), 3.0);
  // numpy.percentile([1,2,3,4,5], 5) = 1.2, 95 -> 4.8
  EXPECT_NEAR(percentile(v, 5), 1.2, 1e-12);
  EXPECT_NEAR(percentile(v, 95), 4.8, 1e-12);
  std::vector<double> even{10, 0};
  EXPECT_DOUBLE_EQ(median(even), 5.0);
}

TEST(Stats, EmptyGivesZeroNotNaN)
{
  std::vector<double> v;
  EXPECT_EQ(percentile(v, 50), 0.0);
  Summary s = summarize(v);
  EXPECT_EQ(s.n, 0u);
  EXPECT_EQ(s.median, 0.0);
}

TEST(Stats, MadIgnoresOneOutlier)
{
  std::vector<double> v{10, 11, 9, 10, 10, 1000};
  Summary s = summarize(v);
  EXPECT_DOUBLE_EQ(s.median, 10.0);
  EXPECT_DOUBLE_EQ(s.mad, 0.5);
  EXPECT_EQ(s.min, 9.0);
  EXPECT_EQ(s.max, 1000.0);
}

TEST(Stats, WeightedPercentileFollowsTheWeights)
{
  // 9 samples at 1 standing for 40 % of the area, 1 sample at 2 standing for 60 %
  std::vector<double> v{1, 1, 1, 1, 1, 1, 1, 1, 1, 2};
  std::vector<double> w(10, 40.0 / 9);
  w[9] = 60;
  EXPECT_DOUBLE_EQ(weighted_percentile(v, w, 50), 2.0);
  EXPECT_DOUBLE_EQ(weighted_percentile(v, w, 30), 1.0);
  // equal weights: an order statistic, like percentile() without interpolation
  std::vector<double> e(10, 1.0);
  EXPECT_DOUBLE_EQ(weighted_percentile(v, e, 50), 1.0);
  EXPECT_DOUBLE_EQ(weighted_percentile(v, e, 100), 2.0);
  EXPECT_EQ(weighted_percentile(v, std::vector<double>(10, 0.0), 50), 0.0);
  EXPECT_THROW(weighted_percentile(v, {1.0}, 50), std::invalid_argument);
}

TEST(Stats, WeightedPercentilesAreEachOneAlone)
{
  // Unsorted values with ties and a non-positive weight: each of several percentiles at once
  // equals the one asked alone.
  const std::vector<double> v{5, 3, 9, 3, 1, 7, 7, 2, 8, 4};
  const std::vector<double> w{1, 2, 0.5, 3, -1, 2, 1, 4, 0, 1.5};
  const std::vector<double> ps{0, 5, 30, 50, 95, 100, 120};
  const std::vector<double> all = weighted_percentiles(v, w, ps);
  ASSERT_EQ(all.size(), ps.size());
  for (std::size_t i = 0; i < ps.size(); ++i)
    EXPECT_EQ(all[i], weighted_percentile(v, w, ps[i])) << "p = " << ps[i];
  // By value the positive weights run 4 (at 2), 2 and 3 (at 3), ...: 15 in all, so the
  // cumulative weight passes 50 % (7.5) at the second 3 (9).
  EXPECT_EQ(all[3], 3.0);
  EXPECT_EQ(weighted_percentiles(v, std::vector<double>(10, 0.0), {50, 95}),
            (std::vector<double>{0.0, 0.0}));
  EXPECT_THROW(weighted_percentiles(v, {1.0}, {50}), std::invalid_argument);
}
