/* Property changes while PLAYING, under load (suite 'stress'; scripts/test-tsan.sh runs it
 * under ThreadSanitizer).
 *
 * The whole chain runs in GstHarnesses: stereorectify (its own aggregator thread) and a bin
 * "exgsegment ! siftmatch ! stereodepth ! treemetrics" driven from the test thread, which
 * pushes pairs rendered by SceneRenderer. Meanwhile a second thread sets, as fast as it can
 * (a change every 0.2 ms), every property that is mutable while PLAYING and keeps the chain
 * meaningful: stereorectify's calibration (two valid files: a YAML one for 320x240 and an XML
 * one for 640x480 that the element scales), alpha and max-skew, the segmentation's threshold
 * and morphology, the matcher's method, ratio, epipolar band, scale, ..., the depth mode and
 * range, the metrics' bands, smoothing and extent method; and reads `paired`.
 *
 * Every frame must come out measured: a treemetrics message with no NaN or inf anywhere, a
 * tree, its distance within 15 % of the truth; and its geometry meta must be exactly that of
 * ONE (calibration, alpha) combination: a calibration change applies at a frame boundary,
 * never half-way. A calibration that cannot be read, set while PLAYING, is an error naming the
 * file.
 *
 * Why GstHarness and not a pipeline with queues: GLib and GStreamer are not instrumented, so
 * ThreadSanitizer sees neither their atomics nor GLib's futex-based GMutex; every thread that
 * hands buffers over through them is a source of false reports. Here only three threads run
 * project code: the test thread (segmentation to metrics), the aggregator's thread
 * (rectification) and the setter thread (set_property), which is exactly what the test is
 * about. */
#include "treestereo/calibration_file.hpp"
#include "treestereo/rectify.hpp"
#include "treestereo/scene.hpp"

#include <opencv2/core/utility.hpp>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <map>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

/* gstcheck last: its fail() macro would rewrite std::ios::fail() in the headers above */
#include <glib/gstdio.h>
#include <gst/check/gstcheck.h>
#include <gst/check/gstharness.h>
#include <gst/treestereo/treestereo-meta.h>
#include <gst/video/video.h>

#include "../common/finite_fields.hpp"

using namespace treestereo;

static const cv::Size SIZE(320, 240);
static const GstClockTime FRAME = GST_SECOND / 7;

/* TREESTEREO_STRESS_FRAMES overrides the number of frames (default 150). */
static int stress_frames()
{
  const char *env = g_getenv("TREESTEREO_STRESS_FRAMES");
  const int n = env ? atoi(env) : 0;
  return n > 0 ? n : 150;
}

static SceneParams scene(cv::Size size)
{
  SceneParams p;
  p.seed = 5;
  p.image_size = size;
  p.distance_mm = 2000.0;
  return p;
}

struct Rig {
  GstElement *rect = nullptr;
  GstHarness *left = nullptr, *right = nullptr, *chain = nullptr;
  GstBus *bus = nullptr;
  std::string dir;
  std::string calib[2];
  /* GstHarness queues the aggregator's output in a GAsyncQueue, whose lock ThreadSanitizer
   * cannot see; this mutex, taken on both sides of that hand-off, shows it the ordering the
   * queue already guarantees (it orders nothing more). */
  std::mutex handoff;
};

static GstPadProbeReturn mark_handoff(GstPad *, GstPadProbeInfo *, gpointer user_data)
{
  std::lock_guard<std::mutex> g(*static_cast<std::mutex *>(user_data));
  return GST_PAD_PROBE_OK;
}

