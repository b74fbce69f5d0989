/**
 * SECTION:element-treemetrics
 * @title: treemetrics
 *
 * Measures the tree: from the left view's canopy silhouette (exgsegment's
 * #GstTreeStereoVegetationMeta) and the canopy's 3D points (stereodepth's
 * #GstTreeStereoPointsMeta), with stereorectify's #GstTreeStereoGeometryMeta, it computes every
 * figure of DESIGN.md's treemetrics table and attaches them as a #GstTreeStereoMetricsMeta.
 * All values are in the rectified-left camera frame (x right, y down, z forward), SI units.
 * The pixels are never written; they are read only for the stereo travel estimate.
 *
 * Along the row (DESIGN.md "In an orchard"; docs/elements/treemetrics.md "Along the row"):
 * - the rig's travel since the previous frame and its position since the stream's start
 *   (`travel-m`, `position-m`, `travel-source` in the message and the meta): #treemetrics:speed
 *   > 0 (wheel odometry, GNSS) gives speed x the PTS difference; otherwise, with
 *   #treemetrics:travel, lib's Odometer (estimate_motion() from a key frame up to 300 mm back,
 *   grey copies of its views) to this one's. A frame without a travel (the first, a failed
 *   estimate) says `travel-source=none` with travel 0 and keeps the position.
 * - with stereodepth's #GstTreeStereoCanopyMeta and #treemetrics:trees, lib's TreeTracker follows
 *   the trees along the row with the meta's segments; each tree leaving the view (and, at EOS,
 *   each one still in view, before EOS goes on) is posted as a `treestereo-tree` element message
 *   (gst_tree_stereo_tree_message_structure()).
 * - with #treemetrics:row-map-location, lib's RowMap is fed per frame and written at EOS: the
 *   CSV at the location, the picture beside it (.png); a write failure is a RESOURCE/OPEN_WRITE
 *   error naming the file.
 * A stream-start starts them over (position 0, tree 1, an empty map).
 *
 * Height and width convert the silhouette's angular extent into metres by
 * #treemetrics:extent-method (default `tangent-points`: each silhouette edge at the depth of
 * the points where its ray touches the canopy; `round-canopy`: exact for a canopy that is a
 * solid of revolution about a vertical axis; see lib/core/include/treestereo/metrics.hpp), with
 * #treemetrics:round-limbs (default true) adding how far a rounded canopy reaches beyond each
 * limb point. Each edge then reaches at least as far as the #treemetrics:extreme-points th
 * (default 6th) most extreme canopy point in its direction: the canopy's 3D extreme often
 * belongs to a cluster behind the one that forms the silhouette's edge, whose extreme projects
 * inside the silhouette (stereodepth's #stereodepth:edge-band samples those parts densely).
 * Only points that project onto the silhouette count.
 *
 * The silhouette measured is the 3D canopy's when the buffer has a #GstTreeStereoCanopyMeta
 * (stereodepth decided in depth which vegetation is the tree or row in front: in an orchard the
 * grass, the next row and the neighbours are green too), else the left view of exgsegment's
 * #GstTreeStereoVegetationMeta (canopy mode `colour`). A canopy meta whose view is not present
 * (nothing in the spray zone) gives `tree-present=false`, whatever colour found.
 *
 * When no canopy is found (the canopy or vegetation meta says none, no valid point falls on it) the
 * message carries `tree-present=false` and no other figure, and the meta's figures are all 0:
 * never NaN, never the previous frame's values. A missing vegetation or points meta (exgsegment
 * or stereodepth not upstream) gives the same, with one warning per run; a missing geometry meta
 * is an error.
 *
 * #treemetrics:smoothing smooths the figures exponentially across frames for a steady readout
 * on a moving sprayer: smoothed = alpha · previous + (1 - alpha) · current (flags and counts are
 * the current frame's). A frame without a tree, a change of the number of bands and a flush
 * forget the history. The raw figures are always there too.
 *
 * ## Element message
 *
 * With #treemetrics:post-messages, an element message named `treemetrics` per buffer:
 *
 * - `timestamp`, `stream-time`, `running-time`: #guint64, ns, of the buffer
 * - `travel-m`, `position-m`: #gdouble, m, the rig's travel since the previous frame and its
 *   position since the start; `travel-source`: string, `stereo`, `speed` or `none`
 * - `tree-present`: #gboolean; when FALSE none of the fields below but `canopy-mode` is present
 * - `canopy-mode`: string, what was measured: `colour` (the colour silhouette, no canopy meta
 *   upstream), `tree` or `row` (the canopy meta's 3D canopy)
 * - `distance`: #gdouble, m, median Z of the canopy's 3D points
 * - `height`, `width`: #gdouble, m, the canopy's real vertical and horizontal extent
 * - `thickness`: #gdouble, m, 95th minus 5th percentile of the points' Z
 * - `area`: #gdouble, m², silhouette area at the extent depth
 * - `perimeter`: #gdouble, m, silhouette perimeter at the extent depth
 * - `complexity`: #gdouble, perimeter² / (4π·area), 1 for a disc
 * - `centroid-x`, `centroid-y`, `centroid-z`: #gdouble, m, the canopy's 3D centre
 * - `clipped`: #guint, #GstTreeStereoClipped flags of the image borders the canopy touches
 *   (height or width is then a lower bound); also as #gboolean `clipped-top`,
 *   `clipped-bottom`, `clipped-left`, `clipped-right`
 * - `points`: #guint, canopy points the figures rest on
 * - `matches`: #guint, points (correspondences) stereodepth delivered: SIFT matches and, with
 *   stereodepth's densify, its grid points
 * - `confidence`: #gdouble, 0..1, how much of the silhouette has depth support: the share of its
 *   pixels within 1.5 % of the view's width of a point the figures rest on
 * - `bands`: #GstValueArray of #GstStructure `band`, #treemetrics:bands of them from the canopy's
 *   top to its bottom, each with `present` (#gboolean), `top`, `bottom` (#gdouble, m, Y),
 *   `left`, `right` (#gdouble, m, X of the canopy's edges in the band), `width` (#gdouble, m)
 *   `depth` (#gdouble, m, nearest-face depth: the 5th percentile of the band's points' Z,
 *   interpolated from the neighbouring bands when the band has fewer than 3 points) and `fill`
 *   (#gdouble, 0..1, the share of the band's left-right extent covered by canopy: of the image
 *   columns between its leftmost and rightmost canopy pixel, those with canopy in one of its
 *   rows)
 * - `smoothed-tree-present` and every field above prefixed `smoothed-`: the smoothed figures
 *   (equal to the raw ones with smoothing=0)
 *
 * ## Example launch line
 * |[
 * gst-launch-1.0 -m stereorectify name=r calibration=rig.yml ! exgsegment ! siftmatch ! \
 *   stereodepth ! treemetrics bands=6 smoothing=0.6 ! fakesink \
 *   treetestsrc view=left ! r.left   treetestsrc view=right ! r.right
 * ]|
 * |[
 * gst-launch-1.0 -m stereorectify name=r calibration=docs/examples/calibration-mer500.yml ! \
 *   stereodepth mode=dense min-depth=1000 max-depth=5000 ! treemetrics ! fakesink \
 *   videotestsrc num-buffers=2 pattern=snow ! video/x-raw,format=GRAY8,width=648,height=486 ! r.left \
 *   videotestsrc num-buffers=2 pattern=snow ! video/x-raw,format=GRAY8,width=648,height=486 ! r.right
 * ]|
 */
