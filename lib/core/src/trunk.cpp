// find_trunk(): where a tree's trunk shows below its crown (canopy.hpp says what and why).
#include "treestereo/canopy.hpp"

#include "treestereo/errors.hpp"
#include "treestereo/stats.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace treestereo {

namespace {

constexpr int kHalf = 2;            // the match window: 2 * kHalf + 1 columns of the band
constexpr double kMinZncc = 0.6;    // a column matches at the crown's depth
constexpr double kMinBare = 0.9;    // share of the column's band that is not plant
constexpr double kMinTrunkMm = 20;  // narrower runs are a twig's edge or noise
constexpr double kMaxShare = 1.0 / 3; // of the segment across: wider is ground or a wall
constexpr int kMinRows = 6;         // a band shorter than this tells nothing
constexpr int kMaxGapPx = 2;        // columns missing inside a run
constexpr double kSpanPx = 2;       // of disparity about a run's median in bare soil: an upright
                                    // trunk's is below 1, the rest the match's noise

bool fits(const cv::Mat &m, const cv::Size &size, int type)
{
  return m.size() == size && m.type() == type;
}

// A pixel coordinate (or disparity) computed in double, held within [lo, hi] before it becomes
// an int: a segment of an absurd depth must not overflow the conversion.
int clamped(double v, int lo, int hi)
{
  return v <= lo ? lo : v >= hi ? hi : int(v);
}

} // namespace