static void rig_setup(Rig &rig, const StereoCalibration &small, const StereoCalibration &big)
{
  gchar *d = g_dir_make_tmp("property-stress-XXXXXX", nullptr);
  rig.dir = d;
  g_free(d);
  rig.calib[0] = rig.dir + "/rig-320.yml";
  rig.calib[1] = rig.dir + "/rig-640.xml";
  save_calibration(small, rig.calib[0]);
  save_calibration(big, rig.calib[1]);

  rig.bus = gst_bus_new();
  rig.rect = gst_element_factory_make("stereorectify", "rect");
  fail_unless(rig.rect != nullptr);
  /* properties first: the harness starts the element at once */
  g_object_set(rig.rect, "calibration", rig.calib[0].c_str(), nullptr);
  gst_element_set_bus(rig.rect, rig.bus);
  rig.left = gst_harness_new_with_element(rig.rect, "left", "src");
  rig.right = gst_harness_new_with_element(rig.rect, "right", nullptr);
  const std::string caps = "video/x-raw,format=RGB,width=" + std::to_string(SIZE.width) +
                           ",height=" + std::to_string(SIZE.height) + ",framerate=7/1";
  gst_harness_set_src_caps_str(rig.left, caps.c_str());
  gst_harness_set_src_caps_str(rig.right, caps.c_str());
  GstPad *src = gst_element_get_static_pad(rig.rect, "src");
  gst_pad_add_probe(src, GST_PAD_PROBE_TYPE_BUFFER, mark_handoff, &rig.handoff, nullptr);
  gst_object_unref(src);

  rig.chain = gst_harness_new_parse("exgsegment name=seg ! siftmatch name=match ! "
                                    "stereodepth name=depth ! treemetrics name=metrics");
  gst_element_set_bus(rig.chain->element, rig.bus);
}

static void rig_teardown(Rig &rig)
{
  gst_harness_teardown(rig.chain);
  gst_harness_teardown(rig.right);
  gst_harness_teardown(rig.left);
  gst_object_unref(rig.rect);
  gst_object_unref(rig.bus);
  for (const std::string &f : rig.calib)
    g_unlink(f.c_str());
  g_rmdir(rig.dir.c_str());
}

static GstBuffer *frame_buffer(const cv::Mat &rgb, GstClockTime pts)
{
  GstVideoInfo info;
  gst_video_info_set_format(&info, GST_VIDEO_FORMAT_RGB, rgb.cols, rgb.rows);
  GstBuffer *buf = gst_buffer_new_allocate(nullptr, GST_VIDEO_INFO_SIZE(&info), nullptr);
  GstMapInfo map;
  fail_unless(gst_buffer_map(buf, &map, GST_MAP_WRITE));
  for (int y = 0; y < rgb.rows; y++)
    memcpy(map.data + y * GST_VIDEO_INFO_PLANE_STRIDE(&info, 0), rgb.ptr(y), rgb.cols * 3);
  gst_buffer_unmap(buf, &map);
  GST_BUFFER_PTS(buf) = pts;
  GST_BUFFER_DURATION(buf) = FRAME;
  return buf;
}

/* Pushes pair @n and returns the rectified pair (ours), or nullptr when none comes. */
static GstBuffer *rectify_pair(Rig &rig, const cv::Mat view[2], int n, bool expect_output = true)
{
  fail_unless_equals_int(gst_harness_push(rig.left, frame_buffer(view[0], n * FRAME)),
                         GST_FLOW_OK);
  const GstFlowReturn r = gst_harness_push(rig.right, frame_buffer(view[1], n * FRAME));
  if (!expect_output)
    return nullptr;
  fail_unless_equals_int(r, GST_FLOW_OK);
  GstBuffer *out = gst_harness_pull(rig.left);
  fail_unless(out != nullptr, "no rectified pair for frame %d", n);
  std::lock_guard<std::mutex> g(rig.handoff);
  return out;
}

/* One property and the values it cycles through (all valid for this scene). */
struct Knob {
  GstElement *element;
  const char *property;
  std::vector<std::string> values;
};

static GstElement *chain_element(Rig &rig, const char *name)
{
  GstElement *e = gst_bin_get_by_name(GST_BIN(rig.chain->element), name);
  fail_unless(e != nullptr, "%s", name);
  gst_object_unref(e); /* the bin keeps it alive as long as the rig */
  return e;
}

/* Not `mutual` nor candidates=5: cosine-norm with candidates=5 and mutual=false (min-depth 300)
 * measures this tree at 1.46 m instead of 1.83 m in a plain gst-launch pipeline too (false
 * matches: a property of that configuration, not of changing it). 60 random static
 * combinations of these values all measured 1.77-1.83 m. */
