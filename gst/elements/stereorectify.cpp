/**
 * SECTION:element-stereorectify
 * @title: stereorectify
 *
 * Pairs the frames of two cameras by running time and rectifies them with a stereo
 * calibration. One buffer goes out per pair: the two rectified views side by side
 * (`multiview-mode=side-by-side`, width 2W), with a #GstTreeStereoGeometryMeta that holds the
 * rectified focal length, principal points, baseline, Q, R1, both frames' timestamps and their
 * skew. The output timestamp is the left frame's running time.
 *
 * Two frames pair when their running times are at most #stereorectify:max-skew apart; otherwise
 * the older one is dropped, counted in #stereorectify:dropped, and a QoS message is posted (and
 * a warning at the start of each run of drops). In a live pipeline a frame whose partner does
 * not arrive within the latency is dropped the same way, so a camera that stops does not stall
 * the other; pairing resumes when it comes back. EOS on either pad ends the stream.
 *
 * When the input size differs from the calibration's image size by a pure scale (binning, a
 * smaller capture) the intrinsics are scaled; any other size is an error that names both.
 * With #stereorectify:rectify=false already-rectified input (Middlebury pairs, a factory-
 * rectified stereo camera) is only composed side by side, and the geometry still comes from
 * the calibration.
 *
 * ## Example launch lines
 * |[
 * gst-launch-1.0 treetestsrc num-buffers=1 calibration-out=rig.yml ! fakesink
 * gst-launch-1.0 stereorectify name=r calibration=rig.yml ! videoconvert ! autovideosink \
 *   treetestsrc view=left ! r.left   treetestsrc view=right ! r.right
 * ]|
 * |[
 * gst-launch-1.0 stereorectify name=r calibration=calib.yml ! videoconvert ! autovideosink \
 *   aravissrc camera-name=10.0.0.11 ! video/x-raw,format=GRAY8 ! r.left \
 *   aravissrc camera-name=10.0.0.12 ! video/x-raw,format=GRAY8 ! r.right
 * ]|
 */
#ifdef HAVE_CONFIG_H
#include "config.h"
#endif

#include "common.hpp"
#include "elements.hpp"
#include "properties.hpp"

#include "treestereo/calibration_file.hpp"
#include "treestereo/rectify.hpp"

#include <gst/base/gstaggregator.h>

#include <memory>
#include <mutex>
#include <optional>
#include <string>

GST_DEBUG_CATEGORY_STATIC(stereorectify_debug);
#define GST_CAT_DEFAULT stereorectify_debug

using namespace treestereo;
using namespace treestereo::gst;

#define DEFAULT_MAX_SKEW (20 * GST_MSECOND)
#define DEFAULT_ALPHA (-1.0)
#define DEFAULT_RECTIFY TRUE
/* A renegotiation on one camera may leave the two sizes apart for a few frames; longer than this
 * is a configuration error. */
#define MAX_MISMATCHED_FRAMES 30

namespace {

struct Settings {
  std::string calibration;
  double alpha = DEFAULT_ALPHA;
  guint64 max_skew = DEFAULT_MAX_SKEW;
  bool rectify = DEFAULT_RECTIFY;
  guint64 generation = 0; // bumped when calibration/alpha/rectify change
};

struct State {
  std::mutex lock; // guards settings and counters (the object lock is not held around C++ code)
  Settings settings;
  guint64 dropped = 0;
  guint64 paired = 0;

  // streaming thread only (the aggregator's src task)
  std::optional<StereoCalibration> calib;
  std::string calib_path;
  GstVideoInfo pad_info[2];
  bool pad_info_set[2] = {false, false};
  GstVideoInfo out_info;
  bool out_configured = false;
  guint64 out_generation = ~guint64(0);
  StereoRectification rect;
  bool ever_paired = false;
  int mismatched = 0;
  bool in_drop_run = false;
};

} // namespace

struct GstStereoRectify {
  GstAggregator parent;
  GstAggregatorPad *pads[2];
  State *state;
};

struct GstStereoRectifyClass {
  GstAggregatorClass parent_class;
};

#define GST_TYPE_STEREO_RECTIFY (gst_stereo_rectify_get_type())
#define GST_STEREO_RECTIFY(obj) \
  (G_TYPE_CHECK_INSTANCE_CAST((obj), GST_TYPE_STEREO_RECTIFY, GstStereoRectify))
