/**
 * SECTION:element-treecamerasrc
 * @title: treecamerasrc
 *
 * One Aravis camera (GigE Vision or USB3 Vision) that comes back when it drops out: a bin around
 * `aravissrc camera-name=... do-timestamp=true` with the chain the live pipelines need behind it
 * (a caps filter for what to ask of the camera, a leaky queue that keeps do-timestamp's stamp the
 * arrival time, `bayer2rgb` when #treecamerasrc:caps asks for Bayer, videoconvert) and a src pad
 * that gives RGB frames.
 *
 * A camera is lost when aravissrc reports an error (the camera went away: aravis gives up after
 * two seconds without a frame) or when no frame came for #treecamerasrc:timeout ms. The bin then
 * keeps the error off the bus, stops and removes that aravissrc (from its own thread, never the
 * streaming thread), posts a WARNING naming the camera and tries again with a fresh aravissrc after
 * #treecamerasrc:reconnect-interval ms, doubling the wait after each failed attempt up to
 * #treecamerasrc:reconnect-max. Frames flow again through the same src pad when the camera is
 * back; their stamps stay the pipeline's running time (the new aravissrc gets the bin's clock and
 * base time), so a stereorectify downstream pairs them again. The camera's own EOS after an
 * error never leaves the bin; one without an error (downstream ended the stream: a flow EOS) goes
 * on and ends it. An EOS sent to the bin (Ctrl-C in an application) goes down the
 * chain at once, whether the camera is streaming or missing.
 *
 * Applications follow the camera through `treestereo-camera` element messages:
 *
 * - `state` "lost": the camera stopped (or could not be opened at the start), with `reason`;
 * - `state` "retry": an attempt to open it again failed (`attempt`, `reason`, `retry-in` ms);
 * - `state` "back": frames come again after `attempt` attempts; `gap` is the time it was missing (ns).
 *
 * Each carries `camera` (the #treecamerasrc:camera string) and `running-time` (ns, the pipeline's).
 * With #treecamerasrc:reconnect-interval 0 nothing is retried: the camera's error reaches the bus
 * as it is and ends the pipeline, as a bare aravissrc does.
 *
 * ## Example launch lines
 * |[
 * gst-launch-1.0 treecamerasrc camera=192.168.1.21 caps="video/x-bayer,framerate=10/1" ! \
 *   videoconvert ! autovideosink
 * ]|
 * Two cameras into stereorectify (a latency so that a missing camera's partner frames are dropped,
 * not waited for):
 * |[
 * gst-launch-1.0 stereorectify name=r calibration=rig.yml latency=250000000 max-skew=75000000 ! \
 *   videoconvert ! autovideosink \
 *   treecamerasrc camera=left-cam ! r.left  treecamerasrc camera=right-cam ! r.right
 * ]|
 */
#ifdef HAVE_CONFIG_H
#include "config.h"
#endif

#include "common.hpp"
#include "elements.hpp"
#include "properties.hpp"

#include <algorithm>
#include <string>

GST_DEBUG_CATEGORY_STATIC(treecamerasrc_debug);
#define GST_CAT_DEFAULT treecamerasrc_debug

using namespace treestereo::gst;

#define DEFAULT_TIMEOUT 2000
#define DEFAULT_RECONNECT_INTERVAL 500
#define DEFAULT_RECONNECT_MAX 8000
#define QUEUE_FRAMES 8

namespace {

struct Settings {
  std::string camera;
  GstCaps *caps = nullptr;
  std::string features;
  guint timeout = DEFAULT_TIMEOUT;                       // ms
  guint reconnect_interval = DEFAULT_RECONNECT_INTERVAL; // ms, 0 = never
  guint reconnect_max = DEFAULT_RECONNECT_MAX;           // ms
};

enum class Phase {
  Connecting, // no aravissrc: the next attempt is due at next_try
  Starting,   // an aravissrc runs, its first frame has not come yet
  Streaming,  // frames come
  Stopped,    // given up (reconnect-interval 0) or a fatal error
};

/* The supervisor's view, under State::lock. The supervisor thread runs from READY->PAUSED to
 * PAUSED->READY; it alone adds and removes the aravissrc while it runs. */
struct State {
  GMutex lock;
  GCond cond;
  GThread *thread = nullptr;
  bool running = false; // the supervisor should run
  bool playing = false; // the bin is PLAYING: a camera is opened and timed only then
  bool eos = false;     // an EOS was sent down the chain: nothing is retried any more
  Phase phase = Phase::Connecting;
  GstElement *source = nullptr;  // the running aravissrc (a child), or null
  GstElement *opening = nullptr; // the aravissrc being opened: its errors fail the attempt
  std::string open_error;        // the error it posted
  bool fault = false;            // the running aravissrc posted an error
  std::string fault_reason;
  std::string first_error; // the first error of this attempt's aravissrc (kept past the fault)
  bool got_buffer = false; // Starting: its first frame came
  gint64 stream_at = 0;    // Starting: when its stream started (its caps set), 0 = not yet
  // A camera of this run has streamed with these caps: a not-negotiated flow after that is a
  // camera caught while it (re)starts or goes away, not caps it cannot give.
  bool streamed = false;
  gint64 started = 0, last_buffer = 0, next_try = 0, lost_at = 0; // monotonic, us
  guint attempt = 0;      // failed attempts since the camera was lost
  bool lost = false;      // "lost" posted, "back" not yet
  guint64 reconnects = 0; // times the camera came back
  GstPad *source_pad = nullptr; // its src pad (a ref): reached without the element's lock
  guint reapers = 0; // threads stopping lost aravissrcs (each holds a ref on the bin)
  // the settings of this run (READY->PAUSED)
  std::string camera;
  guint timeout = DEFAULT_TIMEOUT, interval = DEFAULT_RECONNECT_INTERVAL,
        interval_max = DEFAULT_RECONNECT_MAX;
  /* Serialises the aravissrc's state changes between the supervisor (opening, removing) and
   * change_state (PLAYING <-> PAUSED). Taken before lock, never while holding it. */
  GMutex source_lock;

