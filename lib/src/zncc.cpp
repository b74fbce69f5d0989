#include "zncc.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace treestereo::detail {

// Zero-mean copy of a square patch and its norm; false when it has no texture.
bool centred_patch(const cv::Mat &img, int cx, int cy, int h, std::vector<float> &out, double &norm)
{
  const int n = 2 * h + 1;
  out.resize(std::size_t(n * n));
  double sum = 0;
  for (int y = 0; y < n; ++y) {
    const std::uint8_t *row = img.ptr<std::uint8_t>(cy - h + y) + (cx - h);
    for (int x = 0; x < n; ++x) {
      out[std::size_t(y * n + x)] = row[x];
      sum += row[x];
    }
  }
  const float mean = float(sum / double(n * n));
  double ss = 0;
  for (float &v : out) {
    v -= mean;
    ss += double(v) * v;
  }
  norm = std::sqrt(ss);
  return norm > 1e-3 * n; // flat patch: no peak to find
}

// ZNCC of the centred left patch against the right patch centred at (cx, cy).
double zncc(const std::vector<float> &lc, double lnorm, const cv::Mat &img, int cx, int cy, int h)
{
  const int n = 2 * h + 1;
  double cross = 0, sum = 0, ss = 0;
  for (int y = 0; y < n; ++y) {
    const std::uint8_t *row = img.ptr<std::uint8_t>(cy - h + y) + (cx - h);
    const float *l = &lc[std::size_t(y * n)];
    for (int x = 0; x < n; ++x) {
      const double v = row[x];
      cross += double(l[x]) * v; // sum(lc) = 0, so the right mean drops out of the cross term
      sum += v;
      ss += v * v;
    }
  }
  const double var = ss - sum * sum / double(n * n);
  if (var <= 1e-9)
    return -1.0;
  return cross / (lnorm * std::sqrt(var));
}

// Gauss-Newton steps on the right patch's x position xr (sub-pixel, same row): minimises the
// difference of the zero-mean, unit-norm left and right patches, the right one interpolated
// linearly. A parabola through integer-offset scores is pulled towards whole pixels (by up to
// 0.3 px on smooth texture); this removes most of that bias. Returns xr unchanged when a step
// would leave the image or +-1 px around the start.
double gauss_newton_x(const std::vector<float> &lc, double lnorm, const cv::Mat &img, double xr,
                      int cy, int h)
{
  const int n = 2 * h + 1;
  std::vector<double> v(std::size_t(n * n)), g(std::size_t(n * n));
  const double x0 = xr;
  // Six steps at most: with three, one patch of siftmatch's synthetic-shift test (23.37 px) stayed
  // 0.11 px off at contrast-threshold 0.035 (steps are clamped to 0.5 px); a step below 1e-3 px
  // ends the loop early.
  for (int iter = 0; iter < 6; ++iter) {
    if (xr - h - 1.5 < 0 || xr + h + 1.5 >= img.cols - 1 || std::abs(xr - x0) > 1.0)
      return x0;
    double sum = 0;
    for (int y = 0; y < n; ++y) {
      const std::uint8_t *row = img.ptr<std::uint8_t>(cy - h + y);
      for (int x = 0; x < n; ++x) {
        const double px = xr - h + x;
        const std::size_t k = std::size_t(y * n + x);
        v[k] = sample(row, px);
        g[k] = 0.5 * (sample(row, px + 1.0) - sample(row, px - 1.0));
        sum += v[k];
      }
    }
    const double mean = sum / double(n * n);
    double ss = 0;
    for (double &e : v) {
      e -= mean;
      ss += e * e;
    }
    const double rnorm = std::sqrt(ss);
    if (rnorm < 1e-6)
      return x0;
    double num = 0, den = 0;
    for (std::size_t k = 0; k < v.size(); ++k) {
      const double gn = g[k] / rnorm;
      num += (double(lc[k]) / lnorm - v[k] / rnorm) * gn;
      den += gn * gn;
    }
    if (den <= 1e-12)
      return x0;
    const double step = std::clamp(num / den, -0.5, 0.5);
    xr += step;
    if (std::abs(step) < 1e-3)
      break;
  }
  return std::abs(xr - x0) <= 1.0 ? xr : x0;
}


double parabola_offset(double c_minus, double c0, double c_plus)
{
  const double curv = c_minus - 2.0 * c0 + c_plus;
  return curv < 0 ? std::clamp(0.5 * (c_minus - c_plus) / curv, -0.5, 0.5) : 0.0;
}

} // namespace treestereo::detail
