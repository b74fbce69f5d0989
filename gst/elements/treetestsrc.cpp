/**
 * SECTION:element-treetestsrc
 * @title: treetestsrc
 *
 * A synthetic orchard seen by a calibrated stereo rig: a ray-cast tree (trunk, a canopy of
 * leaf clusters with gaps), soil, a background wall and sky, rendered through one camera of
 * the rig (#treetestsrc:view) with its lens distortion, the right camera rotated and offset
 * from the left one so that rectification is really needed. Two instances with the same
 * scene properties are a stereo rig: pair them with stereorectify and the calibration written
 * by #treetestsrc:calibration-out.
 *
 * Every buffer carries a #GstTreeStereoTruthMeta with the scene's true values (canopy height
 * and width, distance, visible-surface depth percentiles, centroid) and the per-pixel depth
 * (float mm) and canopy mask of this view, so tests and benchmarks compare measured values
 * with the truth inside a pipeline. With #treetestsrc:speed the rig drives along the row.
 *
 * #treetestsrc:scene chooses what surrounds the tree: `lab` (the tree alone on soil), `orchard`
 * (a row of trees on mown grass with dry patches, gaps of #treetestsrc:row-gap-min to
 * #treetestsrc:row-gap-max between neighbouring canopies, a second row
 * #treetestsrc:row-spacing behind) or `hedgerow` (the same with touching, overlapping canopies).
 * The truth meta is always about the tree in front: the near-row tree whose trunk is nearest to
 * the left camera's optical axis; its canopy mask holds only that tree's leaves.
 *
 * Frame size and rate come from caps (default 1296x972 at 7/1, any size from 64x48 to
 * 2592x1944). In live mode (#treetestsrc:is-live) frames are paced by the clock.
 *
 * ## Example launch lines
 * |[
 * gst-launch-1.0 treetestsrc view=left num-buffers=10 ! videoconvert ! pngenc ! \
 *   multifilesink location=left_%04d.png
 * ]|
 * The rig's calibration is known once the frame size is: write it first, then pair the views
 * (stereorectify loads its calibration before the sources negotiate):
 * |[
 * gst-launch-1.0 treetestsrc num-buffers=1 calibration-out=rig.yml ! fakesink
 * gst-launch-1.0 stereorectify name=r calibration=rig.yml ! videoconvert ! autovideosink \
 *   treetestsrc view=left ! r.left  treetestsrc view=right ! r.right
 * ]|
 * An orchard row passing by at 0.5 m/s:
 * |[
 * gst-launch-1.0 treetestsrc scene=orchard speed=0.5 num-buffers=20 ! videoconvert ! \
 *   autovideosink
 * ]|
 */
#ifdef HAVE_CONFIG_H
#include "config.h"
#endif

#include "common.hpp"
#include "elements.hpp"
#include "properties.hpp"

#include "treestereo/calibration_file.hpp"
#include "treestereo/scene.hpp"

#include <gst/base/gstpushsrc.h>

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <memory>
#include <mutex>
#include <string>

GST_DEBUG_CATEGORY_STATIC(treetestsrc_debug);
#define GST_CAT_DEFAULT treetestsrc_debug

using namespace treestereo;
using namespace treestereo::gst;

#define DEFAULT_WIDTH 1296
#define DEFAULT_HEIGHT 972
#define DEFAULT_FPS 7

namespace
{

struct Settings {
  int view = LEFT;
  SceneParams scene;
  bool is_live = false;
  bool truth_maps = true;
  std::string calibration_out;
  guint64 generation = 0;
};

struct State {
  std::mutex lock;
  Settings settings;

  // streaming thread
  GstVideoInfo info;
  std::unique_ptr<SceneRenderer> renderer;
  guint64 renderer_generation = ~guint64(0);
  guint64 frame = 0;
  GstClockTime running_time = 0;
};

} // namespace

struct GstTreeTestSrc {
  GstPushSrc parent;
  State *state;
};

struct GstTreeTestSrcClass {
  GstPushSrcClass parent_class;
};

#define GST_TYPE_TREE_TEST_SRC (gst_tree_test_src_get_type())
#define GST_TREE_TEST_SRC(obj)                                                                     \
  (G_TYPE_CHECK_INSTANCE_CAST((obj), GST_TYPE_TREE_TEST_SRC, GstTreeTestSrc))
G_DEFINE_TYPE(GstTreeTestSrc, gst_tree_test_src, GST_TYPE_PUSH_SRC);
GST_ELEMENT_REGISTER_DEFINE(treetestsrc, "treetestsrc", GST_RANK_NONE, GST_TYPE_TREE_TEST_SRC);