  State()
  {
    g_mutex_init(&lock);
    g_cond_init(&cond);
    g_mutex_init(&source_lock);
  }
  ~State()
  {
    g_mutex_clear(&lock);
    g_cond_clear(&cond);
    g_mutex_clear(&source_lock);
  }
  State(const State &) = delete;
  State &operator=(const State &) = delete;
};

} // namespace

struct GstTreeCameraSrc {
  GstBin parent;
  Settings settings; // under the object lock
  State *state;
  GstPad *ghost;
  // the fixed chain behind the camera, built at NULL->READY (state-change thread only)
  GstElement *camfilter, *queue, *bayer, *convert, *outfilter;
};

struct GstTreeCameraSrcClass {
  GstBinClass parent_class;
};

#define GST_TYPE_TREE_CAMERA_SRC (gst_tree_camera_src_get_type())
#define GST_TREE_CAMERA_SRC(obj) \
  (G_TYPE_CHECK_INSTANCE_CAST((obj), GST_TYPE_TREE_CAMERA_SRC, GstTreeCameraSrc))

G_DEFINE_TYPE(GstTreeCameraSrc, gst_tree_camera_src, GST_TYPE_BIN);
GST_ELEMENT_REGISTER_DEFINE(treecamerasrc, "treecamerasrc", GST_RANK_NONE,
                            GST_TYPE_TREE_CAMERA_SRC);

static GstStaticPadTemplate src_template = GST_STATIC_PAD_TEMPLATE(
    "src", GST_PAD_SRC, GST_PAD_ALWAYS, GST_STATIC_CAPS("video/x-raw, format = (string) RGB"));

/* The pipeline's running time now, or NONE without a clock. */
static GstClockTime running_time_now(GstElement *element)
{
  GstClock *clock = gst_element_get_clock(element);
  if (!clock)
    return GST_CLOCK_TIME_NONE;
  const GstClockTime now = gst_clock_get_time(clock);
  gst_object_unref(clock);
  const GstClockTime base = gst_element_get_base_time(element);
  return now >= base ? now - base : 0;
}

/* A treestereo-camera element message (call with no lock held). */
static void post_camera_message(GstTreeCameraSrc *self, const std::string &camera,
                                const char *state, guint attempt, const std::string &reason,
                                guint retry_in_ms, GstClockTime gap)
{
  GstStructure *s = gst_structure_new("treestereo-camera", "camera", G_TYPE_STRING,
                                      camera.c_str(), "state", G_TYPE_STRING, state, "attempt",
                                      G_TYPE_UINT, attempt, "running-time", G_TYPE_UINT64,
                                      guint64(running_time_now(GST_ELEMENT(self))), nullptr);
  if (!reason.empty())
    gst_structure_set(s, "reason", G_TYPE_STRING, reason.c_str(), nullptr);
  if (std::string(state) == "retry")
    gst_structure_set(s, "retry-in", G_TYPE_UINT, retry_in_ms, nullptr);
  if (GST_CLOCK_TIME_IS_VALID(gap))
    gst_structure_set(s, "gap", G_TYPE_UINT64, guint64(gap), nullptr);
  treestereo::gst::post_element_message(GST_ELEMENT(self), s);
}

/* The wait before attempt @n + 1 after @n failed ones: the interval, doubled per failure. */
static guint backoff_ms(const State &st, guint n)
{
  guint64 ms = st.interval;
  for (guint i = 1; i < n && ms < st.interval_max; i++)
    ms *= 2;
  return guint(std::min<guint64>(ms, std::max(st.interval, st.interval_max)));
}

/* On the aravissrc's src pad: frames mark the camera alive, the CAPS event its stream's start;
 * its EOS after an error is a lost camera, not the end of the stream, and never leaves the bin. */
static GstPadProbeReturn source_probe(GstPad *pad, GstPadProbeInfo *info, gpointer data)
{
  GstTreeCameraSrc *self = GST_TREE_CAMERA_SRC(data);
  State &st = *self->state;
  if (info->type & (GST_PAD_PROBE_TYPE_BUFFER | GST_PAD_PROBE_TYPE_BUFFER_LIST)) {
    g_mutex_lock(&st.lock);
    if (pad != st.source_pad) { // a lost one's late frame (or the first, just before it is set)
      g_mutex_unlock(&st.lock);
      return GST_PAD_PROBE_OK;
    }
    st.last_buffer = g_get_monotonic_time();
    if (!st.got_buffer) {
      st.got_buffer = true;
      g_cond_broadcast(&st.cond);
    }
    g_mutex_unlock(&st.lock);
    return GST_PAD_PROBE_OK;
  }
  GstEvent *event = GST_PAD_PROBE_INFO_EVENT(info);
  if (event && GST_EVENT_TYPE(event) == GST_EVENT_CAPS) {
    // aravissrc configures the camera and starts its acquisition in set_caps, before this
    // event: from now on the camera has the timeout for its first frame
    g_mutex_lock(&st.lock);
    GstObject *parent = GST_OBJECT_PARENT(pad);
    if (parent && (parent == GST_OBJECT(st.opening) || pad == st.source_pad) && !st.stream_at) {
      st.stream_at = g_get_monotonic_time();
      if (st.phase == Phase::Starting)
        GST_DEBUG_OBJECT(self, "stream started %.2f s after the camera opened",
                         (st.stream_at - st.started) / 1e6);
      else
        GST_DEBUG_OBJECT(self, "stream started while the camera was being opened");
      g_cond_broadcast(&st.cond);
    }
    g_mutex_unlock(&st.lock);
    return GST_PAD_PROBE_OK;
  }
  if (event && GST_EVENT_TYPE(event) == GST_EVENT_EOS) {
    // After an error aravissrc posts it (handle_message, in this thread: fault set) and then
    // pushes EOS. An EOS of the streaming aravissrc with no error is the stream's end asked for
    // downstream (a flow EOS: a sink's num-buffers, an application's appsink): it goes on, and
    // nothing is retried after it.
    g_mutex_lock(&st.lock);
    const bool end = pad == st.source_pad && !st.fault && st.got_buffer;
    if (end) {
      st.eos = true;
      g_cond_broadcast(&st.cond);
    }
    g_mutex_unlock(&st.lock);
    if (end) {
      GST_DEBUG_OBJECT(self, "the stream's end, asked for downstream");
      return GST_PAD_PROBE_OK;
    }
    GST_DEBUG_OBJECT(self, "the camera's EOS stays in the bin");
    return GST_PAD_PROBE_DROP;
  }
  return GST_PAD_PROBE_OK;
}

