/**
 * SECTION:element-stereodepth
 * @title: stereodepth
 *
 * Turns stereo correspondences into depth: Z = b·fx / (d - doffs) and the full 3D point
 * X = (xl - cx)·Z / fx, Y = (yl - cy)·Z / fy (what the geometry's Q matrix computes), in the
 * rectified-left camera frame (x right, y down, z forward), millimetres. The points are then
 * cleaned for the canopy: points nearer than #stereodepth:min-depth or farther than
 * #stereodepth:max-depth are dropped, then outliers of the remaining depths (|Z - median| >
 * #stereodepth:outlier-k · 1.4826 · MAD). Dropped points stay in the meta with valid=FALSE and
 * every drop is counted.
 *
 * - `mode=sparse` (default) triangulates the matches of siftmatch's #GstTreeStereoMatchesMeta.
 *   Missing matches meta: an error naming siftmatch. With #stereodepth:densify (default TRUE)
 *   the matches also seed a grid of the canopy: every #stereodepth:densify-step th pixel of the
 *   left vegetation mask is matched along its row by ZNCC within the disparities the matches
 *   span, and kept only on a clear, left-right consistent correlation peak (lib's
 *   densify_matches()). The grid points follow the matches' points in the points meta
 *   (#GstTreeStereoDepthStats.n_grid of them, match_index = the left-view pixel index
 *   y·width + x): an even sample of the visible canopy, which the canopy's distance and
 *   thickness (treemetrics) are statistics of, where SIFT's keypoints crowd on the front
 *   leaves. Densification maps the frame read-only; it needs side-by-side frames and exgsegment's
 *   #GstTreeStereoVegetationMeta, and without them (or with fewer than 10 matches, or no canopy)
 *   the points are the matches' alone (a warning, once, says which is missing). With
 *   densify=FALSE the pixels are not touched (not even mapped). Near the silhouette's extremes
 *   the grid is finer: the mask pixels within #stereodepth:edge-band (0.04) of the canopy box's
 *   height of its top and bottom rows, and of its width of its leftmost and rightmost columns,
 *   are sampled every #stereodepth:edge-step px (automatic: view width / 648, at least 2 px). The
 *   canopy's 3D extremes are there, often on clusters behind the silhouette's edge, and
 *   treemetrics' #treemetrics:extreme-points reads height and width from them.
 * - `mode=dense` runs OpenCV's StereoSGBM (3-way) on the canopy's bounding box of the left view
 *   (and the columns of the right view a match can come from), keeps the pixels of the
 *   vegetation mask, and attaches the depth map (GRAY16_LE, mm, 0 = unknown) to the points meta;
 *   the points are a grid of every #stereodepth:sample-step th canopy pixel, their match_index
 *   the left-view pixel index y·width + x. The frame must hold both views side by side. Without
 *   a vegetation meta the whole left view is matched, unmasked; when the vegetation meta says
 *   there is no canopy nothing is matched and the points meta is empty.
 *
 * With #stereodepth:canopy `tree` (default) or `row` (mode sparse, densify on) the canopy is
 * decided in 3D (lib's canopy_depth(): ground plane, near row, the tree in front along the
 * row; docs/elements/stereodepth.md) and a #GstTreeStereoCanopyMeta is attached; points off it
 * stay with valid=FALSE, counted in `dropped-zone`. With `tree`, a stream's first frame (and one
 * flagged DISCONT) also carries the near row's canopy in the meta's `row_view`, for the row
 * maps' part of the row behind the first tree in view. Without side-by-side frames or a vegetation
 * meta ONE warning says so for densification and the canopy alike; densify=FALSE leaves the
 * canopy off without a warning (a choice). Canopy settings that cannot run together (ground=rig
 * without camera-height, zone-far not beyond zone-near, max-height not above min-height) are a
 * GST_RESOURCE_ERROR_SETTINGS naming the properties.
 *
 * Both modes need stereorectify's #GstTreeStereoGeometryMeta (missing: an error naming
 * stereorectify). The element works in place and adds a #GstTreeStereoPointsMeta.
 *
 * ## Element message
 *
 * With #stereodepth:post-messages, an element message named `stereodepth` per buffer with the
 * same figures as the meta's #GstTreeStereoDepthStats:
 *
 * - `mode`: #gchararray, "sparse" or "dense"
 * - `points`: #guint, points computed (valid or not)
 * - `grid-points`: #guint, of those, the grid points of #stereodepth:densify
 * - `valid`: #guint, points kept
 * - `dropped-disparity`: #guint, points without a finite depth (disparity - doffs <= 0)
 * - `dropped-range`: #guint, dropped as outside [min-depth, max-depth]
 * - `dropped-outlier`: #guint, dropped by the median/MAD cut
 * - `median-depth`: #gdouble, median Z of the kept points, mm (0 when none)
 * - `mad-depth`: #gdouble, median absolute deviation of the kept Z, mm (unscaled)
 * - `p05-depth`, `p95-depth`: #gdouble, 5th and 95th percentile of the kept Z, mm
 * - `accept-min-depth`, `accept-max-depth`: #gdouble, the depth interval kept after the range
 *   and outlier cuts, mm (0 when nothing is kept)
 * - `dropped-zone`: #guint, points off the 3D canopy (another tree, the next row, the ground)
 * - with the canopy decided in 3D: `canopy-present` (#gboolean), `canopy-mode` ("tree"/"row"),
 *   `canopy-near`, `canopy-far` (#gdouble, m, the depth zone used), `ground-found`
 *   (#gboolean), `segments` (#guint, near-row segments along the row), `canopy-points` (#guint)
 * - `timestamp`, `stream-time`, `running-time`: #guint64, ns, of the buffer
 *
 * ## Example launch line
 * |[
 * gst-launch-1.0 -m stereorectify name=r calibration=rig.yml ! exgsegment ! siftmatch ! \
 *   stereodepth max-depth=6000 ! treemetrics ! fakesink \
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

#include "treestereo/canopy.hpp"
#include "treestereo/densify.hpp"
#include "treestereo/depth.hpp"

#include <gst/base/gstbasetransform.h>

#include <cmath>
#include <mutex>
#include <string>
#include <vector>

GST_DEBUG_CATEGORY_STATIC(stereodepth_debug);
#define GST_CAT_DEFAULT stereodepth_debug

using namespace treestereo;
using namespace treestereo::gst;

typedef enum {
  GST_STEREO_DEPTH_MODE_SPARSE = 0,
  GST_STEREO_DEPTH_MODE_DENSE = 1,
} GstStereoDepthMode;

#define GST_TYPE_STEREO_DEPTH_MODE (gst_stereo_depth_mode_get_type())
static GType gst_stereo_depth_mode_get_type(void)
{
  static GType type = 0;
  static const GEnumValue values[] = {
      {GST_STEREO_DEPTH_MODE_SPARSE, "Triangulate siftmatch's matches", "sparse"},
      {GST_STEREO_DEPTH_MODE_DENSE, "Semi-global block matching on the canopy's box", "dense"},
      {0, nullptr, nullptr},
  };
  if (g_once_init_enter(&type)) {
    GType t = g_enum_register_static("GstStereoDepthMode", values);
    g_once_init_leave(&type, t);
  }
  return type;
}

typedef enum {
  GST_STEREO_DEPTH_CANOPY_OFF = 0,
  GST_STEREO_DEPTH_CANOPY_TREE = 1,
  GST_STEREO_DEPTH_CANOPY_ROW = 2,
} GstStereoDepthCanopy;

#define GST_TYPE_STEREO_DEPTH_CANOPY (gst_stereo_depth_canopy_get_type())
static GType gst_stereo_depth_canopy_get_type(void)
{
  static GType type = 0;
  static const GEnumValue values[] = {
      {GST_STEREO_DEPTH_CANOPY_OFF, "The colour mask is the canopy (a lab, one tree)", "off"},
      {GST_STEREO_DEPTH_CANOPY_TREE, "The tree in front, decided in 3D", "tree"},
      {GST_STEREO_DEPTH_CANOPY_ROW, "The near row's canopy in view (hedgerows, fruit walls)",
       "row"},
      {0, nullptr, nullptr},
  };
  if (g_once_init_enter(&type)) {
    GType t = g_enum_register_static("GstStereoDepthCanopy", values);
    g_once_init_leave(&type, t);
  }
  return type;
}

#define GST_TYPE_STEREO_DEPTH_GROUND (gst_stereo_depth_ground_get_type())
static GType gst_stereo_depth_ground_get_type(void)
{
  static GType type = 0;
  static const GEnumValue values[] = {
      {int(GroundModel::Off), "No ground plane", "off"},
      {int(GroundModel::Fit), "A plane fitted to the vegetation's points (grass)", "fit"},
      {int(GroundModel::Rig), "The plane camera-height below the rig, pitched by camera-pitch",
       "rig"},
      {0, nullptr, nullptr},
  };
  if (g_once_init_enter(&type)) {
    GType t = g_enum_register_static("GstStereoDepthGround", values);
    g_once_init_leave(&type, t);
  }
  return type;
}

#define DEFAULT_MODE GST_STEREO_DEPTH_MODE_SPARSE
#define DEFAULT_CANOPY GST_STEREO_DEPTH_CANOPY_TREE
#define DEFAULT_DENSIFY TRUE
#define DEFAULT_POST_MESSAGES TRUE

namespace {

struct Settings {
  GstStereoDepthMode mode = DEFAULT_MODE;
  DenseParams dense; // dense.filter is the depth cleaning of both modes
  bool densify = DEFAULT_DENSIFY;
  DensifyParams grid;
  GstStereoDepthCanopy canopy = DEFAULT_CANOPY;
  CanopyParams zone;
  bool post_messages = DEFAULT_POST_MESSAGES;
};

struct State {
  std::mutex lock; // guards settings
  Settings settings;
  // streaming thread only
  GstVideoInfo info;
  bool info_set = false;
  bool warned_no_densify = false; // the reason densification is skipped was said once
  GroundTracker ground;           // ground=fit: the ground of the frames before
  bool first_frame = true;        // canopy=tree: the next frame also gets the row view
};

/* What one buffer gives: the points, their figures and (dense) the depth map. */
struct Output {
  std::vector<GstTreeStereoPoint> points;
  GstTreeStereoDepthStats stats{};
  GstBuffer *depth_map = nullptr; // owned until attached
  cv::Rect box;
  bool has_canopy = false;        // the 3D canopy was decided
  CanopyResult canopy;
  Silhouette row;                 // canopy=tree, a stream's first frame: the near row's canopy
};

} // namespace