G_DEFINE_TYPE(GstStereoRectify, gst_stereo_rectify, GST_TYPE_AGGREGATOR);
GST_ELEMENT_REGISTER_DEFINE(stereorectify, "stereorectify", GST_RANK_NONE,
                            GST_TYPE_STEREO_RECTIFY);

#define SINK_CAPS GST_VIDEO_CAPS_MAKE(TREESTEREO_VIDEO_FORMATS)
#define SRC_CAPS                                                                              \
  "video/x-raw, format = (string) " TREESTEREO_VIDEO_FORMATS ", width = (int) [ 2, MAX ], "   \
  "height = (int) [ 1, MAX ], framerate = (fraction) [ 0, MAX ], "                            \
  "multiview-mode = (string) side-by-side"

static GstStaticPadTemplate left_template =
    GST_STATIC_PAD_TEMPLATE("left", GST_PAD_SINK, GST_PAD_ALWAYS, GST_STATIC_CAPS(SINK_CAPS));
static GstStaticPadTemplate right_template =
    GST_STATIC_PAD_TEMPLATE("right", GST_PAD_SINK, GST_PAD_ALWAYS, GST_STATIC_CAPS(SINK_CAPS));
static GstStaticPadTemplate src_template =
    GST_STATIC_PAD_TEMPLATE("src", GST_PAD_SRC, GST_PAD_ALWAYS, GST_STATIC_CAPS(SRC_CAPS));

static int pad_index(GstStereoRectify *self, GstAggregatorPad *pad)
{
  return pad == self->pads[RIGHT] ? RIGHT : LEFT;
}

static std::string caps_summary(const GstVideoInfo *info)
{
  return std::string(gst_video_format_to_string(GST_VIDEO_INFO_FORMAT(info))) + " " +
         std::to_string(GST_VIDEO_INFO_WIDTH(info)) + "x" +
         std::to_string(GST_VIDEO_INFO_HEIGHT(info));
}

static bool infos_match(const GstVideoInfo *a, const GstVideoInfo *b)
{
  return GST_VIDEO_INFO_FORMAT(a) == GST_VIDEO_INFO_FORMAT(b) &&
         GST_VIDEO_INFO_WIDTH(a) == GST_VIDEO_INFO_WIDTH(b) &&
         GST_VIDEO_INFO_HEIGHT(a) == GST_VIDEO_INFO_HEIGHT(b);
}

/* The message for a stereorectify without a calibration file. */
static const char *const kNoCalibration =
    "stereorectify has no calibration: set the calibration property to an OpenCV YAML/XML file "
    "or a ROS pair 'left.yaml;right.yaml'.";

/* Loads the calibration named by the settings when it changed. Throws CalibrationError, or
 * BadSettings without a calibration. */
static void ensure_calibration(GstStereoRectify *self, const Settings &s)
{
  State *st = self->state;
  if (st->calib && st->calib_path == s.calibration)
    return;
  if (s.calibration.empty())
    throw BadSettings("the calibration property is empty");
  st->calib = load_calibration(s.calibration);
  st->calib_path = s.calibration;
  GST_INFO_OBJECT(self, "loaded calibration %s (%dx%d, baseline %.2f mm)", s.calibration.c_str(),
                  st->calib->image_size.width, st->calib->image_size.height,
                  st->calib->baseline_mm());
}

static gboolean gst_stereo_rectify_start(GstAggregator *agg)
{
  GstStereoRectify *self = GST_STEREO_RECTIFY(agg);
  State *st = self->state;
  st->calib.reset();
  st->calib_path.clear();
  st->pad_info_set[0] = st->pad_info_set[1] = false;
  st->out_configured = false;
  st->ever_paired = false;
  st->mismatched = 0;
  st->in_drop_run = false;
  {
    std::lock_guard<std::mutex> g(st->lock);
    st->dropped = st->paired = 0;
  }
  const Settings s = settings_snapshot(self);
  try {
    ensure_calibration(self, s);
  } catch (const std::exception &e) {
    treestereo::gst::report_exception(GST_ELEMENT(self), e,
                                      s.calibration.empty() ? kNoCalibration : "");
    return FALSE;
  }
  return TRUE;
}

static gboolean gst_stereo_rectify_stop(GstAggregator *agg)
{
  GstStereoRectify *self = GST_STEREO_RECTIFY(agg);
  self->state->rect = StereoRectification();
  self->state->calib.reset();
  return TRUE;
}

