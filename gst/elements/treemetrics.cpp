/**
 * SECTION:element-treemetrics
 * @title: treemetrics
 *
 * Measures the tree: from the left view's canopy silhouette (exgsegment's
 * #GstTreeStereoVegetationMeta) and the canopy's 3D points (stereodepth's
 * #GstTreeStereoPointsMeta), with stereorectify's #GstTreeStereoGeometryMeta, it computes every
 * figure of DESIGN.md's treemetrics table and attaches them as a #GstTreeStereoMetricsMeta.
 * All values are in the rectified-left camera frame (x right, y down, z forward), SI units.
 * The pixels are neither touched nor mapped.
 *
 * Height and width convert the silhouette's angular extent into metres by
 * #treemetrics:extent-method (default `tangent-points`: each silhouette edge at the depth of
 * the points where its ray touches the canopy; `round-canopy`: exact for a canopy that is a
 * solid of revolution about a vertical axis; see lib/include/treestereo/metrics.hpp), with
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

#include "treestereo/metrics.hpp"

#include <gst/base/gstbasetransform.h>

#include <mutex>
#include <vector>

GST_DEBUG_CATEGORY_STATIC(treemetrics_debug);
#define GST_CAT_DEFAULT treemetrics_debug

using namespace treestereo;

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
/* lib's MetricsSmoother takes alpha in [0, 1) */
#define MAX_SMOOTHING 0.99

enum {
  PROP_0,
  PROP_BANDS,
  PROP_SMOOTHING,
  PROP_EXTENT_METHOD,
  PROP_ROUND_LIMBS,
  PROP_EXTREME_POINTS,
  PROP_POST_MESSAGES,
};