struct GstStereoDepth {
  GstBaseTransform parent;
  State *state;
};

struct GstStereoDepthClass {
  GstBaseTransformClass parent_class;
};

#define GST_TYPE_STEREO_DEPTH (gst_stereo_depth_get_type())
#define GST_STEREO_DEPTH(obj) \
  (G_TYPE_CHECK_INSTANCE_CAST((obj), GST_TYPE_STEREO_DEPTH, GstStereoDepth))
G_DEFINE_TYPE(GstStereoDepth, gst_stereo_depth, GST_TYPE_BASE_TRANSFORM);
GST_ELEMENT_REGISTER_DEFINE(stereodepth, "stereodepth", GST_RANK_NONE, GST_TYPE_STEREO_DEPTH);

#define CAPS GST_VIDEO_CAPS_MAKE(TREESTEREO_VIDEO_FORMATS)

/* Says once why densify=TRUE does nothing on this stream. The same causes stop the 3D canopy
 * (canopy_depth_of() leaves them to this one warning), so with canopy on it says both. */
static void warn_no_densify(GstStereoDepth *self, const Settings &s, const char *why)
{
  if (self->state->warned_no_densify)
    return;
  self->state->warned_no_densify = true;
  if (s.canopy != GST_STEREO_DEPTH_CANOPY_OFF)
    GST_ELEMENT_WARNING(self, STREAM, FAILED,
                        ("densify and canopy: %s; the points are the matches' alone and the "
                         "colour mask is taken as the canopy.",
                         why),
                        (nullptr));
  else
    GST_ELEMENT_WARNING(self, STREAM, FAILED,
                        ("densify: %s; the points are the matches' alone.", why), (nullptr));
}