static gboolean gst_stereo_rectify_sink_event(GstAggregator *agg, GstAggregatorPad *pad,
                                              GstEvent *event)
{
  GstStereoRectify *self = GST_STEREO_RECTIFY(agg);
  if (GST_EVENT_TYPE(event) == GST_EVENT_CAPS) {
    GstCaps *caps;
    gst_event_parse_caps(event, &caps);
    const int i = pad_index(self, pad);
    GstVideoInfo info;
    if (!gst_video_info_from_caps(&info, caps)) {
      const std::string side = i == LEFT ? "left" : "right";
      post_caps_error(GST_ELEMENT(self),
                      "stereorectify cannot read the caps of its " + side +
                          " pad as raw video: check the " + side + " camera's chain.",
                      caps, "invalid caps on the " + side + " pad");
      gst_event_unref(event);
      return FALSE;
    }
    self->state->pad_info[i] = info;
    self->state->pad_info_set[i] = true;
    GST_DEBUG_OBJECT(self, "%s caps: %s", i == LEFT ? "left" : "right",
                     caps_summary(&info).c_str());
    gst_pad_mark_reconfigure(GST_AGGREGATOR_SRC_PAD(agg));
    gst_event_unref(event);
    return TRUE;
  }
  return GST_AGGREGATOR_CLASS(gst_stereo_rectify_parent_class)->sink_event(agg, pad, event);
}

/* Output caps for the current input caps: both views side by side. */
static GstCaps *output_caps(const GstVideoInfo *in)
{
  GstVideoInfo out = *in;
  gst_video_info_set_format(&out, GST_VIDEO_INFO_FORMAT(in), 2 * GST_VIDEO_INFO_WIDTH(in),
                            GST_VIDEO_INFO_HEIGHT(in));
  GST_VIDEO_INFO_FPS_N(&out) = GST_VIDEO_INFO_FPS_N(in);
  GST_VIDEO_INFO_FPS_D(&out) = GST_VIDEO_INFO_FPS_D(in);
  GST_VIDEO_INFO_PAR_N(&out) = GST_VIDEO_INFO_PAR_N(in);
  GST_VIDEO_INFO_PAR_D(&out) = GST_VIDEO_INFO_PAR_D(in);
  GST_VIDEO_INFO_MULTIVIEW_MODE(&out) = GST_VIDEO_MULTIVIEW_MODE_SIDE_BY_SIDE;
  GST_VIDEO_INFO_MULTIVIEW_FLAGS(&out) = GST_VIDEO_MULTIVIEW_FLAGS_NONE;
  return gst_video_info_to_caps(&out);
}

static GstFlowReturn gst_stereo_rectify_update_src_caps(GstAggregator *agg, GstCaps *downstream,
                                                        GstCaps **ret)
{
  GstStereoRectify *self = GST_STEREO_RECTIFY(agg);
  State *st = self->state;
  if (!st->pad_info_set[LEFT] || !st->pad_info_set[RIGHT] ||
      !infos_match(&st->pad_info[LEFT], &st->pad_info[RIGHT]))
    return GST_AGGREGATOR_FLOW_NEED_DATA; // aggregate() decides: wait, drop or error
  *ret = output_caps(&st->pad_info[LEFT]);
  return GST_FLOW_OK;
}

/* (Re)computes the maps for the current input size and settings. Throws. */
static void configure_rectification(GstStereoRectify *self, const Settings &s)
{
  State *st = self->state;
  ensure_calibration(self, s);
  const cv::Size size(GST_VIDEO_INFO_WIDTH(&st->pad_info[LEFT]),
                      GST_VIDEO_INFO_HEIGHT(&st->pad_info[LEFT]));
  st->rect = compute_rectification(*st->calib, size, s.alpha, s.rectify);
  st->out_generation = s.generation;
  GST_INFO_OBJECT(self, "rectification for %dx%d: f %.2f px, baseline %.2f mm, rectify %d",
                  size.width, size.height, st->rect.geometry.fx, st->rect.geometry.baseline_mm,
                  s.rectify);
}

