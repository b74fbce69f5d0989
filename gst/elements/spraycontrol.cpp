/**
 * SECTION:element-spraycontrol
 * @title: spraycontrol
 *
 * Turns the row canopy map into valve commands for the sprayer's nozzle sections, timed for
 * when the nozzles reach each slice of canopy (docs/spraying.md). In place after treemetrics:
 * it reads the rig's position from the #GstTreeStereoMetricsMeta and feeds its own row map with
 * the canopy meta's silhouette, the points and the ground plane (the same feeding as treemetrics'
 * row map, treestereo::gst::feed_row_map()). A travel bin is final once the rig has passed the
 * next bin's centre by the map's settle distance (no later frame can change it then); lib's
 * SprayPlanner turns the final bins into commands per section
 * (default: one per band of the map, or #spraycontrol:section-heights), timed
 *
 *   at = now + (x + nozzle-offset - position) / speed - valve-latency
 *
 * with the latest speed, re-timed every frame until they fall due. Each command is posted as a
 * "treestereo-section" element message (gst_tree_stereo_section_message_parse()).
 *
 * Fail-safe: when no frame with a position arrives for #spraycontrol:hold-time (a camera gap), a
 * callback on the element's clock sets every section to #spraycontrol:fallback (one command
 * each, fallback TRUE) and posts a warning saying so; the next frame resumes control.
 *
 * ## Example launch line
 * |[
 * gst-launch-1.0 stereorectify name=r calibration=rig.yml ! exgsegment ! siftmatch ! \
 *   stereodepth ! treemetrics ! spraycontrol nozzle-offset=1.2 ! fakesink \
 *   treetestsrc scene=orchard speed=2 view=left ! r.left \
 *   treetestsrc scene=orchard speed=2 view=right ! r.right
 * ]|
 */
#ifdef HAVE_CONFIG_H
#include "config.h"
#endif

#include "common.hpp"
#include "elements.hpp"
#include "properties.hpp"

#include "treestereo/rowmap.hpp"
#include "treestereo/spray.hpp"

#include <gst/base/gstbasetransform.h>

#include <climits>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

GST_DEBUG_CATEGORY_STATIC(spraycontrol_debug);
#define GST_CAT_DEFAULT spraycontrol_debug

using namespace treestereo;
using namespace treestereo::gst;

typedef enum {
  GST_SPRAY_CONTROL_RATE_ONOFF = 0,
  GST_SPRAY_CONTROL_RATE_PROPORTIONAL = 1,
} GstSprayControlRateModel;

typedef enum {
  GST_SPRAY_CONTROL_FALLBACK_ON = 0,
  GST_SPRAY_CONTROL_FALLBACK_OFF = 1,
  GST_SPRAY_CONTROL_FALLBACK_HOLD = 2,
} GstSprayControlFallback;

#define GST_TYPE_SPRAY_CONTROL_RATE_MODEL (gst_spray_control_rate_model_get_type())
static GType gst_spray_control_rate_model_get_type(void)
{
  static GType type = 0;
  static const GEnumValue values[] = {
      {GST_SPRAY_CONTROL_RATE_ONOFF, "Open (rate 1) where canopy is, closed elsewhere", "onoff"},
      {GST_SPRAY_CONTROL_RATE_PROPORTIONAL,
       "Rate proportional to the section's fill x its height share covered (0..1)",
       "proportional"},
      {0, nullptr, nullptr},
  };
  if (g_once_init_enter(&type)) {
    GType t = g_enum_register_static("GstSprayControlRateModel", values);
    g_once_init_leave(&type, t);
  }
  return type;
}