/* The grid matches of densify (empty when it cannot run on this buffer). */
static std::vector<StereoMatch> grid_matches(GstStereoDepth *self, GstBuffer *buf,
                                             const std::vector<StereoMatch> &seeds,
                                             const Settings &s)
{
  State *st = self->state;
  if (!st->info_set || treestereo::gst::n_views_of(&st->info) != 2) {
    warn_no_densify(self, s, "the frames are not side-by-side stereo pairs");
    return {};
  }
  const GstTreeStereoVegetationMeta *veg = gst_buffer_get_tree_stereo_vegetation_meta(buf);
  if (!veg || veg->n_views < 1) {
    warn_no_densify(self, s, "no vegetation meta on the buffer (put exgsegment upstream)");
    return {};
  }
  const GstTreeStereoVegetationView *lv = &veg->views[LEFT];
  if (!lv->present || int(seeds.size()) < s.grid.min_seeds)
    return {}; // no canopy, or too few matches to bound the search: nothing to densify
  treestereo::gst::MappedSilhouette sil(lv);
  if (sil.get().mask.empty()) {
    warn_no_densify(self, s, "the vegetation meta carries no mask");
    return {};
  }
  treestereo::gst::MappedFrame frame(&st->info, buf, GST_MAP_READ);
  if (!frame.ok())
    throw BadInput("could not map the frame for densification: it is smaller than its caps say");
  const cv::Mat mat = frame.mat();
  DensifyParams p = s.grid;
  p.order = treestereo::gst::pixel_layout(GST_VIDEO_INFO_FORMAT(&st->info)).order();
  return densify_matches(treestereo::gst::view_mat(mat, LEFT, 2),
                         treestereo::gst::view_mat(mat, RIGHT, 2), sil.get().mask, seeds, p);
}

