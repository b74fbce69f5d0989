/**
 * SECTION:element-treeoverlay
 * @title: treeoverlay
 *
 * Draws what the treestereo metas say onto the video, for a person to watch or to record: the
 * canopy contour and bounding box of each view (#GstTreeStereoVegetationMeta), the stereo
 * matches as dots or lines coloured by their depth (#GstTreeStereoMatchesMeta, depths from the
 * #GstTreeStereoPointsMeta: near red, through magenta, to far blue; grey = no valid depth), the
 * band profile of #GstTreeStereoMetricsMeta placed with the #GstTreeStereoGeometryMeta, and a
 * text panel with distance, height, width and thickness (smoothed values in brackets when they
 * read differently, "&gt;=" before an extent that touches the image border, "no tree" when the
 * tree is absent) and the legend of the depth colours.
 *
 * When stereodepth decided the canopy in 3D (#GstTreeStereoCanopyMeta), its silhouette is the
 * canopy drawn in the left view (contour and box), and the vegetation colour found that is not
 * canopy (the grass, the next row, the neighbours) is tinted a neutral grey-blue, so a person
 * sees what depth rejected (switched with #treeoverlay:draw-contour). The text panel also shows
 * the confidence of the figures ("conf 0.93": the share of the silhouette with depth support).
 *
 * Each layer can be switched off. A missing meta only leaves its layer out: a frame without
 * any treestereo meta passes through unchanged (no "no tree" panel: nothing measured it).
 *
 * With #treeoverlay:views=both the whole (side-by-side) frame is drawn on in place. With
 * views=left a side-by-side input gives a W x H output holding the left view alone (caps
 * without multiview-mode): the left half is copied and drawn on; mono input is drawn on in
 * place either way. The treestereo metas go along; the geometry meta is marked as no longer
 * side by side.
 *
 * ## Example launch lines
 * |[
 * gst-launch-1.0 -e videotestsrc num-buffers=30 ! video/x-raw,format=RGB,width=640,height=240 ! \
 *   capssetter caps="video/x-raw,multiview-mode=side-by-side" ! treeoverlay ! videoconvert ! \
 *   video/x-raw,format=I420 ! x264enc bframes=0 ! mp4mux fragment-duration=1000 ! \
 *   filesink location=out.mp4 buffer-mode=unbuffered o-sync=true
 * ]|
 * |[
 * gst-launch-1.0 stereorectify name=r calibration=rig.yml ! exgsegment ! siftmatch ! \
 *   stereodepth ! treemetrics ! treeoverlay views=left match-style=lines ! videoconvert ! \
 *   autovideosink   treetestsrc view=left ! r.left   treetestsrc view=right ! r.right
 * ]|
 */
#ifdef HAVE_CONFIG_H
#include "config.h"
#endif

#include "common.hpp"
#include "elements.hpp"
#include "properties.hpp"

#include "treestereo/overlay.hpp"
#include "treestereo/rowmap.hpp"

#include <gst/video/gstvideofilter.h>

#include <cmath>
#include <memory>
#include <mutex>

GST_DEBUG_CATEGORY_STATIC(treeoverlay_debug);
#define GST_CAT_DEFAULT treeoverlay_debug

using namespace treestereo;
using namespace treestereo::gst;

typedef enum {
  GST_TREE_OVERLAY_VIEWS_BOTH = 0,
  GST_TREE_OVERLAY_VIEWS_LEFT = 1,
} GstTreeOverlayViews;

typedef enum {
  GST_TREE_OVERLAY_MATCH_DOTS = 0,
  GST_TREE_OVERLAY_MATCH_LINES = 1,
} GstTreeOverlayMatchStyle;

#define DEFAULT_VIEWS GST_TREE_OVERLAY_VIEWS_BOTH
#define DEFAULT_MATCH_STYLE GST_TREE_OVERLAY_MATCH_DOTS

static GType gst_tree_overlay_views_get_type(void)
{
  static GType type = 0;
  static const GEnumValue values[] = {
      {GST_TREE_OVERLAY_VIEWS_BOTH, "Every view the frame holds (side by side stays so)", "both"},
      {GST_TREE_OVERLAY_VIEWS_LEFT, "The left view alone (W x H output)", "left"},
      {0, nullptr, nullptr},
  };
  if (g_once_init_enter(&type))
    g_once_init_leave(&type, g_enum_register_static("GstTreeOverlayViews", values));
  return type;
}