#define SRC_CAPS                                                                                   \
  "video/x-raw, format = (string) { RGB, BGR, RGBx, BGRx, GRAY8 }, "                               \
  "width = (int) [ 64, 2592 ], height = (int) [ 48, 1944 ], "                                      \
  "framerate = (fraction) [ 0/1, 1000/1 ]"

static GstStaticPadTemplate src_template =
    GST_STATIC_PAD_TEMPLATE("src", GST_PAD_SRC, GST_PAD_ALWAYS, GST_STATIC_CAPS(SRC_CAPS));

static GType gst_tree_test_src_view_get_type(void)
{
  static GType type = 0;
  static const GEnumValue values[] = {
      {LEFT, "The left camera", "left"},
      {RIGHT, "The right camera", "right"},
      {0, nullptr, nullptr},
  };
  if (g_once_init_enter(&type)) {
    GType t = g_enum_register_static("GstTreeTestSrcView", values);
    g_once_init_leave(&type, t);
  }
  return type;
}

static GType gst_tree_test_src_scene_get_type(void)
{
  static GType type = 0;
  static const GEnumValue values[] = {
      {int(SceneKind::Lab), "The tree alone on soil", "lab"},
      {int(SceneKind::Orchard), "A row of trees on grass, a second row behind", "orchard"},
      {int(SceneKind::Hedgerow), "A row of touching, overlapping canopies on grass", "hedgerow"},
      {0, nullptr, nullptr},
  };
  if (g_once_init_enter(&type)) {
    GType t = g_enum_register_static("GstTreeTestSrcScene", values);
    g_once_init_leave(&type, t);
  }
  return type;
}

/* A property in m, -1 meaning the scene's default, as SceneParams (mm, NaN = default) has it. */
static double mm_or_default(double m)
{
  return m == -1.0 ? kSceneDefault : 1000.0 * m;
}
static double m_or_default(double mm)
{
  return std::isnan(mm) ? -1.0 : mm / 1000.0;
}

static GstCaps *gst_tree_test_src_fixate(GstBaseSrc *src, GstCaps *caps)
{
  caps = gst_caps_make_writable(caps);
  GstStructure *s = gst_caps_get_structure(caps, 0);
  gst_structure_fixate_field_nearest_int(s, "width", DEFAULT_WIDTH);
  gst_structure_fixate_field_nearest_int(s, "height", DEFAULT_HEIGHT);
  gst_structure_fixate_field_nearest_fraction(s, "framerate", DEFAULT_FPS, 1);
  if (gst_structure_has_field(s, "format"))
    gst_structure_fixate_field_string(s, "format", "RGB");
  return GST_BASE_SRC_CLASS(gst_tree_test_src_parent_class)->fixate(src, caps);
}

/* Builds the renderer for the current size and settings; writes the calibration when asked. */
static void ensure_renderer(GstTreeTestSrc *self, const Settings &s)
{
  State *st = self->state;
  if (st->renderer && st->renderer_generation == s.generation)
    return;
  SceneParams p = s.scene;
  p.image_size = cv::Size(GST_VIDEO_INFO_WIDTH(&st->info), GST_VIDEO_INFO_HEIGHT(&st->info));
  if (GST_VIDEO_INFO_FPS_N(&st->info) > 0)
    p.framerate = double(GST_VIDEO_INFO_FPS_N(&st->info)) / GST_VIDEO_INFO_FPS_D(&st->info);
  st->renderer = std::make_unique<SceneRenderer>(p);
  st->renderer_generation = s.generation;
  if (!s.calibration_out.empty()) {
    try {
      save_calibration(st->renderer->calibration(), s.calibration_out);
    } catch (const CalibrationError &e) {
      if (e.access() != FileAccess::None)
        throw; // the file cannot be written: reported as such
      throw BadSettings("treetestsrc's calibration-out must name an OpenCV YAML/XML file: end "
                        "it in .yml, .yaml or .xml (optionally .gz).",
                        e.what());
    }
    GST_INFO_OBJECT(self, "wrote the rig's calibration to %s", s.calibration_out.c_str());
  }
}

static gboolean gst_tree_test_src_set_caps(GstBaseSrc *src, GstCaps *caps)
{
  GstTreeTestSrc *self = GST_TREE_TEST_SRC(src);
  State *st = self->state;
  if (!gst_video_info_from_caps(&st->info, caps))
    return FALSE;
  st->renderer.reset();
  const Settings s = settings_snapshot(self);
  return treestereo::gst::guarded(GST_ELEMENT(self), FALSE, [&] {
    ensure_renderer(self, s);
    return TRUE;
  });
}

