#include "treestereo/match.hpp"

#include "treestereo/errors.hpp"

#include "zncc.hpp"

#include <opencv2/core/utility.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>

namespace treestereo {

using detail::centred_patch;
using detail::gauss_newton_x;
using detail::parabola_offset;
using detail::sample;
using detail::zncc;

namespace {

// Sub-pixel position of the best match of `patch` (centred on a pixel of the other view) along
// row `yi` of `img`, searched at integer centres xc-S..xc+S: the integer peak,
// a parabola through it and its neighbours, then Gauss-Newton. False when there is no peak of at
// least min_zncc inside the range, or when the scores over the range stay within min_drop of it
// (the patch correlates about as well everywhere along the row: no position to measure).
bool best_position(const detail::Patch &patch, const cv::Mat &img, int xc, int yi, int S,
                   double min_zncc, double min_drop, std::vector<double> &scores, double &x_out)
{
  scores.resize(std::size_t(2 * S + 3));
  // Offsets -S-1..S+1: the outer two only serve as parabola neighbours.
  for (int k = -S - 1; k <= S + 1; ++k)
    scores[std::size_t(k + S + 1)] = zncc(patch, img, xc + k, yi);
  const int best = int(std::max_element(scores.begin(), scores.end()) - scores.begin()) - S - 1;
  const double c0 = scores[std::size_t(best + S + 1)];
  if (std::abs(best) > S || c0 < min_zncc ||
      c0 - *std::min_element(scores.begin(), scores.end()) < min_drop)
    return false; // the peak lies outside the search range, or there is no clear peak
  const double cm = scores[std::size_t(best + S)], cp = scores[std::size_t(best + S + 2)];
  const double delta = parabola_offset(cm, c0, cp);
  x_out = gauss_newton_x(patch, img, double(xc + best) + delta, yi);
  return true;
}

// ZNCC of the left pixels (xi + dx, yi + dy), dx in [x0, x1], dy in [y0, y1], against the right
// view at (xr + dx, yi + dy), xr sub-pixel (linear interpolation along the row). -1 when either
// side is flat.
double zncc_sub(const cv::Mat &L, const cv::Mat &R, int xi, int yi, double xr, int x0, int x1,
                int y0, int y1)
{
  double sl = 0, sr = 0, sll = 0, srr = 0, slr = 0;
  int n = 0;
  // The right samples are whole pixels apart: one interpolation weight for all of them.
  const int i0 = int(std::floor(xr));
  const double f = xr - i0, f1 = 1.0 - f;
  for (int dy = y0; dy <= y1; ++dy) {
    const std::uint8_t *lrow = L.ptr<std::uint8_t>(yi + dy);
    const std::uint8_t *rrow = R.ptr<std::uint8_t>(yi + dy) + i0;
    for (int dx = x0; dx <= x1; ++dx) {
      const double a = lrow[xi + dx], b = f1 * rrow[dx] + f * rrow[dx + 1];
      sl += a;
      sr += b;
      sll += a * a;
      srr += b * b;
      slr += a * b;
      ++n;
    }
  }
  const double vl = sll - sl * sl / n, vr = srr - sr * sr / n;
  if (vl <= 1e-9 || vr <= 1e-9)
    return -1.0;
  return (slr - sl * sr / n) / std::sqrt(vl * vr);
}

// Where the ZNCC of one sub-window (offsets [x0, x1] x [y0, y1] around the left pixel) peaks
// among right positions xr + k, k = -range..range, refined by a parabola; relative to xr (px).
// `scores[range]` is then the sub-window's ZNCC at xr itself.
double sub_peak(const cv::Mat &L, const cv::Mat &R, int xi, int yi, double xr, int x0, int x1,
                int y0, int y1, int range, std::vector<double> &scores)
{
  scores.resize(std::size_t(2 * range + 1));
  for (int k = -range; k <= range; ++k)
    scores[std::size_t(k + range)] = zncc_sub(L, R, xi, yi, xr + k, x0, x1, y0, y1);
  const int b = int(std::max_element(scores.begin(), scores.end()) - scores.begin());
  if (b == 0 || b == 2 * range)
    return double(b - range); // at the border: no parabola
  return double(b - range) + parabola_offset(scores[std::size_t(b - 1)], scores[std::size_t(b)],
                                             scores[std::size_t(b + 1)]);
}

// The two-layer test: the four quadrants of the (2h+1)^2 window (each with the centre row and
// column) and its 3x3 centre, each searched on its own within +-layer_search px, must all peak
// within the tolerance of the refined position xr (the centre: its own tolerance), and each
// quadrant must correlate at xr with at least layer_min_zncc. A patch that straddles a depth edge
// is matched at the disparity of its dominant (textured) layer; a part on the other layer then
// peaks at its own disparity, or anywhere when it is flat, and correlates poorly at xr. The 3x3
// centre is what the match's pixel stands on.
bool layers_agree(const cv::Mat &L, const cv::Mat &R, int xi, int yi, double xr,
                  const RefineParams &p, std::vector<double> &scores)
{
  const int h = p.layer_half_window, range = p.layer_search;
  const int quadrants[4][4] = {{-h, 0, -h, 0}, {0, h, -h, 0}, {-h, 0, 0, h}, {0, h, 0, h}};
  for (const auto &b : quadrants) {
    const double peak = sub_peak(L, R, xi, yi, xr, b[0], b[1], b[2], b[3], range, scores);
    if (!(std::abs(peak) <= p.layer_tolerance) || scores[std::size_t(range)] < p.layer_min_zncc)
      return false;
  }
  const double centre_tol =
      p.layer_centre_tolerance < 0 ? p.layer_tolerance : p.layer_centre_tolerance;
  const double peak = sub_peak(L, R, xi, yi, xr, -1, 1, -1, 1, range, scores);
  return std::abs(peak) <= centre_tol && scores[std::size_t(range)] >= p.layer_centre_min_zncc;
}

// Sum of absolute differences of the left 3x3 patch at (x, y) and the right one at (x + dx, y),
// dx sub-pixel (the right rows linearly interpolated).
double sad3(const cv::Mat &L, const cv::Mat &R, int x, int y, double dx)
{
  double sad = 0;
  for (int a = -1; a <= 1; ++a) {
    const std::uint8_t *lrow = L.ptr<std::uint8_t>(y + a);
    const std::uint8_t *rrow = R.ptr<std::uint8_t>(y + a);
    for (int b = -1; b <= 1; ++b)
      sad += std::abs(double(lrow[x + b]) - sample(rrow, double(x + b) + dx));
  }
  return sad;
}

// Relocation (RefineParams::relocate): of the left pixels within r px of (xi, yi), the one whose
// 3x3 patch differs least from the right view at the disparity xi - xr, among those whose 3x3
// correlates there (ZNCC >= 0.5 with its peak within 0.5 px), when it differs less than the
// keypoint's own pixel does by more than kMinGain; else the keypoint stays, as it does when the
// neighbourhood leaves the views.
cv::Point relocated(const cv::Mat &L, const cv::Mat &R, int xi, int yi, double xr, int r,
                    std::vector<double> &scores)
{
  constexpr int kSearch = 2; // the 3x3's own peak is searched within +-2 px
  constexpr double kMinZncc = 0.5, kPeakTolerance = 0.5;
  // A neighbour must beat the keypoint's own pixel by more than this (grey levels over the 9
  // pixels): below it the difference is the interpolation at a sub-pixel disparity, and a match
  // on one surface would wander for nothing.
  constexpr double kMinGain = 2.0;
  const cv::Point keep(xi, yi);
  if (yi - r - 1 < 0 || yi + r + 1 >= L.rows || xi - r - 1 < 0 || xi + r + 1 >= L.cols ||
      xr - r - 1 - kSearch - 1 < 0 || xr + r + 1 + kSearch + 1 >= R.cols)
    return keep;
  const double shift = xr - double(xi); // right x = left x + shift
  cv::Point best = keep;
  double best_sad = std::numeric_limits<double>::infinity();
  // the keypoint's pixel first, so that a neighbour has to be strictly better
  auto consider = [&](int x, int y) {
    const double xr_here = double(x) + shift;
    const double peak = sub_peak(L, R, x, y, xr_here, -1, 1, -1, 1, kSearch, scores);
    if (!(std::abs(peak) <= kPeakTolerance) || scores[std::size_t(kSearch)] < kMinZncc)
      return;
    const double sad = sad3(L, R, x, y, shift);
    if (sad < best_sad) {
      best_sad = sad;
      best = cv::Point(x, y);
    }
  };
  consider(xi, yi);
  const double own = best_sad;
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx)
      if (dx != 0 || dy != 0)
        consider(xi + dx, yi + dy);
  return best_sad < own - kMinGain ? best : keep;
}

} // namespace