/* The 3D canopy and its points (false when it cannot run on this buffer: then the colour mask
 * stands for the canopy, as with canopy=off). */
static bool canopy_depth_of(GstStereoDepth *self, GstBuffer *buf,
                            const std::vector<StereoMatch> &seeds, const StereoGeometry &g,
                            const Settings &s, Output &out)
{
  State *st = self->state;
  /* densify=false is a choice (documented: the canopy needs densify); the other causes stop
   * densification too, and grid_matches() says them once for both. */
  if (!s.densify)
    return false;
  if (!st->info_set || treestereo::gst::n_views_of(&st->info) != 2)
    return false;
  const GstTreeStereoVegetationMeta *veg = gst_buffer_get_tree_stereo_vegetation_meta(buf);
  if (!veg || veg->n_views < 1)
    return false;
  const GstTreeStereoVegetationView *lv = &veg->views[LEFT];
  treestereo::gst::MappedSilhouette sil(lv);
  if (lv->present && sil.get().mask.empty())
    return false;
  CanopyDepthParams p;
  p.canopy = s.zone;
  p.canopy.mode = s.canopy == GST_STEREO_DEPTH_CANOPY_ROW ? CanopyMode::Row : CanopyMode::Tree;
  p.grid = s.grid;
  p.filter = s.dense.filter;
  out.has_canopy = true;
  if (!lv->present) { // no vegetation: no canopy, said so
    out.canopy = CanopyResult();
    out.canopy.silhouette.mask = cv::Mat::zeros(g.view_size, CV_8U);
    DepthResult r = triangulate_matches(seeds, g, s.dense.filter);
    out.points = treestereo::gst::to_gst_points(r.points);
    treestereo::gst::depth_stats_to_gst(r.stats, &out.stats);
    return true;
  }
  treestereo::gst::MappedFrame frame(&st->info, buf, GST_MAP_READ);
  if (!frame.ok())
    throw BadInput("could not map the frame for the 3D canopy: it is smaller than its caps say");
  const cv::Mat mat = frame.mat();
  p.grid.order = treestereo::gst::pixel_layout(GST_VIDEO_INFO_FORMAT(&st->info)).order();
  // A break in the stream (a camera lost and back) may have moved the rig: no prior then.
  if (GST_BUFFER_FLAG_IS_SET(buf, GST_BUFFER_FLAG_DISCONT)) {
    st->ground.reset();
    st->first_frame = true;
  }
  p.canopy.ground_prior = st->ground.prior();
  // The part of the row behind the first tree in view is no later frame's tree: the first
  // frame's row view is all the row map gets of it.
  p.row_view = st->first_frame && p.canopy.mode == CanopyMode::Tree;
  st->first_frame = false;
  const gint64 t0 = g_get_monotonic_time();
  CanopyDepth c = canopy_depth(treestereo::gst::view_mat(mat, LEFT, 2),
                               treestereo::gst::view_mat(mat, RIGHT, 2), sil.get(), seeds, g, p);
  for (std::size_t i = c.n_seeds; i < c.depth.points.size(); i++) {
    const StereoMatch &m = c.matches[i];
    c.depth.points[i].match_index =
        std::uint32_t(std::lround(m.yl)) * std::uint32_t(g.view_size.width) +
        std::uint32_t(std::lround(m.xl));
  }
  out.points = treestereo::gst::to_gst_points(c.depth.points);
  treestereo::gst::depth_stats_to_gst(c.depth.stats, &out.stats);
  out.stats.n_grid = guint(c.matches.size() - c.n_seeds);
  const CanopyResult &cr = c.canopy;
  out.row = std::move(c.row);
  st->ground.update(cr.ground);
  GST_DEBUG_OBJECT(self,
                   "canopy %s: zone %.0f-%.0f mm, ground %s%s (n %.3f %.3f %.3f, d %.0f mm, %zu "
                   "inliers), %d segments, x %.0f..%.0f mm, %zu canopy points, %zu coarse, %zu "
                   "seam px, %.1f ms",
                   cr.present ? "present" : "absent", cr.near_mm, cr.far_mm,
                   cr.ground.found ? "found" : "none", cr.ground.held ? " (held)" : "", cr.ground.normal[0], cr.ground.normal[1],
                   cr.ground.normal[2], cr.ground.d, cr.ground.inliers, cr.n_segments, cr.left_mm,
                   cr.right_mm, cr.n_canopy_points, c.coarse, cr.n_seam_pixels,
                   (g_get_monotonic_time() - t0) / 1000.0);
  out.canopy = std::move(c.canopy);
  return true;
}

/* The canopy settings checked as a whole (each property alone is in range): "" when they can
 * run, else a sentence naming the properties and what to set. */