#ifdef HAVE_CONFIG_H
#include "config.h"
#endif

#include "common.hpp"
#include "elements.hpp"
#include "properties.hpp"

#include "treestereo/depth.hpp"
#include "treestereo/metrics.hpp"
#include "treestereo/rowmap.hpp"
#include "treestereo/rowtrack.hpp"
#include "treestereo/travel.hpp"
#include "treestereo/worker.hpp"

#include <gst/base/gstbasetransform.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <fstream>
#include <future>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

GST_DEBUG_CATEGORY_STATIC(treemetrics_debug);
#define GST_CAT_DEFAULT treemetrics_debug

using namespace treestereo;
using namespace treestereo::gst;

#define GST_TYPE_TREE_METRICS_EXTENT (gst_tree_metrics_extent_get_type())
static GType gst_tree_metrics_extent_get_type(void)
{
  static GType type = 0;
  static const GEnumValue values[] = {
      {int(ExtentDepth::kRoundCanopy),
       "Tangent rays to a solid of revolution about a vertical axis (exact for a sphere)",
       "round-canopy"},
      {int(ExtentDepth::kEdgePoints), "At the median depth of the points near the left/right edges",
       "edge-points"},
      {int(ExtentDepth::kMidDepth), "At median depth + thickness / 2", "mid-depth"},
      {int(ExtentDepth::kFrontFace), "At the median depth (reads low on a round canopy)",
       "front-face"},
      {int(ExtentDepth::kTangentPoints),
       "Each silhouette edge at the depth of the points where its ray touches the canopy",
       "tangent-points"},
      {0, nullptr, nullptr},
  };
  if (g_once_init_enter(&type)) {
    GType t = g_enum_register_static("GstTreeMetricsExtent", values);
    g_once_init_leave(&type, t);
  }
  return type;
}

#define DEFAULT_BANDS 4
#define DEFAULT_SMOOTHING 0.0
#define DEFAULT_POST_MESSAGES TRUE
#define DEFAULT_SPEED 0.0
#define MAX_SPEED 100.0
#define DEFAULT_TRAVEL TRUE
#define DEFAULT_TREES TRUE
#define DEFAULT_ROW_MAP_BIN 0.05
/* lib's MetricsSmoother takes alpha in [0, 1) */
#define MAX_SMOOTHING 0.99