static GType gst_tree_overlay_match_style_get_type(void)
{
  static GType type = 0;
  static const GEnumValue values[] = {
      {GST_TREE_OVERLAY_MATCH_DOTS, "A dot per match in each view", "dots"},
      {GST_TREE_OVERLAY_MATCH_LINES,
       "A line from the left to the right point (the disparity vector on one view)", "lines"},
      {0, nullptr, nullptr},
  };
  if (g_once_init_enter(&type))
    g_once_init_leave(&type, g_enum_register_static("GstTreeOverlayMatchStyle", values));
  return type;
}

namespace {

struct Settings {
  GstTreeOverlayViews views = DEFAULT_VIEWS;
  OverlayStyle style;
  bool draw_map = false;
};

struct State {
  std::mutex lock; // guards settings
  Settings settings;

  // streaming thread only, set in set_info
  int in_views = 1;
  bool crop = false; // views=left on a side-by-side input: copy the left half
  ChannelOrder order;
  // draw-map: the row map built from the frames seen (as treemetrics' and spraycontrol's), the
  // last ground plane found
  std::unique_ptr<RowMap> map;
  GroundPlane ground;
};

} // namespace

struct GstTreeOverlay {
  GstVideoFilter parent;
  State *state;
};

struct GstTreeOverlayClass {
  GstVideoFilterClass parent_class;
};

#define GST_TYPE_TREE_OVERLAY (gst_tree_overlay_get_type())
#define GST_TREE_OVERLAY(obj) \
  (G_TYPE_CHECK_INSTANCE_CAST((obj), GST_TYPE_TREE_OVERLAY, GstTreeOverlay))
G_DEFINE_TYPE(GstTreeOverlay, gst_tree_overlay, GST_TYPE_VIDEO_FILTER);
GST_ELEMENT_REGISTER_DEFINE(treeoverlay, "treeoverlay", GST_RANK_NONE, GST_TYPE_TREE_OVERLAY);

#define OVERLAY_CAPS GST_VIDEO_CAPS_MAKE(TREESTEREO_COLOR_FORMATS)


/* Halves (or doubles) a width field: an int or an int range. */
static void scale_width(GstStructure *s, bool halve)
{
  const GValue *w = gst_structure_get_value(s, "width");
  if (!w)
    return;
  const auto f = [halve](int v) {
    if (halve)
      return MAX(1, v / 2);
    return v > G_MAXINT / 2 ? G_MAXINT : 2 * v;
  };
  if (G_VALUE_HOLDS_INT(w)) {
    gst_structure_set(s, "width", G_TYPE_INT, f(g_value_get_int(w)), nullptr);
  } else if (GST_VALUE_HOLDS_INT_RANGE(w)) {
    const int lo = f(gst_value_get_int_range_min(w)), hi = f(gst_value_get_int_range_max(w));
    if (lo == hi)
      gst_structure_set(s, "width", G_TYPE_INT, lo, nullptr);
    else
      gst_structure_set(s, "width", GST_TYPE_INT_RANGE, lo, hi, nullptr);
  }
}

/* views=left: a side-by-side sink structure becomes the left view alone (half the width, no
 * multiview fields); a src structure comes from a side-by-side frame twice as wide or from a
 * mono frame of the same size. */
