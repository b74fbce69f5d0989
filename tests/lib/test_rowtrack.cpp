// The tree tracker against a constructed row: trees with known world extents, the rig driving by
// at 0.5 and 2 m/s at 7 frames/s, each frame's segments as the view cuts them and the tree in
// front's measurements. Frames where the tree is clipped carry wrong values on purpose: none of
// them may reach a record.
#include "treestereo/errors.hpp"
#include "treestereo/rowtrack.hpp"
#include "treestereo/record_json.hpp"
#include "treestereo/stats.hpp"
#include "typed_error.hpp"
#include "simple_geometry.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

using namespace treestereo;

namespace {

struct TrueTree {
  double start_mm, end_mm; // world x
  double height_m, distance_m;
  double width_m() const { return (end_mm - start_mm) / 1000.0; }
  double centre_m() const { return 0.5 * (start_mm + end_mm) / 1000.0; }
};

// Gaps 150, 800, 300 and 500 mm.
const std::vector<TrueTree> kRow = {
    {1000, 1700, 0.90, 2.00}, {1850, 2650, 1.00, 2.05}, {3450, 4050, 0.80, 1.95},
    {4350, 5200, 1.10, 2.10}, {5700, 6400, 0.95, 2.02}};

// The view: 1296 px wide, fx 1100, cx 648; the row's front at 2 m.
constexpr double kNear = 2000;
const double kLeftSlope = (-0.5 - 648.0) / 1100.0, kRightSlope = (1296 - 0.5 - 648.0) / 1100.0;
const double kL = kLeftSlope * kNear, kR = kRightSlope * kNear; // -1179 and 1179 mm

// A frame of that view at `position_mm`, with no segment yet.
TrackFrame view_frame(double position_mm)
{
  TrackFrame tf;
  tf.position_mm = position_mm;
  tf.left_slope = kLeftSlope;
  tf.right_slope = kRightSlope;
  return tf;
}

// A segment of the row's front from lo_mm to hi_mm (camera x).
RowSegment front_segment(double lo_mm, double hi_mm, std::size_t n_points = 500)
{
  RowSegment s;
  s.lo_mm = lo_mm;
  s.hi_mm = hi_mm;
  s.near_mm = kNear;
  s.n_points = n_points;
  return s;
}

struct Sim {
  double speed_m_s = 0.5;
  double from_mm = 0, to_mm = 8000;   // the rig's true travel
  int hide_tree = -1;                 // this tree's segment is missing for one frame...
  bool hidden = false;                // ...(the first frame it is fully in view and in front)
  int top_clipped_tree = 3;           // this tree's top is clipped in two frames of three
  bool merge_touching = false;        // touching canopies give one segment (mode Row)
  int split_frame = -1;               // up to this frame touching canopies are seen apart
  bool hide_second = false;           // ...or the second of them not at all
  // Mode Tree: touching canopies are one segment until both show this much in view (mm), then
  // two segments cut at the contact (a valley of the top line: joined_hi / joined_lo). < 0: off.
  double valley_from_mm = -1;
  // Where in the crowns' overlap the valley's cut falls: 0 at the second crown's start, 1 at the
  // first crown's end (the outline dips where the nearer crown's limb is, not always midway).
  double valley_at = 0.5;
  // The measured tree's trunk shows below its crown (RowSegment::trunk_mm, the crown's middle).
  bool trunks = false;
  // The segments of touching crowns end at the cut too, as the chain's do (else at their
  // crowns' true ends).
  bool segments_at_cut = false;
  // Stray points bridge the gap after this tree in the frames it is in view with the next one
  // entering (the next tree's canopy less than 300 mm in view): its segment runs on to the next
  // tree's (seen as one).
  int bridge_tree = -1;
  // This tree's high-x edge reads 50 mm further out in the frame that sees it nearest the axis
  // (its silhouette ran on into the gap).
  int wide_edge_tree = -1;
};

struct SimFrame {
  TrackFrame frame;
  double true_position_mm = 0;
};

// A crown's edge seen off the optical axis is the limb of a leaf cluster in front; one behind it
// that reaches out further is hidden, the more the farther off the axis the ray (up to 40 mm at
// a slope of 0.27, a cluster 150 mm behind): how much an edge of camera x `x_mm` reads short.
double hidden_mm(double x_mm, bool right_edge)
{
  const double outward = (right_edge ? x_mm : -x_mm) / kNear;
  return std::clamp(150.0 * outward, 0.0, 40.0);
}

// The metrics of a crown whose edges are at camera x `lo_mm` and `hi_mm` (not clipped), seen
// with the hidden part of hidden_mm() when `back_clusters`.
TreeMetrics whole_crown(double lo_mm, double hi_mm, bool back_clusters = true)
{
  TreeMetrics m;
  m.tree_present = true;
  m.left_m = (lo_mm + (back_clusters ? hidden_mm(lo_mm, false) : 0)) / 1000.0;
  m.right_m = (hi_mm - (back_clusters ? hidden_mm(hi_mm, true) : 0)) / 1000.0;
  m.left_slope = lo_mm / kNear;
  m.right_slope = hi_mm / kNear;
  m.width_m = m.right_m - m.left_m;
  return m;
}

TreeMetrics measure(const TrueTree &t, int index, int frame, double a, double b, int top_clipped)
{
  TreeMetrics m = whole_crown(std::max(a, kL), std::min(b, kR));
  m.clipped.left = a <= kL;
  m.clipped.right = b >= kR;
  m.clipped.top = index == top_clipped && frame % 3 != 0; // most of its frames
  const bool lr = m.clipped.left || m.clipped.right, tb = m.clipped.top || m.clipped.bottom;
  // Wrong on purpose where clipped: a lower bound of the extent, nonsense for the rest.
  m.height_m = tb ? 0.6 * t.height_m : t.height_m;
  const bool any = lr || tb;
  m.distance_m = any ? 9.9 : t.distance_m;
  m.thickness_m = any ? 0.01 : 0.4;
  m.confidence = any ? 0.05 : 0.8 + 0.01 * (frame % 5);
  for (int k = 0; k < 3; ++k) {
    Band band;
    band.present = true;
    band.top_m = -0.4 + 0.3 * k;
    band.bottom_m = band.top_m + 0.3;
    band.left_m = any ? 0 : a / 1000.0;
    band.right_m = any ? 0 : b / 1000.0;
    band.width_m = any ? 0 : t.width_m();
    band.depth_m = any ? 9 : t.distance_m;
    band.fill = any ? 0 : 0.5 + 0.1 * k;
    m.bands.push_back(band);
  }
  return m;
}

std::vector<SimFrame> simulate(const std::vector<TrueTree> &trees, Sim sim)
{
  const double step = sim.speed_m_s * 1000.0 / 7.0 * (sim.to_mm >= sim.from_mm ? 1 : -1);
  const int n = int(std::floor((sim.to_mm - sim.from_mm) / step)) + 1;
  std::vector<SimFrame> out;
  for (int f = 0; f < n; ++f) {
    SimFrame s;
    const double pos = sim.from_mm + f * step;
    s.true_position_mm = pos;
    TrackFrame &tf = s.frame;
    tf = view_frame(pos + 8.0 * std::sin(1.7 * f)); // the travel estimate's error
    struct Vis {
      double lo, hi, a, b;
      int tree;
      bool joined_lo = false, joined_hi = false;
    };
    std::vector<Vis> vis;
    for (std::size_t i = 0; i < trees.size(); ++i) {
      const double a = trees[i].start_mm - pos, b = trees[i].end_mm - pos;
      double lo = std::max(a, kL), hi = std::min(b, kR);
      if (lo >= hi)
        continue;
      // The limb's sampling moves an end a few mm; an end on the image edge stays there.
      if (a > kL)
        lo += 5.0 * std::sin(0.9 * f + double(i));
      if (b < kR)
        hi += 5.0 * std::cos(1.3 * f + double(i));
      if (int(i) == sim.hide_tree && !sim.hidden && a > kL + 100 && b < kR - 100 &&
          std::abs(0.5 * (a + b)) < 400) {
        sim.hidden = true;
        continue;
      }
      vis.push_back({lo, hi, a, b, int(i), false, false});
    }
    // Touching canopies as one segment, unless this frame is a split one.
    std::vector<Vis> segs;
    for (const Vis &v : vis) {
      if (sim.valley_from_mm >= 0 && !segs.empty() && v.a <= segs.back().b + 1.0) {
        const bool apart = segs.back().tree >= 0 && segs.back().hi - segs.back().lo >= sim.valley_from_mm &&
                           v.hi - v.lo >= sim.valley_from_mm;
        if (!apart) {
          segs.back().hi = std::max(segs.back().hi, v.hi);
          segs.back().b = v.b;
          segs.back().tree = -1;
          continue;
        }
        segs.back().joined_hi = true;
        Vis w = v;
        w.joined_lo = true;
        if (sim.segments_at_cut) {
          const double cut = sim.valley_at * segs.back().b + (1 - sim.valley_at) * v.a;
          segs.back().hi = std::min(segs.back().hi, cut);
          w.lo = std::max(w.lo, cut);
        }
        segs.push_back(w);
        continue;
      }
      if (sim.merge_touching && f > sim.split_frame && !segs.empty() &&
          v.a <= segs.back().b + 1.0) {
        segs.back().hi = std::max(segs.back().hi, v.hi);
        segs.back().b = v.b;
        segs.back().tree = -1; // several trees: measured as one canopy
        continue;
      }
      // Up to the split frame the points near the contact are missing: the second canopy
      // starts 70 mm on (and is not seen while less than 10 mm of it would be left).
      if (sim.merge_touching && f <= sim.split_frame && !segs.empty() &&
          v.a <= segs.back().b + 1.0) {
        Vis w = v;
        w.lo += 70.0;
        if (!sim.hide_second && w.lo < w.hi - 10.0)
          segs.push_back(w);
        continue;
      }
      segs.push_back(v);
    }
    for (std::size_t i = 0; i + 1 < segs.size(); ++i)
      if (sim.bridge_tree >= 0 && segs[i].tree == sim.bridge_tree &&
          segs[i + 1].tree == sim.bridge_tree + 1 && segs[i + 1].hi - segs[i + 1].lo < 300) {
        segs[i].hi = segs[i + 1].hi;
        segs[i].b = segs[i + 1].b;
        segs.erase(segs.begin() + std::ptrdiff_t(i) + 1);
      }
    int front = -1;
    for (std::size_t i = 0; i < segs.size(); ++i) {
      RowSegment r = front_segment(segs[i].lo, segs[i].hi, 100);
      r.joined_lo = segs[i].joined_lo;
      r.joined_hi = segs[i].joined_hi;
      tf.segments.push_back(r);
      const double c = 0.5 * (segs[i].lo + segs[i].hi);
      if (front < 0 ||
          std::abs(c) < std::abs(0.5 * (tf.segments[std::size_t(front)].lo_mm +
                                        tf.segments[std::size_t(front)].hi_mm)))
        front = int(i);
    }
    if (front >= 0 && segs[std::size_t(front)].tree >= 0) {
      const Vis &v = segs[std::size_t(front)];
      tf.measured_segment = front;
      tf.metrics = measure(trees[std::size_t(v.tree)], v.tree, f, v.a, v.b,
                           sim.top_clipped_tree);
      if (v.tree == sim.wide_edge_tree && std::abs(v.b) <= 0.5 * std::abs(step))
        tf.metrics.right_m += 0.05;
      // A side cut at a valley ends at the cut, in the crowns' overlap.
      const std::size_t i = std::size_t(front);
      const double at = sim.valley_at;
      if (v.joined_hi && i + 1 < segs.size())
        tf.metrics.right_m = (at * v.b + (1 - at) * segs[i + 1].a) / 1000.0;
      if (v.joined_lo && i > 0)
        tf.metrics.left_m = (at * segs[i - 1].b + (1 - at) * v.a) / 1000.0;
      if (sim.trunks)
        tf.segments[i].trunk_mm = 0.5 * (v.a + v.b) + 3.0 * std::sin(2.3 * f);
      tf.metrics.width_m = tf.metrics.right_m - tf.metrics.left_m;
      tf.segments[std::size_t(front)].selected = true;
    }
    out.push_back(s);
  }
  return out;
}

struct Emitted {
  TreeRecord record;
  int frame; // -1: from finish()
};

std::vector<Emitted> run(TreeTracker &tracker, const std::vector<SimFrame> &frames,
                         bool finish = true)
{
  std::vector<Emitted> out;
  for (std::size_t f = 0; f < frames.size(); ++f)
    for (TreeRecord &r : tracker.update(frames[f].frame))
      out.push_back({r, int(f)});
  if (finish)
    for (TreeRecord &r : tracker.finish())
      out.push_back({r, -1});
  return out;
}

// The first frame in which the tree's canopy is wholly behind the view's left edge.
int first_frame_behind(const std::vector<SimFrame> &frames, const TrueTree &t)
{
  for (std::size_t f = 0; f < frames.size(); ++f)
    if (t.end_mm - frames[f].true_position_mm <= kL)
      return int(f);
  return -1;
}

void expect_row(const std::vector<Emitted> &got, const std::vector<SimFrame> &frames)
{
  ASSERT_EQ(got.size(), kRow.size());
  for (std::size_t i = 0; i < kRow.size(); ++i) {
    SCOPED_TRACE("tree " + std::to_string(i));
    const TreeRecord &r = got[i].record;
    const TrueTree &t = kRow[i];
    EXPECT_EQ(r.id, int(i) + 1);
    EXPECT_TRUE(r.complete);
    EXPECT_FALSE(r.lost);
    EXPECT_NEAR(r.position_m, t.centre_m(), 0.05);
    EXPECT_NEAR(r.start_m, t.start_mm / 1000.0, 0.05);
    EXPECT_NEAR(r.end_m, t.end_mm / 1000.0, 0.05);
    // The unclipped frames' values exactly: a clipped frame's would move the median.
    ASSERT_TRUE(r.has_height && r.has_width && r.has_depth);
    EXPECT_DOUBLE_EQ(r.height_m, t.height_m);
    // Each edge from the frame nearest the axis, its hidden part at most 150 mm x (half a
    // frame's travel at 2 m/s) / 2 m = 11 mm; the two frames' travel errors (8 mm) between
    // them. The whole-view frames' median reads about 40 mm short (the test below).
    EXPECT_NEAR(r.width_m, t.width_m(), 0.03);
    EXPECT_DOUBLE_EQ(r.distance_m, t.distance_m);
    EXPECT_DOUBLE_EQ(r.thickness_m, 0.4);
    EXPECT_GE(r.confidence, 0.8);
    EXPECT_GE(r.frames, 1);
    EXPECT_GE(r.height_frames, r.frames);
    ASSERT_EQ(r.bands.size(), 3u);
    for (int k = 0; k < 3; ++k) {
      EXPECT_TRUE(r.bands[std::size_t(k)].present);
      EXPECT_DOUBLE_EQ(r.bands[std::size_t(k)].depth_m, t.distance_m);
      EXPECT_DOUBLE_EQ(r.bands[std::size_t(k)].fill, 0.5 + 0.1 * k);
      EXPECT_NEAR(r.bands[std::size_t(k)].left_m, t.start_mm / 1000.0, 0.02);
    }
    // Emitted as it leaves: the frame its canopy is behind the left edge, or the next.
    const int behind = first_frame_behind(frames, t);
    ASSERT_GE(behind, 0);
    EXPECT_GE(got[i].frame, behind);
    EXPECT_LE(got[i].frame, behind + 1);
    if (i == 0) {
      EXPECT_FALSE(r.has_spacing);
    } else {
      ASSERT_TRUE(r.has_spacing);
      EXPECT_NEAR(r.spacing_m, t.centre_m() - kRow[i - 1].centre_m(), 0.05);
      EXPECT_NEAR(r.gap_m, (t.start_mm - kRow[i - 1].end_mm) / 1000.0, 0.05);
    }
  }
}

// `f` as cameras turned by `deg` about the vertical (towards +x: the row's direction in their
// frame is (cos, 0, sin)) see it: every point (x, z) of the unturned frame at
// (x cos - z sin, x sin + z cos), every ray of slope t at slope (t cos - sin) / (t sin + cos).
// A segment's ends lie at the row's front (kNear), the metrics' edges at the extent depth
// (kNear), a band's edges at its depth, a trunk on the crown's axis (half its length behind its
// front).
TrackFrame yawed(const TrackFrame &f, double deg)
{
  const double c = std::cos(deg * CV_PI / 180), s = std::sin(deg * CV_PI / 180);
  const auto x_of = [&](double x, double z) { return x * c - z * s; };
  const auto z_of = [&](double x, double z) { return x * s + z * c; };
  const auto ray = [&](double t) { return (t * c - s) / (t * s + c); };
  TrackFrame y = f;
  y.row_direction = cv::Vec3d(c, 0, s);
  y.left_slope = ray(f.left_slope);
  y.right_slope = ray(f.right_slope);
  for (RowSegment &g : y.segments) {
    const RowSegment &o = g;
    const double mid = 0.5 * (o.lo_mm + o.hi_mm), axis_z = o.near_mm + 0.5 * (o.hi_mm - o.lo_mm);
    if (std::isfinite(o.trunk_mm))
      g.trunk_mm = x_of(o.trunk_mm, axis_z);
    g.near_mm = z_of(mid, o.near_mm);
    g.lo_z_mm = z_of(o.lo_mm, kNear);
    g.hi_z_mm = z_of(o.hi_mm, kNear);
    g.lo_mm = x_of(o.lo_mm, kNear);
    g.hi_mm = x_of(o.hi_mm, kNear);
  }
  TreeMetrics &m = y.metrics;
  if (m.tree_present) {
    m.extent_depth_m = kNear / 1000;
    m.left_m = x_of(f.metrics.left_m * 1000, kNear) / 1000;
    m.right_m = x_of(f.metrics.right_m * 1000, kNear) / 1000;
    m.left_slope = ray(f.metrics.left_slope);
    m.right_slope = ray(f.metrics.right_slope);
    for (Band &b : m.bands) {
      b.left_m = x_of(b.left_m * 1000, b.depth_m * 1000) / 1000;
      b.right_m = x_of(b.right_m * 1000, b.depth_m * 1000) / 1000;
    }
  }
  return y;
}

// `f` as cameras rolled by `deg` about their optical axis see it: every point (x, y, z) at
// (x cos - y sin, x sin + y cos, z), the row's direction at (cos, sin, 0). The crowns' edges and
// segment ends are at height `crown_y_mm` (camera Y, down), the trunks read at `trunk_y_mm`;
// `keep_y` false: every Y given as 0 (unknown), as a tracker that ignores heights sees it.
TrackFrame rolled(const TrackFrame &f, double deg, double crown_y_mm, double trunk_y_mm,
                  bool keep_y = true)
{
  const double c = std::cos(deg * CV_PI / 180), s = std::sin(deg * CV_PI / 180);
  const auto x_of = [&](double x, double y) { return x * c - y * s; };
  const auto y_of = [&](double x, double y) { return keep_y ? x * s + y * c : 0.0; };
  TrackFrame r = f;
  r.row_direction = cv::Vec3d(c, s, 0);
  for (RowSegment &g : r.segments) {
    const RowSegment o = g;
    g.lo_mm = x_of(o.lo_mm, crown_y_mm);
    g.lo_y_mm = y_of(o.lo_mm, crown_y_mm);
    g.hi_mm = x_of(o.hi_mm, crown_y_mm);
    g.hi_y_mm = y_of(o.hi_mm, crown_y_mm);
    if (std::isfinite(o.trunk_mm)) {
      g.trunk_mm = x_of(o.trunk_mm, trunk_y_mm);
      g.trunk_y_mm = y_of(o.trunk_mm, trunk_y_mm);
    }
  }
  TreeMetrics &m = r.metrics;
  if (m.tree_present) {
    const double l = f.metrics.left_m * 1000, rt = f.metrics.right_m * 1000, mid = 0.5 * (l + rt);
    m.left_m = x_of(l, crown_y_mm) / 1000;
    m.right_m = x_of(rt, crown_y_mm) / 1000;
    m.centroid_m = cv::Point3d(x_of(mid, crown_y_mm), y_of(mid, crown_y_mm), kNear) / 1000;
    for (Band &b : m.bands) {
      const double yb = 500 * (b.top_m + b.bottom_m);
      b.left_m = x_of(b.left_m * 1000, yb) / 1000;
      b.right_m = x_of(b.right_m * 1000, yb) / 1000;
    }
  }
  return r;
}

} // namespace