static gboolean gst_stereo_rectify_negotiated_src_caps(GstAggregator *agg, GstCaps *caps)
{
  GstStereoRectify *self = GST_STEREO_RECTIFY(agg);
  State *st = self->state;
  if (!gst_video_info_from_caps(&st->out_info, caps))
    return FALSE;
  const Settings s = settings_snapshot(self);
  try {
    configure_rectification(self, s);
  } catch (const std::exception &e) {
    /* the frames' size does not fit the calibration: the caps are what cannot be used */
    post_caps_error(GST_ELEMENT(self),
                    "stereorectify cannot rectify " + caps_summary(&st->pad_info[LEFT]) +
                        " frames with the calibration \"" + s.calibration +
                        "\": give it frames of the calibration's size (or a pure scale of it), "
                        "or a calibration made at this size.",
                    nullptr, e.what());
    st->out_configured = false;
    return FALSE;
  }
  st->out_configured = true;
  return TRUE;
}

static gboolean gst_stereo_rectify_decide_allocation(GstAggregator *agg, GstQuery *query)
{
  return treestereo::gst::decide_video_allocation(GST_ELEMENT(agg), query);
}

static GstClockTime running_time_of(GstAggregatorPad *pad, GstBuffer *buf)
{
  GstClockTime pts = GST_BUFFER_PTS(buf);
  if (!GST_CLOCK_TIME_IS_VALID(pts))
    return GST_CLOCK_TIME_NONE;
  return gst_segment_to_running_time(&pad->segment, GST_FORMAT_TIME, pts);
}

/* Drops the head buffer of pad @i: counted, QoS message, a warning at the start of a run. */
static void drop_frame(GstStereoRectify *self, int i, GstBuffer *buf, GstClockTime rt,
                       const char *why)
{
  State *st = self->state;
  GstAggregatorPad *pad = self->pads[i];
  guint64 dropped, paired;
  {
    std::lock_guard<std::mutex> g(st->lock);
    dropped = ++st->dropped;
    paired = st->paired;
  }
  GST_INFO_OBJECT(self, "dropping %s frame at %" GST_TIME_FORMAT ": %s",
                  i == LEFT ? "left" : "right", GST_TIME_ARGS(rt), why);
  /* the aggregator reports a latency only with a live source upstream */
  const gboolean live = GST_CLOCK_TIME_IS_VALID(gst_aggregator_get_latency(GST_AGGREGATOR(self)));
  GstMessage *qos = gst_message_new_qos(
      GST_OBJECT(self), live, rt,
      gst_segment_to_stream_time(&pad->segment, GST_FORMAT_TIME, GST_BUFFER_PTS(buf)),
      GST_BUFFER_PTS(buf), GST_BUFFER_DURATION(buf));
  gst_message_set_qos_stats(qos, GST_FORMAT_BUFFERS, paired, dropped);
  gst_element_post_message(GST_ELEMENT(self), qos);
  if (!st->in_drop_run) {
    st->in_drop_run = true;
    GST_ELEMENT_WARNING(self, STREAM, FAILED,
                        ("Dropping unpaired %s camera frames: %s", i == LEFT ? "left" : "right",
                         why),
                        ("running time %" GST_TIME_FORMAT ", %" G_GUINT64_FORMAT
                         " dropped so far",
                         GST_TIME_ARGS(rt), dropped));
  }
  gst_aggregator_pad_drop_buffer(pad);
}

static void advance_position(GstAggregator *agg, GstClockTime rt, GstClockTime duration)
{
  GstSegment *seg = &GST_AGGREGATOR_PAD(agg->srcpad)->segment;
  if (GST_CLOCK_TIME_IS_VALID(rt))
    seg->position = rt + (GST_CLOCK_TIME_IS_VALID(duration) ? duration : 0);
}

/* Metas that do not depend on the pixels (no tags: e.g. treetestsrc's ground truth) travel
 * from the left frame to the pair. */
static void copy_untagged_metas(GstBuffer *in, GstBuffer *out)
{
  gpointer state = nullptr;
  GstMeta *meta;
  GstMetaTransformCopy copy = {FALSE, 0, G_MAXSIZE};
  while ((meta = gst_buffer_iterate_meta(in, &state))) {
    const gchar *const *tags = gst_meta_api_type_get_tags(meta->info->api);
    if ((tags && tags[0]) || !meta->info->transform_func)
      continue;
    meta->info->transform_func(out, meta, in, _gst_meta_transform_copy, &copy);
  }
}

