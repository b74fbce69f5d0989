#include "treestereo/segment.hpp"

#include "treestereo/errors.hpp"

#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>

namespace treestereo {

namespace {

// How one index is computed in integers: code = cr*R + cg*G + cb*B, divided by den*S and scaled
// by q for the normalised ones. real index = code * unit. Codes lie in [lo, hi], which is also
// the histogram's range (one bin per code).
struct Coding {
  int cr, cg, cb;
  bool normalised;
  int q, den; // normalised only: code = num * q / (den * S)
  int lo, hi;
  double unit;
  double default_floor;
  int bins() const { return hi - lo + 1; }
};

// ExG-ExR = 3G - 2.4R - B is kept exact by scaling with 5: 15G - 12R - 5B.
Coding coding_of(VegIndex index)
{
  switch (index) {
  case VegIndex::Exg:
    return {-1, 2, -1, false, 1, 1, -510, 510, 1.0, 8.0};
  case VegIndex::ExgExr:
    return {-12, 15, -5, false, 1, 1, -17 * 255, 15 * 255, 1.0 / 5.0, 0.0};
  case VegIndex::ExgNorm:
    return {-1, 2, -1, true, 512, 1, -512, 1024, 1.0 / 512.0, 0.025};
  case VegIndex::ExgExrNorm:
    return {-12, 15, -5, true, 256, 5, -615, 768, 1.0 / 256.0, 0.0};
  }
  throw std::runtime_error("segment: unknown vegetation index");
}

// Index code of every pixel of one row into dst; dark pixels (R+G+B < dark_floor) get lo - 1,
// below every threshold. SIMD and scalar tail use the same float arithmetic for the normalised
// codes, so a pixel's code does not depend on its position in the row.
template <int CN, bool NORM>
void code_row(const uchar *p, int width, const Coding &c, const ChannelOrder &o, int dark_floor,
              short *dst)
{
  const float scale = float(c.q) / float(c.den);
  const short dark_code = short(c.lo - 1);
  int x = 0;
#if CV_SIMD128
  using namespace cv;
  const v_int16x8 vcr = v_setall_s16(short(c.cr)), vcg = v_setall_s16(short(c.cg)),
                  vcb = v_setall_s16(short(c.cb)), vdark_code = v_setall_s16(dark_code);
  const v_uint16x8 vdark = v_setall_u16(ushort(dark_floor));
  const v_float32x4 vscale = v_setall_f32(scale);
  for (; x <= width - 16; x += 16) {
    v_uint8x16 ch[4];
    if (CN == 3)
      v_load_deinterleave(p + 3 * x, ch[0], ch[1], ch[2]);
    else
      v_load_deinterleave(p + 4 * x, ch[0], ch[1], ch[2], ch[3]);
    v_uint16x8 r[2], g[2], b[2];
    v_expand(ch[o.r], r[0], r[1]);
    v_expand(ch[o.g], g[0], g[1]);
    v_expand(ch[o.b], b[0], b[1]);
    for (int h = 0; h < 2; ++h) {
      const v_uint16x8 sum = r[h] + g[h] + b[h];
      // |terms| <= 15*255: no int16 overflow.
      v_int16x8 code = v_mul_wrap(v_reinterpret_as_s16(r[h]), vcr) +
                       v_mul_wrap(v_reinterpret_as_s16(g[h]), vcg) +
                       v_mul_wrap(v_reinterpret_as_s16(b[h]), vcb);
      if (NORM) {
        v_int32x4 n0, n1;
        v_uint32x4 s0, s1;
        v_expand(code, n0, n1);
        v_expand(sum, s0, s1);
        const v_float32x4 f0 = v_cvt_f32(n0) * vscale / v_cvt_f32(v_reinterpret_as_s32(s0));
        const v_float32x4 f1 = v_cvt_f32(n1) * vscale / v_cvt_f32(v_reinterpret_as_s32(s1));
        code = v_pack(v_round(f0), v_round(f1));
      }
      code = v_select(v_reinterpret_as_s16(sum < vdark), vdark_code, code);
      v_store(dst + x + 8 * h, code);
    }
  }
#endif
  for (; x < width; ++x) {
    const uchar *q = p + CN * x;
    const int R = q[o.r], G = q[o.g], B = q[o.b];
    const int sum = R + G + B;
    if (sum < dark_floor) {
      dst[x] = dark_code;
      continue;
    }
    const int code = c.cr * R + c.cg * G + c.cb * B;
    dst[x] = short(NORM ? cvRound(float(code) * scale / float(sum)) : code);
  }
}

void code_row_dispatch(const uchar *p, int width, int cn, const Coding &c, const ChannelOrder &o,
                       int dark_floor, short *dst)
{
  if (cn == 3)
    (c.normalised ? code_row<3, true> : code_row<3, false>)(p, width, c, o, dark_floor, dst);
  else
    (c.normalised ? code_row<4, true> : code_row<4, false>)(p, width, c, o, dark_floor, dst);
}

void check_view(const cv::Mat &view, const ChannelOrder &o)
{
  if (view.empty())
    throw std::runtime_error("segment: empty view");
  if (view.depth() != CV_8U || (view.channels() != 3 && view.channels() != 4))
    throw std::runtime_error("segment: the view must be 8-bit colour (CV_8UC3 or CV_8UC4, "
                             "e.g. RGB/BGR/RGBx/BGRx); got " + std::to_string(view.channels()) +
                             " channel(s) of depth " + std::to_string(view.depth()) +
                             ": a grey image has no colour to tell leaves from soil");
  const int cn = view.channels();
  for (int i : {o.r, o.g, o.b})
    if (i < 0 || i >= cn)
      throw std::runtime_error("segment: channel index " + std::to_string(i) +
                               " outside the view's " + std::to_string(cn) + " channels");
}

// Rows [begin, end) of stripe s out of n.
cv::Range stripe_rows(int s, int n, int rows)
{
  return {int(std::int64_t(s) * rows / n), int(std::int64_t(s + 1) * rows / n)};
}

// Eight mask bytes at once (any alignment), to skip uniform stretches of a 0/255 mask.
std::uint64_t word_at(const uchar *p)
{
  std::uint64_t v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

double region_perimeter(const std::vector<cv::Point> &contour, double epsilon)
{
  if (epsilon <= 0)
    return cv::arcLength(contour, true) + CV_PI;
  std::vector<cv::Point> poly;
  cv::approxPolyDP(contour, poly, epsilon, true);
  // Moving a simple closed curve half a pixel outward adds 2 pi * 0.5 to its length: from the
  // boundary pixels' centres to their outer edges, consistent with area = pixel count.
  return cv::arcLength(poly, true) + CV_PI;
}

void clear(Silhouette &out, double threshold)
{
  out.present = false;
  out.threshold = threshold;
  out.mask.setTo(0);
  out.contour.clear();
  out.area_px = out.perimeter_px = out.complexity = 0;
  out.centroid = cv::Point2d(0, 0);
  out.bbox = cv::Rect();
  out.n_regions = 0;
}

} // namespace

const char *veg_index_name(VegIndex index)
{
  switch (index) {
  case VegIndex::Exg: return "exg";
  case VegIndex::ExgExr: return "exg-exr";
  case VegIndex::ExgNorm: return "exg-norm";
  case VegIndex::ExgExrNorm: return "exg-exr-norm";
  }
  return "?";
}

std::vector<VegIndex> all_veg_indices()
{
  return {VegIndex::Exg, VegIndex::ExgExr, VegIndex::ExgNorm, VegIndex::ExgExrNorm};
}

VegIndex veg_index_from_name(const std::string &name)
{
  for (VegIndex i : all_veg_indices())
    if (name == veg_index_name(i))
      return i;
  throw BadSettings("segment: unknown vegetation index '" + name +
                    "' (use exg, exg-exr, exg-norm or exg-exr-norm)");
}

const char *keep_mode_name(KeepMode mode) { return mode == KeepMode::Largest ? "largest" : "all"; }

KeepMode keep_mode_from_name(const std::string &name)
{
  if (name == "largest")
    return KeepMode::Largest;
  if (name == "all")
    return KeepMode::All;
  throw BadSettings("segment: unknown keep mode '" + name + "' (use largest or all)");
}

ChannelOrder channel_order_from_name(const std::string &f)
{
  // Position of each letter in the name is the byte position in the pixel.
  static const char *const known[] = {"RGB",  "BGR",  "RGBx", "BGRx", "xRGB",
                                      "xBGR", "RGBA", "BGRA", "ARGB", "ABGR"};
  for (const char *k : known)
    if (f == k)
      return {int(f.find('R')), int(f.find('G')), int(f.find('B')), int(f.size())};
  throw BadSettings("segment: unsupported channel order '" + f +
                    "' (use RGB, BGR, RGBx, BGRx, xRGB, xBGR, RGBA, BGRA, ARGB or ABGR)");
}

void validate(const SegmentParams &p)
{
  const ChannelOrder &o = p.order;
  if (o.r == o.g || o.r == o.b || o.g == o.b || std::min({o.r, o.g, o.b}) < 0 ||
      std::max({o.r, o.g, o.b}) > 3)
    throw BadSettings("segment: channel order needs three distinct indices in 0..3");
  if (p.dark_floor < 1 || p.dark_floor > 765)
    throw BadSettings("segment: dark_floor must be in 1..765 (sum of R+G+B)");
  if (p.morph_size < 0 || p.morph_size > 255)
    throw BadSettings("segment: morph_size must be in 0..255 px");
  if (!(p.min_area >= 0) || !std::isfinite(p.min_area))
    throw BadSettings("segment: min_area must be a finite number >= 0");
  if (!(p.contour_epsilon >= 0) || p.contour_epsilon > 100)
    throw BadSettings("segment: contour_epsilon must be in 0..100 px");
  if (!std::isfinite(p.threshold) || (p.otsu_floor && !std::isfinite(*p.otsu_floor)))
    throw BadSettings("segment: threshold and otsu_floor must be finite");
  if (!(p.unmix_min_contrast >= 0) || p.unmix_min_contrast > 442)
    throw BadSettings("segment: unmix_min_contrast must be in 0..442 (8-bit RGB levels)");
}

int otsu_bin(const std::vector<int> &hist)
{
  double total = 0, sum_all = 0;
  int nonempty = 0;
  for (std::size_t i = 0; i < hist.size(); ++i) {
    total += hist[i];
    sum_all += double(i) * hist[i];
    nonempty += hist[i] > 0;
  }
  if (nonempty < 2)
    return -1;
  double w0 = 0, sum0 = 0, best = -1;
  int first = -1, last = -1;
  for (std::size_t t = 0; t + 1 < hist.size(); ++t) {
    w0 += hist[t];
    sum0 += double(t) * hist[t];
    const double w1 = total - w0;
    if (w0 == 0)
      continue;
    if (w1 == 0)
      break;
    const double d = sum0 / w0 - (sum_all - sum0) / w1;
    const double var = w0 * w1 * d * d;
    if (var > best * (1 + 1e-12)) {
      best = var;
      first = last = int(t);
    } else if (var >= best * (1 - 1e-12) && last == int(t) - 1) {
      last = int(t); // a plateau over empty bins between two modes: cut in its middle
    }
  }
  return (first + last) / 2;
}

VegetationSegmenter::VegetationSegmenter(const SegmentParams &params) : params_(params)
{
  validate(params_);
}

cv::Mat VegetationSegmenter::index_image(const cv::Mat &view) const
{
  check_view(view, params_.order);
  const Coding c = coding_of(params_.index);
  cv::Mat codes(view.size(), CV_16S), out;
  for (int y = 0; y < view.rows; ++y)
    code_row_dispatch(view.ptr<uchar>(y), view.cols, view.channels(), c, params_.order,
                      params_.dark_floor, codes.ptr<short>(y));
  codes.setTo(c.lo, codes < c.lo); // dark pixels: the index's minimum, not a code below it
  codes.convertTo(out, CV_32F, c.unit);
  return out;
}

int VegetationSegmenter::work_scale_for(cv::Size view) const
{
  if (params_.work_scale > 0)
    return params_.work_scale;
  int f = 1;
  while (double(view.area()) / (f * f) > 1.5e6)
    ++f;
  return f;
}

// Fills codes_ and returns the threshold code (canopy: code > it), or INT_MIN when the
// histogram has nothing to separate.
int VegetationSegmenter::index_and_threshold(const cv::Mat &view, double &threshold)
{
  const SegmentParams &p = params_;
  const Coding c = coding_of(p.index);
  const int cn = view.channels();
  codes_.create(view.size(), CV_16S);
  const bool otsu = p.threshold < 0;
  const int nstripes = std::max(1, std::min(view.rows, 4 * cv::getNumThreads()));
  stripe_hist_.resize(std::size_t(nstripes));
  for (auto &h : stripe_hist_)
    h.assign(otsu ? std::size_t(c.bins() + 1) : 0, 0);
  cv::parallel_for_(cv::Range(0, nstripes), [&](const cv::Range &r) {
    for (int s = r.start; s < r.end; ++s) {
      // Bin 0 counts the dark pixels (code lo - 1); they are dropped before Otsu.
      int *h = stripe_hist_[std::size_t(s)].data() - (c.lo - 1);
      const cv::Range rows = stripe_rows(s, nstripes, view.rows);
      for (int y = rows.start; y < rows.end; ++y) {
        short *codes = codes_.ptr<short>(y);
        code_row_dispatch(view.ptr<uchar>(y), view.cols, cn, c, p.order, p.dark_floor, codes);
        if (otsu)
          for (int x = 0; x < view.cols; ++x)
            ++h[codes[x]];
      }
    }
  });
  int tcode;
  if (otsu) {
    std::vector<int> &hist = stripe_hist_[0];
    for (std::size_t s = 1; s < stripe_hist_.size(); ++s)
      for (std::size_t i = 0; i < hist.size(); ++i)
        hist[i] += stripe_hist_[s][i];
    hist[0] = 0;
    const int bin = otsu_bin(hist);
    if (bin < 0) {
      threshold = 0;
      return INT_MIN;
    }
    const double floor_real = p.otsu_floor.value_or(c.default_floor);
    tcode = std::max(bin + c.lo - 1, int(std::floor(floor_real / c.unit)));
  } else {
    tcode = int(std::floor(p.threshold / c.unit));
  }
  threshold = tcode * c.unit;
  return tcode;
}

// cov_ = share of canopy pixels (0..255) in each f x f block; bin_ = cov_ >= 128. `scratch`
// (view size) receives the full-size thresholded codes on the way.
void VegetationSegmenter::coverage(int tcode, int f, cv::Mat &scratch)
{
  cv::Mat &dst = f == 1 ? cov_ : scratch;
  dst.create(codes_.size(), CV_8U);
  cv::parallel_for_(cv::Range(0, codes_.rows), [&](const cv::Range &r) {
    cv::compare(codes_.rowRange(r), tcode, dst.rowRange(r), cv::CMP_GT);
  });
  if (f > 1) {
    // Block averages by OpenCV's integer-factor area resize; a partial last block is padded by
    // repeating the view's last row/column.
    const cv::Size low((codes_.cols + f - 1) / f, (codes_.rows + f - 1) / f);
    const cv::Mat *src = &scratch;
    if (low.width * f != codes_.cols || low.height * f != codes_.rows) {
      cv::copyMakeBorder(scratch, tmp_, 0, low.height * f - codes_.rows, 0,
                         low.width * f - codes_.cols, cv::BORDER_REPLICATE);
      src = &tmp_;
    }
    cv::resize(*src, cov_, low, 0, 0, cv::INTER_AREA);
  }
  cv::threshold(cov_, bin_, 127, 255, cv::THRESH_BINARY);
}

// 255 for the labels to keep, 0 otherwise (label 0 = background is never kept).
std::vector<uchar> VegetationSegmenter::kept_labels(int n, int f, int &n_kept) const
{
  const double min_area = params_.min_area / (double(f) * f);
  std::vector<uchar> keep(std::size_t(std::max(n, 1)), 0);
  int largest = -1;
  n_kept = 0;
  for (int k = 1; k < n; ++k) {
    const int area = stats_.at<int>(k, cv::CC_STAT_AREA);
    if (area < min_area || area == 0)
      continue;
    if (largest < 0 || area > stats_.at<int>(largest, cv::CC_STAT_AREA))
      largest = k;
    if (params_.keep == KeepMode::All) {
      keep[std::size_t(k)] = 255;
      ++n_kept;
    }
  }
  if (params_.keep == KeepMode::Largest && largest > 0) {
    keep[std::size_t(largest)] = 255;
    n_kept = 1;
  }
  return keep;
}

// The kept regions at view size. At f > 1 the kept blocks carry their coverage (gaps filled by
// closing count as full) and linear upscaling puts the edge where the coverage crosses half.
void VegetationSegmenter::final_mask(const std::vector<uchar> &keep, int f, cv::Mat &mask)
{
  cv::Mat &dst = f == 1 ? mask : fin_;
  dst.create(bin_.size(), CV_8U);
  cv::parallel_for_(cv::Range(0, bin_.rows), [&](const cv::Range &r) {
    for (int y = r.start; y < r.end; ++y) {
      const int *l = labels_.ptr<int>(y);
      const uchar *cov = cov_.ptr<uchar>(y);
      uchar *m = dst.ptr<uchar>(y);
      for (int x = 0; x < bin_.cols; ++x)
        m[x] = keep[std::size_t(l[x])] ? (cov[x] >= 128 ? cov[x] : uchar(255)) : uchar(0);
    }
  });
  if (f == 1)
    return;
  cv::resize(fin_, up_, fin_.size() * f, 0, 0, cv::INTER_LINEAR);
  cv::threshold(up_(cv::Rect(cv::Point(0, 0), mask.size())), mask, 127, 255, cv::THRESH_BINARY);
}

// Opening by reconstruction, exact: `opened` (bin_ opened, hence inside it) becomes the union of
// bin_'s 8-connected components that hold one of its pixels. One labelling pass replaces the
// geodesic dilations, whose count would be the length of the longest cut-off tip; labels_ is
// free here (the components of the final mask are labelled after the close).
void VegetationSegmenter::reconstruct(cv::Mat &opened)
{
  const int n = cv::connectedComponents(bin_, labels_, 8, CV_32S);
  touched_.assign(std::size_t(n), 0);
  uchar *t = touched_.data();
  // A run of opened pixels in a row lies in one component (opened is inside bin_), so only the
  // first pixel of each run is looked up: the scan reads the 8-bit mask, not the int labels.
  const int w = opened.cols;
  for (int y = 0; y < opened.rows; ++y) {
    const uchar *o = opened.ptr<uchar>(y);
    const int *l = labels_.ptr<int>(y);
    int x = 0;
    while (x < w) {
      while (x + 8 <= w && word_at(o + x) == 0)
        x += 8;
      while (x < w && !o[x])
        ++x;
      if (x == w)
        break;
      t[l[x]] = 255;
      while (x + 8 <= w && word_at(o + x) == ~std::uint64_t(0))
        x += 8;
      while (x < w && o[x])
        ++x;
    }
  }
  cv::parallel_for_(cv::Range(0, opened.rows), [&](const cv::Range &r) {
    for (int y = r.start; y < r.end; ++y) {
      const int *l = labels_.ptr<int>(y);
      uchar *o = opened.ptr<uchar>(y);
      for (int x = 0; x < opened.cols; ++x)
        o[x] = t[l[x]];
    }
  });
}

// Boundary pixels (those whose 3x3 neighbourhood holds both classes) are decided by their leaf
// fraction alpha in p = B + alpha (F - B), the least-squares projection onto the line between
// the local canopy colour F and background colour B. F and B come from the 5x5 window's pixels
// that are not boundary pixels themselves (those are the mixed ones). All decisions are made on
// the mask as it was, then applied, so the result does not depend on the scan order.
void VegetationSegmenter::unmix_edges(const cv::Mat &view, const cv::Rect &box, cv::Mat &mask)
{
  constexpr int r = 2;
  const cv::Rect roi = cv::Rect(box.x - r - 1, box.y - r - 1, box.width + 2 * r + 2,
                                box.height + 2 * r + 2) & cv::Rect(cv::Point(0, 0), view.size());
  cv::Mat m = mask(roi);
  const cv::Mat v = view(roi);
  const cv::Mat k3 = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3));
  // Beyond the image: background for the dilation, canopy for the erosion, so a canopy that
  // touches the border has no boundary there (nothing is known beyond it).
  cv::dilate(m, dil_, k3, cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::erode(m, ero_, k3, cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(255));
  // Class per pixel: 0 pure background, 1 pure canopy (inside the eroded mask), 2 boundary.
  // (ero <= m <= dil, so dil - ero is 255 exactly on the boundary.)
  cv::subtract(dil_, ero_, cls_);
  cv::min(cls_, 2, cls_);
  cls_.setTo(1, ero_);
  const ChannelOrder &o = params_.order;
  const int cn = view.channels();
  const double min_dd = params_.unmix_min_contrast * params_.unmix_min_contrast;
  // Whether boundary pixel (x, y) of the roi is on the other side of half coverage than the
  // mask has it.
  const auto unmixed_class_differs = [&](int x, int y) {
    int sum[2][3] = {{0, 0, 0}, {0, 0, 0}}, n[2] = {0, 0}; // [background, canopy]
    const int x0 = std::max(0, x - r), x1 = std::min(m.cols - 1, x + r);
    for (int yy = std::max(0, y - r); yy <= std::min(m.rows - 1, y + r); ++yy) {
      const uchar *c = cls_.ptr<uchar>(yy), *px = v.ptr<uchar>(yy) + x0 * cn;
      for (int xx = x0; xx <= x1; ++xx, px += cn) {
        const int k = c[xx];
        if (k == 2)
          continue;
        n[k] += 1;
        sum[k][0] += px[o.r];
        sum[k][1] += px[o.g];
        sum[k][2] += px[o.b];
      }
    }
    if (n[0] < 3 || n[1] < 3)
      return false;
    const uchar *px = v.ptr<uchar>(y) + x * cn;
    const int q[3] = {px[o.r], px[o.g], px[o.b]};
    double dd = 0, pd = 0;
    for (int ch = 0; ch < 3; ++ch) {
      const double f = double(sum[1][ch]) / n[1], b = double(sum[0][ch]) / n[0];
      dd += (f - b) * (f - b);
      pd += (q[ch] - b) * (f - b);
    }
    return dd >= min_dd && (pd >= 0.5 * dd) != bool(m.at<uchar>(y, x));
  };
  const int nstripes = std::max(1, std::min(m.rows, 4 * cv::getNumThreads()));
  flip_.resize(std::size_t(nstripes));
  cv::parallel_for_(cv::Range(0, nstripes), [&](const cv::Range &sr) {
    for (int st = sr.start; st < sr.end; ++st) {
      std::vector<cv::Point> &flip = flip_[std::size_t(st)];
      flip.clear();
      const cv::Range rows = stripe_rows(st, nstripes, m.rows);
      for (int y = rows.start; y < rows.end; ++y) {
        const uchar *c = cls_.ptr<uchar>(y);
        for (int x = 0; x < m.cols; ++x)
          if (c[x] == 2 && unmixed_class_differs(x, y))
            flip.emplace_back(x, y);
      }
    }
  });
  for (const std::vector<cv::Point> &flip : flip_)
    for (const cv::Point &q : flip)
      m.at<uchar>(q) = m.at<uchar>(q) ? 0 : 255;
}

void VegetationSegmenter::run(const cv::Mat &view, Silhouette &out)
{
  const SegmentParams &p = params_;
  check_view(view, p.order);
  out.mask.create(view.size(), CV_8U);
  double threshold = 0;
  const int tcode = index_and_threshold(view, threshold);
  if (tcode == INT_MIN) {
    clear(out, threshold);
    return;
  }
  const int f = work_scale_for(view.size());
  coverage(tcode, f, out.mask);

  // Odd sizes only: OpenCV does not mirror an even element between erosion and dilation, so
  // an even one would shift the mask by a pixel at each open/close.
  const int ks = p.morph_size > 0
                     ? 2 * int(std::lround(std::max(0.0, (double(p.morph_size) / f - 1) / 2))) + 1
                     : 0;
  if (ks > 1) {
    const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(ks, ks));
    cv::morphologyEx(bin_, tmp_, cv::MORPH_OPEN, kernel);
    if (p.reconstruct)
      reconstruct(tmp_);
    cv::morphologyEx(tmp_, bin_, cv::MORPH_CLOSE, kernel);
  }
  const int n = cv::connectedComponentsWithStats(bin_, labels_, stats_, centroids_, 8, CV_32S);
  int n_kept = 0;
  const std::vector<uchar> keep = kept_labels(n, f, n_kept);
  if (n_kept == 0) {
    clear(out, threshold);
    return;
  }
  final_mask(keep, f, out.mask);