TEST(TreeTracker, FiveTreesAtHalfMetrePerSecond)
{
  Sim sim;
  sim.speed_m_s = 0.5;
  const auto frames = simulate(kRow, sim);
  TreeTracker tracker;
  expect_row(run(tracker, frames), frames);
}

TEST(TreeTracker, FiveTreesAtTwoMetresPerSecond)
{
  Sim sim;
  sim.speed_m_s = 2.0;
  const auto frames = simulate(kRow, sim);
  TreeTracker tracker;
  expect_row(run(tracker, frames), frames);
}

// Cameras yawed 5 degrees on the rig against the direction it drives in: each frame's X is
// turned. With the row's direction the records are where the trees are; with the camera's x
// axis instead every place along the row is off by about Z sin 5 degrees (174 mm at 2 m).
TEST(TreeTracker, CamerasYawedOnTheRigReadTheRowAlongItsDirection)
{
  Sim sim;
  sim.speed_m_s = 1.0;
  const auto frames = simulate(kRow, sim);
  std::vector<SimFrame> turned = frames, unread = frames;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    turned[f].frame = yawed(frames[f].frame, 5.0);
    unread[f].frame = turned[f].frame;
    unread[f].frame.row_direction = cv::Vec3d(1, 0, 0);
  }
  TreeTracker straight, along, across;
  const auto want = run(straight, frames);
  const auto got = run(along, turned);
  expect_row(got, turned);
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    SCOPED_TRACE("tree " + std::to_string(i));
    // The edges' depths differ by up to 30 mm across a crown once turned; one extent depth
    // places both: 30 mm x sin 5 degrees.
    EXPECT_NEAR(got[i].record.position_m, want[i].record.position_m, 0.003);
    EXPECT_NEAR(got[i].record.width_m, want[i].record.width_m, 0.006);
  }
  const auto off = run(across, unread);
  ASSERT_EQ(off.size(), kRow.size());
  for (std::size_t i = 0; i < off.size(); ++i)
    EXPECT_LT(off[i].record.position_m - kRow[i].centre_m(), -0.15) << "tree " << i;
}