static std::string canopy_settings_problem(const Settings &s)
{
  const CanopyParams &z = s.zone;
  if (z.ground == GroundModel::Rig && !(z.camera_height_mm > 0))
    return "stereodepth ground=rig needs camera-height: set camera-height to the left camera's "
           "optical centre above the ground (mm), or use ground=fit.";
  if (z.far_mm != 0 && z.far_mm <= z.near_mm)
    return "stereodepth zone-far (" + std::to_string(std::lround(z.far_mm)) +
           " mm) must be beyond zone-near (" + std::to_string(std::lround(z.near_mm)) +
           " mm), or 0 for no far limit.";
  if (z.max_height_mm != 0 && z.max_height_mm <= z.min_height_mm)
    return "stereodepth max-height (" + std::to_string(std::lround(z.max_height_mm)) +
           " mm) must be above min-height (" + std::to_string(std::lround(z.min_height_mm)) +
           " mm), or 0 for no upper limit.";
  try {
    validate(z);
  } catch (const std::exception &e) {
    return std::string("stereodepth: invalid canopy settings: ") + e.what();
  }
  return "";
}

static void sparse_depth(GstStereoDepth *self, GstBuffer *buf, const GstTreeStereoMatchesMeta *mm,
                         const StereoGeometry &g, const Settings &s, Output &out)
{
  std::vector<StereoMatch> matches = treestereo::gst::matches_from_meta(mm);
  if (s.canopy != GST_STEREO_DEPTH_CANOPY_OFF && canopy_depth_of(self, buf, matches, g, s, out))
    return;
  const std::vector<StereoMatch> grid =
      s.densify ? grid_matches(self, buf, matches, s) : std::vector<StereoMatch>();
  matches.insert(matches.end(), grid.begin(), grid.end());
  DepthResult r = triangulate_matches(matches, g, s.dense.filter);
  for (std::size_t i = mm->n_matches; i < r.points.size(); i++) {
    const StereoMatch &m = matches[i];
    r.points[i].match_index = std::uint32_t(std::lround(m.yl)) * std::uint32_t(g.view_size.width) +
                              std::uint32_t(std::lround(m.xl));
  }
  out.points = treestereo::gst::to_gst_points(r.points);
  treestereo::gst::depth_stats_to_gst(r.stats, &out.stats);
  out.stats.n_grid = guint(grid.size());
}

/* The depth map as a GRAY16_LE buffer, rows of width * 2 bytes. */
static GstBuffer *depth_map_buffer(const cv::Mat &depth)
{
  const gsize stride = gsize(depth.cols) * 2;
  GstBuffer *buf = gst_buffer_new_allocate(nullptr, stride * gsize(depth.rows), nullptr);
  GstMapInfo map;
  if (!gst_buffer_map(buf, &map, GST_MAP_WRITE)) {
    gst_buffer_unref(buf);
    throw std::runtime_error("could not map a new depth map buffer");
  }
  for (int y = 0; y < depth.rows; y++) {
    const std::uint16_t *src = depth.ptr<std::uint16_t>(y);
    guint16 *dst = reinterpret_cast<guint16 *>(map.data + stride * gsize(y));
    for (int x = 0; x < depth.cols; x++)
      dst[x] = GUINT16_TO_LE(src[x]);
  }
  gst_buffer_unmap(buf, &map);
  return buf;
}

static void dense(GstStereoDepth *self, GstBuffer *buf, const StereoGeometry &g,
                  const Settings &s, Output &out)
{
  State *st = self->state;
  if (!st->info_set)
    throw BadInput("stereodepth mode=dense got a buffer before its caps: the element upstream "
                   "must send caps first.",
                   "mode=dense: no caps negotiated before the first buffer");
  if (treestereo::gst::n_views_of(&st->info) != 2)
    throw BadInput("stereodepth mode=dense needs side-by-side stereo frames "
                   "(multiview-mode=side-by-side, as stereorectify produces): put stereorectify "
                   "upstream, or use mode=sparse.",
                   "mode=dense on a stream with one view per frame");
  cv::Rect box(cv::Point(0, 0), g.view_size);
  const GstTreeStereoVegetationMeta *veg = gst_buffer_get_tree_stereo_vegetation_meta(buf);
  const GstTreeStereoVegetationView *lv = veg ? &veg->views[LEFT] : nullptr;
  if (lv && !lv->present)
    return; // segmentation found no canopy: nothing to match, an empty points meta
  if (lv)
    box = cv::Rect(lv->bbox_x, lv->bbox_y, lv->bbox_width, lv->bbox_height);
  treestereo::gst::MappedSilhouette sil(lv); // no vegetation meta: no mask
  treestereo::gst::MappedFrame frame(&st->info, buf, GST_MAP_READ);
  if (!frame.ok())
    throw BadInput("could not map the frame for dense matching: it is smaller than its caps say");
  const treestereo::gst::PixelLayout layout =
      treestereo::gst::pixel_layout(GST_VIDEO_INFO_FORMAT(&st->info));
  const cv::Mat mat = frame.mat();
  const cv::Mat left = treestereo::gst::gray_view(treestereo::gst::view_mat(mat, LEFT, 2), layout);
  const cv::Mat right =
      treestereo::gst::gray_view(treestereo::gst::view_mat(mat, RIGHT, 2), layout);
  const DenseResult r = dense_depth(left, right, sil.get().mask, box, g, s.dense);
  out.points = treestereo::gst::to_gst_points(r.points);
  treestereo::gst::depth_stats_to_gst(r.stats, &out.stats);
  out.box = r.box;
  if (!r.depth_mm.empty())
    out.depth_map = depth_map_buffer(r.depth_mm);
}

