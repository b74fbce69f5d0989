#include "treestereo/stats.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace treestereo {

double percentile(std::vector<double> &v, double p)
{
  if (v.empty())
    return 0.0;
  p = std::clamp(p, 0.0, 100.0);
  const double rank = p / 100.0 * double(v.size() - 1);
  const std::size_t lo = std::size_t(std::floor(rank));
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  std::nth_element(v.begin(), v.begin() + lo, v.end());
  const double a = v[lo];
  if (hi == lo)
    return a;
  // The next order statistic is the minimum of the part above lo.
  const double b = *std::min_element(v.begin() + lo + 1, v.end());
  return a + (rank - double(lo)) * (b - a);
}

double median(std::vector<double> &v) { return percentile(v, 50.0); }

double mad(std::vector<double> &v, double med)
{
  std::vector<double> dev(v.size());
  std::transform(v.begin(), v.end(), dev.begin(), [med](double x) { return std::abs(x - med); });
  return median(dev);
}

std::vector<double> weighted_percentiles(const std::vector<double> &values,
                                         const std::vector<double> &weights,
                                         const std::vector<double> &ps)
{
  if (values.size() != weights.size())
    throw std::invalid_argument("weighted_percentile: values and weights differ in size");
  std::vector<double> out(ps.size(), 0.0);
  double total = 0.0;
  for (double w : weights)
    total += w > 0 ? w : 0.0;
  if (total <= 0)
    return out;
  std::vector<std::size_t> order(values.size());
  std::iota(order.begin(), order.end(), std::size_t(0));
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return values[a] < values[b]; });
  for (std::size_t k = 0; k < ps.size(); ++k) {
    const double target = std::clamp(ps[k], 0.0, 100.0) / 100.0 * total;
    double cum = 0.0;
    out[k] = values[order.back()];
    for (std::size_t i : order) {
      cum += weights[i] > 0 ? weights[i] : 0.0;
      if (cum >= target && weights[i] > 0) {
        out[k] = values[i];
        break;
      }
    }
  }
  return out;
}

double weighted_percentile(const std::vector<double> &values, const std::vector<double> &weights,
                           double p)
{
  return weighted_percentiles(values, weights, {p})[0];
}

Summary summarize(const std::vector<double> &values)
{
  Summary s;
  s.n = values.size();
  if (values.empty())
    return s;
  std::vector<double> v(values);
  s.p05 = percentile(v, 5.0);
  s.p95 = percentile(v, 95.0);
  s.median = median(v);
  s.mad = mad(v, s.median);
  auto [mn, mx] = std::minmax_element(v.begin(), v.end());
  s.min = *mn;
  s.max = *mx;
  s.mean = std::accumulate(v.begin(), v.end(), 0.0) / double(v.size());
  double ss = 0.0;
  for (double x : v)
    ss += (x - s.mean) * (x - s.mean);
  s.stddev = v.size() > 1 ? std::sqrt(ss / double(v.size() - 1)) : 0.0;
  return s;
}

} // namespace treestereo
