/* Bad streams through the whole chain: stereorectify ! exgsegment ! siftmatch ! stereodepth !
 * treemetrics, fed by two appsrcs. Between two good pairs rendered by lib's SceneRenderer (two
 * different trees at known distances) come an all-black pair, an all-white pair, a textured
 * pair with no green and a uniformly green pair with no texture (vegetation, no matches).
 * Every element message is walked field by field: no NaN or inf anywhere; the bad frames say
 * tree-present=false and carry no figure; the good frames measure their own tree (not the
 * previous one), and the smoother forgot the first tree. A zero-size buffer ends in an error
 * message, not a crash or a hang. */
#include "treestereo/calibration_file.hpp"
#include "treestereo/scene.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <map>
#include <string>
#include <vector>

/* gstcheck last: its fail() macro would rewrite std::ios::fail() in the headers above */
#include <glib/gstdio.h>
#include <gst/app/gstappsrc.h>
#include <gst/video/video.h>
#include <gst/treestereo/treestereo-meta.h>
#include <gst/check/gstcheck.h>

#include "../common/finite_fields.hpp"

using namespace treestereo;

static const int W = 640, H = 480, FPS = 7;
static const GstClockTime FRAME = GST_SECOND / FPS;

/* The kinds of frame pushed, in order. */
enum Kind { GOOD_A, BLACK, WHITE, NO_GREEN, GREEN_FLAT, GOOD_B };
static const char *const kind_names[] = {"good A", "all black", "all white", "no green",
                                         "green without texture", "good B"};

struct Chain {
  GstElement *pipeline = nullptr;
  GstAppSrc *src[2] = {nullptr, nullptr};
  std::string dir, calib;
};

static SceneParams scene(std::uint64_t seed, double distance_mm)
{
  SceneParams p;
  p.seed = seed;
  p.image_size = {W, H};
  p.distance_mm = distance_mm;
  return p;
}

static void chain_start(Chain &c, const StereoCalibration &calib)
{
  gchar *d = g_dir_make_tmp("bad-streams-XXXXXX", nullptr);
  c.dir = d;
  g_free(d);
  c.calib = c.dir + "/rig.yml";
  save_calibration(calib, c.calib);
  const std::string caps = "video/x-raw,format=RGB,width=" + std::to_string(W) +
                           ",height=" + std::to_string(H) + ",framerate=" + std::to_string(FPS) +
                           "/1";
  const std::string desc =
      "appsrc name=l format=time caps=" + caps + " ! rect.left "
      "appsrc name=r format=time caps=" + caps + " ! rect.right "
      "stereorectify name=rect calibration=" + c.calib +
      " ! exgsegment ! siftmatch ! stereodepth ! treemetrics smoothing=0.6 ! fakesink sync=false";
  GError *err = nullptr;
  c.pipeline = gst_parse_launch(desc.c_str(), &err);
  fail_unless(c.pipeline != nullptr && err == nullptr, "%s: %s", desc.c_str(),
              err ? err->message : "");
  for (int i = 0; i < 2; i++) {
    GstElement *e = gst_bin_get_by_name(GST_BIN(c.pipeline), i == 0 ? "l" : "r");
    c.src[i] = GST_APP_SRC(e);
  }
  fail_unless(gst_element_set_state(c.pipeline, GST_STATE_PLAYING) != GST_STATE_CHANGE_FAILURE);
}

static void chain_stop(Chain &c)
{
  gst_element_set_state(c.pipeline, GST_STATE_NULL);
  for (GstAppSrc *s : c.src)
    gst_object_unref(s);
  gst_object_unref(c.pipeline);
  g_unlink(c.calib.c_str());
  g_rmdir(c.dir.c_str());
}

/* Pushes one RGB frame (CV_8UC3, W x H) to view @i at frame number @n. */
static void push(Chain &c, int i, const cv::Mat &rgb, int n)
{
  GstVideoInfo info;
  gst_video_info_set_format(&info, GST_VIDEO_FORMAT_RGB, W, H);
  GstBuffer *buf = gst_buffer_new_allocate(nullptr, GST_VIDEO_INFO_SIZE(&info), nullptr);
  GstMapInfo map;
  fail_unless(gst_buffer_map(buf, &map, GST_MAP_WRITE));
  const int stride = GST_VIDEO_INFO_PLANE_STRIDE(&info, 0);
  for (int y = 0; y < H; y++)
    memcpy(map.data + y * stride, rgb.ptr(y), W * 3);
  gst_buffer_unmap(buf, &map);
  GST_BUFFER_PTS(buf) = n * FRAME;
  GST_BUFFER_DURATION(buf) = FRAME;
  fail_unless_equals_int(gst_app_src_push_buffer(c.src[i], buf), GST_FLOW_OK);
}

