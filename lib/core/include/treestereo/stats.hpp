// Robust statistics shared by the renderer's ground truth, stereodepth and treemetrics.
#pragma once

#include <vector>

namespace treestereo {

// Percentile by linear interpolation between closest ranks (numpy's default), p in [0, 100].
// The vector is reordered. Returns 0 for an empty vector.
double percentile(std::vector<double> &values, double p);

// Median (the 50th percentile as above). The vector is reordered.
double median(std::vector<double> &values);

// Median absolute deviation from the median (unscaled). The vector is reordered.
double mad(std::vector<double> &values, double med);

// Percentile of values each standing for `weights[i]` of the whole (e.g. the image area a point
// represents), p in [0, 100]: the smallest value at which the cumulative weight reaches p %.
// Non-positive weights count as nothing; no weight at all gives 0. Sizes must match.
double weighted_percentile(const std::vector<double> &values, const std::vector<double> &weights,
                           double p);
// The same for several percentiles at once (one sort of the values): result[i] is ps[i]'s.
std::vector<double> weighted_percentiles(const std::vector<double> &values,
                                         const std::vector<double> &weights,
                                         const std::vector<double> &ps);

struct Summary {
  std::size_t n = 0;
  double median = 0, mad = 0, p05 = 0, p95 = 0, mean = 0, stddev = 0, min = 0, max = 0;
};
// All of the above at once; the input is left untouched.
Summary summarize(const std::vector<double> &values);

} // namespace treestereo