static gboolean gst_stereo_depth_set_caps(GstBaseTransform *trans, GstCaps *incaps,
                                          GstCaps *outcaps)
{
  GstStereoDepth *self = GST_STEREO_DEPTH(trans);
  if (!gst_video_info_from_caps(&self->state->info, incaps)) {
    post_caps_error(GST_ELEMENT(self),
                    "stereodepth cannot read its caps as raw video: check the caps of the "
                    "elements before it.",
                    incaps, "invalid caps");
    return FALSE;
  }
  self->state->info_set = true;
  self->state->ground.reset(); // a new stream
  self->state->first_frame = true;
  return TRUE;
}

static void attach_and_post(GstStereoDepth *self, GstBuffer *buf, const Settings &s, Output &out)
{
  GstTreeStereoPointsMeta *pm = gst_buffer_add_tree_stereo_points_meta(
      buf, out.points.empty() ? nullptr : out.points.data(), guint(out.points.size()),
      &out.stats);
  pm->dense = s.mode == GST_STEREO_DEPTH_MODE_DENSE;
  if (out.depth_map) {
    gst_tree_stereo_points_meta_set_depth_map(pm, out.depth_map, out.box.x, out.box.y,
                                              guint(out.box.width), guint(out.box.height),
                                              guint(out.box.width) * 2);
    gst_clear_buffer(&out.depth_map);
  }
  const GstTreeStereoCanopyMeta *cm =
      out.has_canopy ? treestereo::gst::add_canopy_meta(
                           buf, out.canopy,
                           s.canopy == GST_STEREO_DEPTH_CANOPY_ROW ? CanopyMode::Row
                                                                   : CanopyMode::Tree,
                           &out.row)
                     : nullptr;
  GST_LOG_OBJECT(self, "%u points, %u valid, median %.1f mm", out.stats.n_points,
                 out.stats.n_valid, out.stats.median_z_mm);
  if (!s.post_messages)
    return;
  GstTreeStereoTimes times;
  gst_tree_stereo_times_from_buffer(&times, buf, &GST_BASE_TRANSFORM(self)->segment);
  GstStructure *msg = gst_tree_stereo_depth_message_structure(pm->dense, &pm->stats, &times);
  if (cm)
    gst_tree_stereo_canopy_message_add(msg, cm);
  treestereo::gst::post_element_message(GST_ELEMENT(self), msg);
}

static GstFlowReturn gst_stereo_depth_transform_ip(GstBaseTransform *trans, GstBuffer *buf)
{
  GstStereoDepth *self = GST_STEREO_DEPTH(trans);
  const Settings s = settings_snapshot(self);
  const GstTreeStereoGeometryMeta *gm = gst_buffer_get_tree_stereo_geometry_meta(buf);
  if (!gm) {
    treestereo::gst::post_missing_meta(GST_ELEMENT(self), GST_MESSAGE_ERROR, buf,
                                       treestereo::gst::kGeometryMeta);
    return GST_FLOW_ERROR;
  }
  const GstTreeStereoMatchesMeta *mm = gst_buffer_get_tree_stereo_matches_meta(buf);
  if (s.mode == GST_STEREO_DEPTH_MODE_SPARSE && !mm) {
    treestereo::gst::post_missing_meta(GST_ELEMENT(self), GST_MESSAGE_ERROR, buf,
                                       treestereo::gst::kMatchesMeta, "stereodepth mode=sparse",
                                       " (or use mode=dense).");
    return GST_FLOW_ERROR;
  }
  if (s.mode == GST_STEREO_DEPTH_MODE_SPARSE && s.densify &&
      s.canopy != GST_STEREO_DEPTH_CANOPY_OFF) {
    const std::string problem = canopy_settings_problem(s);
    if (!problem.empty()) {
      GST_ELEMENT_ERROR(self, RESOURCE, SETTINGS, ("%s", problem.c_str()),
                        ("canopy settings: ground %s, camera-height %g mm, zone %g..%g mm, "
                         "height %g..%g mm",
                         ground_model_name(s.zone.ground), s.zone.camera_height_mm,
                         s.zone.near_mm, s.zone.far_mm, s.zone.min_height_mm,
                         s.zone.max_height_mm));
      return GST_FLOW_ERROR;
    }
  }
  Output out;
  const bool ok = treestereo::gst::guarded(GST_ELEMENT(self), false, [&] {
    const StereoGeometry g = treestereo::gst::geometry_from_meta(gm);
    if (s.mode == GST_STEREO_DEPTH_MODE_SPARSE)
      sparse_depth(self, buf, mm, g, s, out);
    else
      dense(self, buf, g, s, out);
    return true;
  });
  if (!ok) {
    gst_clear_buffer(&out.depth_map);
    return GST_FLOW_ERROR;
  }
  attach_and_post(self, buf, s, out);
  return GST_FLOW_OK;
}