#define GST_TYPE_SPRAY_CONTROL_FALLBACK (gst_spray_control_fallback_get_type())
static GType gst_spray_control_fallback_get_type(void)
{
  static GType type = 0;
  static const GEnumValue values[] = {
      {GST_SPRAY_CONTROL_FALLBACK_ON, "Every section on (the agronomically safe default)", "on"},
      {GST_SPRAY_CONTROL_FALLBACK_OFF, "Every section off", "off"},
      {GST_SPRAY_CONTROL_FALLBACK_HOLD, "Keep each section as it is", "hold"},
      {0, nullptr, nullptr},
  };
  if (g_once_init_enter(&type)) {
    GType t = g_enum_register_static("GstSprayControlFallback", values);
    g_once_init_leave(&type, t);
  }
  return type;
}

#define DEFAULT_SECTIONS 0
#define DEFAULT_NOZZLE_OFFSET 1.5
#define DEFAULT_VALVE_LATENCY 160
#define DEFAULT_MIN_GAP 0.075
#define DEFAULT_MIN_CANOPY 0.10
#define DEFAULT_RATE_MODEL GST_SPRAY_CONTROL_RATE_ONOFF
#define DEFAULT_HOLD_TIME 500
#define DEFAULT_FALLBACK GST_SPRAY_CONTROL_FALLBACK_ON
#define DEFAULT_POST_MESSAGES TRUE

namespace {

struct Settings {
  guint sections = DEFAULT_SECTIONS;
  std::string section_heights;
  double nozzle_offset = DEFAULT_NOZZLE_OFFSET; // m
  guint valve_latency = DEFAULT_VALVE_LATENCY;  // ms
  double min_gap = DEFAULT_MIN_GAP;             // m
  double min_canopy = DEFAULT_MIN_CANOPY;       // m
  GstSprayControlRateModel rate_model = DEFAULT_RATE_MODEL;
  guint hold_time = DEFAULT_HOLD_TIME; // ms
  GstSprayControlFallback fallback = DEFAULT_FALLBACK;
  bool post_messages = DEFAULT_POST_MESSAGES;
  std::string timeline_location; // empty: no picture
};

/* The plan of one stream; guarded by State::plan_lock (the streaming thread and the clock's
 * hold callback both use it). */
struct Plan {
  std::unique_ptr<RowMap> map;
  std::unique_ptr<SprayPlanner> planner;
  std::vector<SectionRange> ranges;
  long next_bin = LONG_MIN;
  GroundPlane ground; // the last one found: the rig is rigid
  GstClockID hold_id = nullptr;
  // Upstream is live (a camera): a gap in the arrivals is a gap in the data. Offline (files,
  // a synthetic source not synced) frames arrive at the pace of the processing, and only gaps
  // in the running times count.
  bool live = false;
  bool live_known = false;
  GstClockTime arrival = 0;  // clock time the last frame arrived
  std::int64_t last_running = 0; // its running time
  bool post_messages = true;
  std::vector<SectionCommand> planned; // the canopy's commands, for the timeline's picture
  bool keep_planned = false;
  guint hold_ms = DEFAULT_HOLD_TIME;
  const char *fallback_name = "on";
};

struct State {
  std::mutex plan_lock;
  Plan plan;
  bool warned_missing = false; // streaming thread only
};

} // namespace

struct GstSprayControl {
  GstBaseTransform parent;
  Settings settings; // under the object lock
  State *state;
};

struct GstSprayControlClass {
  GstBaseTransformClass parent_class;
};

#define GST_TYPE_SPRAY_CONTROL (gst_spray_control_get_type())
#define GST_SPRAY_CONTROL(obj) \
  (G_TYPE_CHECK_INSTANCE_CAST((obj), GST_TYPE_SPRAY_CONTROL, GstSprayControl))

G_DEFINE_TYPE(GstSprayControl, gst_spray_control, GST_TYPE_BASE_TRANSFORM);
GST_ELEMENT_REGISTER_DEFINE(spraycontrol, "spraycontrol", GST_RANK_NONE, GST_TYPE_SPRAY_CONTROL);

#define CAPS GST_VIDEO_CAPS_MAKE(TREESTEREO_VIDEO_FORMATS)