static gboolean gst_tree_test_src_decide_allocation(GstBaseSrc *src, GstQuery *query)
{
  return treestereo::gst::decide_video_allocation(GST_ELEMENT(src), query);
}

static gboolean gst_tree_test_src_start(GstBaseSrc *src)
{
  GstTreeTestSrc *self = GST_TREE_TEST_SRC(src);
  self->state->frame = 0;
  self->state->running_time = 0;
  self->state->renderer.reset();
  gst_video_info_init(&self->state->info);
  return TRUE;
}

static gboolean gst_tree_test_src_stop(GstBaseSrc *src)
{
  GST_TREE_TEST_SRC(src)->state->renderer.reset();
  return TRUE;
}

static GstClockTime frame_time(const GstVideoInfo *info, guint64 frame)
{
  if (GST_VIDEO_INFO_FPS_N(info) <= 0)
    return frame == 0 ? 0 : GST_CLOCK_TIME_NONE;
  return gst_util_uint64_scale(frame * GST_SECOND, GST_VIDEO_INFO_FPS_D(info),
                               GST_VIDEO_INFO_FPS_N(info));
}

static void gst_tree_test_src_get_times(GstBaseSrc *src, GstBuffer *buffer, GstClockTime *start,
                                        GstClockTime *end)
{
  /* only a live source syncs to the clock */
  if (gst_base_src_is_live(src)) {
    GstClockTime ts = GST_BUFFER_PTS(buffer);
    if (GST_CLOCK_TIME_IS_VALID(ts)) {
      GstClockTime dur = GST_BUFFER_DURATION(buffer);
      *start = ts;
      *end = GST_CLOCK_TIME_IS_VALID(dur) ? ts + dur : GST_CLOCK_TIME_NONE;
      return;
    }
  }
  *start = *end = GST_CLOCK_TIME_NONE;
}

static void attach_truth(GstBuffer *buf, const GroundTruth &t, const SceneParams &p, bool with_maps)
{
  GstTreeStereoTruth truth = {};
  truth.view = guint(t.view);
  truth.frame = t.frame;
  truth.seed = guint(p.seed);
  truth.distance_m = t.distance_m;
  truth.depth_p05_m = t.depth_p05_m;
  truth.depth_p95_m = t.depth_p95_m;
  truth.thickness_m = t.thickness_m;
  truth.height_m = t.canopy_height_m;
  truth.width_m = t.canopy_width_m;
  truth.trunk_distance_m = t.trunk_distance_m;
  for (int i = 0; i < 3; i++)
    truth.centroid_m[i] = t.centroid_m[i];
  truth.offset_x_m = t.lateral_offset_m;
  truth.baseline_mm = p.baseline_mm;
  GstBuffer *depth = with_maps ? treestereo::gst::buffer_from_mat(t.depth) : nullptr;
  GstBuffer *mask = with_maps ? treestereo::gst::buffer_from_mat(t.canopy_mask) : nullptr;
  gst_buffer_add_tree_stereo_truth_meta(buf, &truth, depth, mask, guint(t.depth.cols),
                                        guint(t.depth.rows));
  if (depth)
    gst_buffer_unref(depth);
  if (mask)
    gst_buffer_unref(mask);
}

/* Converts the rendered RGB picture into the negotiated format, in the output buffer. */
static void write_frame(const GstVideoInfo *info, GstBuffer *buf, const cv::Mat &rgb)
{
  treestereo::gst::MappedFrame frame(info, buf, GST_MAP_WRITE);
  if (!frame.ok())
    throw std::runtime_error("could not map the output buffer");
  cv::Mat dst = frame.mat();
  switch (GST_VIDEO_INFO_FORMAT(info)) {
  case GST_VIDEO_FORMAT_RGB:
    rgb.copyTo(dst);
    break;
  case GST_VIDEO_FORMAT_BGR:
    cv::cvtColor(rgb, dst, cv::COLOR_RGB2BGR);
    break;
  case GST_VIDEO_FORMAT_RGBx:
    cv::cvtColor(rgb, dst, cv::COLOR_RGB2RGBA);
    break;
  case GST_VIDEO_FORMAT_BGRx:
    cv::cvtColor(rgb, dst, cv::COLOR_RGB2BGRA);
    break;
  case GST_VIDEO_FORMAT_GRAY8:
    cv::cvtColor(rgb, dst, cv::COLOR_RGB2GRAY);
    break;
  default:
    throw std::runtime_error("unsupported output format");
  }
}

