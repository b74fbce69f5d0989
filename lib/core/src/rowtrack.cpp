#include "treestereo/rowtrack.hpp"

#include "treestereo/errors.hpp"
#include "treestereo/stats.hpp"
#include "treestereo/travel.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace treestereo {

namespace {

constexpr double kMmToM = 1e-3;
constexpr std::size_t kRecent = 4;

void require(bool ok, const char *field, const char *range)
{
  if (!ok)
    throw BadSettings(std::string("The tree tracker setting ") + field +
                          " is out of range: set it to " + range + ".",
                      std::string("tracker parameters: ") + field + " outside " + range);
}

void check_frame(const TrackFrame &f)
{
  if (!std::isfinite(f.position_mm))
    throw BadInput("The rig's position is not finite: the tree tracker needs a finite position "
                   "along the row in each frame.",
                   "TrackFrame::position_mm = " + std::to_string(f.position_mm));
  if (!std::isfinite(f.left_slope) || !std::isfinite(f.right_slope) ||
      !(f.left_slope < f.right_slope) || !std::isfinite(f.left_offset_mm))
    throw BadInput("The view's edges in the frame cannot be used: the tree tracker needs finite "
                   "edge slopes, the left one below the right one (view_slopes() gives them).",
                   "TrackFrame: left_slope=" + std::to_string(f.left_slope) + " right_slope=" +
                       std::to_string(f.right_slope) + " left_offset_mm=" +
                       std::to_string(f.left_offset_mm));
  if (f.measured_segment < -1 || f.measured_segment >= int(f.segments.size()))
    throw BadInput("The frame's measured segment is not one of its segments: give -1 or an "
                   "index into the frame's segments.",
                   "TrackFrame: measured_segment " + std::to_string(f.measured_segment) +
                       " of " + std::to_string(f.segments.size()) + " segments");
  for (const RowSegment &s : f.segments)
    if (!std::isfinite(s.lo_mm) || !std::isfinite(s.hi_mm) || s.hi_mm < s.lo_mm ||
        !std::isfinite(s.near_mm) || !(s.near_mm > 0) || !(s.lo_z_mm >= 0) ||
        !(s.hi_z_mm >= 0) || !std::isfinite(s.lo_z_mm) || !std::isfinite(s.hi_z_mm) ||
        !std::isfinite(s.lo_y_mm) || !std::isfinite(s.hi_y_mm) || !std::isfinite(s.trunk_y_mm) ||
        std::isinf(s.lo_clear_mm) || std::isinf(s.hi_clear_mm) || std::isinf(s.trunk_mm))
      throw BadInput("A row segment in the frame cannot be used: each needs finite lo_mm <= "
                     "hi_mm, a near_mm above 0, lo_z_mm, hi_z_mm finite and 0 or above, "
                     "lo_y_mm, hi_y_mm, trunk_y_mm finite, and lo_clear_mm, hi_clear_mm, "
                     "trunk_mm finite or NaN (unknown).",
                     "RowSegment: lo_mm=" + std::to_string(s.lo_mm) + " hi_mm=" +
                         std::to_string(s.hi_mm) + " near_mm=" + std::to_string(s.near_mm) +
                         " lo_z_mm=" + std::to_string(s.lo_z_mm) +
                         " hi_z_mm=" + std::to_string(s.hi_z_mm) +
                         " lo_y_mm=" + std::to_string(s.lo_y_mm) +
                         " hi_y_mm=" + std::to_string(s.hi_y_mm) +
                         " trunk_y_mm=" + std::to_string(s.trunk_y_mm) +
                         " lo_clear_mm=" + std::to_string(s.lo_clear_mm) +
                         " hi_clear_mm=" + std::to_string(s.hi_clear_mm) +
                         " trunk_mm=" + std::to_string(s.trunk_mm));
  const cv::Vec3d &d = f.row_direction;
  if (!is_row_direction(d))
    throw BadInput("The row's direction in the frame cannot be used: the tree tracker needs a "
                   "unit vector within 60 degrees of the camera's x axis "
                   "(RowDirection::direction() gives it).",
                   "TrackFrame::row_direction = (" + std::to_string(d[0]) + ", " +
                       std::to_string(d[1]) + ", " + std::to_string(d[2]) + ")");
}

// The frame with its X values placed along the row (TrackFrame::row_direction).
TrackFrame along_the_row(const TrackFrame &in)
{
  const cv::Vec3d &d = in.row_direction;
  if (d == cv::Vec3d(1, 0, 0))
    return in;
  TrackFrame f = in;
  // A point's place along the row (along_row()). Its height counts where the view is rolled
  // against the row: a vertical trunk then leans in the view, and its X below the crown is not
  // the X of the crown's middle above it.
  const auto at = [&d](double x_mm, double y_mm, double z_mm) {
    return along_row(cv::Vec3d(x_mm, y_mm, z_mm), d);
  };
  const auto ray = [&d](double slope) { return slope * d[0] + d[2]; };
  f.left_slope = ray(in.left_slope);
  f.right_slope = ray(in.right_slope);
  f.left_offset_mm = in.left_offset_mm * d[0];
  for (RowSegment &s : f.segments) {
    // The trunk's axis: half the crown's length behind its front (a crown about as deep as it is
    // long along the row).
    if (std::isfinite(s.trunk_mm))
      s.trunk_mm = at(s.trunk_mm, s.trunk_y_mm, s.near_mm + 0.5 * (s.hi_mm - s.lo_mm));
    s.lo_mm = at(s.lo_mm, s.lo_y_mm, s.lo_z_mm > 0 ? s.lo_z_mm : s.near_mm);
    s.hi_mm = at(s.hi_mm, s.hi_y_mm, s.hi_z_mm > 0 ? s.hi_z_mm : s.near_mm);
    s.lo_clear_mm *= d[0]; // a distance along x at one depth (NaN stays NaN)
    s.hi_clear_mm *= d[0];
  }
  TreeMetrics &m = f.metrics;
  if (m.tree_present) {
    const double z_mm = (m.extent_depth_m > 0 ? m.extent_depth_m : m.distance_m) / kMmToM;
    // The extent's left and right edges at the canopy centroid's height.
    const double y_mm = std::isfinite(m.centroid_m.y) ? m.centroid_m.y / kMmToM : 0.0;
    m.left_m = at(m.left_m / kMmToM, y_mm, z_mm) * kMmToM;
    m.right_m = at(m.right_m / kMmToM, y_mm, z_mm) * kMmToM;
    m.left_slope = ray(m.left_slope);
    m.right_slope = ray(m.right_slope);
    for (Band &b : m.bands) {
      if (!b.present)
        continue;
      const double zb_mm = b.depth_m > 0 ? b.depth_m / kMmToM : z_mm;
      const double yb_mm = 0.5 * (b.top_m + b.bottom_m) / kMmToM;
      b.left_m = at(b.left_m / kMmToM, yb_mm, zb_mm) * kMmToM;
      b.right_m = at(b.right_m / kMmToM, yb_mm, zb_mm) * kMmToM;
      b.width_m = b.right_m - b.left_m;
    }
  }
  return f;
}

// A track keeps at most this many samples of each figure (the latest): a tree in view for longer
// (a rig standing in front of it) is measured by its last 64 frames, and a long stop does not
// grow the tracker without bound.
constexpr std::size_t kMaxSamples = 64;

template <typename T> void push_capped(std::vector<T> &v, T value)
{
  if (v.size() >= kMaxSamples)
    v.erase(v.begin());
  v.push_back(std::move(value));
}

// Where a track's edge lies (world x, mm; dir = 1 for its high-x edge, -1 for its low-x one).
// - A limb: the observation seen nearest the optical axis. Nearer the axis an edge may read
//   further out than the next observation by what the crown's depth `depth_mm` can hide between
//   their rays, depth_mm x |difference of their slopes|, and by kEdgeNoiseMm. One that reads
//   further out is not the crown's, and the next one is taken (a frame clipped on the other
//   side, whose silhouette ran on into the gap where the next row's leaves showed, read one
//   crown 48 mm wide of its edge).
// - A side only ever seen cut at a valley: no frame sees beyond the cut, which moves with the
//   view as the outline's dip does; the median of the cuts.
constexpr double kEdgeNoiseMm = 10; // the travel between the frames, a pixel, the limb's depth

template <typename Edge> double axis_edge(std::vector<Edge> edges, double depth_mm, int dir)
{
  std::vector<Edge> limbs;
  std::vector<double> cuts;
  for (const Edge &e : edges) {
    if (!e.at_valley)
      limbs.push_back(e);
    cuts.push_back(e.x_mm);
  }
  if (limbs.empty())
    return median(cuts);
  std::sort(limbs.begin(), limbs.end(),
            [](const Edge &a, const Edge &b) { return std::abs(a.slope) < std::abs(b.slope); });
  std::size_t i = 0;
  while (i + 1 < limbs.size() &&
         dir * (limbs[i].x_mm - limbs[i + 1].x_mm) >
             depth_mm * std::abs(limbs[i + 1].slope - limbs[i].slope) + kEdgeNoiseMm)
    ++i;
  return limbs[i].x_mm;
}

double median_of(std::vector<double> v)
{
  return median(v);
}

// A side only ever seen cut at a valley (crowns grown into each other) ends beyond the cut: the
// neighbour's crown hides the rest. A pruned crown stands about its trunk, so with the trunk seen
// (the median of the frames that saw it) and the other side a limb, the hidden side reaches as
// far from the trunk as the limb does: the limb mirrored, never inside the cut. The limb's error
// counts twice in the width then, as the trunk's does. `lo_hidden`, `hi_hidden`: that side was
// only ever seen cut at a valley.
void mirror_hidden_side(bool lo_hidden, bool hi_hidden, const std::vector<double> &trunks,
                        double &lo, double &hi)
{
  if (trunks.empty() || lo_hidden == hi_hidden)
    return;
  const double t = median_of(trunks);
  if (!(t > lo && t < hi))
    return;
  if (hi_hidden)
    hi = std::max(hi, 2 * t - lo);
  else
    lo = std::min(lo, 2 * t - hi);
}

template <typename Edge> bool all_at_valley(const std::vector<Edge> &edges)
{
  return std::all_of(edges.begin(), edges.end(), [](const Edge &e) { return e.at_valley; });
}

// Whether a side is hidden in part, for mirror_hidden_side(): cut at a valley (`valley`), or
// never driven past (`unpassed`: seen from inside the crown, off the axis only, its edge the limb
// of a front cluster hiding any behind it that reach further out) while the other side is not
// at a valley (that one then gives the mirror).
bool partly_hidden(bool valley, bool unpassed, bool other_valley)
{
  return valley || (unpassed && !other_valley);
}

// Overlap length of [a0, a1] and [b0, b1] (negative: the gap between them).
double overlap(double a0, double a1, double b0, double b1)
{
  return std::min(a1, b1) - std::max(a0, b0);
}

std::vector<BandExtent> fuse_bands(const std::vector<std::vector<BandExtent>> &frames)
{
  std::vector<BandExtent> out;
  if (frames.empty())
    return out;
  const std::size_t n = frames.front().size();
  out.resize(n);
  for (std::size_t b = 0; b < n; ++b) {
    std::vector<double> top, bottom, left, right, width, depth, fill;
    std::size_t count = 0;
    for (const auto &f : frames) {
      if (f.size() != n)
        continue;
      ++count;
      const BandExtent &x = f[b];
      if (!x.present)
        continue;
      top.push_back(x.top_m);
      bottom.push_back(x.bottom_m);
      left.push_back(x.left_m);
      right.push_back(x.right_m);
      width.push_back(x.width_m);
      depth.push_back(x.depth_m);
      fill.push_back(x.fill);
    }
    BandExtent &o = out[b];
    o.present = !top.empty() && 2 * top.size() >= count;
    if (!o.present)
      continue;
    o.top_m = median(top);
    o.bottom_m = median(bottom);
    o.left_m = median(left);
    o.right_m = median(right);
    o.width_m = median(width);
    o.depth_m = median(depth);
    o.fill = median(fill);
  }
  return out;
}

} // namespace