static void post_commands(GstSprayControl *self, const std::vector<SectionCommand> &commands,
                          bool post, bool fallback)
{
  if (!post)
    return;
  for (const SectionCommand &c : commands) {
    GstTreeStereoSectionCommand g{};
    g.section = guint(c.section);
    g.on = c.on;
    g.rate = c.rate;
    g.at_ns = c.at_ns;
    g.position_m = c.position_m;
    g.fallback = fallback;
    treestereo::gst::post_element_message(GST_ELEMENT(self),
                                          gst_tree_stereo_section_message_structure(&g));
  }
}

/* Called with plan_lock held. */
static void unschedule_hold(Plan &p)
{
  if (p.hold_id) {
    gst_clock_id_unschedule(p.hold_id);
    gst_clock_id_unref(p.hold_id);
    p.hold_id = nullptr;
  }
}

/* What the fail-safe did, to post with no lock held. */
struct FallbackEvent {
  bool entered = false;
  std::vector<SectionCommand> commands;
  bool post = false;
  guint hold_ms = 0;
  const char *fallback = "";
};

/* Called with plan_lock held: the planner's fail-safe at @running_ns (no data since its last). */
static FallbackEvent check_hold(Plan &p, std::int64_t running_ns)
{
  FallbackEvent ev;
  if (!p.planner)
    return ev;
  const bool was = p.planner->in_fallback();
  ev.commands = p.planner->tick(running_ns);
  ev.entered = !was && p.planner->in_fallback();
  ev.post = p.post_messages;
  ev.hold_ms = p.hold_ms;
  ev.fallback = p.fallback_name;
  return ev;
}

static void post_fallback(GstSprayControl *self, const FallbackEvent &ev)
{
  if (ev.entered)
    GST_ELEMENT_WARNING(self, STREAM, FAILED,
                        ("No frame with the rig's position for %u ms (hold-time): every nozzle "
                         "section set to the fallback state \"%s\" until frames resume",
                         ev.hold_ms, ev.fallback),
                        ("no buffer with a metrics meta for hold-time; fallback %s", ev.fallback));
  post_commands(self, ev.commands, ev.post, true);
}

static gboolean hold_expired(GstClock *, GstClockTime time, GstClockID id, gpointer user_data)
{
  GstSprayControl *self = GST_SPRAY_CONTROL(user_data);
  State *st = self->state;
  FallbackEvent ev;
  {
    std::lock_guard<std::mutex> lock(st->plan_lock);
    Plan &p = st->plan;
    if (p.hold_id != id || !p.planner)
      return TRUE; // replaced by a newer frame's, or the stream stopped
    // The running time now: the last frame's plus the clock time since it arrived.
    const std::int64_t elapsed = time > p.arrival ? std::int64_t(time - p.arrival) : 0;
    ev = check_hold(p, p.last_running + elapsed);
  }
  post_fallback(self, ev);
  return TRUE;
}

/* Called with plan_lock held: the hold callback hold-time after this frame's arrival (live
 * upstream only). */
static void schedule_hold(GstSprayControl *self, Plan &p, std::int64_t running_ns)
{
  unschedule_hold(p);
  if (!p.live)
    return;
  GstClock *clock = gst_element_get_clock(GST_ELEMENT(self));
  if (!clock)
    return; // not PLAYING on a clock: no camera gap to notice
  p.arrival = gst_clock_get_time(clock);
  p.last_running = running_ns;
  p.hold_id = gst_clock_new_single_shot_id(clock, p.arrival + GstClockTime(p.hold_ms) * GST_MSECOND);
  gst_object_unref(clock);
  if (gst_clock_id_wait_async(p.hold_id, hold_expired, gst_object_ref(self),
                              (GDestroyNotify)gst_object_unref) != GST_CLOCK_OK) {
    gst_clock_id_unref(p.hold_id);
    p.hold_id = nullptr;
  }
}

/* The message for a section-heights that does not parse. */
static const char *const kBadSectionHeights =
    "spraycontrol's section-heights cannot be used: give lo:hi pairs in m above the ground, "
    "comma separated (e.g. 0.4:0.7,0.7:1.0), or an empty string for the row map's bands.";

