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

// ZNCC of the centred left patch against the right patch centred at (cx, cy). The right
// patch's sum and sum of squares are whole numbers, summed exactly in integers; the cross term is
// summed per row, and the rows into two sums, so that fewer additions wait for each other.
double zncc(const std::vector<float> &lc, double lnorm, const cv::Mat &img, int cx, int cy, int h)
{
  const int n = 2 * h + 1;
  double cross[2] = {0, 0};
  std::int64_t sum = 0, ss = 0;
  for (int y = 0; y < n; ++y) {
    const std::uint8_t *row = img.ptr<std::uint8_t>(cy - h + y) + (cx - h);
    const float *l = &lc[std::size_t(y * n)];
    double c = 0;
    int rs = 0, rss = 0; // one row: at most 255 * 255 * n
    for (int x = 0; x < n; ++x) {
      const int v = row[x];
      c += double(l[x]) * v; // sum(lc) = 0, so the right mean drops out of the cross term
      rs += v;
      rss += v * v;
    }
    cross[y & 1] += c;
    sum += rs;
    ss += rss;
  }
  const double var = double(ss) - double(sum) * double(sum) / double(n * n);
  if (var <= 1e-9)
    return -1.0;
  return (cross[0] + cross[1]) / (lnorm * std::sqrt(var));
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
  // Scratch of this thread, reused from call to call (densification calls this for every kept
  // grid point).
  thread_local std::vector<double> v, g;
  v.resize(std::size_t(n * n));
  g.resize(std::size_t(n * n));
  const double x0 = xr;
  // Six steps at most: with three, one patch of siftmatch's synthetic-shift test (23.37 px) stayed
  // 0.11 px off at contrast-threshold 0.035 (steps are clamped to 0.5 px); a step below 1e-3 px
  // ends the loop early.
  for (int iter = 0; iter < 6; ++iter) {
    if (xr - h - 1.5 < 0 || xr + h + 1.5 >= img.cols - 1 || std::abs(xr - x0) > 1.0)
      return x0;
    // Every sample of the patch is a whole number of pixels from xr, so all share the
    // interpolation weight f: sample(row, xr - h + x) = (1 - f) row[i0 + x] + f row[i0 + x + 1].
    const int i0 = int(std::floor(xr)) - h;
    const double f = xr - std::floor(xr), f1 = 1.0 - f;
    double sum = 0;
    for (int y = 0; y < n; ++y) {
      const std::uint8_t *row = img.ptr<std::uint8_t>(cy - h + y) + i0;
      double *vy = &v[std::size_t(y * n)], *gy = &g[std::size_t(y * n)];
      for (int x = 0; x < n; ++x) {
        vy[x] = f1 * row[x] + f * row[x + 1];
        gy[x] = 0.5 * ((f1 * row[x + 1] + f * row[x + 2]) - (f1 * row[x - 1] + f * row[x]));
        sum += vy[x];
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