void check_refine_params(const RefineParams &p)
{
  if (p.half_window < 1 || p.search < 0)
    throw BadSettings("A refinement setting is out of range: set half_window to 1 or more and "
                      "search to 0 or more.",
                      "RefineParams: half_window=" + std::to_string(p.half_window) +
                          " search=" + std::to_string(p.search));
  if (!(p.min_zncc <= 1.0))
    throw BadSettings("The refinement setting min_zncc is out of range: set it to 1 or less.",
                      "RefineParams.min_zncc = " + std::to_string(p.min_zncc));
  if (std::isnan(p.layer_tolerance))
    throw BadSettings("The refinement setting layer_tolerance is not a number: set a number "
                      "(negative turns the layer test off).",
                      "RefineParams.layer_tolerance = nan");
  if (p.layer_half_window < 1 || p.layer_search < 1)
    throw BadSettings("A refinement setting is out of range: set layer_half_window and "
                      "layer_search to 1 or more.",
                      "RefineParams: layer_half_window=" + std::to_string(p.layer_half_window) +
                          " layer_search=" + std::to_string(p.layer_search));
  if (std::isnan(p.layer_centre_tolerance))
    throw BadSettings("The refinement setting layer_centre_tolerance is not a number: set a "
                      "number (negative uses layer_tolerance).",
                      "RefineParams.layer_centre_tolerance = nan");
  if (!(p.layer_min_zncc <= 1.0) || !(p.layer_centre_min_zncc <= 1.0))
    throw BadSettings("A refinement setting is out of range: set layer_min_zncc and "
                      "layer_centre_min_zncc to 1 or less (-1 for no minimum).",
                      "RefineParams: layer_min_zncc=" + std::to_string(p.layer_min_zncc) +
                          " layer_centre_min_zncc=" + std::to_string(p.layer_centre_min_zncc));
  if (!(p.min_zncc_drop >= 0 && p.min_zncc_drop <= 2))
    throw BadSettings("The refinement setting min_zncc_drop is out of range: set it within 0 to "
                      "2 (0 turns it off).",
                      "RefineParams.min_zncc_drop = " + std::to_string(p.min_zncc_drop));
  if (p.relocate < 0 || p.relocate > 3)
    throw BadSettings("The refinement setting relocate is out of range: set it within 0 to 3 px "
                      "(0 turns it off).",
                      "RefineParams.relocate = " + std::to_string(p.relocate));
}