/* The section heights of the settings; throws BadSettings. */
static std::vector<SectionRange> section_ranges(const Settings &s)
{
  try {
    return parse_section_heights(s.section_heights);
  } catch (const std::exception &e) {
    throw BadSettings(kBadSectionHeights,
                      "invalid section-heights \"" + s.section_heights + "\": " + e.what());
  }
}

/* The planner from the settings; throws BadSettings naming the property. */
static void start_plan(Plan &p, const Settings &s, int n_bands)
{
  SprayParams sp;
  p.ranges = section_ranges(s);
  const int wanted = p.ranges.empty() ? n_bands : int(p.ranges.size());
  if (s.sections != 0 && int(s.sections) != wanted)
    throw BadSettings(
        "spraycontrol's sections does not match its section count: set sections=0 or to that "
        "count.",
        "spraycontrol: sections=" + std::to_string(s.sections) + " but " +
            (p.ranges.empty()
                 ? "the row map has " + std::to_string(n_bands) + " bands"
                 : "section-heights gives " + std::to_string(p.ranges.size()) + " ranges"));
  sp.n_sections = wanted;
  sp.nozzle_offset_m = s.nozzle_offset;
  sp.valve_latency_ns = std::int64_t(s.valve_latency) * GST_MSECOND;
  sp.min_gap_m = s.min_gap;
  sp.min_canopy_m = s.min_canopy;
  sp.rate_model = s.rate_model == GST_SPRAY_CONTROL_RATE_PROPORTIONAL ? RateModel::Proportional
                                                                       : RateModel::OnOff;
  sp.hold_time_ns = std::int64_t(s.hold_time) * GST_MSECOND;
  sp.fallback = s.fallback == GST_SPRAY_CONTROL_FALLBACK_OFF    ? SprayFallback::Off
                : s.fallback == GST_SPRAY_CONTROL_FALLBACK_HOLD ? SprayFallback::Hold
                                                                : SprayFallback::On;
  p.planner = std::make_unique<SprayPlanner>(sp);
  p.hold_ms = s.hold_time;
  p.fallback_name = s.fallback == GST_SPRAY_CONTROL_FALLBACK_OFF    ? "off"
                    : s.fallback == GST_SPRAY_CONTROL_FALLBACK_HOLD ? "hold"
                                                                    : "on";
}