void validate(const TrackerParams &p)
{
  require(p.grace_frames >= 0 && p.grace_frames <= 1000, "grace_frames", "0 to 1000");
  require(p.edge_margin_mm >= 0 && p.edge_margin_mm <= 1000, "edge_margin_mm", "0 to 1000 mm");
  require(p.match_tolerance_mm >= 0 && p.match_tolerance_mm <= 2000, "match_tolerance_mm",
          "0 to 2000 mm");
  require(p.forward == 1 || p.forward == -1, "forward", "+1 or -1");
}

void view_slopes(const StereoGeometry &g, double &left_slope, double &right_slope,
                 double &left_offset_mm)
{
  require_valid(g, "the view's edges", "view_slopes");
  right_slope = (g.view_size.width - 0.5 - g.cx[LEFT]) / g.fx;
  const double own = (-0.5 - g.cx[LEFT]) / g.fx, other = (-0.5 - g.cx[RIGHT]) / g.fx;
  if (other * 1000.0 + g.baseline_mm >= own * 1000.0) {
    left_slope = other;
    left_offset_mm = g.baseline_mm;
  } else {
    left_slope = own;
    left_offset_mm = 0;
  }
}

TreeTracker::TreeTracker(const TrackerParams &params) : params_(params)
{
  validate(params_);
  direction_ = params_.forward;
}

