#include "treestereo/sift.hpp"

#include <opencv2/core/hal/hal.hpp>
#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cfloat>
#include <climits>
#include <cmath>
#include <stdexcept>
#include <string>

namespace treestereo {

namespace {

constexpr int kBorder = 5;           // no extremum this close to an octave's edge
constexpr int kMaxSteps = 5;         // sub-pixel location: at most this many moves
constexpr double kInitSigma = 0.5;   // the blur a camera image is assumed to have
constexpr int kCells = 4;            // descriptor: kCells x kCells cells ...
constexpr int kBins = 8;             // ... of kBins orientations
constexpr float kCellScale = 3.f;    // a cell is this many sigmas wide
constexpr float kClip = 0.2f;        // each bin at most this share of the norm
constexpr float kToBytes = 512.f;    // the normalised vector scaled to 0..255 per bin

// Octave index 0 is the upsampled image: one of its pixels is half a pixel of the input.
inline float octave_step(int octave) { return std::ldexp(1.f, octave - 1); }

struct Extremum {
  int octave, layer, r, c;
  float xc, xr, xs, contrast;
};

// The gradient and Hessian of the difference of Gaussians at a sample, in (x, y, scale), on
// [0,1] grey (the pyramid holds 0..255).
struct Derivatives {
  float value;      // the sample, [0,1] grey
  cv::Vec3f grad;   // d/dx, d/dy, d/dscale
  cv::Matx33f hess; // the same order
};

Derivatives derivatives(const std::vector<cv::Mat> &dog, int layer, int r, int c)
{
  const float img_scale = 1.f / 255.f;
  const float d1 = img_scale * 0.5f, d2 = img_scale, dc = img_scale * 0.25f;
  const cv::Mat &cur = dog[layer], &prv = dog[layer - 1], &nxt = dog[layer + 1];
  auto I = [](const cv::Mat &m, int y, int x) { return m.at<float>(y, x); };
  const float v2 = I(cur, r, c) * 2.f;
  const float dxx = (I(cur, r, c + 1) + I(cur, r, c - 1) - v2) * d2;
  const float dyy = (I(cur, r + 1, c) + I(cur, r - 1, c) - v2) * d2;
  const float dss = (I(nxt, r, c) + I(prv, r, c) - v2) * d2;
  const float dxy = (I(cur, r + 1, c + 1) - I(cur, r + 1, c - 1) - I(cur, r - 1, c + 1) +
                     I(cur, r - 1, c - 1)) * dc;
  const float dxs = (I(nxt, r, c + 1) - I(nxt, r, c - 1) - I(prv, r, c + 1) +
                     I(prv, r, c - 1)) * dc;
  const float dys = (I(nxt, r + 1, c) - I(nxt, r - 1, c) - I(prv, r + 1, c) +
                     I(prv, r - 1, c)) * dc;
  return {I(cur, r, c) * img_scale,
          cv::Vec3f((I(cur, r, c + 1) - I(cur, r, c - 1)) * d1,
                    (I(cur, r + 1, c) - I(cur, r - 1, c)) * d1, (I(nxt, r, c) - I(prv, r, c)) * d1),
          cv::Matx33f(dxx, dxy, dxs, dxy, dyy, dys, dxs, dys, dss)};
}

// Lowe's sub-pixel location: a quadratic fit in (x, y, scale) around the sample, moved at most
// kMaxSteps times; then the contrast and edge (curvature ratio) tests.
bool locate(const std::vector<cv::Mat> &dog, int layers, double contrast_threshold,
            double edge_threshold, Extremum &e)
{
  const int rows = dog[0].rows, cols = dog[0].cols;
  cv::Vec3f x;
  Derivatives d;
  int step = 0;
  for (; step < kMaxSteps; ++step) {
    d = derivatives(dog, e.layer, e.r, e.c);
    x = -d.hess.solve(d.grad, cv::DECOMP_LU);
    if (std::abs(x[0]) < 0.5f && std::abs(x[1]) < 0.5f && std::abs(x[2]) < 0.5f)
      break;
    if (std::abs(x[0]) > float(INT_MAX / 3) || std::abs(x[1]) > float(INT_MAX / 3) ||
        std::abs(x[2]) > float(INT_MAX / 3))
      return false;
    e.c += cvRound(x[0]);
    e.r += cvRound(x[1]);
    e.layer += cvRound(x[2]);
    if (e.layer < 1 || e.layer > layers || e.c < kBorder || e.c >= cols - kBorder ||
        e.r < kBorder || e.r >= rows - kBorder)
      return false;
  }
  if (step >= kMaxSteps)
    return false;
  // d is the last location's: the loop left at its break.
  const float contrast = d.value + d.grad.dot(x) * 0.5f;
  if (std::abs(contrast) * float(layers) < float(contrast_threshold))
    return false;
  const float dxx = d.hess(0, 0), dyy = d.hess(1, 1), dxy = d.hess(0, 1);
  const float tr = dxx + dyy, det = dxx * dyy - dxy * dxy;
  const float edge = float(edge_threshold);
  if (det <= 0 || tr * tr * edge >= (edge + 1) * (edge + 1) * det)
    return false;
  e.xc = x[0];
  e.xr = x[1];
  e.xs = x[2];
  e.contrast = contrast;
  return true;
}

// Is cur[c] (v) at least as far from zero as all 26 neighbours, on its side of zero?
inline bool is_extremum(float v, const float *p0, const float *p1, const float *p2,
                        const float *c0, const float *c1, const float *c2, const float *n0,
                        const float *n1, const float *n2, int c)
{
  if (v > 0) {
    if (v < c1[c - 1] || v < c1[c + 1] || v < c0[c] || v < c2[c] || v < c0[c - 1] ||
        v < c0[c + 1] || v < c2[c - 1] || v < c2[c + 1])
      return false;
    for (const float *row : {p0, p1, p2, n0, n1, n2})
      if (v < row[c - 1] || v < row[c] || v < row[c + 1])
        return false;
    return true;
  }
  if (v > c1[c - 1] || v > c1[c + 1] || v > c0[c] || v > c2[c] || v > c0[c - 1] ||
      v > c0[c + 1] || v > c2[c - 1] || v > c2[c + 1])
    return false;
  for (const float *row : {p0, p1, p2, n0, n1, n2})
    if (v > row[c - 1] || v > row[c] || v > row[c + 1])
      return false;
  return true;
}

// One descriptor at angle 0 into `dst` (128 floats). `pt`, `sigma` in the octave's pixels.
//
// Upright, the cells are aligned with the pixel grid: a sample's row bin and column bin depend on
// its row and its column alone, and the Gaussian weight exp(-(x^2 + y^2) / 8) (in cell units)
// is a product of a row and a column factor. So each row is histogrammed over (column bin,
// orientation) first, then added into its two row bins: 4 updates per sample instead of the
// 8 of the trilinear interpolation, the same sums.
// Per-row work arrays, reused from one keypoint to the next.
struct Scratch {
  std::vector<float> f;
  std::vector<int> i;
};

void describe_one(const cv::Mat &img, cv::Point2f pt, float sigma, float *dst, Scratch &buf)
{
  const cv::Point p(cvRound(pt.x), cvRound(pt.y));
  const float cell = kCellScale * sigma, inv_cell = 1.f / cell;
  // A sample counts when it lies less than half a cell outside the 4 x 4 cells' square.
  const int radius = int(std::ceil(cell * (kCells / 2 + 0.5f)));
  const float exp_scale = -1.f / (kCells * kCells * 0.5f);
  // The columns the window covers inside the image (their gradient needs both neighbours).
  const int j_lo = std::max(-radius, 1 - p.x), j_hi = std::min(radius, img.cols - 2 - p.x);
  if (j_hi < j_lo) {
    std::fill(dst, dst + kCells * kCells * kBins, 0.f);
    return;
  }
  const int w = j_hi - j_lo + 1;
  buf.f.resize(size_t(w) * 10);
  buf.i.resize(size_t(w) * 2);
  float *X = buf.f.data(), *Y = X + w, *O = Y + w, *M = O + w, *WC = M + w, *FC = WC + w;
  float *A00 = FC + w, *A01 = A00 + w, *A10 = A01 + w, *A11 = A10 + w;
  int *CI = buf.i.data(), *IDX = CI + w; // each column's first histogram entry, each sample's
  constexpr int hc = kCells + 2, hb = kBins + 2, row_len = hc * hb;
  int n = 0; // columns whose bin is inside
  int first = 0;
  for (int j = j_lo; j <= j_hi; ++j) {
    const float cc = float(j) * inv_cell, cbin = cc + kCells / 2 - 0.5f;
    if (cbin <= -1 || cbin >= kCells) {
      if (n == 0)
        ++first;
      continue;
    }
    const int c0 = cvFloor(cbin);
    CI[n] = (c0 + 1) * hb;
    FC[n] = cbin - float(c0);
    WC[n] = cc * cc * exp_scale;
    ++n;
  }
  if (n == 0) {
    std::fill(dst, dst + kCells * kCells * kBins, 0.f);
    return;
  }
  cv::hal::exp32f(WC, WC, n);
  const int c_first = p.x + j_lo + first; // the image column of the first counted sample

  float hist[hc * row_len] = {};
  const float bins_per_deg = kBins / 360.f;
  for (int i = -radius; i <= radius; ++i) {
    const int r = p.y + i;
    if (r <= 0 || r >= img.rows - 1)
      continue;
    const float rr = float(i) * inv_cell, rbin = rr + kCells / 2 - 0.5f;
    if (rbin <= -1 || rbin >= kCells)
      continue;
    const float *row = img.ptr<float>(r) + c_first, *up = img.ptr<float>(r - 1) + c_first,
                *dn = img.ptr<float>(r + 1) + c_first;
    for (int k = 0; k < n; ++k) {
      X[k] = row[k + 1] - row[k - 1];
      Y[k] = up[k] - dn[k];
    }
    cv::hal::fastAtan32f(Y, X, O, n, true);
    cv::hal::magnitude32f(X, Y, M, n);
    // Each sample's share of its 2 x 2 (column, orientation) bins, 4 lanes at a time.
    int k = 0;
#if CV_SIMD128
    const cv::v_float32x4 vbpd = cv::v_setall_f32(bins_per_deg);
    const cv::v_int32x4 vbins = cv::v_setall_s32(kBins);
    for (; k + 4 <= n; k += 4) {
      const cv::v_float32x4 ob = cv::v_load(O + k) * vbpd; // >= 0: truncation is floor
      cv::v_int32x4 o0 = cv::v_trunc(ob);
      const cv::v_float32x4 fo = ob - cv::v_cvt_f32(o0);
      o0 = cv::v_select(o0 >= vbins, o0 - vbins, o0);
      const cv::v_float32x4 mag = cv::v_load(M + k) * cv::v_load(WC + k);
      const cv::v_float32x4 v1 = mag * cv::v_load(FC + k), v0 = mag - v1;
      const cv::v_float32x4 v11 = v1 * fo, v01 = v0 * fo;
      cv::v_store(A00 + k, v0 - v01);
      cv::v_store(A01 + k, v01);
      cv::v_store(A10 + k, v1 - v11);
      cv::v_store(A11 + k, v11);
      cv::v_store(IDX + k, cv::v_load(CI + k) + o0);
    }
#endif
    for (; k < n; ++k) {
      float obin = O[k] * bins_per_deg;
      int o0 = int(obin);
      obin -= float(o0);
      if (o0 >= kBins)
        o0 -= kBins;
      const float mag = M[k] * WC[k];
      const float v1 = mag * FC[k], v0 = mag - v1;
      const float v11 = v1 * obin, v01 = v0 * obin;
      A00[k] = v0 - v01;
      A01[k] = v01;
      A10[k] = v1 - v11;
      A11[k] = v11;
      IDX[k] = CI[k] + o0;
    }
    float rh[row_len] = {};
    for (k = 0; k < n; ++k) {
      float *h = rh + IDX[k];
      h[0] += A00[k];
      h[1] += A01[k];
      h[hb] += A10[k];
      h[hb + 1] += A11[k];
    }
    const int r0 = cvFloor(rbin);
    const float wy = std::exp(rr * rr * exp_scale), fr = rbin - float(r0);
    const float w1 = wy * fr, w0 = wy - w1;
    float *h0 = hist + (r0 + 1) * row_len, *h1 = h0 + row_len;
    for (int q = 0; q < row_len; ++q) {
      h0[q] += rh[q] * w0;
      h1[q] += rh[q] * w1;
    }
  }
  // Fold the orientation wrap-around, keep the inner cells.
  for (int i = 0; i < kCells; ++i)
    for (int j = 0; j < kCells; ++j) {
      const int idx = ((i + 1) * hc + (j + 1)) * hb;
      hist[idx] += hist[idx + kBins];
      hist[idx + 1] += hist[idx + kBins + 1];
      for (int k = 0; k < kBins; ++k)
        dst[(i * kCells + j) * kBins + k] = hist[idx + k];
    }
  constexpr int len = kCells * kCells * kBins;
  float nrm2 = 0;
  for (int k = 0; k < len; ++k)
    nrm2 += dst[k] * dst[k];
  const float thr = std::sqrt(nrm2) * kClip;
  nrm2 = 0;
  for (int k = 0; k < len; ++k) {
    dst[k] = std::min(dst[k], thr);
    nrm2 += dst[k] * dst[k];
  }
  const float s = kToBytes / std::max(std::sqrt(nrm2), FLT_EPSILON);
  for (int k = 0; k < len; ++k)
    dst[k] = float(cv::saturate_cast<uchar>(dst[k] * s));
}

} // namespace

UprightSift::UprightSift(const SiftParams &params) : params_(params)
{
  if (params.layers < 1 || params.layers > 8)
    throw std::runtime_error("SIFT: layers per octave must be in 1..8, got " +
                             std::to_string(params.layers));
  if (!(params.sigma > 0.5) || !(params.contrast_threshold > 0) || !(params.edge_threshold > 0))
    throw std::runtime_error("SIFT: sigma must be > 0.5, contrast and edge thresholds > 0");
  const int n = params.layers + 3;
  layer_sigma_.resize(n);
  const double k = std::pow(2.0, 1.0 / params.layers);
  layer_sigma_[0] = params.sigma;
  for (int i = 1; i < n; ++i) {
    const double prev = std::pow(k, double(i - 1)) * params.sigma, total = prev * k;
    layer_sigma_[i] = std::sqrt(total * total - prev * prev);
  }
}

std::vector<cv::KeyPoint> UprightSift::detect(const cv::Mat &gray, const cv::Mat &mask,
                                              SiftPyramid &pyr) const
{
  if (gray.empty() || gray.type() != CV_8UC1)
    throw std::runtime_error("SIFT: the image must be 8-bit grey and not empty");
  if (!mask.empty() && (mask.type() != CV_8UC1 || mask.size() != gray.size()))
    throw std::runtime_error("SIFT: the mask must be CV_8UC1 of the image's size");
  const int L = params_.layers;

  // Octave 0: the image upsampled 2x (linear), blurred up to sigma from the assumed 2 x 0.5.
  cv::Mat f, up, base;
  gray.convertTo(f, CV_32F);
  cv::resize(f, up, cv::Size(gray.cols * 2, gray.rows * 2), 0, 0, cv::INTER_LINEAR);
  const double s0 = std::sqrt(std::max(params_.sigma * params_.sigma -
                                           4 * kInitSigma * kInitSigma, 0.01));
  cv::GaussianBlur(up, base, cv::Size(), s0, s0);

  const int octaves =
      std::max(1, cvRound(std::log2(double(std::min(base.cols, base.rows)))) - 2);
  pyr.gauss.assign(octaves, {});
  pyr.dog.assign(octaves, {});
  for (int o = 0; o < octaves; ++o) {
    auto &g = pyr.gauss[o];
    g.resize(L + 3);
    if (o == 0)
      g[0] = base;
    else {
      const cv::Mat &src = pyr.gauss[o - 1][L];
      cv::resize(src, g[0], cv::Size(src.cols / 2, src.rows / 2), 0, 0, cv::INTER_NEAREST);
    }
    for (int i = 1; i < L + 3; ++i)
      cv::GaussianBlur(g[i - 1], g[i], cv::Size(), layer_sigma_[i], layer_sigma_[i]);
    auto &d = pyr.dog[o];
    d.resize(L + 2);
    for (int i = 0; i < L + 2; ++i)
      cv::subtract(g[i + 1], g[i], d[i]);
  }

  const float thr = std::floor(float(0.5 * params_.contrast_threshold / L * 255.0));
  struct Found {
    cv::Vec4i at; // (octave, layer, r, c) the location ended on
    cv::KeyPoint kp;
  };
  std::vector<Found> found;
  for (int o = 0; o < octaves; ++o) {
    const auto &d = pyr.dog[o];
    const int rows = d[0].rows, cols = d[0].cols;
    const float step = octave_step(o);
    for (int i = 1; i <= L; ++i)
      for (int r = kBorder; r < rows - kBorder; ++r) {
        const float *p0 = d[i - 1].ptr<float>(r - 1), *p1 = d[i - 1].ptr<float>(r),
                    *p2 = d[i - 1].ptr<float>(r + 1);
        const float *c0 = d[i].ptr<float>(r - 1), *c1 = d[i].ptr<float>(r),
                    *c2 = d[i].ptr<float>(r + 1);
        const float *n0 = d[i + 1].ptr<float>(r - 1), *n1 = d[i + 1].ptr<float>(r),
                    *n2 = d[i + 1].ptr<float>(r + 1);
        const int c_end = cols - kBorder;
        for (int c = kBorder; c < c_end; ++c) {
#if CV_SIMD128
          // Four samples at a time: skip them when none is above the threshold and at least
          // as far from zero as its four neighbours in the layer (nearly all of them).
          if (c + 4 <= c_end) {
            const cv::v_float32x4 v = cv::v_load(c1 + c), vl = cv::v_load(c1 + c - 1),
                                  vr = cv::v_load(c1 + c + 1), vu = cv::v_load(c0 + c),
                                  vd = cv::v_load(c2 + c);
            const cv::v_float32x4 hi = (v > cv::v_setall_f32(thr)) & (v >= vl) & (v >= vr) &
                                       (v >= vu) & (v >= vd);
            const cv::v_float32x4 lo = (v < cv::v_setall_f32(-thr)) & (v <= vl) & (v <= vr) &
                                       (v <= vu) & (v <= vd);
            if (!cv::v_check_any(hi | lo)) {
              c += 3;
              continue;
            }
          }
#endif
          const float v = c1[c];
          if (!(std::abs(v) > thr) || !is_extremum(v, p0, p1, p2, c0, c1, c2, n0, n1, n2, c))
            continue;
          Extremum e{o, i, r, c, 0, 0, 0, 0};
          if (!locate(d, L, params_.contrast_threshold, params_.edge_threshold, e))
            continue;
          // Octave 0's pixel x is the input's x / 2 - 0.25 (linear upsampling with aligned pixel
          // centres); every later octave keeps every other sample of the one before, so octave
          // pixel x is input pixel x * step - 0.25 in all of them.
          const cv::Point2f pt((float(e.c) + e.xc) * step - 0.25f,
                               (float(e.r) + e.xr) * step - 0.25f);
          if (!mask.empty()) {
            const int mx = cvRound(pt.x), my = cvRound(pt.y);
            if (mx < 0 || my < 0 || mx >= mask.cols || my >= mask.rows || !mask.at<uchar>(my, mx))
              continue;
          }
          const float sigma_oct = float(params_.sigma * std::pow(2.0, (e.layer + e.xs) / L));
          found.push_back({cv::Vec4i(o, e.layer, e.r, e.c),
                           cv::KeyPoint(pt, 2.f * sigma_oct * step, 0.f, std::abs(e.contrast),
                                        o + (e.layer << 8))});
        }
      }
  }
  // Two extrema can converge on one sample: keep it once.
  auto less = [](const Found &a, const Found &b) {
    return std::lexicographical_compare(a.at.val, a.at.val + 4, b.at.val, b.at.val + 4);
  };
  std::sort(found.begin(), found.end(), less);
  std::vector<cv::KeyPoint> kps;
  kps.reserve(found.size());
  for (size_t k = 0; k < found.size(); ++k)
    if (k == 0 || found[k].at != found[k - 1].at)
      kps.push_back(found[k].kp);
  return kps;
}

cv::Mat UprightSift::describe(const SiftPyramid &pyr, const std::vector<cv::KeyPoint> &kps,
                              const std::vector<char> &needed) const
{
  if (!needed.empty() && needed.size() != kps.size())
    throw std::runtime_error("SIFT: one 'needed' flag per keypoint expected");
  cv::Mat desc = cv::Mat::zeros(int(kps.size()), kCells * kCells * kBins, CV_32F);
  Scratch buf;
  for (size_t k = 0; k < kps.size(); ++k) {
    if (!needed.empty() && !needed[k])
      continue;
    const cv::KeyPoint &kp = kps[k];
    const int o = kp.octave & 255, layer = (kp.octave >> 8) & 255;
    if (o >= int(pyr.gauss.size()) || layer >= int(pyr.gauss[o].size()))
      throw std::runtime_error("SIFT: a keypoint does not belong to this pyramid");
    const float step = octave_step(o);
    const cv::Point2f pt((kp.pt.x + 0.25f) / step, (kp.pt.y + 0.25f) / step);
    describe_one(pyr.gauss[o][layer], pt, kp.size * 0.5f / step, desc.ptr<float>(int(k)), buf);
  }
  return desc;
}

} // namespace treestereo