TEST(TreeTracker, ClippedFramesWouldMoveTheMedian)
{
  // The check above can fail: the fourth tree's top-clipped frames, fused, read low.
  Sim sim;
  sim.speed_m_s = 0.5;
  const auto frames = simulate(kRow, sim);
  std::vector<double> all;
  for (const SimFrame &f : frames)
    if (f.frame.measured_segment >= 0 && f.frame.metrics.clipped.top)
      all.push_back(f.frame.metrics.height_m);
  ASSERT_FALSE(all.empty());
  for (double h : all)
    EXPECT_LT(h, kRow[3].height_m);
}

TEST(TreeTracker, EachEdgeFromTheFrameThatSawItNearestTheAxis)
{
  // The width check of expect_row() can fail: the frames that see a tree whole see its edges off
  // the axis, each short by its hidden part, and their widths' median reads far short.
  for (double speed : {0.5, 2.0}) {
    SCOPED_TRACE("speed " + std::to_string(speed));
    Sim sim;
    sim.speed_m_s = speed;
    const auto frames = simulate(kRow, sim);
    for (std::size_t i = 0; i < kRow.size(); ++i) {
      std::vector<double> whole;
      for (const SimFrame &f : frames) {
        const TreeMetrics &m = f.frame.metrics;
        const double a = kRow[i].start_mm - f.true_position_mm;
        if (f.frame.measured_segment >= 0 && !m.clipped.any() &&
            std::abs(m.left_m * 1000 - a) < 50)
          whole.push_back(m.width_m);
      }
      ASSERT_FALSE(whole.empty()) << i;
      EXPECT_LT(median(whole), kRow[i].width_m() - 0.03) << i; // beyond expect_row()'s 0.03
    }
  }
}