std::vector<TreeTracker::Open> TreeTracker::open() const
{
  std::vector<Open> out;
  for (const Track &t : tracks_)
    out.push_back({t.id, t.min_lo_mm * kMmToM, t.max_hi_mm * kMmToM});
  return out;
}

std::pair<double, double> TreeTracker::robust_ends(const Track &k, double lo, double hi) const
{
  // Mode Tree: an end seen off the image edge is the median of the frames it was so seen in,
  // which a later frame of stray points across a gap does not move (rowtrack.hpp).
  std::pair<double, double> e(lo, hi);
  if (params_.mode == CanopyMode::Tree && !k.starts.empty())
    e.first = median_of(k.starts);
  if (params_.mode == CanopyMode::Tree && !k.ends.empty())
    e.second = median_of(k.ends);
  return e;
}

std::vector<TreeRecord> TreeTracker::update(const TrackFrame &frame)
{
  check_frame(frame);
  const TrackFrame f = along_the_row(frame);
  const double pos = f.position_mm;
  if (has_position_ && std::abs(pos - last_position_mm_) > 0.5)
    direction_ = pos > last_position_mm_ ? 1 : -1;
  min_position_mm_ = has_position_ ? std::min(min_position_mm_, pos) : pos;
  max_position_mm_ = has_position_ ? std::max(max_position_mm_, pos) : pos;
  has_position_ = true;
  last_position_mm_ = pos;

  const bool row = params_.mode == CanopyMode::Row;
  const double tol = params_.match_tolerance_mm;
  const std::size_t ns = f.segments.size(), nt = tracks_.size();

  // The segments in world x and whether the image edge cuts them.
  struct Seg {
    double lo, hi;
    bool cut_lo, cut_hi;
  };
  std::vector<Seg> segs(ns);
  for (std::size_t i = 0; i < ns; ++i) {
    const RowSegment &s = f.segments[i];
    const double z_lo = s.lo_z_mm > 0 ? s.lo_z_mm : s.near_mm;
    const double z_hi = s.hi_z_mm > 0 ? s.hi_z_mm : s.near_mm;
    const double clear_lo = std::isnan(s.lo_clear_mm)
                                ? s.lo_mm - (f.left_slope * z_lo + f.left_offset_mm)
                                : s.lo_clear_mm;
    const double clear_hi =
        std::isnan(s.hi_clear_mm) ? f.right_slope * z_hi - s.hi_mm : s.hi_clear_mm;
    segs[i] = {s.lo_mm + pos, s.hi_mm + pos, clear_lo <= params_.edge_margin_mm,
               clear_hi <= params_.edge_margin_mm};
  }
  // Each track's extent to match against: the last frame's, or its ends seen off the edge.
  std::vector<std::pair<double, double>> extent(nt);
  for (std::size_t t = 0; t < nt; ++t)
    extent[t] = robust_ends(tracks_[t], tracks_[t].lo_mm, tracks_[t].hi_mm);
  auto ov = [&](std::size_t i, std::size_t t) {
    return overlap(segs[i].lo, segs[i].hi, extent[t].first - tol, extent[t].second + tol);
  };

  // Which segments each track is seen in.
  std::vector<std::vector<std::size_t>> obs(nt);
  std::vector<bool> seg_used(ns, false), kept_alive(nt, false), piece(nt, false);
  if (!row)
    for (std::size_t i = 0; i < ns; ++i) {
      // A segment cut at a valley overlaps its neighbour's track by as much as the crowns grew
      // into each other: that track counts only when the segment covers half of it or more.
      const bool joined = f.segments[i].joined_lo || f.segments[i].joined_hi;
      std::vector<std::size_t> over;
      for (std::size_t t = 0; t < nt; ++t)
        if (ov(i, t) > (joined ? 0.5 * std::min(extent[t].second - extent[t].first,
                                                segs[i].hi - segs[i].lo)
                               : 0.0))
          over.push_back(t);
      if (over.size() < 2)
        continue;
      // A piece of a tree: a track the last frame started from a segment split off its
      // neighbour's (a sparse column across a crown entering the view): seen once, at the
      // leading edge of the view (its leading end cut there), never measured, and now covered
      // whole by this segment together with a track that is not such a piece. It is dropped,
      // not emitted: it was part of that tree.
      std::size_t pieces = 0;
      for (std::size_t t : over) {
        const Track &k = tracks_[t];
        piece[t] = k.frames_seen == 1 && k.missed == 0 && k.heights.empty() &&
                   k.distances.empty() &&
                   (direction_ > 0 ? k.ends.empty() : k.starts.empty()) &&
                   k.min_lo_mm >= segs[i].lo - tol && k.max_hi_mm <= segs[i].hi + tol;
        pieces += piece[t] ? 1 : 0;
      }
      if (pieces == over.size()) // nothing but pieces: trees of their own
        for (std::size_t t : over)
          piece[t] = false;
      // Two trees seen as one (or a tree with its piece): neither's extent nor measurement is
      // trusted this frame.
      seg_used[i] = true;
      for (std::size_t t : over)
        kept_alive[t] = true;
    }
  struct Pair {
    double overlap;
    std::size_t seg, track;
  };
  std::vector<Pair> pairs;
  for (std::size_t i = 0; i < ns; ++i)
    for (std::size_t t = 0; t < nt; ++t)
      if (!seg_used[i] && !kept_alive[t] && ov(i, t) > 0)
        pairs.push_back({ov(i, t), i, t});
  std::stable_sort(pairs.begin(), pairs.end(),
                   [](const Pair &a, const Pair &b) { return a.overlap > b.overlap; });
  std::vector<bool> track_taken(nt, false);
  for (const Pair &p : pairs)
    if (!seg_used[p.seg] && !track_taken[p.track]) {
      seg_used[p.seg] = track_taken[p.track] = true;
      obs[p.track].push_back(p.seg);
    }
  // A segment left over on a track taken this frame: more of that tree (a sparse frame split
  // it) or, mode Row, more of the same canopy. Mode Tree: not when it touches that tree's
  // segment (a crown grown into it, cut at their valley): a tree seen as one with its
  // neighbour until the valley showed, now a tree of its own.
  std::vector<std::size_t> fresh;
  for (std::size_t i = 0; i < ns; ++i) {
    if (seg_used[i])
      continue;
    double best = 0;
    std::size_t best_t = nt;
    for (std::size_t t = 0; t < nt; ++t)
      if (track_taken[t] && ov(i, t) > best) {
        best = ov(i, t);
        best_t = t;
      }
    bool own_tree = false;
    if (!row && best_t < nt)
      for (std::size_t j : obs[best_t])
        own_tree = own_tree || (j + 1 == i && f.segments[i].joined_lo) ||
                   (i + 1 == j && f.segments[i].joined_hi);
    if (own_tree)
      fresh.push_back(i);
    else if (best_t < nt)
      obs[best_t].push_back(i);
    else
      fresh.push_back(i);
  }

  // New tracks: trees entering the view. A segment over a tree just emitted is its remnant.
  for (std::size_t i : fresh) {
    bool remnant = false;
    for (const auto &e : recent_)
      remnant = remnant || overlap(segs[i].lo, segs[i].hi, e.first - tol, e.second + tol) > 0;
    if (remnant)
      continue;
    Track k;
    k.id = next_id_++;
    k.lo_mm = k.min_lo_mm = segs[i].lo;
    k.hi_mm = k.max_hi_mm = segs[i].hi;
    tracks_.push_back(std::move(k));
    obs.push_back({i});
    kept_alive.push_back(false);
  }

  // Update the tracks seen.
  const TreeMetrics &m = f.metrics;
  for (std::size_t t = 0; t < tracks_.size(); ++t) {
    Track &k = tracks_[t];
    if (kept_alive[t]) {
      k.missed = 0;
      continue;
    }
    if (obs[t].empty()) {
      ++k.missed;
      continue;
    }
    const std::size_t first = obs[t].front();
    double lo = segs[first].lo, hi = segs[first].hi;
    bool cut_lo = segs[first].cut_lo, cut_hi = segs[first].cut_hi;
    bool valley_lo = f.segments[first].joined_lo, valley_hi = f.segments[first].joined_hi;
    double near = f.segments[first].near_mm;
    bool measured = false;
    for (std::size_t i : obs[t]) {
      if (segs[i].lo < lo) {
        lo = segs[i].lo;
        cut_lo = segs[i].cut_lo;
        valley_lo = f.segments[i].joined_lo;
      }
      if (segs[i].hi > hi) {
        hi = segs[i].hi;
        cut_hi = segs[i].cut_hi;
        valley_hi = f.segments[i].joined_hi;
      }
      near = std::min(near, f.segments[i].near_mm);
      measured = measured || int(i) == f.measured_segment;
    }
    // Mode Row: a canopy reaching past an end already seen off the edge has met the next one
    // (touching canopies); that end was none.
    if (row && hi > k.max_hi_mm + tol)
      k.ends.clear();
    if (row && lo < k.min_lo_mm - tol)
      k.starts.clear();
    k.lo_mm = lo;
    k.hi_mm = hi;
    k.min_lo_mm = std::min(k.min_lo_mm, lo);
    k.max_hi_mm = std::max(k.max_hi_mm, hi);
    k.near_mm = near;
    if (!cut_lo) {
      push_capped(k.starts, lo);
      k.start_free = k.start_free || !valley_lo;
    }
    if (!cut_hi) {
      push_capped(k.ends, hi);
      k.end_free = k.end_free || !valley_hi;
    }
    ++k.frames_seen;
    k.missed = 0;
    // The measurement counts when it is of this tree whole: mode Tree, a tree split over
    // several segments this frame was measured on one part only.
    if (!measured || !m.tree_present || (!row && obs[t].size() > 1))
      continue;
    const Clipped &c = m.clipped;
    if (!c.top && !c.bottom) {
      push_capped(k.heights, m.height_m);
    }
    // Width's edges (mode Row has none: the extent in view); a cut or clipped side is a lower
    // bound.
    if (!row) {
      const RowSegment &own = f.segments[obs[t].front()];
      if (!c.left && !cut_lo)
        push_capped(k.lefts, Track::Edge{m.left_slope, m.left_m / kMmToM + pos, own.joined_lo});
      if (!c.right && !cut_hi)
        push_capped(k.rights, Track::Edge{m.right_slope, m.right_m / kMmToM + pos, own.joined_hi});
      if (std::isfinite(own.trunk_mm))
        push_capped(k.trunks, own.trunk_mm + pos);
    }
    if (c.any() || cut_lo || cut_hi)
      continue;
    push_capped(k.distances, m.distance_m);
    push_capped(k.thicknesses, m.thickness_m);
    push_capped(k.confidences, m.confidence);
    std::vector<BandExtent> bands;
    for (const Band &b : m.bands) {
      BandExtent r = b;
      r.left_m += pos * kMmToM;
      r.right_m += pos * kMmToM;
      bands.push_back(r);
    }
    push_capped(k.bands, std::move(bands));
  }

  // The pieces go; an id the last of them took is given again.
  if (std::find(piece.begin(), piece.end(), true) != piece.end()) {
    std::vector<Track> kept;
    std::vector<int> gone;
    for (std::size_t t = 0; t < tracks_.size(); ++t)
      if (t < nt && piece[t])
        gone.push_back(tracks_[t].id);
      else
        kept.push_back(std::move(tracks_[t]));
    tracks_ = std::move(kept);
    std::sort(gone.rbegin(), gone.rend());
    for (int id : gone)
      if (id == next_id_ - 1)
        --next_id_;
  }

  // Mode Row: canopies that now overlap are one (a segment reached across to the next track).
  if (row && tracks_.size() > 1) {
    std::sort(tracks_.begin(), tracks_.end(),
              [](const Track &a, const Track &b) { return a.min_lo_mm < b.min_lo_mm; });
    std::vector<Track> merged;
    for (Track &k : tracks_) {
      if (!merged.empty() && k.min_lo_mm <= merged.back().max_hi_mm) {
        Track &a = merged.back();
        const bool k_ends = k.max_hi_mm > a.max_hi_mm;
        if (k_ends) {
          a.ends = std::move(k.ends);
          a.max_hi_mm = k.max_hi_mm;
          a.hi_mm = std::max(a.hi_mm, k.hi_mm);
        }
        a.lo_mm = std::min(a.lo_mm, k.lo_mm);
        a.id = std::min(a.id, k.id);
        a.near_mm = std::min(a.near_mm, k.near_mm);
        auto append = [](std::vector<double> &x, const std::vector<double> &y) {
          x.insert(x.end(), y.begin(), y.end());
        };
        append(a.heights, k.heights);
        append(a.distances, k.distances);
        append(a.thicknesses, k.thicknesses);
        append(a.confidences, k.confidences);
        a.bands.insert(a.bands.end(), k.bands.begin(), k.bands.end());
        a.frames_seen = std::max(a.frames_seen, k.frames_seen);
        a.missed = std::min(a.missed, k.missed);
        continue;
      }
      merged.push_back(std::move(k));
    }
    tracks_ = std::move(merged);
  }

  // Emit the tracks that left the view behind (their side that leaves last is past the
  // trailing edge at their front depth) or were lost.
  std::vector<Track> done, keep;
  for (Track &k : tracks_) {
    const auto [lo, hi] = robust_ends(k, k.min_lo_mm, k.max_hi_mm);
    const bool behind = k.missed > 0 && (direction_ > 0 ? hi < pos + f.left_slope * k.near_mm +
                                                                   f.left_offset_mm
                                                        : lo > pos + f.right_slope * k.near_mm);
    if (behind) {
      done.push_back(std::move(k));
    } else if (k.missed > params_.grace_frames) {
      k.lost = true;
      done.push_back(std::move(k));
    } else {
      keep.push_back(std::move(k));
    }
  }
  tracks_ = std::move(keep);
  return emit(done);
}