static std::vector<Knob> knobs(Rig &rig)
{
  GstElement *seg = chain_element(rig, "seg"), *match = chain_element(rig, "match"),
             *depth = chain_element(rig, "depth"), *metrics = chain_element(rig, "metrics");
  return {
      {rig.rect, "calibration", {rig.calib[0], rig.calib[1]}},
      {rig.rect, "alpha", {"-1", "0"}},
      {rig.rect, "max-skew", {"0", "20000000", "40000000"}},
      {seg, "threshold", {"-1", "0.1", "0.15"}},
      {seg, "morph-size", {"0", "3", "5"}},
      {seg, "reconstruct", {"true", "false"}},
      {seg, "min-area", {"50", "200"}},
      {match, "method", {"euclidean", "cosine-norm"}},
      {match, "ratio", {"0.7", "0.8", "0.9"}},
      {match, "epipolar-tolerance", {"1", "2", "3"}},
      {match, "scale", {"0", "0.5", "1"}},
      {match, "candidates", {"2", "3"}},
      {match, "refine", {"true", "false"}},
      {match, "min-depth", {"300", "500"}},
      {match, "max-depth", {"6000", "10000"}},
      {match, "mask-inset", {"0", "4", "8"}},
      {match, "relocate", {"0", "1", "2"}},
      {match, "upright", {"true", "false"}},
      {depth, "mode", {"sparse", "dense"}},
      {depth, "min-depth", {"300", "500"}},
      {depth, "max-depth", {"6000", "10000"}},
      {depth, "outlier-k", {"0", "3.5"}},
      {metrics, "bands", {"2", "4", "8"}},
      {metrics, "smoothing", {"0", "0.5", "0.9"}},
      {metrics, "extent-method", {"round-canopy", "edge-points"}},
      {metrics, "speed", {"0", "0.5"}},
      {metrics, "travel", {"true", "false"}},
      {metrics, "trees", {"true", "false"}},
  };
}

/* The geometry of every (calibration file, alpha) the setter can choose, as the element would
 * compute it from the files (read back, so the figures are those of the saved numbers). */
struct Expected {
  std::string what;
  StereoGeometry g;
};

static std::vector<Expected> expected_geometries(const Rig &rig)
{
  std::vector<Expected> out;
  for (const std::string &file : rig.calib)
    for (double alpha : {-1.0, 0.0})
      out.push_back({file + " alpha " + std::to_string(int(alpha)),
                     compute_rectification(load_calibration(file), SIZE, alpha, true).geometry});
  return out;
}

static bool same(double a, double b)
{
  return std::abs(a - b) <= 1e-9 * std::max(1.0, std::abs(b));
}

/* Which expected geometry the meta is (fx, principal points and baseline all from the same
 * one), or -1 when it mixes them. */
static int geometry_of(const GstTreeStereoGeometryMeta *m, const std::vector<Expected> &expected)
{
  for (size_t k = 0; k < expected.size(); k++) {
    const StereoGeometry &g = expected[k].g;
    if (same(m->fx[0], g.fx) && same(m->fy[0], g.fy) && same(m->cx[0], g.cx[0]) &&
        same(m->cx[1], g.cx[1]) && same(m->cy[0], g.cy) && same(m->baseline_mm, g.baseline_mm))
      return int(k);
  }
  return -1;
}

/* The knobs' values now, for failure messages (the frame saw these or the ones just before). */
static std::string settings_now(const std::vector<Knob> &all)
{
  std::string out;
  for (const Knob &k : all) {
    GValue v = G_VALUE_INIT;
    g_object_get_property(G_OBJECT(k.element), k.property, &v);
    gchar *text = g_strdup_value_contents(&v);
    out += std::string(" ") + GST_OBJECT_NAME(k.element) + "." + k.property + "=" + text;
    g_free(text);
    g_value_unset(&v);
  }
  return out;
}