TEST(TreeTracker, AnEdgeFartherOutThanTheCrownCanHideIsNotTaken)
{
  // The frame nearest the axis reads the second tree's end 50 mm out, more than the crown (0.8 m
  // long, so about as deep) can hide between that frame's ray and the next one's: the next one
  // is taken. (At 2 m/s the next frame's ray is 8 degrees away, behind which such a crown could
  // hide 0.11 m: there 50 mm out is no proof, and the edge is taken as read.)
  for (double speed : {0.5, 1.0}) {
    SCOPED_TRACE("speed " + std::to_string(speed));
    Sim sim;
    sim.speed_m_s = speed;
    sim.wide_edge_tree = 1;
    const auto frames = simulate(kRow, sim);
    int wide = 0;
    for (const SimFrame &f : frames) {
      if (f.frame.measured_segment < 0)
        continue;
      const double hi = f.frame.segments[std::size_t(f.frame.measured_segment)].hi_mm;
      wide += std::abs(hi + f.true_position_mm - kRow[1].end_mm) < 50 &&
              f.frame.metrics.right_m * 1000 + f.frame.position_mm > kRow[1].end_mm + 30;
    }
    ASSERT_EQ(wide, 1);
    TreeTracker tracker;
    const auto got = run(tracker, frames);
    ASSERT_EQ(got.size(), kRow.size());
    EXPECT_NEAR(got[1].record.width_m, kRow[1].width_m(), 0.03);
  }
}

TEST(TreeTracker, DrivingBackwardsEmitsInReverse)
{
  Sim sim;
  sim.speed_m_s = 1.0;
  sim.from_mm = 7600;
  sim.to_mm = -1500;
  const auto frames = simulate(kRow, sim);
  TreeTracker tracker;
  const auto got = run(tracker, frames);
  ASSERT_EQ(got.size(), kRow.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    const TrueTree &t = kRow[kRow.size() - 1 - i];
    EXPECT_EQ(got[i].record.id, int(i) + 1);
    EXPECT_NEAR(got[i].record.position_m, t.centre_m(), 0.05);
    EXPECT_GE(got[i].frame, 0) << "left the view before the end";
    if (i > 0) {
      EXPECT_NEAR(got[i].record.gap_m,
                  (kRow[kRow.size() - i].start_mm - t.end_mm) / 1000.0, 0.05);
    }
  }
}

TEST(TreeTracker, HiddenForOneFrameKeepsItsId)
{
  Sim sim;
  sim.speed_m_s = 1.0;
  sim.hide_tree = 2;
  const auto frames = simulate(kRow, sim);
  const auto full = simulate(kRow, Sim{1.0});
  TreeTracker tracker;
  const auto got = run(tracker, frames);
  ASSERT_EQ(got.size(), kRow.size());
  EXPECT_EQ(got[2].record.id, 3);
  EXPECT_FALSE(got[2].record.lost);
  EXPECT_NEAR(got[2].record.position_m, kRow[2].centre_m(), 0.05);
  EXPECT_EQ(got[4].record.id, 5);
  // Seen in one frame fewer than without the gap.
  TreeTracker reference;
  const auto ref = run(reference, full);
  ASSERT_EQ(ref.size(), kRow.size());
  EXPECT_EQ(got[2].record.frames_seen, ref[2].record.frames_seen - 1);

  // Without a grace the tree is lost and found again as a new one.
  TrackerParams p;
  p.grace_frames = 0;
  TreeTracker strict(p);
  const auto split = run(strict, frames);
  ASSERT_EQ(split.size(), kRow.size() + 1);
  int lost = 0;
  for (const Emitted &e : split)
    lost += e.record.lost ? 1 : 0;
  EXPECT_EQ(lost, 1);
}