namespace {

struct Settings {
  int bands = DEFAULT_BANDS;
  double smoothing = DEFAULT_SMOOTHING;
  ExtentDepth extent = MetricsParams{}.extent_depth;
  bool round_limbs = MetricsParams{}.round_limbs;
  guint extreme_points = guint(MetricsParams{}.extreme_points);
  bool post_messages = DEFAULT_POST_MESSAGES;
  double speed = DEFAULT_SPEED; // m/s; > 0: the travel is speed x the time between frames
  bool travel = DEFAULT_TRAVEL; // estimate the travel from stereo when speed is 0
  bool trees = DEFAULT_TREES;
  std::string row_map_location; // empty: no row map
  double row_map_bin = DEFAULT_ROW_MAP_BIN;
};

/* Along the row: the travel's previous frame, the position, the tree tracker and the row map.
 * Reset when a new stream starts. */
struct Along {
  // The stereo travel: grey copies of the key frame's and the previous frame's rectified views.
  std::unique_ptr<Odometer> odometer;
  void reset_views()
  {
    odometer.reset(); // made again for the next frame's view size
  }
  bool has_prev_pts = false;
  GstClockTime prev_pts = GST_CLOCK_TIME_NONE;
  double position_mm = 0;
  // The rig's speed by the last stereo estimates (mm/s, smoothed), for frames whose estimate
  // fails, and how long the position has run on it (s).
  double speed_mm_s = 0;
  bool has_speed = false;
  double predicted_s = 0;
  // The last ground plane stereodepth found: the rig is rigid, so a frame whose grass gave no
  // plane (a hedgerow's base hidden, a sparse frame) takes the last one.
  GroundPlane ground;
  // The direction the rig drives in, from the stereo motions (none from the speed property:
  // the x axis then).
  RowDirection row_direction;
  std::unique_ptr<TreeTracker> tracker;
  // The tracker's first frames, held until the row's direction is measured (at most
  // kMaxHeldFrames; once released, no frame is held again): the first frames placed along the
  // camera's x and the later ones along the measured direction would not agree, and a crown's
  // width taken from an edge of each read 1-2 % wide on the orchard (7 mm apart at 2 m).
  std::vector<TrackFrame> held;
  bool holding = true;
  std::vector<TreeRecord> records; // every record posted, drawn on the row map's picture
  std::unique_ptr<RowMap> row_map;
  GstTreeStereoTimes last_times{GST_CLOCK_TIME_NONE, GST_CLOCK_TIME_NONE, GST_CLOCK_TIME_NONE};
};

struct State {
  std::mutex lock; // guards settings
  Settings settings;
  // streaming thread only
  MetricsSmoother smoother;
  bool warned_missing = false;
  GstVideoInfo info{};
  bool info_set = false;
  Along along;
  bool warned_travel = false; // the travel estimate could not run on this stream (said once)
  // Runs a frame's travel (frame_travel: the views' tracks, along and warned_travel) while the
  // streaming thread measures the canopy: the two share nothing, and on a sequential chain the
  // other core is idle meanwhile.
  Worker travel_worker;
};

/* GstTreeStereoMetrics that frees its bands. */
struct GstMetrics {
  GstTreeStereoMetrics m{};
  GstMetrics() = default;
  GstMetrics(const GstMetrics &) = delete;
  GstMetrics &operator=(const GstMetrics &) = delete;
  ~GstMetrics() { gst_tree_stereo_metrics_clear(&m); }
};

} // namespace

struct GstTreeMetrics {
  GstBaseTransform parent;
  State *state;
};

struct GstTreeMetricsClass {
  GstBaseTransformClass parent_class;
};

#define GST_TYPE_TREE_METRICS (gst_tree_metrics_get_type())
#define GST_TREE_METRICS(obj) \
  (G_TYPE_CHECK_INSTANCE_CAST((obj), GST_TYPE_TREE_METRICS, GstTreeMetrics))
G_DEFINE_TYPE(GstTreeMetrics, gst_tree_metrics, GST_TYPE_BASE_TRANSFORM);
GST_ELEMENT_REGISTER_DEFINE(treemetrics, "treemetrics", GST_RANK_NONE, GST_TYPE_TREE_METRICS);

#define CAPS GST_VIDEO_CAPS_MAKE(TREESTEREO_VIDEO_FORMATS)

/* Once per run: which upstream element is missing. The frame still gets tree-present=false. */
static void warn_missing(GstTreeMetrics *self, GstBuffer *buf, bool veg)
{
  if (self->state->warned_missing)
    return;
  self->state->warned_missing = true;
  treestereo::gst::post_missing_meta(GST_ELEMENT(self), GST_MESSAGE_WARNING, buf,
                                     !veg ? treestereo::gst::kVegetationMeta
                                          : treestereo::gst::kPointsMeta,
                                     nullptr, ". Reporting tree-present=false.");
}

/* Posts one "treestereo-tree" message per record (no lock held) and, when a row map is asked
 * for, keeps the records for its picture (not otherwise: a long run would hold every tree). */
static void post_records(GstTreeMetrics *self, const std::vector<TreeRecord> &records,
                         const GstTreeStereoTimes *times)
{
  State *st = self->state;
  const bool keep = !settings_snapshot(self).row_map_location.empty();
  for (const TreeRecord &r : records) {
    GST_DEBUG_OBJECT(self, "tree %d leaves: %.3f..%.3f m, %d frames%s", r.id, r.start_m, r.end_m,
                     r.frames, r.complete ? "" : " (incomplete)");
    GstTreeStereoTreeRecord g{};
    treestereo::gst::record_to_gst(r, &g);
    treestereo::gst::post_element_message(GST_ELEMENT(self),
                                          gst_tree_stereo_tree_message_structure(&g, times));
    gst_tree_stereo_tree_record_clear(&g);
    if (keep)
      st->along.records.push_back(r);
  }
}