static void gst_stereo_depth_class_init(GstStereoDepthClass *klass)
{
  GObjectClass *gobject_class = G_OBJECT_CLASS(klass);
  GstElementClass *element_class = GST_ELEMENT_CLASS(klass);
  GstBaseTransformClass *bt_class = GST_BASE_TRANSFORM_CLASS(klass);
  const DenseParams d;

  GST_DEBUG_CATEGORY_INIT(stereodepth_debug, "stereodepth", 0, "treestereo stereodepth");

  gobject_class->finalize = finalize_state<GstStereoDepth, &gst_stereo_depth_parent_class>;

  auto props = PropertyTable<Settings>::in_state<GstStereoDepth>(gobject_class);
  props.enumeration("mode", "Mode",
                    "sparse: triangulate siftmatch's matches; dense: StereoSGBM on the "
                    "canopy's box with a GRAY16_LE depth map",
                    GST_TYPE_STEREO_DEPTH_MODE, DEFAULT_MODE, TS_FIELD(mode));
  props.real("min-depth", "Minimum depth",
             "Points nearer than this (mm) are dropped; dense: also bounds the "
             "disparity search",
             1.0, 1e6, d.filter.min_depth_mm, TS_FIELD(dense.filter.min_depth_mm));
  props.real("max-depth", "Maximum depth",
             "Points farther than this (mm) are dropped; must exceed min-depth", 1.0, 1e6,
             d.filter.max_depth_mm, TS_FIELD(dense.filter.max_depth_mm));
  props.real("outlier-k", "Outlier cut",
             "Drop points with |Z - median| > k * 1.4826 * MAD of the canopy's "
             "depths; 0 = off (3.5: Iglewicz and Hoaglin's cut)",
             0.0, 100.0, d.filter.outlier_k, TS_FIELD(dense.filter.outlier_k));
  props.integer("min-disparity", "Minimum disparity",
                "dense: smallest disparity searched (px) when num-disparities is set", -4096, 4096,
                d.min_disparity, TS_FIELD(dense.min_disparity));
  props.integer("num-disparities", "Number of disparities",
                "dense: disparities searched, a multiple of 16; 0 = the smallest window that "
                "covers [min-depth, max-depth]",
                0, 4096, d.num_disparities, TS_FIELD(dense.num_disparities));
  props.integer("block-size", "Block size", "dense: SGBM's matched block size (odd, px)", 1, 51,
                d.block_size, TS_FIELD(dense.block_size));
  props.integer("p1", "P1",
                "dense: SGBM's penalty of a disparity change by 1; 0 = 8 * block-size^2", 0,
                G_MAXINT, d.p1, TS_FIELD(dense.p1));
  props.integer("p2", "P2",
                "dense: SGBM's penalty of larger disparity changes (> p1); 0 = 32 * block-size^2",
                0, G_MAXINT, d.p2, TS_FIELD(dense.p2));
  props.integer("uniqueness-ratio", "Uniqueness ratio",
                "dense: margin (%) by which the best cost must beat the second best", 0, 100,
                d.uniqueness_ratio, TS_FIELD(dense.uniqueness_ratio));
  props.integer("speckle-window-size", "Speckle window size",
                "dense: largest disparity blob (px) removed as a speckle; 0 = no speckle filter", 0,
                100000, d.speckle_window, TS_FIELD(dense.speckle_window));
  props.integer("speckle-range", "Speckle range",
                "dense: largest disparity variation (px) within a connected component", 0, 1000,
                d.speckle_range, TS_FIELD(dense.speckle_range));
  props.integer("sample-step", "Sample step",
                "dense: a 3D point from every n-th canopy pixel in x and in y", 1, 1024,
                d.sample_step, TS_FIELD(dense.sample_step));
  props.boolean("post-messages", "Post messages", "Post a 'stereodepth' element message per buffer",
                DEFAULT_POST_MESSAGES, TS_FIELD(post_messages));
  props.boolean("densify", "Densify",
                "sparse: also match a grid of the canopy's pixels by ZNCC, seeded by "
                "the matches (an even sample of the canopy for its distance and "
                "thickness); needs side-by-side frames and a vegetation meta",
                DEFAULT_DENSIFY, TS_FIELD(densify));
  const DensifyParams dg;
  props.integer("densify-step", "Densify step",
                "sparse with densify: grid step in px; 0 = automatic, about 4000 grid points on "
                "the canopy",
                0, 1024, dg.step, TS_FIELD(grid.step));
  props.real("edge-band", "Edge band",
             "sparse with densify: also sample the mask every edge-step px within "
             "this fraction of the canopy box's height (width) of its top and "
             "bottom rows (left and right columns), where the canopy's 3D extremes "
             "are (treemetrics:extreme-points); 0 = off",
             0.0, 0.5, dg.edge_band, TS_FIELD(grid.edge_band));
  props.integer("edge-step", "Edge step",
                "sparse with densify: the edge bands' grid step in px; 0 = automatic, the view's "
                "width / 648 and at least 2 (2 px at 1296 wide, 4 at 2592)",
                0, 1024, dg.edge_step, TS_FIELD(grid.edge_step));
  const CanopyParams cz;
  props.enumeration("canopy", "Canopy",
                    "sparse with densify: which vegetation is the canopy, decided in 3D: "
                    "tree (the tree in front), row (the near row in view), off (all the "
                    "colour mask)",
                    GST_TYPE_STEREO_DEPTH_CANOPY, DEFAULT_CANOPY, TS_FIELD(canopy));
  props.real("zone-near", "Spray zone near",
             "The spray zone's near depth (mm); zone-near and zone-far both 0: the "
             "near row is found from the data (the nearest dominant depth layer)",
             0.0, 1e6, cz.near_mm, TS_FIELD(zone.near_mm));
  props.real("zone-far", "Spray zone far",
             "The spray zone's far depth (mm); 0 with zone-near set: no far limit", 0.0, 1e6,
             cz.far_mm, TS_FIELD(zone.far_mm));
  props.real("min-height", "Minimum height",
             "Canopy starts this high above the ground (mm): lower vegetation is "
             "grass (needs a ground plane)",
             -1e5, 1e5, cz.min_height_mm, TS_FIELD(zone.min_height_mm));
  props.real("max-height", "Maximum height",
             "Canopy ends this high above the ground (mm); 0 = no limit", 0.0, 1e5,
             cz.max_height_mm, TS_FIELD(zone.max_height_mm));
  props.enumeration("ground", "Ground",
                    "The ground plane: fit (to the vegetation's points), rig (camera-height "
                    "and camera-pitch), off",
                    GST_TYPE_STEREO_DEPTH_GROUND, int(cz.ground), TS_FIELD(zone.ground));
  props.real("camera-height", "Camera height",
             "ground=rig: the left camera's optical centre above the ground (mm)", 0.0, 1e5,
             cz.camera_height_mm, TS_FIELD(zone.camera_height_mm));
  props.real("camera-pitch", "Camera pitch",
             "ground=rig: the camera's pitch (degrees, positive = looking down)", -80.0, 80.0,
             cz.camera_pitch_deg, TS_FIELD(zone.camera_pitch_deg));

  add_filter_pad_templates(element_class, CAPS);
  gst_element_class_set_static_metadata(
      element_class, "Stereo depth", "Filter/Analyzer/Video",
      "3D points (mm, rectified-left frame) from stereo matches or dense SGBM, cleaned by a "
      "depth range and a median/MAD outlier cut",
      "treestereo developers");
  gst_type_mark_as_plugin_api(GST_TYPE_STEREO_DEPTH_MODE, GstPluginAPIFlags(0));
  gst_type_mark_as_plugin_api(GST_TYPE_STEREO_DEPTH_CANOPY, GstPluginAPIFlags(0));
  gst_type_mark_as_plugin_api(GST_TYPE_STEREO_DEPTH_GROUND, GstPluginAPIFlags(0));

  bt_class->set_caps = gst_stereo_depth_set_caps;
  bt_class->transform_ip = gst_stereo_depth_transform_ip;
}

static void gst_stereo_depth_init(GstStereoDepth *self)
{
  self->state = new State();
  gst_base_transform_set_in_place(GST_BASE_TRANSFORM(self), TRUE);
  gst_base_transform_set_passthrough(GST_BASE_TRANSFORM(self), FALSE);
}