/* On the chain's first pad: with no camera linked the latency query is answered as a live
 * source's (no latency of its own), so that an aggregator downstream runs in live mode and times
 * out instead of waiting for a camera that is not there. */
static GstPadProbeReturn chain_query_probe(GstPad *pad, GstPadProbeInfo *info, gpointer)
{
  GstQuery *query = GST_PAD_PROBE_INFO_QUERY(info);
  if (!query || GST_QUERY_TYPE(query) != GST_QUERY_LATENCY)
    return GST_PAD_PROBE_OK;
  GstPad *peer = gst_pad_get_peer(pad);
  if (peer) {
    gst_object_unref(peer);
    return GST_PAD_PROBE_OK;
  }
  gst_query_set_latency(query, TRUE, 0, GST_CLOCK_TIME_NONE);
  return GST_PAD_PROBE_HANDLED;
}

/* Stops and removes @src, an aravissrc whose opening failed (supervisor thread). */
static void remove_source(GstTreeCameraSrc *self, GstElement *src)
{
  const gint64 t0 = g_get_monotonic_time();
  gst_element_set_state(src, GST_STATE_NULL);
  gst_bin_remove(GST_BIN(self), src); // drops the bin's ref
  GST_INFO_OBJECT(self, "an aravissrc stopped and removed in %.2f s",
                  (g_get_monotonic_time() - t0) / 1e6);
}

#define REAPER_WAIT_US (2 * G_USEC_PER_SEC)
// The longest a camera's stream set-up may take before the first-frame timeout applies
#define STREAM_SETUP_US (5 * G_USEC_PER_SEC)

struct Reap {
  GstTreeCameraSrc *self; // a ref
  GstElement *src;        // a ref
};

/* A lost aravissrc's end, on its own thread: out of the bin, then stopped. */
static gpointer reap(gpointer data)
{
  Reap *r = static_cast<Reap *>(data);
  State &st = *r->self->state;
  const gint64 t0 = g_get_monotonic_time();
  // waits for the element's lock, which its frame wait holds (aravis: 2 s after the last frame)
  gst_bin_remove(GST_BIN(r->self), r->src);
  gst_element_set_state(r->src, GST_STATE_NULL);
  GST_INFO_OBJECT(r->self, "a lost aravissrc stopped and removed in %.2f s",
                  (g_get_monotonic_time() - t0) / 1e6);
  gst_object_unref(r->src);
  g_mutex_lock(&st.lock);
  st.reapers--;
  g_cond_broadcast(&st.cond);
  g_mutex_unlock(&st.lock);
  gst_object_unref(r->self);
  delete r;
  return nullptr;
}

/* Takes the running aravissrc, if any, off the chain at once (the chain is free for the next
 * one) and stops and removes it on a reaper thread. Stopping an
 * aravissrc whose camera is gone takes seconds (its frame wait times out, then aravis waits for
 * the camera to acknowledge the end of the acquisition and of its control, 2.5 s each): the next
 * attempt need not wait for it. */
static void teardown_source(GstTreeCameraSrc *self)
{
  State &st = *self->state;
  g_mutex_lock(&st.source_lock);
  g_mutex_lock(&st.lock);
  GstElement *src = st.source;
  GstPad *pad = st.source_pad;
  st.source = nullptr;
  st.source_pad = nullptr;
  g_mutex_unlock(&st.lock);
  if (pad) {
    if (GstPad *peer = gst_pad_get_peer(pad)) {
      gst_pad_unlink(pad, peer);
      gst_object_unref(peer);
    }
    gst_object_unref(pad);
  }
  if (src) {
    GST_DEBUG_OBJECT(self, "removing %" GST_PTR_FORMAT, src);
    g_mutex_lock(&st.lock);
    st.reapers++;
    g_mutex_unlock(&st.lock);
    Reap *r = new Reap{GST_TREE_CAMERA_SRC(gst_object_ref(self)),
                       GST_ELEMENT(gst_object_ref(src))};
    g_thread_unref(g_thread_new("treecamerasrc-stop", reap, r));
  }
  g_mutex_unlock(&st.source_lock);
}

/* Waits a little for the reapers: an aravissrc whose camera is gone may take aravis 8 s and
 * more to stop, which must not hold up the pipeline's stop (Ctrl-C); a reaper still running
 * finishes on its own (it holds refs on the bin and the aravissrc). */
static void wait_reapers(GstTreeCameraSrc *self)
{
  State &st = *self->state;
  const gint64 end = g_get_monotonic_time() + REAPER_WAIT_US;
  g_mutex_lock(&st.lock);
  while (st.reapers > 0 && g_cond_wait_until(&st.cond, &st.lock, end)) {
  }
  if (st.reapers > 0)
    GST_INFO_OBJECT(self, "%u lost aravissrc(s) still stopping: not waiting for them",
                    st.reapers);
  g_mutex_unlock(&st.lock);
}

/* One attempt: a fresh aravissrc, the camera opened (aravissrc opens it when camera-name is
 * set), linked to the chain, started in the bin's state with its clock and base time. TRUE when
 * it runs; otherwise @why says what failed and nothing is left behind. */