/* At most this many frames are held for the row's direction: 1.4 s at 7 frames/s, 350 mm at
 * 0.25 m/s (RowDirection::kMinSpanMm is 250 mm). */
static constexpr std::size_t kMaxHeldFrames = 10;

/* Hands the held frames to the tracker along the row's direction `d` (RowDirection::direction()
 * as it is now); no frame is held after. */
static std::vector<TreeRecord> release_held(Along &a, const cv::Vec3d &d)
{
  std::vector<TreeRecord> out;
  for (TrackFrame &f : a.held) {
    f.row_direction = d;
    std::vector<TreeRecord> r = a.tracker->update(f);
    out.insert(out.end(), r.begin(), r.end());
  }
  a.held.clear();
  a.holding = false;
  return out;
}

/* The held frames, then every track left: the records of the trees still in view. */
static std::vector<TreeRecord> finish_tracker(Along &a, const cv::Vec3d &d)
{
  std::vector<TreeRecord> out = release_held(a, d);
  std::vector<TreeRecord> rest = a.tracker->finish();
  out.insert(out.end(), rest.begin(), rest.end());
  return out;
}

/* The records of the trees still in view: the stream ends (or jumps), none of them will be seen
 * leaving. */
static void finish_trees(GstTreeMetrics *self)
{
  Along &a = self->state->along;
  if (!a.tracker)
    return;
  std::vector<TreeRecord> left;
  treestereo::gst::guarded(GST_ELEMENT(self), false, [&] {
    left = finish_tracker(a, a.row_direction.direction(a.ground));
    return true;
  });
  post_records(self, left, &a.last_times);
}

/* A new stream: the position starts at 0, tree ids at 1, the row map empty. */
static void reset_along(GstTreeMetrics *self)
{
  self->state->along = Along();
  self->state->warned_travel = false;
}

/* Keypoints (siftmatch's matches) enough for the travel to rest on them alone: at 2 m/s about a
 * third of the points are tracked, and the estimate needs TravelParams::min_inliers (20). */
static constexpr std::size_t kMinTravelKeypoints = 100;

/* How long the position may run on the last measured speed without a new measurement (s). */
static constexpr double kMaxPredictedS = 1.0;

/* The travel since the previous frame (mm) and where it came from. Keeps this frame's grey views
 * for the next one when the stereo estimate is on. */