/* Checks every message the bus holds; returns the number of treemetrics messages. */
static int check_messages(Rig &rig, const std::vector<Knob> &all, double truth_m, int n)
{
  int metrics = 0;
  while (GstMessage *msg = gst_bus_pop(rig.bus)) {
    const GstMessageType t = GST_MESSAGE_TYPE(msg);
    if (t == GST_MESSAGE_ERROR || t == GST_MESSAGE_WARNING) {
      GError *e = nullptr;
      gchar *dbg = nullptr;
      if (t == GST_MESSAGE_ERROR)
        gst_message_parse_error(msg, &e, &dbg);
      else
        gst_message_parse_warning(msg, &e, &dbg);
      fail("frame %d: %s from %s: %s (%s)", n, t == GST_MESSAGE_ERROR ? "error" : "warning",
           GST_OBJECT_NAME(GST_MESSAGE_SRC(msg)), e->message, dbg);
    }
    const GstStructure *s = gst_message_get_structure(msg);
    if (t == GST_MESSAGE_ELEMENT && s) {
      expect_structure_finite(s);
      if (gst_structure_has_name(s, GST_TREE_STEREO_MESSAGE_TREEMETRICS)) {
        GstTreeStereoMetrics raw{}, smooth{};
        GstTreeStereoTimes times;
        fail_unless(gst_tree_stereo_metrics_message_parse(s, &raw, &smooth, &times));
        fail_unless(raw.tree_present && smooth.tree_present, "frame %d: no tree", n);
        fail_unless(std::abs(raw.distance_m - truth_m) < 0.15 * truth_m,
                    "frame %d: distance %.3f m, true %.3f m;%s", n, raw.distance_m, truth_m,
                    settings_now(all).c_str());
        fail_unless_equals_uint64(times.timestamp, n * FRAME);
        gst_tree_stereo_metrics_clear(&raw);
        gst_tree_stereo_metrics_clear(&smooth);
        metrics++;
      }
    }
    gst_message_unref(msg);
  }
  return metrics;
}

