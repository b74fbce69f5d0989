// Following the near row's trees along the row: one record per tree (DESIGN.md "In an orchard":
// the tree record), built from the per-frame segments of select_canopy() and the tree in
// front's TreeMetrics.
//
// World coordinate along the row: the rig's position since the start (travel) plus a point's
// place along the row in the rectified-left frame, its projection on the row's direction
// (TrackFrame::row_direction; travel.hpp's RowDirection), as the renderer's row_trees() has it
// (mm internally, m in the record). The rig may drive either way; the direction of travel is
// taken from the change of position (TrackerParams::forward until it moves).
//
// Per frame (TrackFrame): the position, the slopes x/z of the image's left and right edge rays
// (view_slopes() from the rectified geometry), the near row's segments and, when a tree was
// measured, its TreeMetrics and the index of the segment they describe.
//
//  - A segment end is cut by the view's edge when any of its points comes within
//    edge_margin_mm of that edge's ray at the point's own depth (RowSegment::lo_clear_mm /
//    hi_clear_mm). Where that is not known, the end's own point is tested at its depth
//    (lo_z_mm / hi_z_mm; the front depth near_mm where that is not known either). The left edge
//    is that of the stereo view: the points need both cameras, and the right camera's left edge
//    ray lies a baseline inside the left one's (TrackFrame::left_offset_mm). Each point at its
//    own depth: a limb behind the front reaches further out on an edge ray than the front does,
//    so the front depth would call a crown whose deep limb ends just inside the view cut, and
//    lose that frame's measurement; the extreme point's depth alone would call a crown clear of
//    the edge whose front points stop at the edge while one point behind them lies a few cm
//    further out.
//  - Association: each segment's world extent against each track's world extent, widened by
//    match_tolerance_mm (travel error, sparse points at the limbs); pairs taken one to one,
//    largest overlap first. A track's extent is the last frame's, except (mode Tree) an end seen
//    off the image edge in a frame or more, which is the median of those: a frame whose segment
//    reached across a gap (stray points bridging it to the next tree, entering the view, its end
//    cut there) does not lend a tree its neighbour's canopy, and the next tree is not taken for
//    more of it. A segment no track takes starts a new track (ids count up from 1) unless it
//    overlaps a track already taken this frame: mode Tree counts it as a split of that tree (a
//    sparse frame), mode Row as more of the same canopy; but a segment cut from the taken one at
//    a valley (RowSegment::joined_lo / joined_hi: crowns grown into each other) is a tree of its
//    own. One segment over two tracks: mode Tree keeps both tracks alive without updating them
//    (two trees seen as one: neither's extent nor the measurement is trusted; a segment cut at a
//    valley counts a neighbour's track only when it covers half of it); mode Row merges them
//    (touching canopies are one). Mode Tree, a piece of a tree: a track started the frame
//    before from a segment split off at the leading edge of the view (a sparse column across a
//    crown entering it), seen once and never measured, which one segment now covers whole with
//    a track that is no such piece, is dropped without a record (its id is given again when it
//    was the last one given).
//  - Fusion (median over frames): height from the frames whose metrics are clipped neither at
//    the top nor the bottom, distance, thickness, bands and confidence from the frames fully in
//    view (no clipped side). start_m from the frames whose segment is not cut on its low-x side,
//    end_m likewise on the high-x side. A clipped extent never enters a median.
//  - Width: each edge of the metrics' extent (TreeMetrics::left_m, right_m) along the row from
//    the frame that saw it nearest the optical axis, of those where that side is neither clipped
//    nor cut by the view's edge; a frame clipped on the other side counts. Seen off the axis, a
//    crown's edge is the limb of a leaf cluster in front, and one behind it that reaches further
//    out is hidden: the median of whole-view frames read the orchard's crowns 1.6 % narrow on
//    average, 5 % where a back cluster stood out. An observation reading further out than the
//    next nearest by more than the crown could hide between their rays is set aside. A side cut
//    at a valley (RowSegment::joined_lo, joined_hi: crowns grown into each other) counts only
//    when no frame saw it free, and then as the median of its cuts. The cut lies inside the
//    crown (the neighbour hides the rest; the outline dips where the nearer crown's limb is):
//    with its trunk seen (RowSegment::trunk_mm, the median over the frames) and the other side
//    free, that side is the free one mirrored about the trunk, never inside the cut. So is
//    start_m or end_m (mode Tree) when that end was only ever seen at a valley. A side the rig
//    never drove past (the run began or ended before the camera came level with that edge: the
//    first crown's, the last one's) was seen from inside the crown only, off the axis, and
//    hides its back clusters the same way: with the trunk seen and the other side neither cut
//    at a valley nor unpassed, it is mirrored too.
//  - position_m is the canopy's centre along the row, (start_m + end_m) / 2, not the trunk's
//    (seen in some frames only); on a symmetric crown the two agree.
//  - confidence is the median over the fused frames, like every other fused value: the record
//    stands on the median frame, and one frame of poor depth support (a blurred view) does not
//    say the record is poorly supported.
//  - A track not seen for more than grace_frames frames is lost. A track not seen in a frame is
//    emitted when its far end (the side that leaves last: its highest world x when driving
//    along +x) is behind the view's trailing edge at its front depth, or when it is lost;
//    finish() emits every track left. A new segment over a tree that left in the last records
//    is what is still in view of it (a limb behind the front reaches further out on the edge
//    ray) and starts no track; a lost tree seen again starts a new one.
//  - A tree never fully in view (never a frame without clipped sides, or an end never seen off
//    the image edge) still gets a record, with complete = false and the fields it lacks absent
//    (has_height etc.): a sprayer log needs to know a tree was passed, and no clipped number is
//    ever reported as a measurement.
//  - Spacing: spacing_m = |position_m - the previous record's position_m| (centre to centre),
//    gap_m = the empty stretch between the previous record's canopy and this one along the
//    direction of travel (negative: overlapping canopies). Absent on the first record.
//  - Mode Row (hedgerows, fruit walls): the records are canopy segments (start_m, end_m); a
//    segment is what the frames' segments show as one continuous canopy; metrics' width (the
//    extent in view) is not used, the record's width is end_m - start_m.
#pragma once