static GstCaps *left_view_caps(GstCaps *caps, GstPadDirection direction)
{
  if (gst_caps_is_any(caps))
    return gst_caps_ref(caps);
  GstCaps *out = gst_caps_new_empty();
  for (guint i = 0; i < gst_caps_get_size(caps); i++) {
    const GstStructure *s = gst_caps_get_structure(caps, i);
    const gchar *mode = gst_structure_get_string(s, "multiview-mode");
    const bool has_mode = gst_structure_has_field(s, "multiview-mode");
    if (direction == GST_PAD_SINK) {
      const bool sbs = mode && g_str_equal(mode, "side-by-side");
      if (!sbs)
        gst_caps_append_structure(out, gst_structure_copy(s)); // mono (or maybe): as it is
      if (sbs || !has_mode) {
        GstStructure *half = gst_structure_copy(s);
        scale_width(half, true);
        gst_structure_remove_fields(half, "multiview-mode", "multiview-flags", nullptr);
        gst_caps_append_structure(out, half);
      }
    } else {
      if (mode && g_str_equal(mode, "side-by-side"))
        continue; // views=left never outputs side by side
      gst_caps_append_structure(out, gst_structure_copy(s));
      GstStructure *twice = gst_structure_copy(s);
      scale_width(twice, false);
      gst_structure_set(twice, "multiview-mode", G_TYPE_STRING, "side-by-side", nullptr);
      gst_caps_append_structure(out, twice);
    }
  }
  return gst_caps_simplify(out);
}

static GstCaps *gst_tree_overlay_transform_caps(GstBaseTransform *trans, GstPadDirection direction,
                                                GstCaps *caps, GstCaps *filter)
{
  GstTreeOverlay *self = GST_TREE_OVERLAY(trans);
  GstCaps *out = settings_snapshot(self).views == GST_TREE_OVERLAY_VIEWS_LEFT
                     ? left_view_caps(caps, direction)
                     : gst_caps_ref(caps);
  if (filter) {
    GstCaps *f = gst_caps_intersect_full(filter, out, GST_CAPS_INTERSECT_FIRST);
    gst_caps_unref(out);
    out = f;
  }
  GST_DEBUG_OBJECT(self, "%s %" GST_PTR_FORMAT " -> %" GST_PTR_FORMAT,
                   direction == GST_PAD_SINK ? "sink" : "src", caps, out);
  return out;
}

static gboolean gst_tree_overlay_set_info(GstVideoFilter *filter, GstCaps *incaps,
                                          GstVideoInfo *in_info, GstCaps *outcaps,
                                          GstVideoInfo *out_info)
{
  GstTreeOverlay *self = GST_TREE_OVERLAY(filter);
  State *st = self->state;
  const treestereo::gst::PixelLayout layout = treestereo::gst::pixel_layout(GST_VIDEO_INFO_FORMAT(in_info));
  if (!layout.color || GST_VIDEO_INFO_FORMAT(in_info) != GST_VIDEO_INFO_FORMAT(out_info)) {
    gchar *out = gst_caps_to_string(outcaps);
    post_caps_error(GST_ELEMENT(self),
                    std::string("treeoverlay draws on colour frames of one format in and out, "
                                "got ") +
                        gst_video_format_to_string(GST_VIDEO_INFO_FORMAT(in_info)) +
                        ": put videoconvert before it.",
                    incaps, std::string("unsupported formats, out caps ") + out);
    g_free(out);
    return FALSE;
  }
  st->order = layout.order();
  st->in_views = treestereo::gst::n_views_of(in_info);
  st->map.reset(); // a new stream (or new views): its own map
  st->ground = GroundPlane();
  const int in_w = GST_VIDEO_INFO_WIDTH(in_info), out_w = GST_VIDEO_INFO_WIDTH(out_info);
  st->crop = st->in_views == 2 && out_w == in_w / 2;
  if ((!st->crop && out_w != in_w) || GST_VIDEO_INFO_HEIGHT(in_info) != GST_VIDEO_INFO_HEIGHT(out_info)) {
    post_caps_error(GST_ELEMENT(self),
                    "treeoverlay gives out the frame's size, or its left view's with "
                    "views=left: set caps downstream that fit.",
                    nullptr,
                    "output " + std::to_string(out_w) + "x" +
                        std::to_string(GST_VIDEO_INFO_HEIGHT(out_info)) + " does not fit input " +
                        std::to_string(in_w) + "x" + std::to_string(GST_VIDEO_INFO_HEIGHT(in_info)));
    return FALSE;
  }
  gst_base_transform_set_in_place(GST_BASE_TRANSFORM(self), !st->crop);
  GST_INFO_OBJECT(self, "%d view(s) in, %s", st->in_views,
                  st->crop ? "left view out (copy)" : "drawn in place");
  return TRUE;
}