double find_trunk(const cv::Mat &left, const cv::Mat &right, const cv::Mat &vegetation,
                  const cv::Mat &canopy, const RowSegment &s, const GroundPlane &ground,
                  const StereoGeometry &g, double *row_y_mm)
{
  require_valid(g, "Finding a trunk", "find_trunk");
  const cv::Size size = g.view_size;
  if (!fits(left, size, CV_8UC1) || !fits(right, size, CV_8UC1) ||
      !fits(vegetation, size, CV_8UC1) || !fits(canopy, size, CV_8UC1))
    throw BadInput("The views or masks do not fit the stereo geometry: finding a trunk needs "
                   "both rectified views in grey and 8-bit masks, all of the view's size.",
                   "find_trunk: view " + std::to_string(size.width) + "x" +
                       std::to_string(size.height));
  constexpr double kNone = std::numeric_limits<double>::quiet_NaN();
  if (!(s.near_mm > 0) || !(s.hi_mm > s.lo_mm))
    return kNone;
  const double z0 = s.near_mm, z1 = s.near_mm + (s.hi_mm - s.lo_mm);
  const double cx = g.cx[0], fy = g.fy > 0 ? g.fy : g.fx;
  const int u0 = clamped(std::floor(cx + g.fx * s.lo_mm / z0), kHalf, size.width - 1 - kHalf);
  const int u1 = clamped(std::ceil(cx + g.fx * s.hi_mm / z0), kHalf, size.width - 1 - kHalf);
  if (u1 - u0 < 2 * kHalf + 1)
    return kNone;

  // The crown's lowest row in its columns.
  int bottom = -1;
  for (int y = size.height - 1; y >= 0 && bottom < 0; --y) {
    const uchar *m = canopy.ptr<uchar>(y);
    for (int u = u0; u <= u1; ++u)
      if (m[u]) {
        bottom = y;
        break;
      }
  }
  if (bottom < 0)
    return kNone;
  // The ground under the crown's middle, at its middle depth.
  double ground_row = size.height;
  const double zm = 0.5 * (z0 + z1), xm = 0.5 * (s.lo_mm + s.hi_mm);
  if (ground.found && std::abs(ground.normal[1]) > 0.5) {
    const double y_mm =
        -(ground.normal[0] * xm + ground.normal[2] * zm + ground.d) / ground.normal[1];
    ground_row = std::min(ground_row, g.cy + fy * y_mm / zm);
  }
  const int y0 = bottom + 2;
  const int y1 = clamped(y0 + 2.0 / 3.0 * (ground_row - y0), y0, size.height);
  const int rows = y1 - y0;
  if (rows < kMinRows)
    return kNone;

  // Per column: the best ZNCC over the crown's disparities, and its share of bare pixels.
  const int d_lo = clamped(std::floor(g.fx * g.baseline_mm / z1 + g.doffs()), 0, size.width);
  const int d_hi = clamped(std::ceil(g.fx * g.baseline_mm / z0 + g.doffs()), 0, size.width);
  const int nc = u1 - u0 + 1;
  std::vector<double> best(std::size_t(nc), -1.0), best_d(std::size_t(nc), 0.0),
      bare(std::size_t(nc), 0.0);
  for (int u = u0; u <= u1; ++u) {
    int n = 0;
    for (int y = y0; y < y1; ++y)
      n += vegetation.at<uchar>(y, u) == 0;
    bare[std::size_t(u - u0)] = double(n) / rows;
  }
  // Per column of the rows [ya, yb): the best ZNCC over the crown's disparities and where it
  // peaks. Column sums of the band (left), refreshed per disparity for the right and the
  // products.
  const auto match_rows = [&](int ya, int yb, std::vector<double> &score,
                              std::vector<double> &score_d) {
    std::vector<double> sl(std::size_t(size.width), 0), sll(sl), sr(sl), srr(sl), slr(sl);
    for (int y = ya; y < yb; ++y) {
      const uchar *a = left.ptr<uchar>(y);
      for (int u = u0 - kHalf; u <= u1 + kHalf; ++u) {
        sl[std::size_t(u)] += a[u];
        sll[std::size_t(u)] += double(a[u]) * a[u];
      }
    }
    const double n = double(yb - ya) * (2 * kHalf + 1);
    for (int d = d_lo; d <= d_hi; ++d) {
      // Columns whose window the right view holds at this disparity.
      const int ua = std::max(u0, d + kHalf);
      if (ua > u1)
        continue;
      std::fill(sr.begin(), sr.end(), 0.0);
      std::fill(srr.begin(), srr.end(), 0.0);
      std::fill(slr.begin(), slr.end(), 0.0);
      for (int y = ya; y < yb; ++y) {
        const uchar *a = left.ptr<uchar>(y), *b = right.ptr<uchar>(y);
        for (int u = ua - kHalf; u <= u1 + kHalf; ++u) {
          const double r = b[u - d];
          sr[std::size_t(u)] += r;
          srr[std::size_t(u)] += r * r;
          slr[std::size_t(u)] += r * a[u];
        }
      }
      for (int u = ua; u <= u1; ++u) {
        double a = 0, aa = 0, b = 0, bb = 0, ab = 0;
        for (int k = u - kHalf; k <= u + kHalf; ++k) {
          a += sl[std::size_t(k)];
          aa += sll[std::size_t(k)];
          b += sr[std::size_t(k)];
          bb += srr[std::size_t(k)];
          ab += slr[std::size_t(k)];
        }
        const double va = n * aa - a * a, vb = n * bb - b * b;
        if (va <= n || vb <= n) // flat: no match to tell
          continue;
        const double z = (n * ab - a * b) / std::sqrt(va * vb);
        if (z > score[std::size_t(u - u0)]) {
          score[std::size_t(u - u0)] = z;
          score_d[std::size_t(u - u0)] = d;
        }
      }
    }
  };
  match_rows(y0, y1, best, best_d);

  // Runs of the columns [a, b] where `holds` does, kMaxGapPx missing at most inside one.
  struct Run {
    int a, b;
    int len() const { return b - a + 1; }
  };
  const auto runs_where = [](int a, int b, const auto &holds) {
    std::vector<Run> out;
    for (int i = a; i <= b; ++i) {
      if (!holds(i))
        continue;
      if (!out.empty() && i - out.back().b <= kMaxGapPx + 1)
        out.back().b = i;
      else
        out.push_back({i, i});
    }
    return out;
  };
  // Runs of bare columns: the trunk fills the band's rows, the ground behind it seldom does.
  const std::vector<Run> runs =
      runs_where(0, nc - 1, [&](int i) { return bare[std::size_t(i)] >= kMinBare; });
  // In bare soil (below): the rows of the band's upper half, where the soil seen behind the
  // trunk lies further behind it than near its foot. A column matched there at the crown's depth
  // with its peak inside the crown's disparities (bare soil behind matches at the range's end if
  // at all).
  std::vector<double> best_up, best_d_up;
  const int y_up = y0 + std::max(kMinRows, rows / 2);
  const auto matched = [&](int i) {
    if (best_up.empty()) {
      best_up.assign(std::size_t(nc), -1.0);
      best_d_up.assign(std::size_t(nc), 0.0);
      match_rows(y0, y_up, best_up, best_d_up);
    }
    const double d = best_d_up[std::size_t(i)];
    return best_up[std::size_t(i)] >= kMinZncc && d > d_lo && d < d_hi;
  };
  const double seg_mm = s.hi_mm - s.lo_mm;
  // The candidate trunks: their columns, the depth of their front and the middle of the rows
  // matched.
  struct Candidate {
    Run run;
    double z, row;
  };
  std::vector<Candidate> found;
  // Whether the run, matched at the disparities `ds`, is as wide as a trunk (then a candidate).
  const auto consider = [&](const Run &r, std::vector<double> ds, double row) {
    const double disparity = median(ds) - g.doffs();
    if (disparity <= 0)
      return false;
    const double z = g.fx * g.baseline_mm / disparity;
    const double width_mm = r.len() * z / g.fx;
    if (width_mm < kMinTrunkMm || width_mm > kMaxShare * seg_mm)
      return false;
    found.push_back({r, z, row});
    return true;
  };
  for (const Run &r : runs) {
    // Most of it matches at the crown's depth (a bare patch of ground behind does not): the
    // trunk alone.
    std::vector<double> ds;
    for (int i = r.a; i <= r.b; ++i)
      if (best[std::size_t(i)] >= kMinZncc)
        ds.push_back(best_d[std::size_t(i)]);
    if (2 * int(ds.size()) >= r.len() && consider(r, ds, 0.5 * (y0 + y1 - 1)))
      continue;
    // Otherwise the trunk may stand in bare soil (a path, a herbicide strip) that widened its
    // run: the soil lies deeper than the crown and matches there only where its depth, drifting
    // along the row, passes through the crown's. A trunk is upright and stands at one depth:
    // stretches of matched columns (gaps up to kMaxGapPx) with three quarters of them within
    // kSpanPx of their median disparity, trimmed to the first and last of those.
    for (const Run &stretch : runs_where(r.a, r.b, matched)) {
      std::vector<double> dd;
      for (int i = stretch.a; i <= stretch.b; ++i)
        if (matched(i))
          dd.push_back(best_d_up[std::size_t(i)]);
      std::vector<double> sorted = dd; // median() reorders
      const double mid = median(sorted);
      Run t{-1, -1};
      std::vector<double> kept;
      for (int i = stretch.a; i <= stretch.b; ++i)
        if (matched(i) && std::abs(best_d_up[std::size_t(i)] - mid) <= kSpanPx) {
          t.a = t.a < 0 ? i : t.a;
          t.b = i;
          kept.push_back(best_d_up[std::size_t(i)]);
        }
      if (4 * kept.size() >= 3 * dd.size())
        consider(t, kept, 0.5 * (y0 + y_up - 1));
    }
  }
  const Candidate *pick = nullptr;
  int second = 0;
  for (const Candidate &c : found) {
    if (!pick || c.run.len() > pick->run.len()) {
      if (pick)
        second = std::max(second, pick->run.len());
      pick = &c;
    } else {
      second = std::max(second, c.run.len());
    }
  }
  if (!pick || 2 * second > pick->run.len())
    return kNone;
  const Run &r = pick->run;
  const double u_mid = u0 + 0.5 * (r.a + r.b);
  // The match sees the trunk's front; its axis stands a radius (half its width) behind.
  const double z_axis = pick->z * (1 + 0.5 * r.len() / g.fx);
  if (row_y_mm)
    *row_y_mm = (pick->row - g.cy) * z_axis / fy;
  return (u_mid - cx) * z_axis / g.fx;
}

} // namespace treestereo