TEST(TreeTracker, FinishFlushesTheTreesInView)
{
  Sim sim;
  sim.speed_m_s = 0.5;
  sim.to_mm = 3000; // stops with the third tree in view and the second leaving
  const auto frames = simulate(kRow, sim);
  TreeTracker tracker;
  const auto got = run(tracker, frames, false);
  ASSERT_EQ(got.size(), 1u);   // only the first tree has left
  EXPECT_EQ(tracker.open_tracks(), 2u);
  const auto rest = tracker.finish();
  ASSERT_EQ(rest.size(), 2u);
  EXPECT_EQ(rest[0].id, 2);
  EXPECT_EQ(rest[1].id, 3);
  // The view at 3 m runs from 1.82 to 4.18 m: the second tree (1.85-2.65) is still whole, the
  // third (3.45-4.05) too, but it has been whole for two frames only, in which the second was
  // nearer the centre and measured: both its ends are known, its measurements are not.
  EXPECT_NEAR(rest[0].position_m, kRow[1].centre_m(), 0.05);
  EXPECT_TRUE(rest[0].complete);
  EXPECT_DOUBLE_EQ(rest[0].height_m, kRow[1].height_m);
  EXPECT_TRUE(rest[1].start_seen && rest[1].end_seen);
  EXPECT_NEAR(rest[1].position_m, kRow[2].centre_m(), 0.05);
  EXPECT_FALSE(rest[1].has_depth);
  EXPECT_FALSE(rest[1].has_height);
  EXPECT_FALSE(rest[1].complete);
  EXPECT_EQ(tracker.open_tracks(), 0u);
  EXPECT_TRUE(tracker.finish().empty());
}

TEST(TreeTracker, NeverFullyInViewIsFlaggedNotMeasured)
{
  // A tree already cut by the trailing edge at the start, and one still cut by the leading edge
  // at the end.
  const std::vector<TrueTree> row = {{-1700, -900, 1.0, 2.0}, {1000, 1700, 0.9, 2.0},
                                     {2800, 3600, 0.9, 2.0}};
  Sim sim;
  sim.speed_m_s = 1.0;
  sim.to_mm = 2000; // ends with the view at 0.82-3.18 m: the third tree cut at 3.18
  const auto frames = simulate(row, sim);
  TreeTracker tracker;
  const auto got = run(tracker, frames);
  ASSERT_EQ(got.size(), 3u);
  const TreeRecord &a = got[0].record, &b = got[1].record, &c = got[2].record;
  EXPECT_FALSE(a.complete);
  EXPECT_FALSE(a.start_seen);
  EXPECT_TRUE(a.end_seen);
  EXPECT_FALSE(a.has_width);
  EXPECT_FALSE(a.has_depth);
  EXPECT_NEAR(a.end_m, -0.9, 0.05);
  EXPECT_TRUE(b.complete);
  EXPECT_NEAR(b.width_m, 0.7, 0.03); // as expect_row()'s
  EXPECT_FALSE(c.complete);
  EXPECT_FALSE(c.end_seen);
  EXPECT_FALSE(c.has_width);
  EXPECT_LT(c.end_m, 3.6 - 0.3); // the farthest seen, not the tree's end
  const std::string js = to_json(a);
  EXPECT_EQ(js.find("width_m"), std::string::npos);
  EXPECT_EQ(js.find("distance_m"), std::string::npos);
  EXPECT_NE(js.find("\"complete\":false"), std::string::npos);
}

TEST(TreeTracker, RowModeTouchingCanopiesAreOneSegment)
{
  // Two touching canopies (1.0-1.8 and 1.8-2.6 m), then a gap of 0.5 m and a third.
  const std::vector<TrueTree> row = {{1000, 1800, 1.0, 2.0}, {1800, 2600, 1.0, 2.0},
                                     {3100, 3700, 1.0, 2.0}};
  for (double speed : {0.5, 2.0}) {
    for (bool hide : {false, true}) {
      SCOPED_TRACE("speed " + std::to_string(speed) + (hide ? ", second hidden" : ", apart"));
      Sim sim;
      sim.speed_m_s = speed;
      sim.hide_second = hide;
      sim.to_mm = 6000;
      sim.merge_touching = true;
      sim.top_clipped_tree = -1;
      // The second canopy is seen apart from the first for its first frames in view (sparse
      // points at the contact), or not at all while the first one's end is seen; then joined.
      const double step = speed * 1000.0 / 7.0;
      sim.split_frame = int(std::ceil((1800 + 100 - kR) / step)) + 1;
      const auto frames = simulate(row, sim);
      ASSERT_EQ(frames[std::size_t(sim.split_frame)].frame.segments.size(), hide ? 1u : 2u);
      TrackerParams p;
      p.mode = CanopyMode::Row;
      TreeTracker tracker(p);
      const auto got = run(tracker, frames);
      ASSERT_EQ(got.size(), 2u);
      EXPECT_EQ(got[0].record.id, 1);
      // Seen apart, the second canopy had a track of its own (id 2) until it joined the first.
      EXPECT_EQ(got[1].record.id, hide ? 2 : 3);
      EXPECT_NEAR(got[0].record.start_m, 1.0, 0.05);
      EXPECT_NEAR(got[0].record.end_m, 2.6, 0.05);
      EXPECT_NEAR(got[0].record.width_m, 1.6, 0.05);
      EXPECT_NEAR(got[1].record.start_m, 3.1, 0.05);
      EXPECT_NEAR(got[1].record.end_m, 3.7, 0.05);
      EXPECT_NEAR(got[1].record.gap_m, 0.5, 0.05);
      EXPECT_TRUE(got[0].record.complete);
      EXPECT_EQ(got[0].record.mode, CanopyMode::Row);
    }
  }
}

// Mode Tree: two crowns grown into each other are one segment while one of them shows less than
// 300 mm in view, then two segments cut at their valley. Each is a tree of its own, measured
// from the frames it is seen apart.
TEST(TreeTracker, TouchingCrownsCutAtTheirValleyAreTwoTrees)
{
  const std::vector<TrueTree> row = {{1000, 1750, 0.9, 2.0}, {1700, 2400, 1.0, 2.0},
                                     {2900, 3500, 0.95, 2.0}};
  for (double speed : {0.5, 1.0, 2.0}) {
    SCOPED_TRACE("speed " + std::to_string(speed));
    Sim sim;
    sim.speed_m_s = speed;
    sim.to_mm = 6000;
    sim.top_clipped_tree = -1;
    sim.valley_from_mm = 300;
    const auto frames = simulate(row, sim);
    TreeTracker tracker;
    const auto got = run(tracker, frames);
    ASSERT_EQ(got.size(), 3u);
    for (std::size_t i = 0; i < 3; ++i) {
      SCOPED_TRACE("tree " + std::to_string(i));
      const TreeRecord &r = got[i].record;
      EXPECT_EQ(r.id, int(i) + 1);
      EXPECT_TRUE(r.complete) << to_json(r);
      EXPECT_NEAR(r.position_m, row[i].centre_m(), 0.05);
      ASSERT_TRUE(r.has_height && r.has_width);
      EXPECT_DOUBLE_EQ(r.height_m, row[i].height_m);
      EXPECT_NEAR(r.width_m, row[i].width_m(), 0.03); // as expect_row()'s
    }
    EXPECT_NEAR(got[1].record.gap_m, -0.05, 0.03); // the crowns overlap by 50 mm
  }
}

// Runs `row` (three trees) at 0.5 and 2 m/s, with and without their trunks seen below the
// crowns, with `sim`'s other settings, and hands each run's three records, each with a width,
// and whether the trunks were seen to `check`.
template <typename Check> void with_and_without_trunks(const std::vector<TrueTree> &row, Sim sim,
                                                       Check check)
{
  for (bool trunks : {false, true})
    for (double speed : {0.5, 2.0}) {
      SCOPED_TRACE(std::string(trunks ? "trunks seen" : "no trunk") + ", speed " +
                   std::to_string(speed));
      sim.speed_m_s = speed;
      sim.top_clipped_tree = -1;
      sim.trunks = trunks;
      TreeTracker tracker;
      const auto got = run(tracker, simulate(row, sim));
      ASSERT_EQ(got.size(), 3u);
      for (std::size_t i = 0; i < 3; ++i)
        ASSERT_TRUE(got[i].record.has_width) << i;
      check(got, trunks);
    }
}