static GstTreeStereoTravelSource frame_travel(GstTreeMetrics *self, GstBuffer *buf,
                                             const Settings &s, const StereoGeometry &geometry,
                                             const GstTreeStereoCanopyMeta *canopy,
                                             const GstTreeStereoPointsMeta *pm, double &travel_mm)
{
  State *st = self->state;
  Along &a = st->along;
  travel_mm = 0;
  if (canopy && canopy->ground_found)
    a.ground = treestereo::gst::ground_from_meta(canopy);
  const GstClockTime pts = GST_BUFFER_PTS(buf);
  const bool had_pts = a.has_prev_pts && GST_CLOCK_TIME_IS_VALID(pts);
  const GstClockTime prev_pts = a.prev_pts;
  a.has_prev_pts = GST_CLOCK_TIME_IS_VALID(pts);
  a.prev_pts = pts;

  if (s.speed > 0) {
    // The application's speed (wheel odometry, GNSS) wins; the stereo views kept so far would
    // be stale when it is set back to 0.
    a.reset_views();
    if (!had_pts)
      return GST_TREE_STEREO_TRAVEL_NONE; // the first frame: no time has passed
    const double dt_s = double(GST_CLOCK_DIFF(prev_pts, pts)) / double(GST_SECOND);
    travel_mm = s.speed * dt_s * 1000.0;
    return GST_TREE_STEREO_TRAVEL_SPEED;
  }
  if (!s.travel) {
    a.reset_views();
    return GST_TREE_STEREO_TRAVEL_NONE;
  }
  if (!st->info_set || treestereo::gst::n_views_of(&st->info) != 2) {
    if (!st->warned_travel) {
      st->warned_travel = true;
      GST_ELEMENT_WARNING(self, STREAM, FAILED,
                          ("treemetrics cannot measure the travel: the frames do not hold both "
                           "views side by side. Set the speed property, or travel=false."),
                          ("caps %s", st->info_set ? "with one view" : "not set"));
    }
    return GST_TREE_STEREO_TRAVEL_NONE;
  }
  treestereo::gst::MappedFrame frame(&st->info, buf, GST_MAP_READ);
  if (!frame.ok()) {
    // A buffer without the pixels its caps promise (metas alone, as a test or a replay of the
    // metas hands on): nothing to track. The measurements need no pixels, so this stops
    // nothing; travel-source "none" says it in every message.
    a.reset_views();
    if (!st->warned_travel) {
      st->warned_travel = true;
      GST_INFO_OBJECT(self, "no travel: buffer %" GST_PTR_FORMAT " is not a whole video frame",
                      buf);
    }
    return GST_TREE_STEREO_TRAVEL_NONE;
  }
  const cv::Mat mat = frame.mat();
  const treestereo::gst::PixelLayout layout =
      treestereo::gst::pixel_layout(GST_VIDEO_INFO_FORMAT(&st->info));
  // Grey copies: the next frame compares with these after this buffer has gone downstream.
  cv::Mat left = treestereo::gst::gray_view(treestereo::gst::view_mat(mat, 0, 2), layout);
  cv::Mat right = treestereo::gst::gray_view(treestereo::gst::view_mat(mat, 1, 2), layout);
  if (!layout.color) {
    left = left.clone();
    right = right.clone();
  }
  GstTreeStereoTravelSource source = GST_TREE_STEREO_TRAVEL_NONE;
  if (!a.odometer) {
    OdometerParams op;
    // Views up to 800 px wide are tracked at full size: at half size the tracks of 640x480
    // views read the travel ~5 % short on the orchard (the canopy's points alone), for the
    // same cost as half size at 1296x972. They are measured from the previous frame: their
    // coarser depth makes an estimate over a key frame's longer span worse, not better
    // (docs/results.md, "Travel from key frames").
    if (left.cols <= 800) {
      op.travel.scale = 1.0;
      op.key_span_mm = 0;
    }
    a.odometer = std::make_unique<Odometer>(op);
  }
  // No points (no points meta): nothing to measure from, but the views serve the next frame.
  // The travel rests on the matched keypoints when there are kMinTravelKeypoints of them:
  // about a sixth of the densification's grid points carry the front leaves' depth on a back
  // leaf seen through a gap, and they read the travel about 0.5 % short (docs/results.md,
  // "Travel on the keypoints"). Fewer keypoints: every point.
  // The keypoints of the whole view count, not only the canopy's: the rig moves past a static
  // scene, and stereodepth drops points off the tree in front (its neighbours, the next row,
  // the grass) for what they are, not for their depth. The canopy's alone failed where the tree
  // in front had just entered at the view's edge (its points all outside the previous view) and
  // read 3-7 % short where it was leaving (a narrow strip at one depth, where a turn and a move
  // along the row look alike; docs/results.md, "The travel on the whole view"). Depths outside
  // lib's default range are left out: a false match at a few centimetres would shrink the
  // coarse search's steps.
  std::vector<PixelPoint> points;
  if (pm) {
    const GstTreeStereoMatchesMeta *mm = gst_buffer_get_tree_stereo_matches_meta(buf);
    const guint width = guint(geometry.view_size.width);
    const DepthParams range;
    points = treestereo::gst::pixel_points_of(pm, mm, width, false, range.min_depth_mm,
                                              range.max_depth_mm);
    if (points.size() < kMinTravelKeypoints)
      points = treestereo::gst::pixel_points_of(pm, mm, width, true, range.min_depth_mm,
                                                range.max_depth_mm);
  }
  const bool had_views = a.odometer->has_previous();
  const auto t0 = std::chrono::steady_clock::now();
  const OdometryStep step =
      a.odometer->add(left, right, points, geometry, a.row_direction.direction(a.ground));
  if (had_views) {
    const Motion &m = step.motion;
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    GST_DEBUG_OBJECT(self,
                     "travel %s: %.1f mm (from the %s frame: %zu of %zu points, coarse search "
                     "%.1f mm, %zu tracked, %zu inliers, %.2f px) in %.1f ms",
                     step.found ? "found" : "not found", step.travel_mm,
                     step.from_key ? "key" : "previous", m.points, points.size(), m.prior_mm,
                     m.tracked, m.inliers, m.rms_px, ms);
    const double dt_s =
        had_pts ? double(GST_CLOCK_DIFF(prev_pts, pts)) / double(GST_SECOND) : 0.0;
    if (step.found) {
      travel_mm = step.travel_mm;
      a.row_direction.add(m.displacement_mm);
      source = GST_TREE_STEREO_TRAVEL_STEREO;
      if (dt_s > 0) {
        const double v = step.travel_mm / dt_s;
        a.speed_mm_s = a.has_speed ? 0.5 * (a.speed_mm_s + v) : v;
        a.has_speed = true;
      }
      a.predicted_s = 0;
    } else if (a.has_speed && dt_s > 0 && a.predicted_s + dt_s <= kMaxPredictedS) {
      // A rig does not stop between two frames: the speed of the last measured frames carries
      // the position over a frame whose tracks failed (too few at speed, a frame of sky).
      travel_mm = a.speed_mm_s * dt_s;
      a.predicted_s += dt_s;
      source = GST_TREE_STEREO_TRAVEL_PREDICTED;
    } else {
      a.has_speed = false;
    }
  }
  return source;
}

/* The trees along the row (tree records) and the row map, fed with this frame; `row_direction`:
 * the frame's, as its metrics meta carries it. */