static GstFlowReturn gst_tree_test_src_fill(GstPushSrc *psrc, GstBuffer *buf)
{
  GstTreeTestSrc *self = GST_TREE_TEST_SRC(psrc);
  State *st = self->state;
  if (GST_VIDEO_INFO_FORMAT(&st->info) == GST_VIDEO_FORMAT_UNKNOWN) {
    post_caps_error(GST_ELEMENT(self),
                    "treetestsrc was asked for a frame before its caps were agreed: link it to "
                    "an element that takes raw video.",
                    nullptr, "format was not negotiated");
    return GST_FLOW_NOT_NEGOTIATED;
  }
  const Settings s = settings_snapshot(self);
  const bool ok = treestereo::gst::guarded(GST_ELEMENT(self), false, [&] {
    ensure_renderer(self, s);
    cv::Mat rgb;
    GroundTruth truth;
    st->renderer->render(s.view, st->frame, rgb, &truth);
    write_frame(&st->info, buf, rgb);
    attach_truth(buf, truth, st->renderer->params(), s.truth_maps);
    return true;
  });
  if (!ok)
    return GST_FLOW_ERROR;

  GST_BUFFER_PTS(buf) = frame_time(&st->info, st->frame);
  GST_BUFFER_DTS(buf) = GST_CLOCK_TIME_NONE;
  const GstClockTime next = frame_time(&st->info, st->frame + 1);
  GST_BUFFER_DURATION(buf) = GST_CLOCK_TIME_IS_VALID(next) && GST_BUFFER_PTS_IS_VALID(buf)
                                 ? next - GST_BUFFER_PTS(buf)
                                 : GST_CLOCK_TIME_NONE;
  GST_BUFFER_OFFSET(buf) = st->frame;
  GST_BUFFER_OFFSET_END(buf) = st->frame + 1;
  st->frame++;
  return GST_FLOW_OK;
}

static gboolean gst_tree_test_src_is_seekable(GstBaseSrc *)
{
  return FALSE;
}

/* A length property in metres over a scene length in mm; -1 m, where the range has it, stands for
 * the scene's default. */
static void install_metres(PropertyTable<Settings> &props, const char *name, const char *nick,
                           const char *blurb, double min, double max, double def,
                           double SceneParams::*mm)
{
  props.custom(
      g_param_spec_double(name, nick, blurb, min, max, def, kRwPlaying),
      [mm](Settings &s, const GValue *v) { s.scene.*mm = mm_or_default(g_value_get_double(v)); },
      [mm](const Settings &s, GValue *v) { g_value_set_double(v, m_or_default(s.scene.*mm)); });
}