static bool open_source(GstTreeCameraSrc *self, std::string &why)
{
  State &st = *self->state;
  GstElement *src = gst_element_factory_make("aravissrc", nullptr);
  if (!src) {
    why = "the GStreamer element aravissrc is missing";
    return false;
  }
  GST_OBJECT_LOCK(self);
  const std::string features = self->settings.features;
  GST_OBJECT_UNLOCK(self);
  g_object_set(src, "do-timestamp", TRUE, nullptr);
  gst_element_set_locked_state(src, TRUE); // the supervisor and change_state set its state
  // the bin is the source: GstBin would clear its SOURCE flag when this child is removed, and a
  // pipeline sends EOS only to children flagged so (gst_bin_iterate_sources)
  GST_OBJECT_FLAG_UNSET(src, GST_ELEMENT_FLAG_SOURCE);
  g_mutex_lock(&st.lock);
  st.opening = src;
  st.open_error.clear();
  st.first_error.clear();
  const std::string camera = st.camera;
  g_mutex_unlock(&st.lock);
  gst_bin_add(GST_BIN(self), src);
  g_object_set(src, "camera-name", camera.c_str(), nullptr);
  if (!features.empty())
    g_object_set(src, "features", features.c_str(), nullptr);
  GstPad *srcpad = nullptr;
  GObject *arv_camera = nullptr;
  g_object_get(src, "camera", &arv_camera, nullptr);
  bool ok = arv_camera != nullptr;
  if (arv_camera)
    g_object_unref(arv_camera);
  if (ok) {
    srcpad = gst_element_get_static_pad(src, "src");
    GstPad *sinkpad = gst_element_get_static_pad(self->camfilter, "sink");
    gst_pad_add_probe(srcpad,
                      GstPadProbeType(GST_PAD_PROBE_TYPE_BUFFER | GST_PAD_PROBE_TYPE_BUFFER_LIST |
                                      GST_PAD_PROBE_TYPE_EVENT_DOWNSTREAM),
                      source_probe, self, nullptr);
    ok = gst_pad_link(srcpad, sinkpad) == GST_PAD_LINK_OK;
    if (!ok)
      why = "cannot link aravissrc to the chain";
    gst_object_unref(sinkpad);
  }
  if (ok) {
    g_mutex_lock(&st.source_lock);
    g_mutex_lock(&st.lock);
    const bool playing = st.playing && st.running && !st.eos;
    st.got_buffer = false;
    st.stream_at = 0;
    st.fault = false;
    g_mutex_unlock(&st.lock);
    if (playing) {
      if (GstClock *clock = gst_element_get_clock(GST_ELEMENT(self))) {
        gst_element_set_clock(src, clock);
        gst_object_unref(clock);
      }
      gst_element_set_base_time(src, gst_element_get_base_time(GST_ELEMENT(self)));
      ok = gst_element_set_state(src, GST_STATE_PLAYING) != GST_STATE_CHANGE_FAILURE;
    } else {
      ok = false;
      why = "stopping";
    }
    g_mutex_lock(&st.lock);
    if (ok) {
      st.source = src;
      st.source_pad = GST_PAD(gst_object_ref(srcpad));
    }
    st.opening = nullptr;
    g_mutex_unlock(&st.lock);
    g_mutex_unlock(&st.source_lock);
  }
  if (!ok) {
    g_mutex_lock(&st.lock);
    st.opening = nullptr;
    if (why.empty())
      why = st.open_error.empty() ? "cannot open the camera" : st.open_error;
    g_mutex_unlock(&st.lock);
    remove_source(self, src);
  }
  if (srcpad)
    gst_object_unref(srcpad);
  return ok;
}

/* The supervisor: opens the camera, watches its frames and errors, removes a lost aravissrc and
 * opens a new one with back-off. Waits on State::cond, woken by frames, errors, EOS, state
 * changes and the stop. */