/* Runs to EOS; returns every element message of the chain. An error fails the test. */
static std::vector<GstStructure *> collect_to_eos(Chain &c)
{
  std::vector<GstStructure *> out;
  GstBus *bus = gst_element_get_bus(c.pipeline);
  for (;;) {
    GstMessage *msg = gst_bus_timed_pop_filtered(
        bus, 120 * GST_SECOND,
        GstMessageType(GST_MESSAGE_EOS | GST_MESSAGE_ERROR | GST_MESSAGE_ELEMENT));
    fail_unless(msg != nullptr, "no EOS within 120 s");
    if (GST_MESSAGE_TYPE(msg) == GST_MESSAGE_ERROR) {
      GError *e = nullptr;
      gchar *dbg = nullptr;
      gst_message_parse_error(msg, &e, &dbg);
      fail("error from %s: %s (%s)", GST_OBJECT_NAME(GST_MESSAGE_SRC(msg)), e->message, dbg);
    }
    if (GST_MESSAGE_TYPE(msg) == GST_MESSAGE_EOS) {
      gst_message_unref(msg);
      break;
    }
    const GstStructure *s = gst_message_get_structure(msg);
    if (s)
      out.push_back(gst_structure_copy(s));
    gst_message_unref(msg);
  }
  gst_object_unref(bus);
  return out;
}

static cv::Mat render(const SceneRenderer &r, int view, GroundTruth *truth = nullptr)
{
  cv::Mat rgb;
  r.render(view, 0, rgb, truth);
  return rgb;
}

GST_START_TEST(test_bad_frames_never_lie)
{
  const SceneRenderer a(scene(3, 1800.0)), b(scene(11, 2400.0));
  /* one rig for both trees: the calibration depends on the size and the baseline only */
  fail_unless(cv::norm(a.calibration().M1, b.calibration().M1) == 0.0);
  GroundTruth truth_a, truth_b;
  const cv::Mat good_a[2] = {render(a, 0, &truth_a), render(a, 1)};
  const cv::Mat good_b[2] = {render(b, 0, &truth_b), render(b, 1)};
  /* no green: the good pair in grey (R = G = B: no excess green), texture and matches kept */
  cv::Mat grey[2];
  for (int i = 0; i < 2; i++) {
    cv::Mat g;
    cv::cvtColor(good_a[i], g, cv::COLOR_RGB2GRAY);
    cv::cvtColor(g, grey[i], cv::COLOR_GRAY2RGB);
  }
  const cv::Mat black(H, W, CV_8UC3, cv::Scalar::all(0));
  const cv::Mat white(H, W, CV_8UC3, cv::Scalar::all(255));
  const cv::Mat green(H, W, CV_8UC3, cv::Scalar(40, 170, 30));

  Chain c;
  chain_start(c, a.calibration());
  const std::vector<const cv::Mat *> frames[2] = {
      {&good_a[0], &black, &white, &grey[0], &green, &good_b[0]},
      {&good_a[1], &black, &white, &grey[1], &green, &good_b[1]}};
  for (int n = 0; n < static_cast<int>(frames[0].size()); n++)
    for (int i = 0; i < 2; i++)
      push(c, i, *frames[i][n], n);
  for (GstAppSrc *s : c.src)
    fail_unless_equals_int(gst_app_src_end_of_stream(s), GST_FLOW_OK);
  std::vector<GstStructure *> msgs = collect_to_eos(c);
  chain_stop(c);

  std::map<int, GstStructure *> metrics; /* frame -> treemetrics message */
  std::map<std::string, int> per_element;
  for (GstStructure *s : msgs) {
    expect_structure_finite(s);
    per_element[gst_structure_get_name(s)]++;
    if (gst_structure_has_name(s, GST_TREE_STEREO_MESSAGE_TREEMETRICS)) {
      guint64 ts = 0;
      fail_unless(gst_structure_get_uint64(s, "timestamp", &ts));
      metrics[static_cast<int>((ts + FRAME / 2) / FRAME)] = s;
    }
  }
  const int n_frames = static_cast<int>(frames[0].size());
  for (const char *name : {"exgsegment", "siftmatch", "stereodepth", "treemetrics"})
    fail_unless_equals_int(per_element[name], n_frames);

  const GroundTruth *truths[] = {&truth_a, &truth_b};
  double distance[2] = {0, 0};
  for (int n = 0; n < n_frames; n++) {
    fail_unless(metrics.count(n) == 1, "no treemetrics message for frame %d", n);
    GstTreeStereoMetrics raw{}, smooth{};
    GstTreeStereoTimes times;
    fail_unless(gst_tree_stereo_metrics_message_parse(metrics[n], &raw, &smooth, &times));
    const bool good = n == GOOD_A || n == GOOD_B;
    GST_INFO("frame %d (%s): present %d distance %.3f", n, kind_names[n], raw.tree_present,
             raw.distance_m);
    if (!good) {
      fail_if(raw.tree_present, "frame %d (%s) claims a tree at %.3f m", n, kind_names[n],
              raw.distance_m);
      fail_if(smooth.tree_present, "frame %d (%s): the smoothed figures claim a tree", n,
              kind_names[n]);
      /* an absent tree carries no figures at all, so nothing can be stale */
      fail_if(gst_structure_has_field(metrics[n], "distance"), "frame %d has a distance", n);
      fail_if(gst_structure_has_field(metrics[n], "smoothed-distance"), "frame %d", n);
    } else {
      const int k = n == GOOD_A ? 0 : 1;
      fail_unless(raw.tree_present, "frame %d (%s): no tree found", n, kind_names[n]);
      /* each good frame measures its own tree: within 10 % of its true distance, which
       * tells the two trees (1.8 m and 2.4 m) apart */
      const double truth = truths[k]->distance_m;
      fail_unless(std::abs(raw.distance_m - truth) < 0.1 * truth,
                  "frame %d: distance %.3f m, true %.3f m", n, raw.distance_m, truth);
      distance[k] = raw.distance_m;
      /* the smoother was reset by the tree-less frames in between: no trace of tree A */
      if (n == GOOD_B)
        fail_unless(smooth.distance_m == raw.distance_m && smooth.height_m == raw.height_m,
                    "smoothed distance %.4f != raw %.4f: history of the earlier tree kept",
                    smooth.distance_m, raw.distance_m);
    }
    gst_tree_stereo_metrics_clear(&raw);
    gst_tree_stereo_metrics_clear(&smooth);
  }
  fail_unless(distance[0] != distance[1]);
  for (GstStructure *s : msgs)
    gst_structure_free(s);
}