static GstFlowReturn compose_pair(GstStereoRectify *self, GstBuffer *in[2], GstClockTime rt[2])
{
  GstAggregator *agg = GST_AGGREGATOR(self);
  State *st = self->state;
  GstBuffer *out = nullptr;
  GstBufferPool *pool = gst_aggregator_get_buffer_pool(agg);
  if (pool) {
    if (!gst_buffer_pool_is_active(pool))
      gst_buffer_pool_set_active(pool, TRUE);
    GstFlowReturn ret = gst_buffer_pool_acquire_buffer(pool, &out, nullptr);
    gst_object_unref(pool);
    if (ret != GST_FLOW_OK)
      return ret;
  } else {
    out = gst_buffer_new_allocate(nullptr, GST_VIDEO_INFO_SIZE(&st->out_info), nullptr);
  }

  bool ok = treestereo::gst::guarded(GST_ELEMENT(self), false, [&] {
    treestereo::gst::MappedFrame dst(&st->out_info, out, GST_MAP_WRITE);
    if (!dst.ok())
      throw std::runtime_error("could not map the output frame");
    cv::Mat dmat = dst.mat();
    for (int v = 0; v < 2; v++) {
      treestereo::gst::MappedFrame src(&st->pad_info[v], in[v], GST_MAP_READ);
      if (!src.ok())
        throw BadInput(std::string("could not map the ") + (v == LEFT ? "left" : "right") +
                       " frame: it is smaller than its caps say");
      cv::Mat half = treestereo::gst::view_mat(dmat, v, 2);
      if (st->rect.rectify)
        rectify_view(st->rect, v, src.mat(), half);
      else
        src.mat().copyTo(half);
    }
    return true;
  });
  if (!ok) {
    gst_buffer_unref(out);
    return GST_FLOW_ERROR;
  }

  copy_untagged_metas(in[LEFT], out);
  GstTreeStereoGeometryMeta *meta = gst_buffer_add_tree_stereo_geometry_meta(out);
  treestereo::gst::geometry_to_meta(st->rect.geometry, meta);
  meta->side_by_side = TRUE;
  meta->rectified = st->rect.rectify;
  meta->pts[LEFT] = GST_BUFFER_PTS(in[LEFT]);
  meta->pts[RIGHT] = GST_BUFFER_PTS(in[RIGHT]);
  meta->skew_ns = GST_CLOCK_DIFF(rt[LEFT], rt[RIGHT]);

  GST_BUFFER_PTS(out) = rt[LEFT];
  GST_BUFFER_DTS(out) = GST_CLOCK_TIME_NONE;
  GST_BUFFER_DURATION(out) = GST_BUFFER_DURATION(in[LEFT]);
  advance_position(agg, rt[LEFT], GST_BUFFER_DURATION(in[LEFT]));
  {
    std::lock_guard<std::mutex> g(st->lock);
    st->paired++;
  }
  st->ever_paired = true;
  st->in_drop_run = false;
  st->mismatched = 0;
  gst_aggregator_selected_samples(agg, rt[LEFT], GST_CLOCK_TIME_NONE,
                                  GST_BUFFER_DURATION(in[LEFT]), nullptr);
  gst_aggregator_pad_drop_buffer(self->pads[LEFT]);
  gst_aggregator_pad_drop_buffer(self->pads[RIGHT]);
  return gst_aggregator_finish_buffer(agg, out);
}

