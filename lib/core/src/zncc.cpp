#include "zncc.hpp"

#include <opencv2/core/hal/intrin.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace treestereo::detail {

bool centred_patch(const cv::Mat &img, int cx, int cy, int h, Patch &out)
{
  const int n = 2 * h + 1;
  out.h = h;
  const int stride = out.stride();
  out.pixels.assign(std::size_t(n * stride), 0);
  out.centred.resize(std::size_t(n * n));
  std::int64_t sum = 0, ss = 0;
  for (int y = 0; y < n; ++y) {
    const std::uint8_t *row = img.ptr<std::uint8_t>(cy - h + y) + (cx - h);
    std::int16_t *px = &out.pixels[std::size_t(y * stride)];
    for (int x = 0; x < n; ++x) {
      px[x] = row[x];
      out.centred[std::size_t(y * n + x)] = row[x];
      sum += row[x];
      ss += row[x] * row[x];
    }
  }
  out.sum = sum;
  out.var = std::int64_t(n) * n * ss - sum * sum;
  const float mean = float(double(sum) / double(n * n));
  double cs = 0;
  for (float &v : out.centred) {
    v -= mean;
    cs += double(v) * v;
  }
  out.norm = std::sqrt(cs);
  return out.norm > 1e-3 * n; // flat patch: no peak to find
}

double zncc(const Patch &l, const cv::Mat &img, int cx, int cy)
{
  const int h = l.h, n = l.n(), stride = l.stride(), x0 = cx - h;
  std::int64_t sr = 0, srr = 0, slr = 0;
#if CV_SIMD128
  // Eight pixels at a time (the 16-bit products summed in pairs into 32 bits: at most
  // 2 * 255 * 255 a lane a step, 441 * 255 * 255 in all for a 21x21 patch). The padded rows read
  // up to stride - n pixels past the patch, so only where the image has them.
  if (x0 + stride <= img.cols) {
    // The last chunk keeps its first n - 8 (chunks - 1) lanes (1..8): a window into -1s then 0s.
    static const std::int16_t kKeep[16] = {-1, -1, -1, -1, -1, -1, -1, -1, 0, 0, 0, 0, 0, 0, 0, 0};
    const int chunks = stride / 8;
    const cv::v_int16x8 tail = cv::v_load(kKeep + 8 - (n - 8 * (chunks - 1))),
                        ones = cv::v_setall_s16(1);
    cv::v_int32x4 a_r = cv::v_setzero_s32(), a_rr = cv::v_setzero_s32(),
                  a_lr = cv::v_setzero_s32();
    for (int y = 0; y < n; ++y) {
      const std::uint8_t *row = img.ptr<std::uint8_t>(cy - h + y) + x0;
      const std::int16_t *lp = &l.pixels[std::size_t(y * stride)];
      for (int c = 0; c < chunks; ++c) {
        cv::v_int16x8 r = cv::v_reinterpret_as_s16(cv::v_load_expand(row + 8 * c));
        if (c == chunks - 1)
          r = r & tail;
        a_lr += cv::v_dotprod(cv::v_load(lp + 8 * c), r);
        a_rr += cv::v_dotprod(r, r);
        a_r += cv::v_dotprod(r, ones);
      }
    }
    sr = cv::v_reduce_sum(a_r);
    srr = cv::v_reduce_sum(a_rr);
    slr = cv::v_reduce_sum(a_lr);
  } else
#endif
  {
    for (int y = 0; y < n; ++y) {
      const std::uint8_t *row = img.ptr<std::uint8_t>(cy - h + y) + x0;
      const std::int16_t *lp = &l.pixels[std::size_t(y * stride)];
      for (int x = 0; x < n; ++x) {
        const int v = row[x];
        sr += v;
        srr += v * v;
        slr += lp[x] * v;
      }
    }
  }
  const std::int64_t nn = std::int64_t(n) * n;
  const std::int64_t vr = nn * srr - sr * sr; // n^2 * sum of squared deviations: 0 when flat
  if (vr <= 0 || l.var <= 0)
    return -1.0;
  return double(nn * slr - l.sum * sr) / std::sqrt(double(l.var) * double(vr));
}

// Gauss-Newton steps on the right patch's x position xr (sub-pixel, same row): minimises the
// difference of the zero-mean, unit-norm left and right patches, the right one interpolated
// linearly. A parabola through integer-offset scores is pulled towards whole pixels (by up to
// 0.3 px on smooth texture); this removes most of that bias. Returns xr unchanged when a step
// would leave the image or +-1 px around the start.
double gauss_newton_x(const Patch &patch, const cv::Mat &img, double xr, int cy)
{
  const int h = patch.h, n = patch.n();
  const std::vector<float> &lc = patch.centred;
  const double lnorm = patch.norm;
  // Scratch of this thread, reused from call to call (densification calls this for every kept
  // grid point).
  thread_local std::vector<double> v, g, ln;
  v.resize(std::size_t(n * n));
  g.resize(std::size_t(n * n));
  ln.resize(std::size_t(n * n));
  for (std::size_t k = 0; k < ln.size(); ++k) // the unit-norm patch, the same at every step
    ln[k] = double(lc[k]) / lnorm;
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
      num += (ln[k] - v[k] / rnorm) * gn;
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
