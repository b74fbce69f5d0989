#include "treestereo/match.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>

namespace treestereo {

namespace {

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

} // namespace

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
    const double curv = cm - 2.0 * c0 + cp;
    const double delta = curv < 0 ? std::clamp(0.5 * (cm - cp) / curv, -0.5, 0.5) : 0.0;
    const double d = double(xi) - (double(xc + best) + delta);
    m.xr = float(double(m.xl) - d);
    m.yr = m.yl;
    matches[kept++] = m;
  }
  const std::size_t removed = matches.size() - kept;
  matches.resize(kept);
  return removed;
}

} // namespace treestereo