GST_START_TEST(test_properties_change_while_playing)
{
  const SceneRenderer r(scene(SIZE)), big(scene({640, 480}));
  cv::Mat view[2];
  GroundTruth truth;
  r.render(0, 0, view[0], &truth);
  r.render(1, 0, view[1]);
  Rig rig;
  rig_setup(rig, r.calibration(), big.calibration());
  const std::vector<Expected> expected = expected_geometries(rig);
  const std::vector<Knob> all = knobs(rig);

  /* frame 0 before the setter starts: it fixes the caps of the chain */
  GstBuffer *first = rectify_pair(rig, view, 0);
  gst_harness_set_src_caps(rig.chain, gst_pad_get_current_caps(rig.left->sinkpad));
  gst_buffer_unref(gst_harness_push_and_pull(rig.chain, first));
  fail_unless_equals_int(check_messages(rig, all, truth.distance_m, 0), 1);

  std::atomic<bool> stop{false};
  std::vector<int> changes(all.size(), 0);
  std::thread setter([&] {
    std::mt19937 rng(10);
    guint64 paired = 0;
    while (!stop.load()) {
      const size_t k = rng() % all.size();
      const Knob &knob = all[k];
      gst_util_set_object_arg(G_OBJECT(knob.element), knob.property,
                              knob.values[rng() % knob.values.size()].c_str());
      changes[k]++;
      g_object_get(rig.rect, "paired", &paired, nullptr);
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  });

  const int n_frames = stress_frames();
  std::map<int, int> per_geometry;
  int metrics = 0;
  const gint64 t0 = g_get_monotonic_time();
  for (int n = 1; n < n_frames; n++) {
    GstBuffer *out = gst_harness_push_and_pull(rig.chain, rectify_pair(rig, view, n));
    fail_unless(out != nullptr, "frame %d went missing in the chain", n);
    const GstTreeStereoGeometryMeta *g = gst_buffer_get_tree_stereo_geometry_meta(out);
    fail_unless(g != nullptr);
    const int k = geometry_of(g, expected);
    fail_unless(k >= 0, "frame %d: a geometry (fx %.6f, baseline %.6f) of no single calibration",
                n, g->fx[0], g->baseline_mm);
    per_geometry[k]++;
    const GstTreeStereoMetricsMeta *mm = gst_buffer_get_tree_stereo_metrics_meta(out);
    fail_unless(mm != nullptr && mm->metrics.tree_present, "frame %d: no tree in the meta;%s", n,
                settings_now(all).c_str());
    gst_buffer_unref(out);
    metrics += check_messages(rig, all, truth.distance_m, n);
  }
  const double seconds = (g_get_monotonic_time() - t0) / 1e6;
  stop = true;
  setter.join();
  fail_unless_equals_int(metrics, n_frames - 1);

  int total = 0;
  std::string summary;
  for (size_t k = 0; k < all.size(); k++) {
    total += changes[k];
    summary += std::string(" ") + GST_OBJECT_NAME(all[k].element) + "." + all[k].property + "=" +
               std::to_string(changes[k]);
  }
  g_print("property stress: %d frames in %.1f s, %d property changes:%s\n", n_frames, seconds,
          total, summary.c_str());
  for (const auto &[k, count] : per_geometry)
    g_print("  %d frames with %s\n", count, expected[k].what.c_str());
  /* the setter must have switched the calibration while frames were flowing */
  fail_unless(per_geometry.size() >= 2, "every frame used the same calibration");
  fail_unless(changes[0] >= 2);
  guint64 paired = 0, dropped = 0;
  g_object_get(rig.rect, "paired", &paired, "dropped", &dropped, nullptr);
  fail_unless_equals_uint64(paired, guint64(n_frames));
  fail_unless_equals_uint64(dropped, 0);
  rig_teardown(rig);
}

GST_END_TEST;

/* A calibration that cannot be read, set while PLAYING: the next pair ends in an error that
 * names the file, not in a crash or a pair rectified with half of each. */
GST_START_TEST(test_unreadable_calibration_while_playing)
{
  const SceneRenderer r(scene(SIZE)), big(scene({640, 480}));
  cv::Mat view[2];
  r.render(0, 0, view[0]);
  r.render(1, 0, view[1]);
  Rig rig;
  rig_setup(rig, r.calibration(), big.calibration());
  gst_buffer_unref(rectify_pair(rig, view, 0));
  const std::string missing = rig.dir + "/no-such-rig.yml";
  g_object_set(rig.rect, "calibration", missing.c_str(), nullptr);
  rectify_pair(rig, view, 1, false);
  GstMessage *msg = gst_bus_timed_pop_filtered(rig.bus, 30 * GST_SECOND, GST_MESSAGE_ERROR);
  fail_unless(msg != nullptr, "no error for an unreadable calibration set while PLAYING");
  GError *e = nullptr;
  gchar *dbg = nullptr;
  gst_message_parse_error(msg, &e, &dbg);
  const std::string text = std::string(e->message) + " " + (dbg ? dbg : "");
  GST_INFO("error: %s", text.c_str());
  fail_unless(e->domain == GST_RESOURCE_ERROR, "%s", text.c_str());
  fail_unless(text.find("no-such-rig.yml") != std::string::npos, "the file is not named: %s",
              text.c_str());
  g_error_free(e);
  g_free(dbg);
  gst_message_unref(msg);
  fail_unless(gst_harness_try_pull(rig.left) == nullptr, "a pair came out after the error");
  guint64 paired = 0;
  g_object_get(rig.rect, "paired", &paired, nullptr);
  fail_unless_equals_uint64(paired, 1);
  rig_teardown(rig);
}

GST_END_TEST;

static Suite *property_stress_suite(void)
{
#if defined(__SANITIZE_THREAD__)
  /* OpenCV's parallel loops run on TBB, whose synchronisation ThreadSanitizer cannot see (TBB is
   * not instrumented): they run in the calling thread here. What this test is about, the
   * elements' threads and the setter, still run concurrently. */
  cv::setNumThreads(1);
#endif
  Suite *s = suite_create("property_stress");
  TCase *tc = tcase_create("general");
  tcase_set_timeout(tc, 600);
  suite_add_tcase(s, tc);
  tcase_add_test(tc, test_properties_change_while_playing);
  tcase_add_test(tc, test_unreadable_calibration_while_playing);
  return s;
}

GST_CHECK_MAIN(property_stress)