namespace {

struct Settings {
  int bands = DEFAULT_BANDS;
  double smoothing = DEFAULT_SMOOTHING;
  ExtentDepth extent = MetricsParams{}.extent_depth;
  bool round_limbs = MetricsParams{}.round_limbs;
  guint extreme_points = guint(MetricsParams{}.extreme_points);
  bool post_messages = DEFAULT_POST_MESSAGES;
};

struct State {
  std::mutex lock; // guards settings
  Settings settings;
  // streaming thread only
  MetricsSmoother smoother;
  bool warned_missing = false;
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
static GstStaticPadTemplate sink_template =
    GST_STATIC_PAD_TEMPLATE("sink", GST_PAD_SINK, GST_PAD_ALWAYS, GST_STATIC_CAPS(CAPS));
static GstStaticPadTemplate src_template =
    GST_STATIC_PAD_TEMPLATE("src", GST_PAD_SRC, GST_PAD_ALWAYS, GST_STATIC_CAPS(CAPS));

static Settings snapshot(GstTreeMetrics *self)
{
  std::lock_guard<std::mutex> g(self->state->lock);
  return self->state->settings;
}

static std::vector<Point3> points_of(const GstTreeStereoPointsMeta *pm)
{
  std::vector<Point3> pts(pm->n_points);
  for (guint i = 0; i < pm->n_points; i++) {
    const GstTreeStereoPoint &p = pm->points[i];
    pts[i].x = p.x;
    pts[i].y = p.y;
    pts[i].z = p.z;
    pts[i].match_index = p.match_index;
    pts[i].valid = p.valid != FALSE;
  }
  return pts;
}

/* Once per run: which upstream element is missing. The frame still gets tree-present=false. */
static void warn_missing(GstTreeMetrics *self, bool veg, bool points)
{
  if (self->state->warned_missing)
    return;
  self->state->warned_missing = true;
  GST_ELEMENT_WARNING(self, STREAM, FAILED,
                      ("treemetrics has no %s on its buffers: put %s upstream. Reporting "
                       "tree-present=false.",
                       !veg ? "vegetation meta" : "3D points meta",
                       !veg ? "exgsegment" : "stereodepth"),
                      ("vegetation meta %s, points meta %s", veg ? "present" : "missing",
                       points ? "present" : "missing"));
}

static GstFlowReturn gst_tree_metrics_transform_ip(GstBaseTransform *trans, GstBuffer *buf)
{
  GstTreeMetrics *self = GST_TREE_METRICS(trans);
  State *st = self->state;
  const Settings s = snapshot(self);
  const GstTreeStereoGeometryMeta *gm = gst_buffer_get_tree_stereo_geometry_meta(buf);
  if (!gm) {
    GST_ELEMENT_ERROR(self, STREAM, FAILED,
                      ("No stereo geometry on the buffer: treemetrics needs the geometry meta "
                       "of stereorectify upstream."),
                      ("buffer %" GST_PTR_FORMAT " has no GstTreeStereoGeometryMeta", buf));
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
    warn_missing(self, silhouette != nullptr, pm != nullptr);

  GstMetrics raw, smoothed;
  const bool ok = treestereo::gst::guarded(GST_ELEMENT(self), false, [&] {
    TreeMetrics m; // no tree unless a silhouette and the points are there
    if (silhouette && pm) {
      MetricsParams p;
      p.n_bands = s.bands;
      p.extent_depth = s.extent;
      p.round_limbs = s.round_limbs;
      p.extreme_points = int(s.extreme_points);
      const treestereo::gst::MappedSilhouette sil(silhouette);
      m = compute_tree_metrics(sil.get(), points_of(pm), treestereo::gst::geometry_from_meta(gm),
                               p);
    }
    if (st->smoother.alpha() != s.smoothing)
      st->smoother = MetricsSmoother(s.smoothing);
    treestereo::gst::metrics_to_gst(m, &raw.m, mode);
    treestereo::gst::metrics_to_gst(st->smoother.update(m), &smoothed.m, mode);
    return true;
  });
  if (!ok)
    return GST_FLOW_ERROR;

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
  return TRUE;
}

static gboolean gst_tree_metrics_sink_event(GstBaseTransform *trans, GstEvent *event)
{
  if (GST_EVENT_TYPE(event) == GST_EVENT_FLUSH_STOP)
    GST_TREE_METRICS(trans)->state->smoother.reset(); // a seek: the previous frames are history
  return GST_BASE_TRANSFORM_CLASS(gst_tree_metrics_parent_class)->sink_event(trans, event);
}

static void gst_tree_metrics_set_property(GObject *object, guint prop_id, const GValue *value,
                                          GParamSpec *pspec)
{
  GstTreeMetrics *self = GST_TREE_METRICS(object);
  std::lock_guard<std::mutex> g(self->state->lock);
  Settings &s = self->state->settings;
  switch (prop_id) {
  case PROP_BANDS: s.bands = g_value_get_int(value); break;
  case PROP_SMOOTHING: s.smoothing = g_value_get_double(value); break;
  case PROP_EXTENT_METHOD: s.extent = ExtentDepth(g_value_get_enum(value)); break;
  case PROP_ROUND_LIMBS: s.round_limbs = g_value_get_boolean(value); break;
  case PROP_EXTREME_POINTS: s.extreme_points = g_value_get_uint(value); break;
  case PROP_POST_MESSAGES: s.post_messages = g_value_get_boolean(value); break;
  default: G_OBJECT_WARN_INVALID_PROPERTY_ID(object, prop_id, pspec); break;
  }
}

static void gst_tree_metrics_get_property(GObject *object, guint prop_id, GValue *value,
                                          GParamSpec *pspec)
{
  GstTreeMetrics *self = GST_TREE_METRICS(object);
  std::lock_guard<std::mutex> g(self->state->lock);
  const Settings &s = self->state->settings;
  switch (prop_id) {
  case PROP_BANDS: g_value_set_int(value, s.bands); break;
  case PROP_SMOOTHING: g_value_set_double(value, s.smoothing); break;
  case PROP_EXTENT_METHOD: g_value_set_enum(value, int(s.extent)); break;
  case PROP_ROUND_LIMBS: g_value_set_boolean(value, s.round_limbs); break;
  case PROP_EXTREME_POINTS: g_value_set_uint(value, s.extreme_points); break;
  case PROP_POST_MESSAGES: g_value_set_boolean(value, s.post_messages); break;
  default: G_OBJECT_WARN_INVALID_PROPERTY_ID(object, prop_id, pspec); break;
  }
}

static void gst_tree_metrics_finalize(GObject *object)
{
  GstTreeMetrics *self = GST_TREE_METRICS(object);
  delete self->state;
  self->state = nullptr;
  G_OBJECT_CLASS(gst_tree_metrics_parent_class)->finalize(object);
}

#define RW_PLAYING \
  GParamFlags(G_PARAM_READWRITE | G_PARAM_STATIC_STRINGS | GST_PARAM_MUTABLE_PLAYING)

static void gst_tree_metrics_class_init(GstTreeMetricsClass *klass)
{
  GObjectClass *gobject_class = G_OBJECT_CLASS(klass);
  GstElementClass *element_class = GST_ELEMENT_CLASS(klass);
  GstBaseTransformClass *bt_class = GST_BASE_TRANSFORM_CLASS(klass);

  GST_DEBUG_CATEGORY_INIT(treemetrics_debug, "treemetrics", 0, "treestereo treemetrics");

  gobject_class->set_property = gst_tree_metrics_set_property;
  gobject_class->get_property = gst_tree_metrics_get_property;
  gobject_class->finalize = gst_tree_metrics_finalize;

  g_object_class_install_property(
      gobject_class, PROP_BANDS,
      g_param_spec_int("bands", "Bands",
                       "Horizontal bands from the canopy's top to its bottom, each with its "
                       "left/right edge, width and nearest-face depth",
                       1, 64, DEFAULT_BANDS, RW_PLAYING));
  g_object_class_install_property(
      gobject_class, PROP_SMOOTHING,
      g_param_spec_double("smoothing", "Smoothing",
                          "Exponential smoothing across frames: smoothed = smoothing * previous "
                          "+ (1 - smoothing) * current; 0 = off. Raw figures are always kept.",
                          0.0, MAX_SMOOTHING, DEFAULT_SMOOTHING, RW_PLAYING));
  g_object_class_install_property(
      gobject_class, PROP_EXTENT_METHOD,
      g_param_spec_enum("extent-method", "Extent method",
                        "How the silhouette's angular extent becomes metres (height, width, "
                        "bands, area, perimeter)",
                        GST_TYPE_TREE_METRICS_EXTENT, int(MetricsParams{}.extent_depth),
                        RW_PLAYING));
  g_object_class_install_property(
      gobject_class, PROP_ROUND_LIMBS,
      g_param_spec_boolean("round-limbs", "Round limbs",
                           "tangent-points: add how far the canopy reaches beyond each limb point "
                           "(the limb is not the extreme unless the ray is straight ahead), from "
                           "the curvature the edge points show; false = the limb points' extent",
                           MetricsParams{}.round_limbs, RW_PLAYING));
  g_object_class_install_property(
      gobject_class, PROP_EXTREME_POINTS,
      g_param_spec_uint("extreme-points", "Extreme points",
                        "Each edge of height and width reaches at least as far as the n-th most "
                        "extreme canopy point in its direction (clusters behind the silhouette's "
                        "edge reach further in metres than it shows); 0 = the silhouette alone",
                        0, 10000, guint(MetricsParams{}.extreme_points), RW_PLAYING));
  g_object_class_install_property(
      gobject_class, PROP_POST_MESSAGES,
      g_param_spec_boolean("post-messages", "Post messages",
                           "Post a 'treemetrics' element message per buffer",
                           DEFAULT_POST_MESSAGES, RW_PLAYING));

  gst_element_class_add_static_pad_template(element_class, &sink_template);
  gst_element_class_add_static_pad_template(element_class, &src_template);
  gst_element_class_set_static_metadata(
      element_class, "Tree metrics", "Filter/Analyzer/Video",
      "Measures the tree canopy (distance, height, width, thickness, area, perimeter, "
      "complexity, centroid, height bands, confidence) from its silhouette (the 3D canopy's "
      "when decided) and 3D points",
      "treestereo developers");
  gst_type_mark_as_plugin_api(GST_TYPE_TREE_METRICS_EXTENT, GstPluginAPIFlags(0));

  bt_class->start = gst_tree_metrics_start;
  bt_class->sink_event = gst_tree_metrics_sink_event;
  bt_class->transform_ip = gst_tree_metrics_transform_ip;
}

static void gst_tree_metrics_init(GstTreeMetrics *self)
{
  self->state = new State();
  gst_base_transform_set_in_place(GST_BASE_TRANSFORM(self), TRUE);
  gst_base_transform_set_passthrough(GST_BASE_TRANSFORM(self), FALSE);
}