std::size_t refine_matches(const cv::Mat &left, const cv::Mat &right,
                           std::vector<StereoMatch> &matches, const RefineParams &p)
{
  if (left.size() != right.size())
    throw BadInput("The views differ in size: refinement needs a left and a right view of the "
                   "same size.",
                   "refine_matches: left " + std::to_string(left.cols) + "x" +
                       std::to_string(left.rows) + ", right " + std::to_string(right.cols) + "x" +
                       std::to_string(right.rows));
  check_refine_params(p);
  const cv::Mat L = to_gray8(left), R = to_gray8(right);
  const int h = p.half_window, S = p.search;
  // Each match is refined on its own: split them over the threads, then keep the survivors in
  // their order.
  std::vector<unsigned char> keep(matches.size(), 0);
  cv::parallel_for_(cv::Range(0, int(matches.size())), [&](const cv::Range &range) {
    detail::Patch lp;
    std::vector<double> scores;
    for (int i = range.start; i < range.end; ++i) {
      StereoMatch &m = matches[std::size_t(i)];
      const int xi = int(std::lround(m.xl)), yi = int(std::lround(m.yl));
      const int xc = int(std::lround(double(xi) - m.disparity())); // right estimate on the grid
      const bool inside = yi - h >= 0 && yi + h < L.rows && xi - h >= 0 && xi + h < L.cols &&
                          xc - S - 1 - h >= 0 && xc + S + 1 + h < R.cols;
      double xr = 0;
      if (!inside || !centred_patch(L, xi, yi, h, lp) ||
          !best_position(lp, R, xc, yi, S, p.min_zncc, p.min_zncc_drop, scores, xr))
        continue;
      if (p.layer_tolerance >= 0) {
        const int hl = p.layer_half_window, rs = p.layer_search;
        if (yi - hl < 0 || yi + hl >= L.rows || xi - hl < 0 || xi + hl >= L.cols ||
            xr - hl - rs < 0 || xr + hl + rs + 1 >= R.cols ||
            !layers_agree(L, R, xi, yi, xr, p, scores))
          continue;
      }
      const double d = double(xi) - xr;
      if (p.relocate > 0) {
        const cv::Point to = relocated(L, R, xi, yi, xr, p.relocate, scores);
        m.xl += float(to.x - xi);
        m.yl += float(to.y - yi);
      }
      m.xr = float(double(m.xl) - d);
      m.yr = m.yl;
      keep[std::size_t(i)] = 1;
    }
  });
  std::size_t kept = 0;
  for (std::size_t i = 0; i < matches.size(); ++i)
    if (keep[i])
      matches[kept++] = matches[i];
  const std::size_t removed = matches.size() - kept;
  matches.resize(kept);
  return removed;
}

} // namespace treestereo