static std::vector<TreeRecord> follow_row(GstTreeMetrics *self, GstBuffer *buf, const Settings &s,
                                          const StereoGeometry &geometry,
                                          const GstTreeStereoCanopyMeta *canopy,
                                          const GstTreeStereoPointsMeta *pm, const TreeMetrics &m,
                                          const cv::Vec3d &row_direction)
{
  Along &a = self->state->along;
  std::vector<TreeRecord> out;
  if (!canopy || (canopy->mode != GST_TREE_STEREO_CANOPY_TREE &&
                  canopy->mode != GST_TREE_STEREO_CANOPY_ROW))
    return out; // the colour silhouette says nothing of the row
  const CanopyMode mode =
      canopy->mode == GST_TREE_STEREO_CANOPY_ROW ? CanopyMode::Row : CanopyMode::Tree;
  if (s.trees) {
    if (a.tracker && a.tracker->params().mode != mode) {
      // stereodepth's canopy mode changed: the tracks were another's
      out = finish_tracker(a, row_direction);
      a.tracker.reset();
    }
    if (!a.tracker) {
      TrackerParams tp;
      tp.mode = mode;
      a.tracker = std::make_unique<TreeTracker>(tp);
    }
    TrackFrame f;
    f.position_mm = a.position_mm;
    view_slopes(geometry, f.left_slope, f.right_slope, f.left_offset_mm);
    f.segments = treestereo::gst::segments_from_meta(canopy);
    // The metrics describe the selected canopy: one segment (the tree in front; in mode row
    // only when the canopy is one segment, else they span several canopies).
    int selected = -1, n_selected = 0;
    for (std::size_t i = 0; i < f.segments.size(); i++)
      if (f.segments[i].selected) {
        if (selected < 0)
          selected = int(i);
        n_selected++;
      }
    if (m.tree_present && n_selected == 1) {
      f.metrics = m;
      f.measured_segment = selected;
    }
    if (gst_debug_category_get_threshold(treemetrics_debug) >= GST_LEVEL_LOG) {
      // What the tracker is given, along the row (m): "[" an end, "~" cut at a valley, "*" the
      // segment measured.
      std::string segs;
      char seg[96];
      for (std::size_t i = 0; i < f.segments.size(); i++) {
        const RowSegment &g = f.segments[i];
        std::snprintf(seg, sizeof seg, " %s%.3f..%.3f%s%s", g.joined_lo ? "~" : "[",
                      (f.position_mm + g.lo_mm) / 1000, (f.position_mm + g.hi_mm) / 1000,
                      g.joined_hi ? "~" : "]", int(i) == f.measured_segment ? "*" : "");
        segs += seg;
      }
      GST_LOG_OBJECT(self, "at %.3f m, segments along the row:%s", f.position_mm / 1000,
                     segs.c_str());
    }
    a.held.push_back(std::move(f));
    const bool measuring = s.speed <= 0 && s.travel;
    if (!a.holding || !measuring || a.row_direction.measured() ||
        a.held.size() >= kMaxHeldFrames) {
      std::vector<TreeRecord> r = release_held(a, row_direction);
      out.insert(out.end(), r.begin(), r.end());
    }
  }
  if (!s.row_map_location.empty() && a.ground.found) {
    if (!a.row_map) {
      RowMapParams rp;
      rp.bin_mm = s.row_map_bin * 1000.0;
      a.row_map = std::make_unique<RowMap>(rp);
    }
    treestereo::gst::feed_row_map(*a.row_map, buf, geometry, canopy, pm, a.ground, a.position_mm,
                                  row_direction);
  }
  return out;
}

/* At EOS: the row map's CSV at row-map-location and its picture beside it (.png). */
static bool write_row_map(GstTreeMetrics *self, const std::string &location)
{
  Along &a = self->state->along;
  const std::string png = with_extension(location, ".png");
  std::string failed;
  try {
    failed = location;
    if (a.row_map && !a.row_map->empty()) {
      a.row_map->write_csv(location);
      failed = png;
      a.row_map->write_png(png, a.records);
    } else {
      // No frame with a canopy and a ground plane: the header alone, no picture.
      std::ofstream f(location);
      f << RowMap::kCsvHeader << '\n';
      f.flush();
      if (!f)
        throw FileError(location, FileAccess::Write,
                        "cannot write " + location + ": " + g_strerror(errno));
      GST_ELEMENT_WARNING(self, STREAM, FAILED,
                          ("The row map is empty (no 3D canopy, or no ground plane: see "
                           "stereodepth's ground=rig): "
                           "\"%s\" holds the header alone, no picture written.",
                           location.c_str()),
                          (nullptr));
    }
  } catch (const std::exception &e) {
    GST_ELEMENT_ERROR(self, RESOURCE, OPEN_WRITE,
                      ("Could not write the row map to \"%s\": check that its folder exists, "
                       "is writable and has room.",
                       failed.c_str()),
                      ("%s", e.what()));
    return false;
  }
  GST_INFO_OBJECT(self, "row map written to %s and %s", location.c_str(), png.c_str());
  return true;
}