GST_END_TEST;

/* A zero-size buffer where a frame should be: an error naming the problem, no crash, no hang,
 * and no treemetrics message with figures for it. */
GST_START_TEST(test_zero_size_buffer_is_an_error)
{
  const SceneRenderer a(scene(3, 1800.0));
  Chain c;
  chain_start(c, a.calibration());
  for (int i = 0; i < 2; i++) {
    GstBuffer *empty = gst_buffer_new();
    GST_BUFFER_PTS(empty) = 0;
    GST_BUFFER_DURATION(empty) = FRAME;
    gst_app_src_push_buffer(c.src[i], empty);
    gst_app_src_end_of_stream(c.src[i]);
  }
  GstBus *bus = gst_element_get_bus(c.pipeline);
  bool error = false;
  for (;;) {
    GstMessage *msg = gst_bus_timed_pop_filtered(
        bus, 60 * GST_SECOND,
        GstMessageType(GST_MESSAGE_EOS | GST_MESSAGE_ERROR | GST_MESSAGE_ELEMENT));
    fail_unless(msg != nullptr, "neither an error nor EOS within 60 s");
    const GstMessageType t = GST_MESSAGE_TYPE(msg);
    if (t == GST_MESSAGE_ELEMENT) {
      const GstStructure *s = gst_message_get_structure(msg);
      expect_structure_finite(s);
      gboolean present = FALSE;
      if (gst_structure_has_name(s, GST_TREE_STEREO_MESSAGE_TREEMETRICS))
        fail_if(gst_structure_get_boolean(s, "tree-present", &present) && present);
    } else if (t == GST_MESSAGE_ERROR) {
      GError *e = nullptr;
      gst_message_parse_error(msg, &e, nullptr);
      GST_INFO("zero-size buffer: %s", e->message);
      g_error_free(e);
      error = true;
    }
    gst_message_unref(msg);
    if (t != GST_MESSAGE_ELEMENT)
      break;
  }
  fail_unless(error, "a zero-size frame went through without an error");
  gst_object_unref(bus);
  chain_stop(c);
}

GST_END_TEST;

static Suite *bad_streams_suite(void)
{
  Suite *s = suite_create("bad_streams");
  TCase *tc = tcase_create("general");
  tcase_set_timeout(tc, 300);
  suite_add_tcase(s, tc);
  tcase_add_test(tc, test_bad_frames_never_lie);
  tcase_add_test(tc, test_zero_size_buffer_is_an_error);
  return s;
}

GST_CHECK_MAIN(bad_streams)
