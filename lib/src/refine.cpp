#include "treestereo/match.hpp"

#include "zncc.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>

namespace treestereo {

using detail::centred_patch;
using detail::gauss_newton_x;
using detail::parabola_offset;
using detail::zncc;


std::size_t refine_matches(const cv::Mat &left, const cv::Mat &right,
                           std::vector<StereoMatch> &matches, const RefineParams &p)
{
  if (left.size() != right.size())
    throw std::runtime_error("refinement: the two views must have the same size");
  if (p.half_window < 1 || p.search < 0)
    throw std::runtime_error("refinement: need half_window >= 1 and search >= 0");
  const cv::Mat L = to_gray8(left), R = to_gray8(right);
  const int h = p.half_window, S = p.search;
  std::vector<float> lc;
  std::vector<double> scores(std::size_t(2 * S + 3));
  std::size_t kept = 0;
  for (const StereoMatch &m0 : matches) {
    StereoMatch m = m0;
    const int xi = int(std::lround(m.xl)), yi = int(std::lround(m.yl));
    const int xc = int(std::lround(double(xi) - m.disparity())); // right estimate on the pixel grid
    const bool inside = yi - h >= 0 && yi + h < L.rows && xi - h >= 0 && xi + h < L.cols &&
                        xc - S - 1 - h >= 0 && xc + S + 1 + h < R.cols;
    double lnorm = 0;
    if (!inside || !centred_patch(L, xi, yi, h, lc, lnorm))
      continue;
    // Offsets -S-1..S+1: the outer two only serve as parabola neighbours.
    for (int k = -S - 1; k <= S + 1; ++k)
      scores[std::size_t(k + S + 1)] = zncc(lc, lnorm, R, xc + k, yi, h);
    const int best = int(std::max_element(scores.begin(), scores.end()) - scores.begin()) - S - 1;
    const double c0 = scores[std::size_t(best + S + 1)];
    if (std::abs(best) > S || c0 < p.min_zncc)
      continue; // the peak lies outside the search range, or there is no clear peak
    const double cm = scores[std::size_t(best + S)], cp = scores[std::size_t(best + S + 2)];
    const double delta = parabola_offset(cm, c0, cp);
    const double xr = gauss_newton_x(lc, lnorm, R, double(xc + best) + delta, yi, h);
    const double d = double(xi) - xr;
    m.xr = float(double(m.xl) - d);
    m.yr = m.yl;
    matches[kept++] = m;
  }
  const std::size_t removed = matches.size() - kept;
  matches.resize(kept);
  return removed;
}

} // namespace treestereo