static GstFlowReturn gst_tree_metrics_transform_ip(GstBaseTransform *trans, GstBuffer *buf)
{
  GstTreeMetrics *self = GST_TREE_METRICS(trans);
  State *st = self->state;
  const Settings s = settings_snapshot(self);
  const GstTreeStereoGeometryMeta *gm = gst_buffer_get_tree_stereo_geometry_meta(buf);
  if (!gm) {
    treestereo::gst::post_missing_meta(GST_ELEMENT(self), GST_MESSAGE_ERROR, buf,
                                       treestereo::gst::kGeometryMeta);
    return GST_FLOW_ERROR;
  }
  const GstTreeStereoVegetationMeta *veg = gst_buffer_get_tree_stereo_vegetation_meta(buf);
  const GstTreeStereoPointsMeta *pm = gst_buffer_get_tree_stereo_points_meta(buf);
  // The 3D canopy (stereodepth), when decided, is what is measured: colour alone takes the
  // grass, the next row and the neighbours too.
  const GstTreeStereoCanopyMeta *canopy = gst_buffer_get_tree_stereo_canopy_meta(buf);
  const GstTreeStereoVegetationView *silhouette =
      canopy ? &canopy->view : veg ? &veg->views[LEFT] : nullptr;
  const GstTreeStereoCanopyMode mode = canopy ? canopy->mode : GST_TREE_STEREO_CANOPY_COLOUR;
  if (!silhouette || !pm)
    warn_missing(self, buf, silhouette != nullptr);

  GstMetrics raw, smoothed;
  std::vector<TreeRecord> records;
  const bool ok = treestereo::gst::guarded(GST_ELEMENT(self), false, [&] {
    const StereoGeometry geometry = treestereo::gst::geometry_from_meta(gm);
    // The rig's travel along the row, measured beside the canopy; a frame whose travel is
    // unknown keeps the position.
    double travel_mm = 0;
    std::future<GstTreeStereoTravelSource> travel = st->travel_worker.run(
        [&] { return frame_travel(self, buf, s, geometry, canopy, pm, travel_mm); });
    // Whatever happens below, the job reads this buffer and the state until it is done.
    const WaitFor waited(travel);
    TreeMetrics m; // no tree unless a silhouette and the points are there
    if (silhouette && pm) {
      MetricsParams p;
      p.n_bands = s.bands;
      p.extent_depth = s.extent;
      p.round_limbs = s.round_limbs;
      p.extreme_points = int(s.extreme_points);
      const treestereo::gst::MappedSilhouette sil(silhouette);
      m = compute_tree_metrics(sil.get(), treestereo::gst::points_from_meta(pm), geometry, p);
    }
    if (st->smoother.alpha() != s.smoothing)
      st->smoother = MetricsSmoother(s.smoothing);
    treestereo::gst::metrics_to_gst(m, &raw.m, mode);
    treestereo::gst::metrics_to_gst(st->smoother.update(m), &smoothed.m, mode);

    const GstTreeStereoTravelSource source = travel.get();
    st->along.position_mm += travel_mm;
    const cv::Vec3d dir = st->along.row_direction.direction(st->along.ground);
    for (GstTreeStereoMetrics *out : {&raw.m, &smoothed.m}) {
      out->travel_m = travel_mm * 1e-3;
      out->position_m = st->along.position_mm * 1e-3;
      out->travel_source = guint(source);
      for (int i = 0; i < 3; i++)
        out->row_direction[i] = dir[i];
    }
    records = follow_row(self, buf, s, geometry, canopy, pm, m, dir);
    return true;
  });
  if (!ok)
    return GST_FLOW_ERROR;
  gst_tree_stereo_times_from_buffer(&st->along.last_times, buf, &trans->segment);
  post_records(self, records, &st->along.last_times);

  GstTreeStereoMetricsMeta *meta = gst_buffer_add_tree_stereo_metrics_meta(buf, &raw.m, &smoothed.m);
  GST_LOG_OBJECT(self, "tree %d, distance %.3f m, width %.3f m, height %.3f m",
                 meta->metrics.tree_present, meta->metrics.distance_m, meta->metrics.width_m,
                 meta->metrics.height_m);
  if (s.post_messages) {
    GstTreeStereoTimes times;
    gst_tree_stereo_times_from_buffer(&times, buf, &trans->segment);
    treestereo::gst::post_element_message(
        GST_ELEMENT(self),
        gst_tree_stereo_metrics_message_structure(&meta->metrics, &meta->smoothed, &times));
  }
  return GST_FLOW_OK;
}

static gboolean gst_tree_metrics_start(GstBaseTransform *trans)
{
  GstTreeMetrics *self = GST_TREE_METRICS(trans);
  self->state->smoother.reset();
  self->state->warned_missing = false;
  self->state->info_set = false;
  reset_along(self);
  return TRUE;
}

static gboolean gst_tree_metrics_set_caps(GstBaseTransform *trans, GstCaps *incaps, GstCaps *)
{
  GstTreeMetrics *self = GST_TREE_METRICS(trans);
  State *st = self->state;
  GstVideoInfo info;
  if (!gst_video_info_from_caps(&info, incaps)) {
    GST_ERROR_OBJECT(self, "invalid caps %" GST_PTR_FORMAT, incaps);
    return FALSE;
  }
  // Other views (size, format, layout): the previous frame cannot be compared with the next.
  if (!st->info_set || !gst_video_info_is_equal(&info, &st->info)) {
    st->along.reset_views();
  }
  st->info = info;
  st->info_set = true;
  return TRUE;
}

static gboolean gst_tree_metrics_sink_event(GstBaseTransform *trans, GstEvent *event)
{
  GstTreeMetrics *self = GST_TREE_METRICS(trans);
  State *st = self->state;
  switch (GST_EVENT_TYPE(event)) {
  case GST_EVENT_FLUSH_STOP:
    // A seek: the previous frames are history. The trees in view are closed (their frames no
    // longer follow); the position keeps counting from where it was.
    st->smoother.reset();
    st->along.reset_views();
    st->along.has_prev_pts = false;
    finish_trees(self);
    st->along.tracker.reset();
    break;
  case GST_EVENT_STREAM_START:
    reset_along(self); // a new stream starts at position 0, tree 1, an empty row map
    break;
  case GST_EVENT_EOS: {
    // The trees still in view are posted, and the row map written, before EOS goes on.
    finish_trees(self);
    const Settings s = settings_snapshot(self);
    if (!s.row_map_location.empty())
      write_row_map(self, s.row_map_location);
    break;
  }
  default:
    break;
  }
  return GST_BASE_TRANSFORM_CLASS(gst_tree_metrics_parent_class)->sink_event(trans, event);
}