static GstFlowReturn gst_spray_control_transform_ip(GstBaseTransform *trans, GstBuffer *buf)
{
  GstSprayControl *self = GST_SPRAY_CONTROL(trans);
  State *st = self->state;
  GST_OBJECT_LOCK(self);
  const Settings s = self->settings;
  GST_OBJECT_UNLOCK(self);

  const GstTreeStereoMetricsMeta *mm = gst_buffer_get_tree_stereo_metrics_meta(buf);
  const GstTreeStereoGeometryMeta *gm = gst_buffer_get_tree_stereo_geometry_meta(buf);
  const GstClockTime pts = GST_BUFFER_PTS(buf);
  const GstClockTime running =
      gst_segment_to_running_time(&trans->segment, GST_FORMAT_TIME, pts);
  if (!mm || !gm || !GST_CLOCK_TIME_IS_VALID(running)) {
    if (!st->warned_missing) {
      st->warned_missing = true;
      static const char *const then =
          ". Until it comes the sections keep their state, then take the fallback after "
          "hold-time.";
      if (!mm || !gm)
        treestereo::gst::post_missing_meta(
            GST_ELEMENT(self), GST_MESSAGE_WARNING, buf,
            !mm ? treestereo::gst::kMetricsMeta : treestereo::gst::kGeometryMeta, nullptr, then);
      else
        GST_ELEMENT_WARNING(self, STREAM, FAILED,
                            ("No timestamp on the buffer: spraycontrol needs the running time of "
                             "each frame; give the buffers timestamps upstream."),
                            ("buffer %" GST_PTR_FORMAT " has no valid running time", buf));
    }
    return GST_FLOW_OK; // no data: the hold callback runs out
  }
  const GstTreeStereoCanopyMeta *canopy = gst_buffer_get_tree_stereo_canopy_meta(buf);
  const GstTreeStereoPointsMeta *pm = gst_buffer_get_tree_stereo_points_meta(buf);
  const double position_m = mm->metrics.position_m;

  gboolean live = FALSE;
  bool query_live = false;
  {
    std::lock_guard<std::mutex> lock(st->plan_lock);
    query_live = !st->plan.live_known;
  }
  if (query_live) { // no lock held: the query travels upstream
    GstQuery *q = gst_query_new_latency();
    if (gst_pad_peer_query(GST_BASE_TRANSFORM_SINK_PAD(trans), q))
      gst_query_parse_latency(q, &live, nullptr, nullptr);
    gst_query_unref(q);
  }

  std::vector<SectionCommand> commands;
  FallbackEvent gap;
  const bool ok = treestereo::gst::guarded(GST_ELEMENT(self), false, [&] {
    std::lock_guard<std::mutex> lock(st->plan_lock);
    Plan &p = st->plan;
    if (query_live) {
      p.live = live != FALSE;
      p.live_known = true;
    }
    if (!p.map)
      p.map = std::make_unique<RowMap>();
    if (!p.planner)
      start_plan(p, s, p.map->n_bands());
    // A gap in the running times (a recording with frames missing, or the clock callback not
    // yet run): the fail-safe first, then this frame resumes control.
    gap = check_hold(p, std::int64_t(running));
    p.post_messages = s.post_messages;
    if (canopy && canopy->ground_found)
      p.ground = treestereo::gst::ground_from_meta(canopy);
    const StereoGeometry geometry = treestereo::gst::geometry_from_meta(gm);
    std::vector<SpraySlice> slices;
    if (canopy && p.ground.found && geometry.valid()) {
      treestereo::gst::feed_row_map(*p.map, buf, geometry, canopy, pm, p.ground,
                                    position_m * 1000.0,
                                    treestereo::gst::row_direction_of(mm->metrics));
      slices = take_final_slices(*p.map, position_m * 1000.0, p.next_bin, p.ranges);
    }
    commands = p.planner->update(std::int64_t(running), position_m, slices);
    p.keep_planned = !s.timeline_location.empty();
    if (p.keep_planned)
      p.planned.insert(p.planned.end(), commands.begin(), commands.end());
    schedule_hold(self, p, std::int64_t(running));
    return true;
  });
  if (!ok)
    return GST_FLOW_ERROR;
  post_fallback(self, gap);
  post_commands(self, commands, s.post_messages, false);
  return GST_FLOW_OK;
}

/* At EOS: the row map with the valve timeline under it, at timeline-location. */
static bool write_timeline(GstSprayControl *self)
{
  GST_OBJECT_LOCK(self);
  const std::string location = self->settings.timeline_location;
  GST_OBJECT_UNLOCK(self);
  if (location.empty())
    return true;
  State *st = self->state;
  std::lock_guard<std::mutex> lock(st->plan_lock);
  const Plan &p = st->plan;
  if (!p.map || p.map->empty()) {
    GST_ELEMENT_WARNING(self, STREAM, FAILED,
                        ("No valve timeline written to \"%s\": the row map is empty (no 3D "
                         "canopy, or no ground plane: see stereodepth's ground=rig).",
                         location.c_str()),
                        (nullptr));
    return true;
  }
  try {
    p.map->write_png(location, {}, sprayed_stretches(p.planned),
                     p.planner ? p.planner->params().n_sections : p.map->n_bands());
  } catch (const std::exception &e) {
    GST_ELEMENT_ERROR(self, RESOURCE, OPEN_WRITE,
                      ("Could not write the valve timeline to \"%s\": check that its folder "
                       "exists, is writable and has room.",
                       location.c_str()),
                      ("%s", e.what()));
    return false;
  }
  GST_INFO_OBJECT(self, "valve timeline written to %s", location.c_str());
  return true;
}