#include "treestereo/canopy.hpp"
#include "treestereo/metrics.hpp"
#include "treestereo/types.hpp"

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace treestereo {

struct TrackerParams {
  CanopyMode mode = CanopyMode::Tree;
  // Frames a track survives without a segment (a tree hidden by a sparse frame, a sprayer arm).
  int grace_frames = 1;
  // A segment end whose points come this close to the view edge's ray (mm, at each point's
  // depth) is cut.
  // About two point spacings of stereodepth's grid at 2 m (19 px at 1296 px wide ~ 25 mm).
  double edge_margin_mm = 50;
  // World extents are compared widened by this (mm): the travel estimate's error per frame and
  // the limb's sampling. Below the smallest gap between trees (select_canopy's min_gap_mm is 80).
  double match_tolerance_mm = 40;
  // The direction of travel before the position has changed: +1 along +x (the renderer's), -1.
  int forward = 1;
};

// Throws BadSettings naming the field when a value is out of range.
void validate(const TrackerParams &params);

// What one frame tells the tracker.
struct TrackFrame {
  double position_mm = 0;        // the rig's travel since the start, along the row (+x)
  // The edges of the stereo view (rectified left camera's frame): at depth Z the left edge is
  // at camera x = left_slope * Z + left_offset_mm, the right one at right_slope * Z; left_slope
  // < right_slope. See view_slopes().
  double left_slope = 0, right_slope = 0;
  double left_offset_mm = 0;
  std::vector<RowSegment> segments; // the near row's segments, left to right (CanopyResult)
  // The tree in front's measurements (tree_present false: none) and the index into `segments`
  // of the segment they describe (-1: none).
  TreeMetrics metrics;
  int measured_segment = -1;
  // The row's direction in the rectified-left frame (unit, x component above 0.5:
  // RowDirection::direction()). Every X above (the segments' ends and trunks, the metrics' edges
  // and bands, the view's edges) is placed along the row by its projection on it at its own
  // depth and height: a point (X, Y, Z) at X dx + Y dy + Z dz, a ray of slope t at (t dx + dz)
  // per unit of depth. The heights: the segments' lo_y_mm, hi_y_mm and trunk_y_mm, the metrics'
  // edges at the centroid's Y (a crown's side extremes lie near the middle of its height), a
  // band's at its middle. They count where the view is rolled against the row (dy not 0): a
  // vertical trunk read below the crown then has another X than the crown's middle above it.
  // (1, 0, 0): X itself.
  cv::Vec3d row_direction{1, 0, 0};
};

// The edges of the view both rectified cameras see, in the left camera's frame: on the right
// the left image's edge ray, slope (width - 0.5 - cx_left) / fx; on the left the right image's
// edge ray, slope (-0.5 - cx_right) / fx, a baseline to the side (left_offset_mm), or the left
// image's own edge ray (slope (-0.5 - cx_left) / fx, offset 0) when the principal points make
// that one the inner one at 1 m. Pixel centres at integers: the images' outer pixel edges.
// Throws on an invalid geometry.
void view_slopes(const StereoGeometry &geometry, double &left_slope, double &right_slope,
                 double &left_offset_mm);

struct TreeRecord {
  int id = 0;                      // 1, 2, ... in the order the trees entered the view
  CanopyMode mode = CanopyMode::Tree;
  bool complete = false;           // both ends seen off the edge and a frame fully in view
  bool start_seen = false, end_seen = false; // else start_m / end_m is the farthest seen
  double position_m = 0;           // canopy centre along the row: (start_m + end_m) / 2
  double start_m = 0, end_m = 0;   // canopy along the row, world x, start < end
  bool has_height = false, has_width = false, has_depth = false; // has_depth: distance,
                                                                 // thickness, bands, confidence
  double height_m = 0, width_m = 0, distance_m = 0, thickness_m = 0;
  // The bands fused over the frames fully in view (median per value; present when it was present
  // in at least half of them). left_m / right_m are world positions along the row; top_m /
  // bottom_m as the frames have them (camera y, down).
  std::vector<BandExtent> bands;
  double confidence = 0;
  int frames = 0;                  // frames fused: fully in view (mode Row: seen)
  int frames_seen = 0;             // frames its segment was seen in
  // Frames each extent is fused over: height's median; width's two edges, the fewer of them.
  int height_frames = 0, width_frames = 0;
  bool has_spacing = false;        // false on the first record
  double spacing_m = 0, gap_m = 0; // to the previous record (see the top of this header)
  bool lost = false;               // emitted because it was not seen for grace_frames + 1
                                   // frames while still in view, not because it left
};

class TreeTracker {
public:
  explicit TreeTracker(const TrackerParams &params = TrackerParams()); // validates

  // Feeds one frame; returns the records of the trees that left the view (or were lost) with
  // it, in the order they leave (along the direction of travel). Throws BadInput on
  // inconsistent input (slopes, a measured_segment out of range, non-finite values).
  std::vector<TreeRecord> update(const TrackFrame &frame);

  // Emits every track still open, in the order they would leave; the tracker is then empty
  // (ids keep counting).
  std::vector<TreeRecord> finish();

  std::size_t open_tracks() const { return tracks_.size(); }
  const TrackerParams &params() const { return params_; }

  // The open tracks' ids and world extents (m), for display.
  struct Open {
    int id;
    double start_m, end_m;
  };
  std::vector<Open> open() const;

private:
  struct Track {
    int id = 0;
    double lo_mm = 0, hi_mm = 0;         // world extent in the last frame it was seen
    double min_lo_mm = 0, max_hi_mm = 0; // farthest seen over all frames
    double near_mm = 0;                  // front depth in the last frame it was seen
    std::vector<double> starts, ends;    // world extents of uncut sides
    bool start_free = false, end_free = false; // a start (end) seen not at a valley either
    std::vector<double> heights, distances, thicknesses, confidences;
    // The metrics' extent edges, world x (mm), with the slopes of their rays; `at_valley` those
    // of sides cut at a valley.
    struct Edge {
      double slope = 0, x_mm = 0;
      bool at_valley = false;
    };
    std::vector<Edge> lefts, rights;
    std::vector<double> trunks; // world x (mm) of its trunk, where seen (RowSegment::trunk_mm)
    std::vector<std::vector<BandExtent>> bands; // per frame fully in view
    int frames_seen = 0, missed = 0;
    bool lost = false;
  };
  std::vector<TreeRecord> emit(std::vector<Track> &done);
  // The track's ends along the row (world mm): in mode Tree the medians of its ends seen off
  // the image edge (two or more), else `lo` / `hi`.
  std::pair<double, double> robust_ends(const Track &k, double lo, double hi) const;

  TrackerParams params_;
  std::vector<Track> tracks_;
  int next_id_ = 1;
  int direction_ = 1;
  bool has_position_ = false;
  double last_position_mm_ = 0;
  double min_position_mm_ = 0, max_position_mm_ = 0; // the rig's travel so far
  bool has_previous_ = false;
  TreeRecord previous_;
  // World extents (mm) of the last records: a segment appearing over one of them is what is left
  // in view of a tree already emitted (a limb at the trailing edge), not a new tree.
  std::vector<std::pair<double, double>> recent_;
};

} // namespace treestereo