static GstFlowReturn gst_stereo_rectify_aggregate(GstAggregator *agg, gboolean timeout)
{
  GstStereoRectify *self = GST_STEREO_RECTIFY(agg);
  State *st = self->state;
  GstBuffer *buf[2];
  GstClockTime rt[2];
  GstFlowReturn ret = GST_FLOW_OK;

  for (int i = 0; i < 2; i++) {
    buf[i] = gst_aggregator_pad_peek_buffer(self->pads[i]);
    rt[i] = buf[i] ? running_time_of(self->pads[i], buf[i]) : GST_CLOCK_TIME_NONE;
  }

  for (int i = 0; i < 2; i++) {
    if (!buf[i] && gst_aggregator_pad_is_eos(self->pads[i])) {
      GST_INFO_OBJECT(self, "%s pad is at EOS: ending the stream", i == LEFT ? "left" : "right");
      ret = GST_FLOW_EOS;
      goto done;
    }
  }

  if (!buf[LEFT] || !buf[RIGHT]) {
    /* Live and the deadline passed with only one side there: the other camera is late or gone. */
    if (timeout) {
      const int i = buf[LEFT] ? LEFT : RIGHT;
      if (buf[i]) {
        drop_frame(self, i, buf[i], rt[i],
                   i == LEFT ? "no right frame in time" : "no left frame in time");
        advance_position(agg, rt[i], GST_BUFFER_DURATION(buf[i]));
      }
    }
    ret = GST_AGGREGATOR_FLOW_NEED_DATA;
    goto done;
  }

  if (!infos_match(&st->pad_info[LEFT], &st->pad_info[RIGHT])) {
    const std::string l = caps_summary(&st->pad_info[LEFT]),
                      r = caps_summary(&st->pad_info[RIGHT]);
    if (!st->ever_paired || ++st->mismatched > MAX_MISMATCHED_FRAMES) {
      post_caps_error(GST_ELEMENT(self),
                      "The left and right cameras deliver different formats or sizes: left " + l +
                          ", right " + r +
                          ". Both must be the same; set caps filters so they agree.",
                      nullptr);
      ret = GST_FLOW_NOT_NEGOTIATED;
      goto done;
    }
    /* mid-stream renegotiation: one side changed first; drop the older frame and wait */
    const int older = rt[LEFT] <= rt[RIGHT] ? LEFT : RIGHT;
    drop_frame(self, older, buf[older], rt[older],
               ("sizes differ during renegotiation (left " + l + ", right " + r + ")").c_str());
    ret = GST_AGGREGATOR_FLOW_NEED_DATA;
    goto done;
  }

  {
    const Settings s = settings_snapshot(self);
    GstCaps *current = gst_pad_get_current_caps(GST_AGGREGATOR_SRC_PAD(agg));
    GstVideoInfo cur;
    const bool caps_ok = current && gst_video_info_from_caps(&cur, current) &&
                         GST_VIDEO_INFO_FORMAT(&cur) == GST_VIDEO_INFO_FORMAT(&st->pad_info[LEFT]) &&
                         GST_VIDEO_INFO_WIDTH(&cur) == 2 * GST_VIDEO_INFO_WIDTH(&st->pad_info[LEFT]) &&
                         GST_VIDEO_INFO_HEIGHT(&cur) == GST_VIDEO_INFO_HEIGHT(&st->pad_info[LEFT]);
    gst_clear_caps(&current);
    if (!caps_ok || !st->out_configured) {
      /* the inputs agree now on a new size: renegotiate before composing */
      gst_pad_mark_reconfigure(GST_AGGREGATOR_SRC_PAD(agg));
      ret = GST_AGGREGATOR_FLOW_NEED_DATA;
      goto done;
    }
    if (s.generation != st->out_generation) {
      /* calibration, alpha or rectify changed while running */
      try {
        configure_rectification(self, s);
      } catch (const std::exception &e) {
        treestereo::gst::report_exception(GST_ELEMENT(self), e,
                                          s.calibration.empty() ? kNoCalibration : "");
        ret = GST_FLOW_ERROR;
        goto done;
      }
    }

    if (!GST_CLOCK_TIME_IS_VALID(rt[LEFT]) || !GST_CLOCK_TIME_IS_VALID(rt[RIGHT])) {
      /* without timestamps frames can only be paired in arrival order */
      rt[LEFT] = GST_CLOCK_TIME_IS_VALID(rt[LEFT]) ? rt[LEFT] : rt[RIGHT];
      rt[RIGHT] = rt[LEFT];
    }
    const GstClockTimeDiff skew = GST_CLOCK_DIFF(rt[LEFT], rt[RIGHT]);
    if (guint64(ABS(skew)) > s.max_skew) {
      const int older = skew > 0 ? LEFT : RIGHT;
      gchar *why = g_strdup_printf("skew %.1f ms exceeds max-skew %.1f ms", ABS(skew) / 1e6,
                                   s.max_skew / 1e6);
      drop_frame(self, older, buf[older], rt[older], why);
      g_free(why);
      ret = GST_AGGREGATOR_FLOW_NEED_DATA;
      goto done;
    }
    ret = compose_pair(self, buf, rt);
  }

done:
  for (int i = 0; i < 2; i++)
    if (buf[i])
      gst_buffer_unref(buf[i]);
  return ret;
}