static gpointer supervise(gpointer data)
{
  GstTreeCameraSrc *self = GST_TREE_CAMERA_SRC(data);
  State &st = *self->state;
  g_mutex_lock(&st.lock);
  while (st.running) {
    if (st.eos || !st.playing || st.phase == Phase::Stopped) {
      g_cond_wait(&st.cond, &st.lock);
      continue;
    }
    const gint64 now = g_get_monotonic_time();
    const std::string camera = st.camera;
    if (st.phase == Phase::Connecting) {
      if (now < st.next_try) {
        g_cond_wait_until(&st.cond, &st.lock, st.next_try);
        continue;
      }
      g_mutex_unlock(&st.lock);
      std::string why;
      const bool ok = open_source(self, why);
      g_mutex_lock(&st.lock);
      if (ok) {
        st.phase = Phase::Starting;
        st.started = g_get_monotonic_time();
        GST_INFO_OBJECT(self, "camera '%s' opened (attempt %u)", camera.c_str(), st.attempt + 1);
      }
      if (ok || !st.running || st.eos || !st.playing)
        continue; // the stop removes a source that opened meanwhile
      st.attempt++;
      if (st.interval == 0) {
        // no reconnecting: aravissrc's error went to the bus as it is (handle_message)
        st.phase = Phase::Stopped;
        const bool posted = !st.open_error.empty();
        g_mutex_unlock(&st.lock);
        if (!posted)
          GST_ELEMENT_ERROR(self, RESOURCE, NOT_FOUND,
                            ("Camera '%s' cannot be opened: %s", camera.c_str(), why.c_str()),
                            ("reconnect-interval is 0: not retrying"));
        g_mutex_lock(&st.lock);
        continue;
      }
      const guint wait = backoff_ms(st, st.attempt);
      st.next_try = g_get_monotonic_time() + gint64(wait) * 1000;
      const bool first = !st.lost;
      if (first) {
        st.lost = true;
        st.lost_at = now;
      }
      const guint attempt = st.attempt;
      g_mutex_unlock(&st.lock);
      if (first) {
        GST_ELEMENT_WARNING(self, RESOURCE, NOT_FOUND,
                            ("camera '%s' not available: %s; reconnecting", camera.c_str(),
                             why.c_str()),
                            ("next attempt in %u ms", wait));
        post_camera_message(self, camera, "lost", attempt, why, 0, GST_CLOCK_TIME_NONE);
      } else {
        GST_INFO_OBJECT(self, "attempt %u at camera '%s' failed: %s; next in %u ms", attempt,
                        camera.c_str(), why.c_str(), wait);
        post_camera_message(self, camera, "retry", attempt, why, wait, GST_CLOCK_TIME_NONE);
      }
      g_mutex_lock(&st.lock);
      continue;
    }

    // Starting or Streaming
    if (st.phase == Phase::Starting && st.got_buffer) {
      st.phase = Phase::Streaming;
      st.streamed = true;
      const bool was_lost = st.lost;
      const guint attempt = st.attempt + 1;
      const GstClockTime gap = GstClockTime(now - st.lost_at) * GST_USECOND;
      st.lost = false;
      st.attempt = 0;
      if (was_lost)
        st.reconnects++;
      g_mutex_unlock(&st.lock);
      // the new aravissrc's latency may differ from what was answered without a camera
      gst_element_post_message(GST_ELEMENT(self), gst_message_new_latency(GST_OBJECT(self)));
      if (was_lost) {
        GST_INFO_OBJECT(self, "camera '%s' back after %.1f s", camera.c_str(), gap / 1e9);
        post_camera_message(self, camera, "back", attempt, "", 0, gap);
      }
      g_mutex_lock(&st.lock);
      continue;
    }
    // A newly opened camera has the timeout for its first frame from its stream's start; the
    // configuration before that (aravissrc's set_caps: many register writes, stretched by a
    // loaded host) has up to STREAM_SETUP_US more, and a camera gone meanwhile fails it
    // with aravis's error at once.
    const gint64 timeout_us = gint64(st.timeout) * 1000;
    gint64 deadline = st.started + std::max(timeout_us, gint64(STREAM_SETUP_US));
    if (st.phase == Phase::Streaming)
      deadline = st.last_buffer + timeout_us;
    else if (st.stream_at)
      deadline = st.stream_at + timeout_us;
    if (!st.fault && now < deadline) {
      g_cond_wait_until(&st.cond, &st.lock, deadline);
      continue;
    }
    std::string reason = st.fault ? st.fault_reason
                                  : "no frame for " + std::to_string(st.timeout) + " ms";
    const bool was_streaming = st.phase == Phase::Streaming;
    st.phase = Phase::Connecting;
    st.fault = false;
    const bool first = !st.lost;
    if (st.interval > 0 && first) {
      st.lost = true;
      st.lost_at = was_streaming ? st.last_buffer : now;
      st.attempt = 0;
    } else if (st.interval > 0) {
      st.attempt++; // it opened but sent no frame
    }
    const guint wait = first ? st.interval : backoff_ms(st, st.attempt);
    const guint attempt = st.attempt;
    const guint interval = st.interval;
    g_mutex_unlock(&st.lock);
    // said at once: the lost camera's aravissrc is then unlinked and stopped on a reaper thread
    if (interval > 0 && first) {
      GST_ELEMENT_WARNING(self, RESOURCE, READ,
                          ("camera '%s' lost: %s; reconnecting", camera.c_str(), reason.c_str()),
                          ("first attempt in %u ms", wait));
      post_camera_message(self, camera, "lost", attempt, reason, 0, GST_CLOCK_TIME_NONE);
    } else if (interval > 0) {
      post_camera_message(self, camera, "retry", attempt, reason, wait, GST_CLOCK_TIME_NONE);
    }
    const gint64 t0 = g_get_monotonic_time();
    teardown_source(self);
    GST_INFO_OBJECT(self, "camera '%s': %s; its aravissrc taken off the chain", camera.c_str(),
                    reason.c_str());
    g_mutex_lock(&st.lock);
    if (!st.running || st.eos)
      continue;
    if (interval == 0) {
      st.phase = Phase::Stopped;
      g_mutex_unlock(&st.lock);
      GST_ELEMENT_ERROR(self, RESOURCE, READ, ("Camera '%s' lost: %s", camera.c_str(),
                                               reason.c_str()),
                        ("reconnect-interval is 0: not reconnecting"));
      g_mutex_lock(&st.lock);
      continue;
    }
    // the wait counts from the loss, not from the end of the removal
    st.next_try = t0 + gint64(wait) * 1000;
  }
  g_mutex_unlock(&st.lock);
  return nullptr;
}

/* Whether aravissrc's set-up failed because the camera would not take orders now, not because
 * of what was asked. Another process controls it (GigE Vision grants control to one
 * application, and one that ended without letting go holds it until its heartbeat times out, a
 * few seconds): aravis says "Controller privilege required", or the camera refuses or ignores
 * the register writes ("GigEVision write_register error (access-denied)" or "... timeout"). A
 * camera that does not answer for a moment fails the same way. Both pass. Only aravis's message
 * tells them from caps or features the camera refuses ("[Gain] Not found"): aravissrc posts no
 * error code. */
static bool camera_held_or_silent(const std::string &error)
{
  for (const char *word : {"privilege", "access-denied", "busy", "timeout"})
    if (error.find(word) != std::string::npos)
      return true;
  return false;
}

/* Errors of the aravissrc (opening, streaming) are a lost camera while reconnecting is on: they
 * stay in the bin and the supervisor acts. A not-negotiated flow (the caps ask for what the
 * camera cannot give) is a configuration fault and goes to the bus, unless a camera has streamed
 * with these caps in this run: then it is a camera caught while it restarts (seen with a fake
 * camera killed and started again), and the attempt fails like any other. So it does when
 * another process controls the camera, or the camera does not answer: that passes too. */