static gboolean gst_spray_control_sink_event(GstBaseTransform *trans, GstEvent *event)
{
  GstSprayControl *self = GST_SPRAY_CONTROL(trans);
  State *st = self->state;
  if (GST_EVENT_TYPE(event) == GST_EVENT_EOS) {
    // The end of the data, not a camera gap: every planned command, no fallback.
    std::vector<SectionCommand> commands;
    bool post = false;
    const bool ok = treestereo::gst::guarded(GST_ELEMENT(self), false, [&] {
      std::lock_guard<std::mutex> lock(st->plan_lock);
      unschedule_hold(st->plan);
      // the map's bins the rig did not pass count too: no later frame will change them
      if (st->plan.planner)
        commands = st->plan.planner->finish(
            st->plan.map ? take_final_slices(*st->plan.map, std::numeric_limits<double>::infinity(),
                                             st->plan.next_bin, st->plan.ranges)
                         : std::vector<SpraySlice>());
      post = st->plan.post_messages;
      if (st->plan.keep_planned)
        st->plan.planned.insert(st->plan.planned.end(), commands.begin(), commands.end());
      return true;
    });
    if (ok)
      post_commands(self, commands, post, false);
    if (!ok || !write_timeline(self)) { // the event is ours: unused, it goes
      gst_event_unref(event);
      return FALSE;
    }
  } else if (GST_EVENT_TYPE(event) == GST_EVENT_STREAM_START) {
    std::lock_guard<std::mutex> lock(st->plan_lock);
    unschedule_hold(st->plan);
    st->plan = Plan();
  }
  return GST_BASE_TRANSFORM_CLASS(gst_spray_control_parent_class)->sink_event(trans, event);
}

static gboolean gst_spray_control_start(GstBaseTransform *trans)
{
  GstSprayControl *self = GST_SPRAY_CONTROL(trans);
  GST_OBJECT_LOCK(self);
  const Settings s = self->settings;
  GST_OBJECT_UNLOCK(self);
  // The section heights are checked here so a typo stops the pipeline before it runs.
  try {
    section_ranges(s);
  } catch (const std::exception &e) {
    treestereo::gst::report_exception(GST_ELEMENT(self), e);
    return FALSE;
  }
  std::lock_guard<std::mutex> lock(self->state->plan_lock);
  unschedule_hold(self->state->plan);
  self->state->plan = Plan();
  self->state->warned_missing = false;
  return TRUE;
}

static gboolean gst_spray_control_stop(GstBaseTransform *trans)
{
  GstSprayControl *self = GST_SPRAY_CONTROL(trans);
  std::lock_guard<std::mutex> lock(self->state->plan_lock);
  unschedule_hold(self->state->plan);
  self->state->plan = Plan();
  return TRUE;
}

static void gst_spray_control_finalize(GObject *object)
{
  GstSprayControl *self = GST_SPRAY_CONTROL(object);
  {
    std::lock_guard<std::mutex> lock(self->state->plan_lock);
    unschedule_hold(self->state->plan);
  }
  delete self->state;
  self->settings.~Settings();
  G_OBJECT_CLASS(gst_spray_control_parent_class)->finalize(object);
}