/* The treestereo metas of @buf as what lib/ draws. */
static OverlayScene scene_from_metas(GstBuffer *buf, int n_views)
{
  OverlayScene scene;
  scene.n_views = n_views;
  const GstTreeStereoVegetationMeta *veg = gst_buffer_get_tree_stereo_vegetation_meta(buf);
  if (veg)
    for (guint v = 0; v < MIN(veg->n_views, 2u); v++)
      scene.views[v] = treestereo::gst::silhouette_from_view(&veg->views[v], nullptr);
  /* the 3D canopy, when decided, is the canopy: its outline in the left view, and the
   * vegetation it left out tinted so a person sees what depth rejected */
  if (const GstTreeStereoCanopyMeta *canopy = gst_buffer_get_tree_stereo_canopy_meta(buf)) {
    scene.views[LEFT] = treestereo::gst::silhouette_from_view(&canopy->view, nullptr);
    if (veg) {
      const treestereo::gst::MappedSilhouette vegetation(&veg->views[LEFT]);
      const treestereo::gst::MappedSilhouette tree(&canopy->view);
      if (!vegetation.get().mask.empty())
        scene.rejected = rejected_vegetation(vegetation.get().mask, tree.get().mask);
    }
  }

  if (const GstTreeStereoMatchesMeta *mm = gst_buffer_get_tree_stereo_matches_meta(buf)) {
    if (mm->matches)
      scene.matches = treestereo::gst::matches_from_meta(mm);
    if (const GstTreeStereoPointsMeta *pm = gst_buffer_get_tree_stereo_points_meta(buf)) {
      scene.match_depth_m.assign(scene.matches.size(), 0.0);
      /* the trailing grid points of stereodepth's densification are no matches */
      const guint n_match_points = pm->n_points - MIN(pm->stats.n_grid, pm->n_points);
      for (guint i = 0; pm->points && !pm->dense && i < n_match_points; i++) {
        const GstTreeStereoPoint &p = pm->points[i];
        if (p.valid && p.match_index < scene.match_depth_m.size() && std::isfinite(p.z))
          scene.match_depth_m[p.match_index] = p.z / 1000.0;
      }
    }
  }

  if (const GstTreeStereoMetricsMeta *mt = gst_buffer_get_tree_stereo_metrics_meta(buf)) {
    const TreeMetrics raw = treestereo::gst::metrics_from_meta(&mt->metrics);
    const TreeMetrics smoothed = treestereo::gst::metrics_from_meta(&mt->smoothed);
    scene.text = metrics_text(raw, &smoothed, true);
    if (const GstTreeStereoGeometryMeta *gm = gst_buffer_get_tree_stereo_geometry_meta(buf)) {
      scene.geometry = treestereo::gst::geometry_from_meta(gm);
      scene.bands = raw.bands;
      scene.band_depth_m = raw.centroid_m.z; // see band_segment(): the edges' conversion depth
    }
  }
  return scene;
}

/* The row map as a strip across the bottom of the left view: the travel from 2.5 m behind the
 * camera to 1 m ahead of it, the bands from the ground up, the camera's place a white line. It
 * scrolls with the travel; a cell is drawn as soon as a frame has seen it. */
static void draw_map_strip(State *st, GstBuffer *metas, cv::Mat &image, int n_views)
{
  const GstTreeStereoMetricsMeta *mt = gst_buffer_get_tree_stereo_metrics_meta(metas);
  const GstTreeStereoGeometryMeta *gm = gst_buffer_get_tree_stereo_geometry_meta(metas);
  const GstTreeStereoCanopyMeta *canopy = gst_buffer_get_tree_stereo_canopy_meta(metas);
  if (!mt || !gm)
    return; // no position: nothing to scroll with
  const double position_m = mt->metrics.position_m;
  if (canopy && canopy->ground_found)
    st->ground = treestereo::gst::ground_from_meta(canopy);
  if (!st->map)
    st->map = std::make_unique<RowMap>();
  const StereoGeometry geometry = treestereo::gst::geometry_from_meta(gm);
  if (canopy && st->ground.found && geometry.valid())
    treestereo::gst::feed_row_map(*st->map, metas, geometry, canopy,
                                  gst_buffer_get_tree_stereo_points_meta(metas), st->ground,
                                  position_m * 1000.0,
                                  treestereo::gst::row_direction_of(mt->metrics));
  const int view_w = image.cols / std::max(1, n_views);
  const int h = std::max(24, image.rows / 6);
  if (view_w < 16 || image.rows < 2 * h)
    return;
  cv::Mat strip(h, view_w, CV_8UC3);
  st->map->draw_strip(strip, position_m - 2.5, position_m + 1.0, position_m);
  const ChannelOrder &o = st->order;
  for (int y = 0; y < h; y++) {
    const cv::Vec3b *src = strip.ptr<cv::Vec3b>(y);
    uchar *dst = image.ptr<uchar>(image.rows - h + y);
    for (int x = 0; x < view_w; x++) {
      uchar *p = dst + x * o.channels;
      if (o.channels == 4)
        p[6 - o.r - o.g - o.b] = 255; // the padding or alpha channel
      p[o.b] = src[x][0];
      p[o.g] = src[x][1];
      p[o.r] = src[x][2];
    }
  }
}