  // Where the kept regions can be at view size: their work-scale boxes plus the reach of the
  // interpolation (one block).
  cv::Rect box;
  for (int k = 1; k < n; ++k)
    if (keep[std::size_t(k)]) {
      const cv::Rect b(stats_.at<int>(k, cv::CC_STAT_LEFT), stats_.at<int>(k, cv::CC_STAT_TOP),
                       stats_.at<int>(k, cv::CC_STAT_WIDTH), stats_.at<int>(k, cv::CC_STAT_HEIGHT));
      box = box.empty() ? b : (box | b);
    }
  box = cv::Rect(box.x * f - f, box.y * f - f, box.width * f + 2 * f, box.height * f + 2 * f) &
        cv::Rect(cv::Point(0, 0), view.size());
  if (p.unmix_edges) // boundary pixels are inside the box already (one block around the regions)
    unmix_edges(view, box, out.mask);
  if (!describe_silhouette(out, box, p.contour_epsilon * f)) {
    clear(out, threshold);
    return;
  }
  out.threshold = threshold;
  out.n_regions = n_kept;
}

bool describe_silhouette(Silhouette &out, const cv::Rect &box, double contour_epsilon)
{
  const cv::Moments mo = cv::moments(out.mask(box), true);
  if (mo.m00 <= 0)
    return false;
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(out.mask(box), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE, box.tl());
  double perimeter = 0, largest_area = -1;
  cv::Rect bbox;
  std::size_t largest = 0;
  for (std::size_t i = 0; i < contours.size(); ++i) {
    perimeter += region_perimeter(contours[i], contour_epsilon);
    const cv::Rect b = cv::boundingRect(contours[i]);
    bbox = bbox.empty() ? b : (bbox | b);
    const double a = cv::contourArea(contours[i]);
    if (a > largest_area) {
      largest_area = a;
      largest = i;
    }
  }
  out.contour = std::move(contours[largest]);
  out.present = true;
  out.area_px = mo.m00;
  out.centroid = cv::Point2d(box.x + mo.m10 / mo.m00, box.y + mo.m01 / mo.m00);
  out.bbox = bbox;
  out.perimeter_px = perimeter;
  out.complexity = perimeter * perimeter / (4.0 * CV_PI * mo.m00);
  out.n_regions = int(contours.size());
  return true;
}

Silhouette segment_vegetation(const cv::Mat &view, const SegmentParams &params)
{
  VegetationSegmenter seg(params);
  Silhouette out;
  seg.run(view, out);
  return out;
}

} // namespace treestereo