static void gst_stereo_rectify_class_init(GstStereoRectifyClass *klass)
{
  GObjectClass *gobject_class = G_OBJECT_CLASS(klass);
  GstElementClass *element_class = GST_ELEMENT_CLASS(klass);
  GstAggregatorClass *agg_class = GST_AGGREGATOR_CLASS(klass);

  GST_DEBUG_CATEGORY_INIT(stereorectify_debug, "stereorectify", 0, "treestereo stereorectify");

  gobject_class->finalize = finalize_state<GstStereoRectify, &gst_stereo_rectify_parent_class>;

  /* The pair counters sit beside the settings, under the same lock. */
  PropertyTable<State> props(
      gobject_class, [](GObject *o) -> State & { return *GST_STEREO_RECTIFY(o)->state; },
      [](GObject *o) -> std::mutex & { return GST_STEREO_RECTIFY(o)->state->lock; });
  const auto remap = [](State &s) { s.settings.generation++; }; // the maps are made again
  props.after_set(remap);
  props.string("calibration", "Calibration",
               "Stereo calibration: an OpenCV YAML/XML file (M1 D1 M2 D2 R T) or two "
               "ROS camera_info files 'left.yaml;right.yaml'. May change while "
               "playing.",
               TS_FIELD(settings.calibration));
  props.real("alpha", "Alpha",
             "Free scaling of cv::stereoRectify: -1 = OpenCV's default, 0 = only "
             "valid pixels, 1 = every source pixel kept",
             -1.0, 1.0, DEFAULT_ALPHA, TS_FIELD(settings.alpha));
  props.after_set(nullptr);
  props.uint64("max-skew", "Maximum skew",
               "How far apart (ns of running time) a left and a right frame may be "
               "and still pair",
               0, G_MAXUINT64, DEFAULT_MAX_SKEW, TS_FIELD(settings.max_skew));
  props.after_set(remap);
  props.boolean("rectify", "Rectify",
                "Rectify the views; false for already-rectified input (the geometry "
                "still comes from the calibration)",
                DEFAULT_RECTIFY, TS_FIELD(settings.rectify));
  props.uint64("dropped", "Dropped", "Frames dropped for want of a partner", 0, G_MAXUINT64, 0,
               TS_FIELD(dropped), kReadOnly);
  props.uint64("paired", "Paired", "Stereo pairs pushed", 0, G_MAXUINT64, 0, TS_FIELD(paired),
               kReadOnly);

  gst_element_class_add_static_pad_template_with_gtype(element_class, &left_template,
                                                       GST_TYPE_AGGREGATOR_PAD);
  gst_element_class_add_static_pad_template_with_gtype(element_class, &right_template,
                                                       GST_TYPE_AGGREGATOR_PAD);
  gst_element_class_add_static_pad_template_with_gtype(element_class, &src_template,
                                                       GST_TYPE_AGGREGATOR_PAD);
  gst_element_class_set_static_metadata(
      element_class, "Stereo rectifier", "Filter/Converter/Video",
      "Pairs the frames of two cameras by running time and rectifies them into one side-by-side "
      "stereo frame with a stereo geometry meta",
      "treestereo developers");

  agg_class->start = gst_stereo_rectify_start;
  agg_class->stop = gst_stereo_rectify_stop;
  agg_class->sink_event = gst_stereo_rectify_sink_event;
  agg_class->update_src_caps = gst_stereo_rectify_update_src_caps;
  agg_class->negotiated_src_caps = gst_stereo_rectify_negotiated_src_caps;
  agg_class->decide_allocation = gst_stereo_rectify_decide_allocation;
  agg_class->aggregate = gst_stereo_rectify_aggregate;
  agg_class->get_next_time = gst_aggregator_simple_get_next_time;
}

static void gst_stereo_rectify_init(GstStereoRectify *self)
{
  self->state = new State();
  static GstStaticPadTemplate *templates[2] = {&left_template, &right_template};
  for (int i = 0; i < 2; i++) {
    GstPadTemplate *templ = gst_static_pad_template_get(templates[i]);
    self->pads[i] = GST_AGGREGATOR_PAD(g_object_new(GST_TYPE_AGGREGATOR_PAD, "name",
                                                    templates[i]->name_template, "direction",
                                                    GST_PAD_SINK, "template", templ, nullptr));
    gst_object_unref(templ);
    gst_element_add_pad(GST_ELEMENT(self), GST_PAD(self->pads[i]));
  }
}