static GstFlowReturn draw(GstTreeOverlay *self, GstBuffer *metas, cv::Mat image, int n_views)
{
  const Settings s = settings_snapshot(self);
  const ChannelOrder order = self->state->order;
  return treestereo::gst::guarded(GST_ELEMENT(self), GST_FLOW_ERROR, [&] {
    draw_overlay(image, order, scene_from_metas(metas, n_views), s.style);
    if (s.draw_map)
      draw_map_strip(self->state, metas, image, n_views);
    return GST_FLOW_OK;
  });
}

static GstFlowReturn gst_tree_overlay_transform_frame_ip(GstVideoFilter *filter,
                                                         GstVideoFrame *frame)
{
  GstTreeOverlay *self = GST_TREE_OVERLAY(filter);
  return draw(self, frame->buffer, treestereo::gst::frame_mat(frame), self->state->in_views);
}

static GstFlowReturn gst_tree_overlay_transform_frame(GstVideoFilter *filter, GstVideoFrame *in,
                                                      GstVideoFrame *out)
{
  GstTreeOverlay *self = GST_TREE_OVERLAY(filter);
  cv::Mat dst = treestereo::gst::frame_mat(out);
  treestereo::gst::view_mat(treestereo::gst::frame_mat(in), LEFT, 2).copyTo(dst);
  if (GstTreeStereoGeometryMeta *gm = gst_buffer_get_tree_stereo_geometry_meta(out->buffer))
    gm->side_by_side = FALSE;
  return draw(self, in->buffer, dst, 1);
}

/* The treestereo metas follow the left view into a cropped output: their left-view pixel
 * coordinates still hold (the base class would drop metas tagged with the video size). */
static gboolean gst_tree_overlay_transform_meta(GstBaseTransform *trans, GstBuffer *outbuf,
                                                GstMeta *meta, GstBuffer *inbuf)
{
  const GType api = meta->info->api;
  if (api == GST_TREE_STEREO_GEOMETRY_META_API_TYPE ||
      api == GST_TREE_STEREO_VEGETATION_META_API_TYPE ||
      api == GST_TREE_STEREO_MATCHES_META_API_TYPE || api == GST_TREE_STEREO_POINTS_META_API_TYPE ||
      api == GST_TREE_STEREO_METRICS_META_API_TYPE || api == GST_TREE_STEREO_TRUTH_META_API_TYPE ||
      api == GST_TREE_STEREO_CANOPY_META_API_TYPE)
    return TRUE;
  return GST_BASE_TRANSFORM_CLASS(gst_tree_overlay_parent_class)
      ->transform_meta(trans, outbuf, meta, inbuf);
}