std::vector<TreeRecord> TreeTracker::finish()
{
  std::vector<Track> done = std::move(tracks_);
  tracks_.clear();
  return emit(done);
}

std::vector<TreeRecord> TreeTracker::emit(std::vector<Track> &done)
{
  // In the order they leave: the lowest world x first when driving along +x.
  const int dir = direction_;
  std::sort(done.begin(), done.end(), [dir](const Track &a, const Track &b) {
    return dir > 0 ? a.max_hi_mm < b.max_hi_mm : a.min_lo_mm > b.min_lo_mm;
  });
  const bool row = params_.mode == CanopyMode::Row;
  std::vector<TreeRecord> out;
  for (const Track &k : done) {
    TreeRecord r;
    r.id = k.id;
    r.mode = params_.mode;
    r.lost = k.lost;
    r.start_seen = !k.starts.empty();
    r.end_seen = !k.ends.empty();
    r.start_m = (r.start_seen ? median_of(k.starts) : k.min_lo_mm) * kMmToM;
    r.end_m = (r.end_seen ? median_of(k.ends) : k.max_hi_mm) * kMmToM;
    if (r.end_m < r.start_m) // a median pair of a tree seen at both ends in different frames
      std::swap(r.start_m, r.end_m);
    // A side the rig never drove past: the first tree's, the last one's when the run ends before
    // it (the rig's travel never reached the edge seen nearest the axis).
    const bool lo_unpassed = !k.lefts.empty() && min_position_mm_ > axis_edge(k.lefts, 0, -1);
    const bool hi_unpassed = !k.rights.empty() && max_position_mm_ < axis_edge(k.rights, 0, 1);
    if (!row && r.start_seen && r.end_seen) {
      double lo = r.start_m / kMmToM, hi = r.end_m / kMmToM;
      mirror_hidden_side(partly_hidden(!k.start_free, lo_unpassed, !k.end_free),
                         partly_hidden(!k.end_free, hi_unpassed, !k.start_free), k.trunks, lo, hi);
      r.start_m = lo * kMmToM;
      r.end_m = hi * kMmToM;
    }
    r.position_m = 0.5 * (r.start_m + r.end_m);
    r.frames_seen = k.frames_seen;
    r.height_frames = int(k.heights.size());
    r.has_height = !k.heights.empty();
    if (r.has_height)
      r.height_m = median_of(k.heights);
    if (row) {
      r.has_width = r.start_seen && r.end_seen;
      r.width_m = r.end_m - r.start_m;
      r.width_frames = r.has_width ? int(std::min(k.starts.size(), k.ends.size())) : 0;
    } else {
      r.has_width = !k.lefts.empty() && !k.rights.empty();
      if (r.has_width) {
        // A crown about as deep as it is long along the row: how far behind its front a leaf
        // cluster may stand.
        const double depth_mm = (r.end_m - r.start_m) / kMmToM;
        double lo = axis_edge(k.lefts, depth_mm, -1), hi = axis_edge(k.rights, depth_mm, 1);
        const bool lo_valley = all_at_valley(k.lefts), hi_valley = all_at_valley(k.rights);
        mirror_hidden_side(partly_hidden(lo_valley, lo_unpassed, hi_valley),
                           partly_hidden(hi_valley, hi_unpassed, lo_valley), k.trunks, lo, hi);
        r.width_m = (hi - lo) * kMmToM;
        r.width_frames = int(std::min(k.lefts.size(), k.rights.size()));
      }
    }
    r.has_depth = !k.distances.empty();
    if (r.has_depth) {
      r.distance_m = median_of(k.distances);
      r.thickness_m = median_of(k.thicknesses);
      r.confidence = median_of(k.confidences);
      r.bands = fuse_bands(k.bands);
    }
    r.frames = row ? k.frames_seen : int(k.distances.size());
    r.complete = r.start_seen && r.end_seen && (row || r.has_depth);
    if (has_previous_) {
      r.has_spacing = true;
      r.spacing_m = std::abs(r.position_m - previous_.position_m);
      r.gap_m = dir > 0 ? r.start_m - previous_.end_m : previous_.start_m - r.end_m;
    }
    previous_ = r;
    has_previous_ = true;
    if (!k.lost) { // a lost tree may come back into sight: it is then a new track
      recent_.push_back(robust_ends(k, k.min_lo_mm, k.max_hi_mm));
      if (recent_.size() > kRecent)
        recent_.erase(recent_.begin());
    }
    out.push_back(std::move(r));
  }
  return out;
}

} // namespace treestereo