static void gst_tree_camera_src_handle_message(GstBin *bin, GstMessage *msg)
{
  GstTreeCameraSrc *self = GST_TREE_CAMERA_SRC(bin);
  State &st = *self->state;
  if (GST_MESSAGE_TYPE(msg) == GST_MESSAGE_ERROR) {
    GError *err = nullptr;
    gst_message_parse_error(msg, &err, nullptr);
    gint flow = GST_FLOW_OK;
    const GstStructure *details = nullptr;
    gst_message_parse_error_details(msg, &details);
    if (details)
      gst_structure_get_int(details, "flow-return", &flow);
    bool keep = false;
    std::string config_fault; // set: a configuration fault, posted as the bin's own error
    std::string camera;
    GstObject *from = GST_MESSAGE_SRC(msg);
    // an aravissrc: the current one, the one being opened, or one being removed (perhaps
    // already out of the bin: its message was on its way)
    bool from_camera = false;
    if (GST_IS_ELEMENT(from))
      if (GstElementFactory *f = gst_element_get_factory(GST_ELEMENT(from)))
        from_camera = g_str_equal(GST_OBJECT_NAME(f), "aravissrc");
    g_mutex_lock(&st.lock);
    const bool from_opening = st.opening && from == GST_OBJECT(st.opening);
    const bool from_source = st.source && from == GST_OBJECT(st.source);
    if ((from_opening || from_source) && st.first_error.empty())
      st.first_error = err->message;
    const bool held = camera_held_or_silent(st.first_error);
    if (from_camera && st.eos) {
      keep = true; // the end was asked for: a camera failing now changes nothing
    } else if (from_camera && flow == GST_FLOW_NOT_NEGOTIATED && !st.streamed && !held) {
      // also from an aravissrc the supervisor has just taken off the chain for the error that
      // came before this one (set_caps's), which it may see first
      st.phase = Phase::Stopped; // goes to the bus: the caps are wrong, retrying cannot help
      // aravissrc's own error before it says why (set_caps: "[Gain] Not found"); its flow error
      // alone says only "Internal data stream error"
      config_fault = st.first_error.empty() ? std::string(err->message) : st.first_error;
      camera = st.camera;
    } else if (from_camera && !from_opening && !from_source) {
      // an aravissrc already taken off the chain (lost, or stopping: unlinked, it fails with
      // not-linked): a camera failing now changes nothing
      keep = true;
    } else if (from_opening) {
      // the first error says why (set_caps's); the flow error that follows it does not
      if (st.open_error.empty())
        st.open_error = err->message;
      keep = st.interval > 0;
    } else if (from_source && st.interval > 0) {
      if (!st.fault)
        st.fault_reason = err->message;
      st.fault = true;
      keep = true;
      g_cond_broadcast(&st.cond);
    } else if (from_source) {
      st.phase = Phase::Stopped;
    }
    g_mutex_unlock(&st.lock);
    if (keep)
      GST_INFO_OBJECT(self, "kept off the bus: %s", err->message);
    g_error_free(err);
    if (!config_fault.empty()) {
      GST_OBJECT_LOCK(self);
      gchar *caps = self->settings.caps ? gst_caps_to_string(self->settings.caps) : nullptr;
      const std::string features = self->settings.features;
      GST_OBJECT_UNLOCK(self);
      GST_ELEMENT_ERROR(self, CORE, NEGOTIATION,
                        ("Camera '%s' cannot stream as configured: %s", camera.c_str(),
                         config_fault.c_str()),
                        ("check treecamerasrc's caps (%s) and features (%s); retrying cannot help",
                         caps ? caps : "none", features.empty() ? "none" : features.c_str()));
      g_free(caps);
      gst_message_unref(msg);
      return;
    }
    if (keep) {
      gst_message_unref(msg);
      return;
    }
  }
  GST_BIN_CLASS(gst_tree_camera_src_parent_class)->handle_message(bin, msg);
}

/* EOS goes into the chain at once, ahead of the camera: it ends the stream whether the camera
 * streams, is being opened or is missing. */
static gboolean gst_tree_camera_src_send_event(GstElement *element, GstEvent *event)
{
  GstTreeCameraSrc *self = GST_TREE_CAMERA_SRC(element);
  State &st = *self->state;
  if (GST_EVENT_TYPE(event) != GST_EVENT_EOS || !self->camfilter)
    return GST_ELEMENT_CLASS(gst_tree_camera_src_parent_class)->send_event(element, event);
  g_mutex_lock(&st.lock);
  const bool already = st.eos;
  st.eos = true;
  g_cond_broadcast(&st.cond);
  g_mutex_unlock(&st.lock);
  if (already) {
    gst_event_unref(event);
    return TRUE;
  }
  GST_DEBUG_OBJECT(self, "EOS into the chain");
  GstPad *sinkpad = gst_element_get_static_pad(self->camfilter, "sink");
  const gboolean ok = gst_pad_send_event(sinkpad, event);
  gst_object_unref(sinkpad);
  return ok;
}

static void remove_chain(GstTreeCameraSrc *self)
{
  gst_ghost_pad_set_target(GST_GHOST_PAD(self->ghost), nullptr);
  for (GstElement **e : {&self->camfilter, &self->queue, &self->bayer, &self->convert,
                         &self->outfilter}) {
    if (*e) {
      gst_element_set_state(*e, GST_STATE_NULL);
      gst_bin_remove(GST_BIN(self), *e);
      *e = nullptr;
    }
  }
}

static GstElement *make(GstTreeCameraSrc *self, const char *factory)
{
  GstElement *e = gst_element_factory_make(factory, nullptr);
  if (!e)
    GST_ELEMENT_ERROR(self, CORE, MISSING_PLUGIN,
                      ("The GStreamer element %s is missing: install the package that has it "
                       "(scripts/deps.sh lists them)",
                       factory),
                      (nullptr));
  return e;
}

