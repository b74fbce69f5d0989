#include "treestereo/densify.hpp"

#include "treestereo/errors.hpp"
#include "treestereo/features.hpp"
#include "treestereo/stats.hpp"

#include "zncc.hpp"

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace treestereo {

namespace {

void check_input(const cv::Mat &left, const cv::Mat &right, const cv::Mat &mask,
                 const DensifyParams &p)
{
  if (left.empty() || left.size() != right.size() || left.type() != right.type())
    throw BadInput("The views cannot be matched densely: give two non-empty views of the same "
                   "size and type.",
                   "densify: left " + std::to_string(left.cols) + "x" + std::to_string(left.rows) +
                       " type " + std::to_string(left.type()) + ", right " +
                       std::to_string(right.cols) + "x" + std::to_string(right.rows) + " type " +
                       std::to_string(right.type()));
  check_mask(mask, left.size(), "densify (the left mask)");
  if (p.step < 0 || p.target_points < 1 || p.half_window < 1 || !(p.min_zncc <= 1.0) ||
      !(p.min_margin >= 0.0) || !(p.seed_percentile >= 0.0) || !(p.seed_percentile < 50.0) ||
      !(p.search_margin_px >= 0.0) || p.min_seeds < 1 || !(p.edge_band >= 0.0) ||
      !(p.edge_band <= 0.5) || p.edge_step < 0)
    throw BadSettings("A dense matching setting is out of range: keep step >= 0, target points "
                      ">= 1, half window >= 1, min zncc <= 1, margin >= 0, seed percentile in "
                      "[0, 50), search margin >= 0, min seeds >= 1, edge band in [0, 0.5] and "
                      "edge step >= 0.",
                      "DensifyParams: step=" + std::to_string(p.step) +
                          " target_points=" + std::to_string(p.target_points) +
                          " half_window=" + std::to_string(p.half_window) +
                          " min_zncc=" + std::to_string(p.min_zncc) +
                          " min_margin=" + std::to_string(p.min_margin) +
                          " seed_percentile=" + std::to_string(p.seed_percentile) +
                          " search_margin_px=" + std::to_string(p.search_margin_px) +
                          " min_seeds=" + std::to_string(p.min_seeds) +
                          " edge_band=" + std::to_string(p.edge_band) +
                          " edge_step=" + std::to_string(p.edge_step));
}

enum class Outcome { kKept, kFlat, kWeak, kAmbiguous, kInconsistent };

// The integer disparity of the best ZNCC of `patch` (of `from` at (x, y)) against patches of
// `to` at x - sign * d, d in [lo, hi]; scores[d - lo + 1] holds d's score (and the ends lo - 1,
// hi + 1 as parabola neighbours). Returns lo - 1 when the peak is not inside [lo, hi].
int best_disparity(const detail::Patch &patch, const cv::Mat &to, int x, int y, int lo, int hi,
                   int sign, std::vector<double> &scores)
{
  const int h = patch.h;
  scores.assign(std::size_t(hi - lo + 3), -1.0);
  for (int d = lo - 1; d <= hi + 1; ++d) {
    const int xt = x - sign * d;
    if (xt - h - 1 >= 0 && xt + h + 1 < to.cols)
      scores[std::size_t(d - lo + 1)] = detail::zncc(patch, to, xt, y);
  }
  const auto it = std::max_element(scores.begin(), scores.end());
  const int best = int(it - scores.begin()) + lo - 1;
  return best >= lo && best <= hi ? best : lo - 1;
}

struct GridPoint {
  Outcome outcome;
  StereoMatch match;
};

// Per-thread scratch buffers, reused from one grid point to the next.
struct Scratch {
  detail::Patch lp, rp;             // the left and right patches
  std::vector<double> scores, back; // ZNCC along the row, and back from the right view
};

GridPoint match_grid_point(const cv::Mat &L, const cv::Mat &R, int x, int y, int lo, int hi,
                           const DensifyParams &p, Scratch &sc)
{
  std::vector<double> &scores = sc.scores;
  const int h = p.half_window;
  if (!detail::centred_patch(L, x, y, h, sc.lp))
    return {Outcome::kFlat, {}};
  const int best = best_disparity(sc.lp, R, x, y, lo, hi, +1, scores);
  if (best < lo)
    return {Outcome::kWeak, {}};
  const double c0 = scores[std::size_t(best - lo + 1)];
  if (c0 < p.min_zncc)
    return {Outcome::kWeak, {}};
  double second = -1.0;
  for (int d = lo; d <= hi; ++d)
    if (std::abs(d - best) >= 2)
      second = std::max(second, scores[std::size_t(d - lo + 1)]);
  if (c0 - second < p.min_margin)
    return {Outcome::kAmbiguous, {}};
  const double cm = scores[std::size_t(best - lo)], cp = scores[std::size_t(best - lo + 2)];
  if (p.left_right_check) {
    const int xr = x - best;
    if (!detail::centred_patch(R, xr, y, h, sc.rp))
      return {Outcome::kInconsistent, {}};
    const int b = best_disparity(sc.rp, L, xr, y, lo, hi, -1, sc.back);
    if (b < lo || std::abs(b - best) > 1)
      return {Outcome::kInconsistent, {}};
  }
  const double start = double(x - best) - detail::parabola_offset(cm, c0, cp);
  const double xr = detail::gauss_newton_x(sc.lp, R, start, y);
  StereoMatch m;
  m.xl = float(x);
  m.yl = float(y);
  m.xr = float(xr);
  m.yr = float(y);
  m.score = float(1.0 - c0);
  return {Outcome::kKept, m};
}

} // namespace

std::vector<StereoMatch> densify_matches(const cv::Mat &left, const cv::Mat &right,
                                         const cv::Mat &mask_left,
                                         const std::vector<StereoMatch> &seeds,
                                         const DensifyParams &p, DensifyStats *stats_out)
{
  check_input(left, right, mask_left, p);
  DensifyStats st;
  std::vector<StereoMatch> out;
  if (int(seeds.size()) < p.min_seeds) {
    if (stats_out)
      *stats_out = st;
    return out;
  }
  std::vector<double> d(seeds.size());
  std::transform(seeds.begin(), seeds.end(), d.begin(),
                 [](const StereoMatch &m) { return double(m.disparity()); });
  const double d_lo = percentile(d, p.seed_percentile), d_hi = percentile(d, 100.0 - p.seed_percentile);
  const int lo = int(std::floor(d_lo - p.search_margin_px));
  const int hi = int(std::ceil(d_hi + p.search_margin_px));
  const int area = cv::countNonZero(mask_left);
  if (area == 0) {
    if (stats_out)
      *stats_out = st;
    return out; // no canopy: nothing to sample
  }
  st.step = p.step > 0 ? p.step
                       : std::max(1, int(std::lround(std::sqrt(double(area) / p.target_points))));
  st.min_disparity = lo;
  st.max_disparity = hi;

  // Only the canopy's box (and, in the right view, the columns its disparities reach) is
  // converted to grey and searched; coordinates below are those of the crops.
  const int h = p.half_window, s = st.step;
  const cv::Rect whole(cv::Point(0, 0), left.size());
  const cv::Rect box = cv::boundingRect(mask_left);
  const int mx = h + 2;
  const cv::Rect lroi = cv::Rect(box.x - mx, box.y - mx, box.width + 2 * mx, box.height + 2 * mx) & whole;
  const int rx0 = std::max(0, lroi.x - std::max(hi, 0) - mx);
  const int rx1 = std::min(left.cols, lroi.br().x - std::min(lo, 0) + mx);
  if (lroi.empty() || rx1 <= rx0) {
    if (stats_out)
      *stats_out = st;
    return out;
  }
  // The right crop starts rx0 - lroi.x columns right of the left crop: shift the window.
  const int shift = lroi.x - rx0;
  const cv::Mat L = to_gray8(left(lroi), p.order);
  const cv::Mat R = to_gray8(right(cv::Rect(rx0, lroi.y, rx1 - rx0, lroi.height)), p.order);
  const cv::Mat M = mask_left(lroi);
  const int wlo = lo - shift, whi = hi - shift;
  // Grid phase in view coordinates (step/2 from the view's origin), so that the grid does not
  // move with the canopy's box; the edge bands' finer grid has its phase there too.
  const auto on_grid = [](int view_coord, int step) { return (view_coord - step / 2) % step == 0; };
  const bool bands = p.edge_band > 0;
  const int fs = p.edge_step > 0 ? p.edge_step : std::max(2, int(std::lround(left.cols / 648.0)));
  st.edge_step = bands ? fs : 0;
  // The bands in crop coordinates: rows [.., top_end) and [bottom_start, ..), columns likewise.
  const int band_rows = int(std::ceil(p.edge_band * box.height));
  const int band_cols = int(std::ceil(p.edge_band * box.width));
  const int top_end = box.y - lroi.y + band_rows, bottom_start = box.br().y - lroi.y - band_rows;
  const int left_end = box.x - lroi.x + band_cols, right_start = box.br().x - lroi.x - band_cols;
  std::vector<int> grid_rows; // crop rows that hold grid points
  for (int y = h; y < L.rows - h; ++y) {
    const int vy = y + lroi.y;
    if (on_grid(vy, s) || (bands && on_grid(vy, fs)))
      grid_rows.push_back(y);
  }
  std::vector<std::vector<StereoMatch>> rows(grid_rows.size());
  std::vector<DensifyStats> row_stats(rows.size());
  cv::parallel_for_(cv::Range(0, int(grid_rows.size())), [&](const cv::Range &r) {
    Scratch scratch;
    for (int i = r.start; i < r.end; ++i) {
      const int y = grid_rows[std::size_t(i)];
      const bool coarse_row = on_grid(y + lroi.y, s);
      const bool fine_row = bands && on_grid(y + lroi.y, fs);
      const bool band_row = fine_row && (y < top_end || y >= bottom_start);
      const uchar *m = M.ptr<uchar>(y);
      DensifyStats &rs = row_stats[std::size_t(i)];
      for (int x = h; x < L.cols - h; ++x) {
        if (!m[x])
          continue;
        const int vx = x + lroi.x;
        const bool coarse = coarse_row && on_grid(vx, s);
        const bool fine = fine_row && on_grid(vx, fs) &&
                          (band_row || x < left_end || x >= right_start);
        if (!coarse && !fine)
          continue;
        ++rs.grid;
        GridPoint g = match_grid_point(L, R, x, y, wlo, whi, p, scratch);
        switch (g.outcome) {
        case Outcome::kKept:
          ++rs.kept;
          g.match.xl += float(lroi.x);
          g.match.yl += float(lroi.y);
          g.match.xr += float(rx0);
          g.match.yr += float(lroi.y);
          rows[std::size_t(i)].push_back(g.match);
          break;
        case Outcome::kFlat: ++rs.flat; break;
        case Outcome::kWeak: ++rs.weak; break;
        case Outcome::kAmbiguous: ++rs.ambiguous; break;
        case Outcome::kInconsistent: ++rs.inconsistent; break;
        }
      }
    }
  });
  for (std::size_t i = 0; i < rows.size(); ++i) {
    out.insert(out.end(), rows[i].begin(), rows[i].end());
    st.grid += row_stats[i].grid;
    st.kept += row_stats[i].kept;
    st.flat += row_stats[i].flat;
    st.weak += row_stats[i].weak;
    st.ambiguous += row_stats[i].ambiguous;
    st.inconsistent += row_stats[i].inconsistent;
  }
  if (stats_out)
    *stats_out = st;
  return out;
}

} // namespace treestereo