/* Read when the stream's first frame starts the plan: changes apply from the next start. */
static void gst_spray_control_class_init(GstSprayControlClass *klass)
{
  GObjectClass *gobject_class = G_OBJECT_CLASS(klass);
  GstElementClass *element_class = GST_ELEMENT_CLASS(klass);
  GstBaseTransformClass *bt_class = GST_BASE_TRANSFORM_CLASS(klass);

  GST_DEBUG_CATEGORY_INIT(spraycontrol_debug, "spraycontrol", 0, "treestereo spraycontrol");

  gobject_class->finalize = gst_spray_control_finalize;

  auto props = PropertyTable<Settings>::in_object<GstSprayControl>(gobject_class);
  props.uinteger("sections", "Sections",
                 "Nozzle sections; 0 = one per height band of the row map (or one per "
                 "section-heights range); another count must match those",
                 0, 256, DEFAULT_SECTIONS, TS_FIELD(sections), kRwReady);
  props.string("section-heights", "Section heights",
               "Each section's height range above the ground (m), lowest first: "
               "\"0.4:0.7,0.7:1.0,...\"; NULL = one section per band of the row map",
               TS_FIELD(section_heights), kRwReady);
  props.real("nozzle-offset", "Nozzle offset",
             "How far the nozzles sit behind the camera along the travel (m)", 0.0, 100.0,
             DEFAULT_NOZZLE_OFFSET, TS_FIELD(nozzle_offset), kRwReady);
  props.uinteger("valve-latency", "Valve latency",
                 "The valves' response time (ms): each command is due this much before "
                 "the nozzles reach its canopy slice",
                 0, 10000, DEFAULT_VALVE_LATENCY, TS_FIELD(valve_latency), kRwReady);
  props.real("min-gap", "Minimum gap", "Gaps in the canopy shorter than this (m) stay sprayed", 0.0,
             100.0, DEFAULT_MIN_GAP, TS_FIELD(min_gap), kRwReady);
  props.real("min-canopy", "Minimum canopy",
             "Canopy shorter than this along the row (m) is not sprayed (canopy where the data "
             "begins is, whatever its length: the view cut it)",
             0.0, 100.0,
             DEFAULT_MIN_CANOPY, TS_FIELD(min_canopy), kRwReady);
  props.enumeration("rate-model", "Rate model", "How a section's rate follows the canopy",
                    GST_TYPE_SPRAY_CONTROL_RATE_MODEL, DEFAULT_RATE_MODEL, TS_FIELD(rate_model),
                    kRwReady);
  props.uinteger("hold-time", "Hold time",
                 "Without a frame for this long (ms) the sections go to the fallback "
                 "state; until then they keep the last one",
                 1, 600000, DEFAULT_HOLD_TIME, TS_FIELD(hold_time), kRwReady);
  props.enumeration("fallback", "Fallback", "The sections' state after hold-time without data",
                    GST_TYPE_SPRAY_CONTROL_FALLBACK, DEFAULT_FALLBACK, TS_FIELD(fallback),
                    kRwReady);
  props.boolean("post-messages", "Post messages",
                "Post a 'treestereo-section' element message per valve command",
                DEFAULT_POST_MESSAGES, TS_FIELD(post_messages));
  props.string("timeline-location", "Timeline location",
               "PNG written at the end of the stream: the row map with each "
               "section's valve timeline under it (NULL: none)",
               TS_FIELD(timeline_location), kRwReady);

  add_filter_pad_templates(element_class, CAPS);
  gst_element_class_set_static_metadata(
      element_class, "Spray control", "Filter/Analyzer/Video",
      "Valve commands for the sprayer's nozzle sections from the row canopy map, timed for the "
      "travel, the nozzle offset and the valve latency, with a fail-safe when frames stop",
      "treestereo developers");
  gst_type_mark_as_plugin_api(GST_TYPE_SPRAY_CONTROL_RATE_MODEL, GstPluginAPIFlags(0));
  gst_type_mark_as_plugin_api(GST_TYPE_SPRAY_CONTROL_FALLBACK, GstPluginAPIFlags(0));

  bt_class->start = gst_spray_control_start;
  bt_class->stop = gst_spray_control_stop;
  bt_class->sink_event = gst_spray_control_sink_event;
  bt_class->transform_ip = gst_spray_control_transform_ip;
}

static void gst_spray_control_init(GstSprayControl *self)
{
  new (&self->settings) Settings();
  self->state = new State();
  gst_base_transform_set_in_place(GST_BASE_TRANSFORM(self), TRUE);
  gst_base_transform_set_passthrough(GST_BASE_TRANSFORM(self), FALSE);
}