/* caps filter ! leaky queue ! [bayer2rgb] ! videoconvert ! RGB, the ghost pad on its end. */
static bool build_chain(GstTreeCameraSrc *self)
{
  remove_chain(self);
  GST_OBJECT_LOCK(self);
  const std::string camera = self->settings.camera;
  GstCaps *caps = self->settings.caps ? gst_caps_ref(self->settings.caps) : nullptr;
  GST_OBJECT_UNLOCK(self);
  if (camera.empty()) {
    if (caps)
      gst_caps_unref(caps);
    GST_ELEMENT_ERROR(self, RESOURCE, SETTINGS,
                      ("No camera: set treecamerasrc's camera property to the camera's name, "
                       "serial number or IP address (arv-tool-0.8 lists the cameras it sees)."),
                      ("the camera property is empty"));
    return false;
  }
  GstPluginFeature *arv = gst_registry_lookup_feature(gst_registry_get(), "aravissrc");
  if (!arv) {
    if (caps)
      gst_caps_unref(caps);
    GST_ELEMENT_ERROR(self, CORE, MISSING_PLUGIN,
                      ("The GStreamer element aravissrc is missing: install the Aravis plugin "
                       "(Debian: gstreamer1.0-plugins-bad's aravis part, libaravis-0.8-0)"),
                      (nullptr));
    return false;
  }
  gst_object_unref(arv);
  bool bayer = false;
  if (caps && !gst_caps_is_any(caps) && !gst_caps_is_empty(caps))
    bayer = gst_structure_has_name(gst_caps_get_structure(caps, 0), "video/x-bayer");

  self->camfilter = make(self, "capsfilter");
  self->queue = make(self, "queue");
  self->bayer = bayer ? make(self, "bayer2rgb") : nullptr;
  self->convert = make(self, "videoconvert");
  self->outfilter = make(self, "capsfilter");
  if (!self->camfilter || !self->queue || (bayer && !self->bayer) || !self->convert ||
      !self->outfilter) {
    for (GstElement **e : {&self->camfilter, &self->queue, &self->bayer, &self->convert,
                           &self->outfilter})
      if (*e) {
        gst_object_unref(gst_object_ref_sink(*e));
        *e = nullptr;
      }
    if (caps)
      gst_caps_unref(caps);
    return false;
  }
  if (caps) {
    g_object_set(self->camfilter, "caps", caps, nullptr);
    gst_caps_unref(caps);
  }
  // a leaky queue right behind the camera: the source thread never blocks, so do-timestamp's
  // stamp is the frame's arrival (docs/aravis.md)
  g_object_set(self->queue, "max-size-buffers", guint(QUEUE_FRAMES), "max-size-bytes", 0u,
               "max-size-time", guint64(0), nullptr);
  gst_util_set_object_arg(G_OBJECT(self->queue), "leaky", "downstream");
  GstCaps *rgb = gst_caps_from_string("video/x-raw,format=RGB");
  g_object_set(self->outfilter, "caps", rgb, nullptr);
  gst_caps_unref(rgb);

  gst_bin_add_many(GST_BIN(self), self->camfilter, self->queue, self->convert, self->outfilter,
                   nullptr);
  bool linked;
  if (self->bayer) {
    gst_bin_add(GST_BIN(self), self->bayer);
    linked = gst_element_link_many(self->camfilter, self->queue, self->bayer, self->convert,
                                   self->outfilter, nullptr);
  } else {
    linked = gst_element_link_many(self->camfilter, self->queue, self->convert, self->outfilter,
                                   nullptr);
  }
  GstPad *sinkpad = gst_element_get_static_pad(self->camfilter, "sink");
  gst_pad_add_probe(sinkpad, GST_PAD_PROBE_TYPE_QUERY_UPSTREAM, chain_query_probe, self, nullptr);
  gst_object_unref(sinkpad);
  GstPad *out = gst_element_get_static_pad(self->outfilter, "src");
  linked = linked && gst_ghost_pad_set_target(GST_GHOST_PAD(self->ghost), out);
  gst_object_unref(out);
  if (!linked) {
    GST_ELEMENT_ERROR(self, CORE, NEGOTIATION, ("Cannot link the chain behind the camera"),
                      (nullptr));
    return false;
  }
  return true;
}

static void start_supervisor(GstTreeCameraSrc *self)
{
  State &st = *self->state;
  GST_OBJECT_LOCK(self);
  const Settings &s = self->settings;
  g_mutex_lock(&st.lock);
  st.camera = s.camera;
  st.timeout = s.timeout;
  st.interval = s.reconnect_interval;
  st.interval_max = s.reconnect_max;
  GST_OBJECT_UNLOCK(self);
  st.running = true;
  st.playing = false;
  st.eos = false;
  st.phase = Phase::Connecting;
  st.next_try = 0;
  st.attempt = 0;
  st.lost = false;
  st.fault = false;
  st.got_buffer = false;
  st.streamed = false;
  g_mutex_unlock(&st.lock);
  st.thread = g_thread_new("treecamerasrc", supervise, self);
}

static void stop_supervisor(GstTreeCameraSrc *self)
{
  State &st = *self->state;
  g_mutex_lock(&st.lock);
  st.running = false;
  g_cond_broadcast(&st.cond);
  GThread *thread = st.thread;
  st.thread = nullptr;
  g_mutex_unlock(&st.lock);
  const gint64 t0 = g_get_monotonic_time();
  if (thread)
    g_thread_join(thread);
  const gint64 t1 = g_get_monotonic_time();
  // on a reaper too: the camera may be gone without the timeout having said so yet
  teardown_source(self);
  wait_reapers(self);
  GST_INFO_OBJECT(self, "stopped: supervisor %.2f s, cameras %.2f s", (t1 - t0) / 1e6,
                  (g_get_monotonic_time() - t1) / 1e6);
}

/* PLAYING <-> PAUSED for the aravissrc, which the bin's own state changes skip (locked). */
static void set_playing(GstTreeCameraSrc *self, bool playing)
{
  State &st = *self->state;
  g_mutex_lock(&st.source_lock);
  g_mutex_lock(&st.lock);
  st.playing = playing;
  // time from now: a pause is no gap
  st.started = st.last_buffer = g_get_monotonic_time();
  if (st.stream_at)
    st.stream_at = st.started;
  GstElement *src = st.source ? GST_ELEMENT(gst_object_ref(st.source)) : nullptr;
  g_cond_broadcast(&st.cond);
  g_mutex_unlock(&st.lock);
  if (src) {
    if (playing)
      gst_element_set_base_time(src, gst_element_get_base_time(GST_ELEMENT(self)));
    gst_element_set_state(src, playing ? GST_STATE_PLAYING : GST_STATE_PAUSED);
    gst_object_unref(src);
  }
  g_mutex_unlock(&st.source_lock);
}