static void gst_tree_metrics_class_init(GstTreeMetricsClass *klass)
{
  GObjectClass *gobject_class = G_OBJECT_CLASS(klass);
  GstElementClass *element_class = GST_ELEMENT_CLASS(klass);
  GstBaseTransformClass *bt_class = GST_BASE_TRANSFORM_CLASS(klass);

  GST_DEBUG_CATEGORY_INIT(treemetrics_debug, "treemetrics", 0, "treestereo treemetrics");

  gobject_class->finalize = finalize_state<GstTreeMetrics, &gst_tree_metrics_parent_class>;

  auto props = PropertyTable<Settings>::in_state<GstTreeMetrics>(gobject_class);
  props.integer("bands", "Bands",
                "Horizontal bands from the canopy's top to its bottom, each with its "
                "left/right edge, width and nearest-face depth",
                1, 64, DEFAULT_BANDS, TS_FIELD(bands));
  props.real("smoothing", "Smoothing",
             "Exponential smoothing across frames: smoothed = smoothing * previous "
             "+ (1 - smoothing) * current; 0 = off. Raw figures are always kept.",
             0.0, MAX_SMOOTHING, DEFAULT_SMOOTHING, TS_FIELD(smoothing));
  props.enumeration("extent-method", "Extent method",
                    "How the silhouette's angular extent becomes metres (height, width, "
                    "bands, area, perimeter)",
                    GST_TYPE_TREE_METRICS_EXTENT, int(MetricsParams{}.extent_depth),
                    TS_FIELD(extent));
  props.boolean("round-limbs", "Round limbs",
                "tangent-points: add how far the canopy reaches beyond each limb point "
                "(the limb is not the extreme unless the ray is straight ahead), from "
                "the curvature the edge points show; false = the limb points' extent",
                MetricsParams{}.round_limbs, TS_FIELD(round_limbs));
  props.uinteger("extreme-points", "Extreme points",
                 "Each edge of height and width reaches at least as far as the n-th most "
                 "extreme canopy point in its direction (clusters behind the silhouette's "
                 "edge reach further in metres than it shows); 0 = the silhouette alone",
                 0, 10000, guint(MetricsParams{}.extreme_points), TS_FIELD(extreme_points));
  props.boolean("post-messages", "Post messages", "Post a 'treemetrics' element message per buffer",
                DEFAULT_POST_MESSAGES, TS_FIELD(post_messages));
  props.real("speed", "Speed",
             "The rig's speed along the row (m/s, towards the camera's +x) from "
             "wheel odometry or GNSS: when > 0 the travel is speed x the time "
             "between the frames' timestamps; 0 = measure it from stereo",
             0.0, MAX_SPEED, DEFAULT_SPEED, TS_FIELD(speed));
  props.boolean("travel", "Travel",
                "Estimate the rig's travel between frames from stereo when speed is "
                "0 (about 13 ms a frame at 1296x972); false: no travel (source none)",
                DEFAULT_TRAVEL, TS_FIELD(travel));
  props.boolean("trees", "Trees",
                "Follow the trees along the row (stereodepth's 3D canopy) and post a "
                "'treestereo-tree' message per tree as it leaves the view (and the "
                "ones in view at EOS)",
                DEFAULT_TREES, TS_FIELD(trees));
  props.string("row-map-location", "Row map location",
               "Write the row map (CSV: position_m, band, present, distance_m, fill) "
               "here at EOS, and its picture beside it (same name, .png); NULL = no "
               "row map. Set before the stream starts.",
               TS_FIELD(row_map_location));
  props.real("row-map-bin", "Row map bin",
             "Travel bin of the row map along the row (m); read when the map "
             "starts (the stream's first frame with a canopy)",
             0.005, 10.0, DEFAULT_ROW_MAP_BIN, TS_FIELD(row_map_bin));

  add_filter_pad_templates(element_class, CAPS);
  gst_element_class_set_static_metadata(
      element_class, "Tree metrics", "Filter/Analyzer/Video",
      "Measures the tree canopy (distance, height, width, thickness, area, perimeter, "
      "complexity, centroid, height bands, confidence) from its silhouette (the 3D canopy's "
      "when decided) and 3D points",
      "treestereo developers");
  gst_type_mark_as_plugin_api(GST_TYPE_TREE_METRICS_EXTENT, GstPluginAPIFlags(0));

  bt_class->start = gst_tree_metrics_start;
  bt_class->sink_event = gst_tree_metrics_sink_event;
  bt_class->set_caps = gst_tree_metrics_set_caps;
  bt_class->transform_ip = gst_tree_metrics_transform_ip;
}

static void gst_tree_metrics_init(GstTreeMetrics *self)
{
  self->state = new State();
  gst_base_transform_set_in_place(GST_BASE_TRANSFORM(self), TRUE);
  gst_base_transform_set_passthrough(GST_BASE_TRANSFORM(self), FALSE);
}