// Two crowns grown into each other, then a free one. The outline of touching crowns dips where
// the nearer one's limb is: the cut lies at the second crown's start, 100 mm inside the first.
const std::vector<TrueTree> kTouching = {{1000, 1750, 0.9, 2.0}, {1650, 2400, 1.0, 2.0},
                                         {2900, 3500, 0.95, 2.0}};
Sim touching_sim()
{
  Sim sim;
  sim.to_mm = 6000;
  sim.valley_from_mm = 300;
  sim.valley_at = 0;
  sim.segments_at_cut = true;
  return sim;
}

// A trunk seen below the first of kTouching gives its hidden side: the free side mirrored about
// it, for its width and for its end and place along the row.
TEST(TreeTracker, ACrownCutAtAValleyReachesAsFarFromItsTrunkAsItsFreeSide)
{
  const std::vector<TrueTree> &row = kTouching;
  with_and_without_trunks(row, touching_sim(), [&](const std::vector<Emitted> &got, bool trunks) {
    // Its end and place likewise: at the cut, 50 mm short of its centre without the trunk.
    const TreeRecord &a = got[0].record;
    if (trunks) {
      EXPECT_NEAR(a.end_m, row[0].end_mm / 1000.0, 0.03);
      EXPECT_NEAR(a.position_m, row[0].centre_m(), 0.015);
    } else {
      EXPECT_NEAR(a.end_m, row[1].start_mm / 1000.0, 0.015);
      EXPECT_LT(a.position_m, row[0].centre_m() - 0.035);
    }
    const double first = got[0].record.width_m - row[0].width_m();
    // The mirror doubles the free edge's error and the trunk's: as expect_row()'s.
    if (trunks)
      EXPECT_NEAR(first, 0, 0.03);
    else
      EXPECT_LT(first, -0.07); // the cut, 100 mm inside
    // The second's cut side is its own start: the mirror never moves an edge inward.
    EXPECT_NEAR(got[1].record.width_m, row[1].width_m(), 0.03);
    EXPECT_NEAR(got[2].record.width_m, row[2].width_m(), 0.03);
  });
}

// The run starts with the first crown in front and ends with the last one in front: the rig never
// drives past the first one's low-x side nor the last one's high-x side. Both are seen from inside
// the crown only, off the axis, and read short by the back clusters they hide (hidden_mm(): 26 mm
// where a frame first sees the side, 350 mm off the axis, and more after). With the trunk seen,
// such a side reaches as far from it as the side the rig drove past, as a side cut at a valley.
TEST(TreeTracker, ASideTheRigNeverPassedReachesAsFarFromItsTrunkAsTheOther)
{
  const std::vector<TrueTree> row = {{-350, 350, 0.9, 2.0}, {900, 1600, 1.0, 2.0},
                                     {2300, 3000, 0.95, 2.0}};
  Sim sim;
  sim.from_mm = 0;
  sim.to_mm = 2650;
  with_and_without_trunks(row, sim, [&](const std::vector<Emitted> &got, bool trunks) {
    const double first = got[0].record.width_m - row[0].width_m();
    const double last = got[2].record.width_m - row[2].width_m();
    // The mirror adds the seen side's error and twice the trunk's (travel noise of 8 mm, the
    // trunk's 3 mm): within 15 mm here, 20-36 mm short without it.
    if (trunks) {
      EXPECT_NEAR(first, 0, 0.015);
      EXPECT_NEAR(last, 0, 0.015);
      EXPECT_NEAR(got[0].record.start_m, row[0].start_mm / 1000.0, 0.015);
      EXPECT_NEAR(got[2].record.end_m, row[2].end_mm / 1000.0, 0.015);
    } else {
      EXPECT_LT(first, -0.018);
      EXPECT_LT(last, -0.018);
    }
    // The middle crown was passed on both sides: its own edges.
    EXPECT_NEAR(got[1].record.width_m, row[1].width_m(), 0.03);
  });
}

// Cameras rolled 1.5 degrees on the rig against the row (a rectification that levels the
// baseline rotates the view too): a vertical trunk leans in the view. Read 600 mm below the crown's
// edges, its X is 16 mm off the X of the crown's middle above it; only its place along the row,
// its height included, is the crown's. The mirrored side doubles what is off.
TEST(TreeTracker, ARolledViewPlacesATrunkAlongTheRowByItsHeight)
{
  Sim sim = touching_sim();
  sim.speed_m_s = 1.0;
  sim.trunks = true;
  const auto frames = simulate(kTouching, sim);
  std::vector<SimFrame> turned = frames, unknown = frames;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    turned[f].frame = rolled(frames[f].frame, 1.5, -100, 500);
    unknown[f].frame = rolled(frames[f].frame, 1.5, -100, 500, false);
  }
  TreeTracker level, along, flat;
  const auto want = run(level, frames);
  const auto got = run(along, turned);
  const auto off = run(flat, unknown);
  ASSERT_EQ(want.size(), 3u);
  ASSERT_EQ(got.size(), 3u);
  ASSERT_EQ(off.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    SCOPED_TRACE("tree " + std::to_string(i));
    ASSERT_TRUE(got[i].record.has_width);
    EXPECT_NEAR(got[i].record.width_m, want[i].record.width_m, 0.002);
    EXPECT_NEAR(got[i].record.position_m, want[i].record.position_m, 0.002);
  }
  // Without the heights the first crown's mirrored end moves by twice the trunk's 16 mm less
  // the crown edges' 3 mm.
  EXPECT_LT(off[0].record.width_m - want[0].record.width_m, -0.02);
}

// Stray points bridge the 800 mm gap between trees 1 and 2 while tree 2 enters the view: tree 1
// keeps its own extent (its end seen off the edge before), tree 2 gets its own record.
TEST(TreeTracker, AFrameBridgingAGapDoesNotJoinTwoTrees)
{
  for (double speed : {0.5, 1.0, 2.0}) {
    SCOPED_TRACE("speed " + std::to_string(speed));
    Sim sim;
    sim.speed_m_s = speed;
    sim.bridge_tree = 1;
    const auto frames = simulate(kRow, sim);
    int bridged = 0;
    for (const SimFrame &f : frames)
      for (const RowSegment &s : f.frame.segments)
        bridged += s.lo_mm + f.frame.position_mm < 2650 && s.hi_mm + f.frame.position_mm > 3450;
    ASSERT_GT(bridged, 0) << "no frame bridges the gap";
    TreeTracker tracker;
    expect_row(run(tracker, frames), frames);
  }
}