static GstStateChangeReturn gst_tree_camera_src_change_state(GstElement *element,
                                                             GstStateChange transition)
{
  GstTreeCameraSrc *self = GST_TREE_CAMERA_SRC(element);
  switch (transition) {
  case GST_STATE_CHANGE_NULL_TO_READY:
    if (!build_chain(self))
      return GST_STATE_CHANGE_FAILURE;
    break;
  case GST_STATE_CHANGE_READY_TO_PAUSED:
    start_supervisor(self);
    break;
  case GST_STATE_CHANGE_PLAYING_TO_PAUSED:
    set_playing(self, false);
    break;
  case GST_STATE_CHANGE_PAUSED_TO_READY:
    stop_supervisor(self);
    break;
  default:
    break;
  }
  GstStateChangeReturn ret =
      GST_ELEMENT_CLASS(gst_tree_camera_src_parent_class)->change_state(element, transition);
  if (ret == GST_STATE_CHANGE_FAILURE) {
    if (transition == GST_STATE_CHANGE_READY_TO_PAUSED)
      stop_supervisor(self);
    return ret;
  }
  switch (transition) {
  case GST_STATE_CHANGE_PAUSED_TO_PLAYING:
    // after the bin: the base time is the pipeline's now
    set_playing(self, true);
    break;
  case GST_STATE_CHANGE_READY_TO_NULL:
    remove_chain(self);
    break;
  default:
    break;
  }
  // a live source: no preroll in PAUSED
  if (transition == GST_STATE_CHANGE_READY_TO_PAUSED ||
      transition == GST_STATE_CHANGE_PLAYING_TO_PAUSED)
    ret = GST_STATE_CHANGE_NO_PREROLL;
  return ret;
}

static void gst_tree_camera_src_finalize(GObject *object)
{
  GstTreeCameraSrc *self = GST_TREE_CAMERA_SRC(object);
  if (self->settings.caps)
    gst_caps_unref(self->settings.caps);
  self->settings.~Settings();
  delete self->state;
  G_OBJECT_CLASS(gst_tree_camera_src_parent_class)->finalize(object);
}

/* Read when the camera is opened (READY->PAUSED): changes apply from the next start. */
static void gst_tree_camera_src_class_init(GstTreeCameraSrcClass *klass)
{
  GObjectClass *gobject_class = G_OBJECT_CLASS(klass);
  GstElementClass *element_class = GST_ELEMENT_CLASS(klass);
  GstBinClass *bin_class = GST_BIN_CLASS(klass);

  GST_DEBUG_CATEGORY_INIT(treecamerasrc_debug, "treecamerasrc", 0, "treestereo treecamerasrc");

  gobject_class->finalize = gst_tree_camera_src_finalize;

  auto props = PropertyTable<Settings>::in_object<GstTreeCameraSrc>(gobject_class);
  props.string("camera", "Camera",
               "The camera's name, serial number or IP address, as aravissrc's "
               "camera-name (arv-tool-0.8 lists them)",
               TS_FIELD(camera), kRwReady);
  props.custom(
      g_param_spec_boxed("caps", "Caps",
                         "What to ask of the camera (e.g. video/x-bayer,framerate=10/1: Bayer "
                         "adds bayer2rgb); NULL = what it gives by default",
                         GST_TYPE_CAPS, kRwReady),
      [](Settings &s, const GValue *v) {
        gst_caps_replace(&s.caps, static_cast<GstCaps *>(g_value_get_boxed(v)));
      },
      [](const Settings &s, GValue *v) { g_value_set_boxed(v, s.caps); });
  props.string("features", "Features",
               "GenICam features set on each opening, as aravissrc's features "
               "(\"TriggerMode=On TriggerSource=Line0\")",
               TS_FIELD(features), kRwReady);
  props.uinteger("timeout", "Timeout",
                 "The camera is lost when no frame came for this long (ms); also the "
                 "time a newly opened camera has for its first frame once its stream "
                 "started (its set-up before that may take 5 s)",
                 100, 600000, DEFAULT_TIMEOUT, TS_FIELD(timeout), kRwReady);
  props.uinteger("reconnect-interval", "Reconnect interval",
                 "Wait before the first attempt to open a lost camera again (ms), doubled "
                 "after each failed one; 0 = no reconnecting: the camera's error ends "
                 "the stream",
                 0, 600000, DEFAULT_RECONNECT_INTERVAL, TS_FIELD(reconnect_interval), kRwReady);
  props.uinteger("reconnect-max", "Reconnect maximum", "The longest wait between two attempts (ms)",
                 100, 3600000, DEFAULT_RECONNECT_MAX, TS_FIELD(reconnect_max), kRwReady);
  /* The supervisor's figures, under its own lock. */
  props.on_object(g_param_spec_boolean("connected", "Connected", "Frames come from the camera",
                                       FALSE, kReadOnly),
                  nullptr, [](GObject *o, GValue *v) {
                    State &st = *GST_TREE_CAMERA_SRC(o)->state;
                    g_mutex_lock(&st.lock);
                    g_value_set_boolean(v, st.phase == Phase::Streaming && st.running);
                    g_mutex_unlock(&st.lock);
                  });
  props.on_object(g_param_spec_uint64("reconnects", "Reconnects", "Times the camera came back", 0,
                                      G_MAXUINT64, 0, kReadOnly),
                  nullptr, [](GObject *o, GValue *v) {
                    State &st = *GST_TREE_CAMERA_SRC(o)->state;
                    g_mutex_lock(&st.lock);
                    g_value_set_uint64(v, st.reconnects);
                    g_mutex_unlock(&st.lock);
                  });

  gst_element_class_add_static_pad_template(element_class, &src_template);
  gst_element_class_set_static_metadata(
      element_class, "Tree camera source", "Source/Video/Bin",
      "An Aravis camera (aravissrc) that is reopened when it drops out, with the caps filter, "
      "leaky queue and conversion to RGB that live measuring needs",
      "treestereo developers");

  element_class->change_state = gst_tree_camera_src_change_state;
  element_class->send_event = gst_tree_camera_src_send_event;
  bin_class->handle_message = gst_tree_camera_src_handle_message;
}

static void gst_tree_camera_src_init(GstTreeCameraSrc *self)
{
  new (&self->settings) Settings();
  self->state = new State();
  self->camfilter = self->queue = self->bayer = self->convert = self->outfilter = nullptr;
  GstPadTemplate *templ = gst_static_pad_template_get(&src_template);
  self->ghost = gst_ghost_pad_new_no_target_from_template("src", templ);
  gst_object_unref(templ);
  gst_element_add_pad(GST_ELEMENT(self), self->ghost);
  // a source also while no aravissrc is inside (a pipeline's EOS goes to its sources only)
  GST_OBJECT_FLAG_SET(self, GST_ELEMENT_FLAG_SOURCE);
}