static void gst_tree_test_src_class_init(GstTreeTestSrcClass *klass)
{
  GObjectClass *gobject_class = G_OBJECT_CLASS(klass);
  GstElementClass *element_class = GST_ELEMENT_CLASS(klass);
  GstBaseSrcClass *base_class = GST_BASE_SRC_CLASS(klass);
  GstPushSrcClass *push_class = GST_PUSH_SRC_CLASS(klass);
  const SceneParams d;

  GST_DEBUG_CATEGORY_INIT(treetestsrc_debug, "treetestsrc", 0, "treestereo synthetic orchard");

  gobject_class->finalize = finalize_state<GstTreeTestSrc, &gst_tree_test_src_parent_class>;

  auto props = PropertyTable<Settings>::in_state<GstTreeTestSrc>(gobject_class);
  props.after_set([](Settings &s) { s.generation++; }); // the scene is rendered anew
  props.enumeration("view", "View", "Which camera of the rig renders",
                    gst_tree_test_src_view_get_type(), LEFT, TS_FIELD(view), kRwReady);
  props.uint64("seed", "Seed", "The tree, its textures and the sensor noise", 0, G_MAXUINT64,
               d.seed, TS_FIELD(scene.seed));
  install_metres(props, "distance", "Distance", "Distance from the left camera to the trunk (m)",
                 0.5, 10.0, d.distance_mm / 1000.0, &SceneParams::distance_mm);
  install_metres(props, "canopy-height", "Canopy height", "True vertical extent of the canopy (m)",
                 0.1, 5.0, d.canopy_height_mm / 1000.0, &SceneParams::canopy_height_mm);
  install_metres(props, "canopy-width", "Canopy width", "True horizontal extent of the canopy (m)",
                 0.1, 5.0, d.canopy_width_mm / 1000.0, &SceneParams::canopy_width_mm);
  props.real("baseline", "Baseline", "Distance between the two cameras (mm)", 5.0, 1000.0,
             d.baseline_mm, TS_FIELD(scene.baseline_mm));
  props.real("speed", "Speed", "Lateral speed of the sprayer along the row (m/s)", -20.0, 20.0,
             d.speed_m_s, TS_FIELD(scene.speed_m_s));
  props.real("light", "Light", "Light level (1 = nominal; the paper's +-30% is 0.7-1.3)", 0.2, 2.0,
             d.light, TS_FIELD(scene.light));
  props.real("noise", "Noise", "Sensor noise standard deviation (8-bit levels)", 0.0, 50.0, d.noise,
             TS_FIELD(scene.noise));
  props.on_object(
      g_param_spec_boolean("is-live", "Is live", "Pace frames by the clock like a camera", FALSE,
                           kRwReady),
      [](GObject *o, const GValue *v) {
        State &st = *GST_TREE_TEST_SRC(o)->state;
        const gboolean live = g_value_get_boolean(v);
        {
          std::lock_guard<std::mutex> g(st.lock);
          st.settings.is_live = live;
          st.settings.generation++;
        }
        gst_base_src_set_live(GST_BASE_SRC(o), live); // takes the object lock
      },
      [](GObject *o, GValue *v) {
        State &st = *GST_TREE_TEST_SRC(o)->state;
        std::lock_guard<std::mutex> g(st.lock);
        g_value_set_boolean(v, st.settings.is_live);
      });
  props.string("calibration-out", "Calibration out",
               "Write the rig's true calibration (OpenCV YAML/XML by extension) here "
               "once the frame size is known",
               TS_FIELD(calibration_out), kRwReady);
  props.boolean("truth-maps", "Truth maps",
                "Attach the per-pixel depth and canopy mask to the ground-truth meta", TRUE,
                TS_FIELD(truth_maps));
  props.enumeration("scene", "Scene", "What surrounds the tree: lab, orchard or hedgerow",
                    gst_tree_test_src_scene_get_type(), int(SceneKind::Lab), TS_FIELD(scene.kind));
  install_metres(props, "row-gap-min", "Row gap min",
                 "Smallest gap between neighbouring canopies of the row (m; negative = "
                 "overlap, at least -half the canopy width; -1 = the scene's default: orchard "
                 "0.2, hedgerow -0.15 canopy widths)",
                 -1.0, 20.0, -1.0, &SceneParams::row_gap_min_mm);
  install_metres(props, "row-gap-max", "Row gap max",
                 "Largest gap between neighbouring canopies of the row (m; -1 = the scene's "
                 "default: orchard 0.6, hedgerow 0)",
                 -1.0, 20.0, -1.0, &SceneParams::row_gap_max_mm);
  install_metres(props, "row-spacing", "Row spacing",
                 "Distance from the row to the next row behind it (m, 1.5-8; -1 = the scene's "
                 "default 3.5)",
                 -1.0, 8.0, -1.0, &SceneParams::row_spacing_mm);
  props.custom(
      g_param_spec_int("touching-pair", "Touching pair",
                       "Orchard and hedgerow: the canopies of row trees K and K + 1 touch "
                       "(overlapping by 5 cm; tree 0 stands at tree-x, trees ahead count up "
                       "along the drive); -1 = none",
                       -1, 100, -1, kRwPlaying),
      [](Settings &s, const GValue *v) {
        const int k = g_value_get_int(v);
        s.scene.touching_pair = k < 0 ? SceneParams::kNoTouchingPair : k;
      },
      [](const Settings &s, GValue *v) {
        g_value_set_int(
            v, s.scene.touching_pair == SceneParams::kNoTouchingPair ? -1 : s.scene.touching_pair);
      });

  gst_element_class_add_static_pad_template(element_class, &src_template);
  gst_element_class_set_static_metadata(
      element_class, "Synthetic stereo orchard source", "Source/Video",
      "Renders one camera of a calibrated stereo rig looking at a fruit tree, with ground truth",
      "treestereo developers");

  base_class->fixate = gst_tree_test_src_fixate;
  base_class->set_caps = gst_tree_test_src_set_caps;
  base_class->start = gst_tree_test_src_start;
  base_class->decide_allocation = gst_tree_test_src_decide_allocation;
  base_class->stop = gst_tree_test_src_stop;
  base_class->get_times = gst_tree_test_src_get_times;
  base_class->is_seekable = gst_tree_test_src_is_seekable;
  push_class->fill = gst_tree_test_src_fill;
}

static void gst_tree_test_src_init(GstTreeTestSrc *self)
{
  self->state = new State();
  gst_video_info_init(&self->state->info);
  gst_base_src_set_format(GST_BASE_SRC(self), GST_FORMAT_TIME);
  gst_base_src_set_live(GST_BASE_SRC(self), FALSE);
}