TEST(TreeTracker, AnEndSeenOnceOffTheEdgeHoldsAgainstABridgingFrame)
{
  // Tree A (world -0.4..0.3 m) is seen whole once; the next frame's segment reaches across the
  // gap to tree B (1.15..1.85 m), which enters the view at its right edge; then A and B are two
  // segments, B cut by the edge. B is a tree of its own from the frame it is seen apart: A's
  // end seen once off the edge is where A ends, not the bridging frame's.
  TreeTracker tracker;
  std::vector<TreeRecord> got;
  for (int f = 0; f < 12; ++f) {
    const double pos = 100.0 * f;
    TrackFrame tf = view_frame(pos);
    auto add = [&](double lo, double hi) {
      // The view's right edge cuts it.
      const RowSegment s = front_segment(lo - pos, std::min(hi - pos, kR - 9), 300);
      if (s.hi_mm - s.lo_mm > 50)
        tf.segments.push_back(s);
    };
    if (f == 1) {
      add(-400, 1850); // stray points across the gap
    } else {
      add(-400, 300);
      add(1150, 1850);
    }
    for (TreeRecord &r : tracker.update(tf))
      got.push_back(r);
    if (f >= 2) {
      SCOPED_TRACE("frame " + std::to_string(f));
      const auto open = tracker.open();
      ASSERT_EQ(open.size(), 2u);
      EXPECT_NEAR(open[1].start_m, 1.15, 1e-9);
    }
  }
  for (TreeRecord &r : tracker.finish())
    got.push_back(r);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_NEAR(got[0].start_m, -0.4, 1e-9);
  EXPECT_NEAR(got[0].end_m, 0.3, 1e-9);
  EXPECT_NEAR(got[1].start_m, 1.15, 1e-9);
  EXPECT_NEAR(got[1].end_m, 1.85, 1e-9);
  EXPECT_EQ(got[1].frames_seen, 10);
}

TEST(TreeTracker, AnEnteringCrownSplitForOneFrameIsOneTree)
{
  // The fourth tree enters at the right edge; in one frame a sparse column splits what is in
  // view of it in two: a piece at the edge 80 mm beyond the rest. The next frames see it whole.
  for (double speed : {0.5, 1.0, 2.0}) {
    SCOPED_TRACE("speed " + std::to_string(speed));
    Sim sim;
    sim.speed_m_s = speed;
    auto frames = simulate(kRow, sim);
    const TrueTree &t = kRow[3];
    std::size_t split = frames.size();
    for (std::size_t f = 0; f < frames.size() && split == frames.size(); ++f) {
      const double a = t.start_mm - frames[f].true_position_mm;
      if (a < kR - 200 && t.end_mm - frames[f].true_position_mm > kR)
        split = f;
    }
    ASSERT_LT(split, frames.size()) << "no frame with the tree entering";
    auto &segs = frames[split].frame.segments;
    ASSERT_FALSE(segs.empty());
    RowSegment &entering = segs.back(); // the rightmost: the tree at the edge
    RowSegment rest = entering, edge_piece = entering;
    rest.hi_mm = entering.hi_mm - 100;
    edge_piece.lo_mm = entering.hi_mm - 20;
    entering = rest;
    segs.push_back(edge_piece);
    TreeTracker tracker;
    expect_row(run(tracker, frames), frames);
  }
}

TEST(TreeTracker, RemnantAtTheTrailingEdgeIsNoNewTree)
{
  // A limb at the back of the first tree (0.6 m behind the row's front) shows at the left edge
  // the frame after the tree was emitted: the edge ray reaches further back there.
  Sim sim;
  sim.speed_m_s = 1.0;
  auto frames = simulate(kRow, sim);
  TreeTracker probe;
  const auto ref = run(probe, frames);
  ASSERT_EQ(ref.size(), kRow.size());
  const std::size_t f = std::size_t(ref[0].frame) + 1;
  ASSERT_LT(f, frames.size());
  RowSegment limb;
  limb.near_mm = kNear + 600;
  limb.lo_mm = kLeftSlope * limb.near_mm;
  limb.hi_mm = limb.lo_mm + 30;
  ASSERT_LT(limb.lo_mm + frames[f].true_position_mm, kRow[0].end_mm); // over the first tree
  auto &segs = frames[f].frame.segments;
  segs.insert(segs.begin(), limb);
  if (frames[f].frame.measured_segment >= 0)
    ++frames[f].frame.measured_segment;
  TreeTracker tracker;
  const auto got = run(tracker, frames);
  ASSERT_EQ(got.size(), kRow.size());
  for (std::size_t i = 0; i < got.size(); ++i)
    EXPECT_EQ(got[i].record.id, int(i) + 1);
}

TEST(TreeTracker, AStandingRigIsMeasuredByItsLatestFrames)
{
  // The rig stands in front of one tree for 200 frames: the tree reads 1.0 m high for 136 frames,
  // then 0.8 m. A track keeps its latest 64 samples, so the record says 0.8 m (all 200 would
  // give 1.0 m) and a long stop does not grow the tracker without bound.
  TreeTracker tracker;
  for (int f = 0; f < 200; ++f) {
    TrackFrame tf = view_frame(0);
    RowSegment seg = front_segment(-350, 350);
    seg.selected = true;
    tf.segments = {seg};
    tf.metrics = whole_crown(-350, 350, false);
    tf.metrics.height_m = f < 136 ? 1.0 : 0.8;
    tf.metrics.distance_m = 2.0;
    tf.measured_segment = 0;
    EXPECT_TRUE(tracker.update(tf).empty()) << f;
  }
  const auto rec = tracker.finish();
  ASSERT_EQ(rec.size(), 1u);
  ASSERT_TRUE(rec[0].has_height);
  EXPECT_NEAR(rec[0].height_m, 0.8, 1e-9);
  EXPECT_NEAR(rec[0].width_m, 0.7, 1e-9);
  EXPECT_EQ(rec[0].frames_seen, 200);
}

// The record of one tree the rig stands in front of for 5 frames, its left end `lo_mm` at depth
// `lo_z_mm` (0: unknown), the stereo view's left edge `left_offset_mm` inside the image's, its
// points at least `lo_clear_mm` inside that edge (NaN: unknown).
TreeRecord stand_before(double lo_mm, double lo_z_mm, double left_offset_mm,
                        double lo_clear_mm = std::numeric_limits<double>::quiet_NaN())
{
  TreeTracker tracker;
  for (int f = 0; f < 5; ++f) {
    TrackFrame tf = view_frame(0);
    tf.left_offset_mm = left_offset_mm;
    RowSegment seg = front_segment(lo_mm, lo_mm + 700);
    seg.lo_z_mm = lo_z_mm;
    seg.hi_z_mm = kNear;
    seg.lo_clear_mm = lo_clear_mm;
    seg.selected = true;
    tf.segments = {seg};
    tf.metrics = whole_crown(lo_mm, lo_mm + 700, false);
    tf.metrics.height_m = 0.9;
    tf.metrics.distance_m = 2.0;
    tf.measured_segment = 0;
    EXPECT_TRUE(tracker.update(tf).empty()) << f;
  }
  const auto rec = tracker.finish();
  EXPECT_EQ(rec.size(), 1u);
  return rec.empty() ? TreeRecord() : rec[0];
}