static void gst_tree_overlay_class_init(GstTreeOverlayClass *klass)
{
  GObjectClass *gobject_class = G_OBJECT_CLASS(klass);
  GstElementClass *element_class = GST_ELEMENT_CLASS(klass);
  GstBaseTransformClass *trans_class = GST_BASE_TRANSFORM_CLASS(klass);
  GstVideoFilterClass *filter_class = GST_VIDEO_FILTER_CLASS(klass);

  GST_DEBUG_CATEGORY_INIT(treeoverlay_debug, "treeoverlay", 0, "treestereo treeoverlay");

  gobject_class->finalize = finalize_state<GstTreeOverlay, &gst_tree_overlay_parent_class>;

  auto props = PropertyTable<Settings>::in_state<GstTreeOverlay>(gobject_class);
  props.enumeration("views", "Views",
                    "Draw on every view of the frame, or output the left view alone",
                    gst_tree_overlay_views_get_type(), DEFAULT_VIEWS, TS_FIELD(views), kRwReady);
  props.custom(
      g_param_spec_boolean(
          "draw-contour", "Draw contour",
          "Draw the canopy's outer contour (yellow) and, with a 3D canopy upstream, tint "
          "the vegetation depth rejected (grey-blue)",
          TRUE, kRwPlaying),
      [](Settings &s, const GValue *v) {
        s.style.contour = s.style.rejected = g_value_get_boolean(v);
      },
      [](const Settings &s, GValue *v) { g_value_set_boolean(v, s.style.contour); });
  props.boolean("draw-box", "Draw box", "Draw the canopy's bounding box (cyan)", true,
                TS_FIELD(style.box));
  props.boolean("draw-matches", "Draw matches",
                "Draw the stereo matches coloured by depth (near red, far blue, grey unknown)",
                true, TS_FIELD(style.matches));
  props.custom(
      g_param_spec_enum("match-style", "Match style", "How a match is drawn",
                        gst_tree_overlay_match_style_get_type(), DEFAULT_MATCH_STYLE, kRwPlaying),
      [](Settings &s, const GValue *v) {
        s.style.match_style = g_value_get_enum(v) == GST_TREE_OVERLAY_MATCH_LINES
                                  ? MatchStyle::kLines
                                  : MatchStyle::kDots;
      },
      [](const Settings &s, GValue *v) {
        g_value_set_enum(v, s.style.match_style == MatchStyle::kLines
                                ? GST_TREE_OVERLAY_MATCH_LINES
                                : GST_TREE_OVERLAY_MATCH_DOTS);
      });
  props.boolean("draw-bands", "Draw bands",
                "Draw the band profile of treemetrics (needs the geometry meta)", true,
                TS_FIELD(style.bands));
  props.boolean("draw-text", "Draw text",
                "Draw the panel with distance, height, width, thickness and the depth legend", true,
                TS_FIELD(style.text));
  props.real("depth-near", "Depth near",
             "Depth (m) drawn red; with depth-far <= depth-near the colour range "
             "follows each frame's 5th..95th percentile of match depths",
             0.0, 1000.0, 0.0, TS_FIELD(style.depth_near_m));
  props.real("depth-far", "Depth far",
             "Depth (m) drawn blue (see depth-near); a fixed range keeps the "
             "colours steady in a recording",
             0.0, 1000.0, 0.0, TS_FIELD(style.depth_far_m));
  props.boolean("draw-map", "Draw map",
                "Draw the row canopy map as a strip across the bottom of the left "
                "view, scrolling with the travel (needs treemetrics' position and "
                "stereodepth's canopy meta)",
                FALSE, TS_FIELD(draw_map));

  add_filter_pad_templates(element_class, OVERLAY_CAPS);
  gst_element_class_set_static_metadata(
      element_class, "Tree overlay", "Filter/Effect/Video",
      "Draws the canopy contour and box, the stereo matches coloured by depth, the band profile "
      "and the tree's measurements onto the video",
      "treestereo developers");

  trans_class->transform_caps = gst_tree_overlay_transform_caps;
  trans_class->transform_meta = gst_tree_overlay_transform_meta;
  filter_class->set_info = gst_tree_overlay_set_info;
  filter_class->transform_frame_ip = gst_tree_overlay_transform_frame_ip;
  filter_class->transform_frame = gst_tree_overlay_transform_frame;

  gst_type_mark_as_plugin_api(gst_tree_overlay_views_get_type(), GstPluginAPIFlags(0));
  gst_type_mark_as_plugin_api(gst_tree_overlay_match_style_get_type(), GstPluginAPIFlags(0));
}

static void gst_tree_overlay_init(GstTreeOverlay *self)
{
  self->state = new State();
}