TEST(TreeTracker, AnEndIsOnTheViewEdgeAtItsOwnDepth)
{
  // A limb 0.4 m behind the front ends 20 mm inside the edge ray at the front's depth, 256 mm
  // inside it at its own: the tree is whole in view, and measured.
  const double lo = kLeftSlope * kNear + 20;
  const TreeRecord deep = stand_before(lo, kNear + 400, 0);
  EXPECT_TRUE(deep.start_seen);
  EXPECT_TRUE(deep.complete);
  ASSERT_TRUE(deep.has_width);
  EXPECT_NEAR(deep.width_m, 0.7, 1e-9);
  EXPECT_EQ(deep.width_frames, 5);
  // Its depth unknown, the front's decides: on the edge, a lower bound, no width.
  const TreeRecord unknown = stand_before(lo, 0, 0);
  EXPECT_FALSE(unknown.start_seen);
  EXPECT_FALSE(unknown.has_width);
  EXPECT_FALSE(unknown.complete);
  // An end 100 mm inside the left image's edge, at the front: in view of the left camera, but
  // within the strip the right camera does not see (a baseline of 120 mm): the stereo points
  // stop at that strip's edge, whatever the canopy does beyond it.
  const double in_strip = kLeftSlope * kNear + 100;
  EXPECT_TRUE(stand_before(in_strip, kNear, 0).has_width);
  const TreeRecord strip = stand_before(in_strip, kNear, 120);
  EXPECT_FALSE(strip.start_seen);
  EXPECT_FALSE(strip.has_width);
}

TEST(TreeTracker, AnEndIsOnTheViewEdgeWhenAnyOfItsPointsIs)
{
  // The deep limb of the test above, its end 256 mm inside the edge at its own depth; but the
  // points in front of it come within 20 mm of the edge (the crown goes on beyond the view,
  // and only the limb behind seemed clear of it): a lower bound, no width.
  const double lo = kLeftSlope * kNear + 20;
  const TreeRecord touching = stand_before(lo, kNear + 400, 0, 20);
  EXPECT_FALSE(touching.start_seen);
  EXPECT_FALSE(touching.has_width);
  EXPECT_FALSE(touching.complete);
  // Every point 120 mm or more inside the edge: whole in view.
  const TreeRecord clear = stand_before(lo, kNear + 400, 0, 120);
  EXPECT_TRUE(clear.start_seen);
  ASSERT_TRUE(clear.has_width);
  EXPECT_NEAR(clear.width_m, 0.7, 1e-9);
  // The clearance decides, not the end's own point: the end 20 mm inside the edge at the
  // front's depth, but every point (the end's among them, at its depth) 120 mm inside it.
  EXPECT_TRUE(stand_before(lo, 0, 0, 120).start_seen);
}

TEST(TreeTracker, ViewEdgesOfTheStereoPair)
{
  StereoGeometry g = simple_geometry(cv::Size(1296, 972), 1100, 120);
  double l = 0, r = 0, off = 0;
  view_slopes(g, l, r, off);
  // The right camera's left edge ray, a baseline to the side; the left camera's right edge.
  EXPECT_NEAR(l, (-0.5 - 648) / 1100, 1e-12);
  EXPECT_NEAR(off, 120, 1e-12);
  EXPECT_NEAR(r, (1296 - 0.5 - 648) / 1100, 1e-12);
  // A point on the right view's left border at 2 m: u_r = -0.5, d = fx B / Z.
  const double Z = 2000, d = g.fx * g.baseline_mm / Z, u = -0.5 + d;
  EXPECT_NEAR(l * Z + off, (u - g.cx[0]) / g.fx * Z, 1e-9);
  // Principal points far apart (the right one 300 px further right): the left image's own edge
  // is the inner one.
  g.cx[1] = 948;
  view_slopes(g, l, r, off);
  EXPECT_NEAR(l, (-0.5 - 648) / 1100, 1e-12);
  EXPECT_EQ(off, 0);
  g.baseline_mm = 0;
  EXPECT_THROW(view_slopes(g, l, r, off), BadInput);
}

TEST(TreeTracker, JsonLineHasTheDesignNames)
{
  Sim sim;
  const auto frames = simulate(kRow, sim);
  TreeTracker tracker;
  const auto got = run(tracker, frames);
  ASSERT_GE(got.size(), 2u);
  const std::string js = to_json(got[1].record);
  EXPECT_EQ(js.find('\n'), std::string::npos);
  EXPECT_EQ(js.rfind("{\"id\":2,", 0), 0u) << js;
  for (const char *k : {"\"position_m\":", "\"start_m\":", "\"end_m\":", "\"distance_m\":",
                        "\"height_m\":", "\"width_m\":", "\"thickness_m\":", "\"bands\":[{",
                        "\"frames\":", "\"confidence\":", "\"spacing_m\":", "\"gap_m\":",
                        "\"fill\":"})
    EXPECT_NE(js.find(k), std::string::npos) << k << " in " << js;
  EXPECT_NE(js.find("\"height_m\":1,"), std::string::npos) << js;
  EXPECT_EQ(js.find("null"), std::string::npos);
}

TEST(TreeTracker, RejectsBadInput)
{
  TrackerParams p;
  p.grace_frames = -1;
  EXPECT_THROW({ TreeTracker t(p); }, BadSettings);
  p = TrackerParams();
  p.forward = 0;
  try {
    TreeTracker t(p);
    FAIL() << "no error";
  } catch (const BadSettings &e) {
    EXPECT_NE(std::string(e.what()).find("forward"), std::string::npos);
  }
  TreeTracker t;
  TrackFrame f;
  f.left_slope = 0.5;
  f.right_slope = -0.5;
  EXPECT_THROW(t.update(f), BadInput);
  f.left_slope = kLeftSlope;
  f.right_slope = kRightSlope;
  f.measured_segment = 0; // no segments
  EXPECT_THROW(t.update(f), BadInput);
  f.measured_segment = -1;
  for (const cv::Vec3d &d : {cv::Vec3d(0, 0, 1), cv::Vec3d(2, 0, 0), cv::Vec3d(-1, 0, 0),
                             cv::Vec3d(std::nan(""), 0, 0)}) {
    f.row_direction = d;
    EXPECT_THROW(t.update(f), BadInput);
  }
}

TEST(TreeTracker, ErrorsAreTypedAndNameTheProblem)
{
  TrackerParams p;
  p.forward = 0;
  expect_typed_error<BadSettings>([&] { TreeTracker t(p); }, "forward");
  TreeTracker t;
  TrackFrame f;
  f.position_mm = std::nan("");
  expect_typed_error<BadInput>([&] { t.update(f); }, "rig's position");
  f = view_frame(0);
  RowSegment seg = front_segment(-300, 300);
  seg.hi_clear_mm = std::numeric_limits<double>::infinity();
  f.segments = {seg};
  expect_typed_error<BadInput>([&] { t.update(f); }, "hi_clear_mm");
  seg = front_segment(-300, 300);
  seg.trunk_mm = -std::numeric_limits<double>::infinity();
  f.segments = {seg};
  expect_typed_error<BadInput>([&] { t.update(f); }, "trunk_mm");
  seg = front_segment(-300, 300);
  seg.trunk_y_mm = std::nan("");
  f.segments = {seg};
  expect_typed_error<BadInput>([&] { t.update(f); }, "trunk_y_mm");
  double l = 0, r = 0, off = 0;
  expect_typed_error<BadInput>([&] { view_slopes(StereoGeometry(), l, r, off); },
                               "stereo geometry");
}
