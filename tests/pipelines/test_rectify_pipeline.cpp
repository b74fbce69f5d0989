/* Pipeline tests of the rig: treetestsrc pairs written as PNG files rectify onto common rows with
 * the calibration treetestsrc wrote; stereorectify does the same inside a pipeline; the committed
 * fixtures replay through multifilesrc. Rows are checked with OpenCV's own SIFT and matcher,
 * independent of the project's matcher. */
#include "treestereo/calibration_file.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <string>
#include <vector>

/* gstcheck last: its fail() macro would rewrite std::ios::fail() in the headers above */
#include <glib/gstdio.h>
#include <gst/app/gstappsink.h>
#include <gst/video/video.h>
#include <gst/treestereo/treestereo-meta.h>
#include <gst/check/gstcheck.h>

using namespace treestereo;

/* Runs a gst-launch description to EOS; fails the test on an error. */
static void run_to_eos(const std::string &desc)
{
  GError *err = nullptr;
  GstElement *p = gst_parse_launch(desc.c_str(), &err);
  fail_unless(p != nullptr && err == nullptr, "%s: %s", desc.c_str(), err ? err->message : "");
  fail_unless(gst_element_set_state(p, GST_STATE_PLAYING) != GST_STATE_CHANGE_FAILURE);
  GstBus *bus = gst_element_get_bus(p);
  GstMessage *msg = gst_bus_timed_pop_filtered(
      bus, 120 * GST_SECOND, GstMessageType(GST_MESSAGE_EOS | GST_MESSAGE_ERROR));
  fail_unless(msg != nullptr, "timeout: %s", desc.c_str());
  if (GST_MESSAGE_TYPE(msg) == GST_MESSAGE_ERROR) {
    GError *e = nullptr;
    gchar *dbg = nullptr;
    gst_message_parse_error(msg, &e, &dbg);
    fail("%s: %s (%s)", desc.c_str(), e->message, dbg);
  }
  gst_message_unref(msg);
  gst_object_unref(bus);
  gst_element_set_state(p, GST_STATE_NULL);
  gst_object_unref(p);
}

/* Row differences |yl - yr| of OpenCV SIFT matches (Lowe ratio 0.7) between two views. */
static std::vector<double> row_differences(const cv::Mat &left, const cv::Mat &right)
{
  cv::Ptr<cv::SIFT> sift = cv::SIFT::create();
  std::vector<cv::KeyPoint> kl, kr;
  cv::Mat dl, dr, gl, gr;
  cv::cvtColor(left, gl, left.channels() == 3 ? cv::COLOR_RGB2GRAY : cv::COLOR_RGBA2GRAY);
  cv::cvtColor(right, gr, right.channels() == 3 ? cv::COLOR_RGB2GRAY : cv::COLOR_RGBA2GRAY);
  sift->detectAndCompute(gl, cv::noArray(), kl, dl);
  sift->detectAndCompute(gr, cv::noArray(), kr, dr);
  cv::BFMatcher bf(cv::NORM_L2);
  std::vector<std::vector<cv::DMatch>> knn;
  bf.knnMatch(dl, dr, knn, 2);
  std::vector<double> dy;
  for (const auto &m : knn) {
    if (m.size() < 2 || m[0].distance > 0.7f * m[1].distance)
      continue;
    const cv::Point2f a = kl[m[0].queryIdx].pt, b = kr[m[0].trainIdx].pt;
    /* a stereo match: the right view sees it to the left, within a plausible disparity */
    const double d = a.x - b.x;
    if (d < -2 || d > 120)
      continue;
    dy.push_back(std::abs(a.y - b.y));
  }
  return dy;
}

static std::string tmpdir()
{
  gchar *d = g_dir_make_tmp("rectify-pipeline-XXXXXX", nullptr);
  std::string s = d;
  g_free(d);
  return s;
}

static const char *kCaps = "video/x-raw,format=RGB,width=640,height=480,framerate=7/1";

GST_START_TEST(test_png_pair_rectifies_with_written_calibration)
{
  const std::string dir = tmpdir();
  run_to_eos(std::string("treetestsrc view=left num-buffers=2 seed=4 calibration-out=") + dir +
             "/rig.yml ! " + kCaps + " ! videoconvert ! pngenc ! multifilesink location=" +
             dir + "/left_%04d.png");
  run_to_eos(std::string("treetestsrc view=right num-buffers=2 seed=4 ! ") + kCaps +
             " ! videoconvert ! pngenc ! multifilesink location=" + dir + "/right_%04d.png");

  const StereoCalibration c = load_calibration(dir + "/rig.yml");
  cv::Mat R1, R2, P1, P2, Q;
  cv::stereoRectify(c.M1, c.D1, c.M2, c.D2, c.image_size, c.R, c.T, R1, R2, P1, P2, Q,
                    cv::CALIB_ZERO_DISPARITY);
  cv::Mat m1x, m1y, m2x, m2y;
  cv::initUndistortRectifyMap(c.M1, c.D1, R1, P1, c.image_size, CV_32FC1, m1x, m1y);
  cv::initUndistortRectifyMap(c.M2, c.D2, R2, P2, c.image_size, CV_32FC1, m2x, m2y);

  cv::Mat l = cv::imread(dir + "/left_0001.png"), r = cv::imread(dir + "/right_0001.png");
  fail_unless(!l.empty() && !r.empty(), "PNG files not written");
  cv::Mat rl, rr;
  cv::remap(l, rl, m1x, m1y, cv::INTER_LINEAR);
  cv::remap(r, rr, m2x, m2y, cv::INTER_LINEAR);
  std::vector<double> raw = row_differences(l, r), rect = row_differences(rl, rr);
  fail_unless(rect.size() >= 100, "only %zu matches", rect.size());
  const double med_raw = median(raw), med_rect = median(rect);
  GST_INFO("PNG pair: %zu matches, median |dy| %.3f px raw, %.3f px rectified", rect.size(),
           med_raw, med_rect);
  fail_unless(med_rect < 0.5, "median |dy| %.3f px after rectification", med_rect);
  /* the rig really needs it: the raw views are off by more */
  fail_unless(med_raw > 2 * med_rect, "raw |dy| %.3f not worse than rectified", med_raw);
  for (const char *f : {"rig.yml", "left_0000.png", "left_0001.png", "right_0000.png",
                        "right_0001.png"})
    g_unlink((dir + "/" + f).c_str());
  g_rmdir(dir.c_str());
}
GST_END_TEST;

/* Pulls every buffer of a pipeline ending in "appsink name=out". */
static std::vector<GstSample *> pull_all(const std::string &desc)
{
  GError *err = nullptr;
  GstElement *p = gst_parse_launch(desc.c_str(), &err);
  fail_unless(p != nullptr && err == nullptr, "%s: %s", desc.c_str(), err ? err->message : "");
  GstElement *sink = gst_bin_get_by_name(GST_BIN(p), "out");
  fail_unless(gst_element_set_state(p, GST_STATE_PLAYING) != GST_STATE_CHANGE_FAILURE);
  std::vector<GstSample *> samples;
  while (GstSample *s = gst_app_sink_try_pull_sample(GST_APP_SINK(sink), 60 * GST_SECOND))
    samples.push_back(s);
  GstBus *bus = gst_element_get_bus(p);
  GstMessage *msg = gst_bus_pop_filtered(bus, GST_MESSAGE_ERROR);
  if (msg) {
    GError *e = nullptr;
    gst_message_parse_error(msg, &e, nullptr);
    fail("%s: %s", desc.c_str(), e->message);
  }
  fail_unless(gst_app_sink_is_eos(GST_APP_SINK(sink)), "no EOS: %s", desc.c_str());
  gst_object_unref(bus);
  gst_object_unref(sink);
  gst_element_set_state(p, GST_STATE_NULL);
  gst_object_unref(p);
  return samples;
}

GST_START_TEST(test_stereorectify_rows)
{
  const std::string dir = tmpdir();
  /* the rig's calibration, written by a source at this size */
  run_to_eos(std::string("treetestsrc num-buffers=1 seed=9 calibration-out=") + dir +
             "/rig.yml ! " + kCaps + " ! fakesink");
  std::vector<GstSample *> samples =
      pull_all("stereorectify name=r calibration=" + dir + "/rig.yml ! appsink name=out " +
               "sync=false treetestsrc view=left seed=9 num-buffers=2 ! " + kCaps +
               " ! r.left treetestsrc view=right seed=9 num-buffers=2 ! " + kCaps + " ! r.right");
  fail_unless_equals_int(samples.size(), 2);
  GstSample *s = samples.back();
  GstVideoInfo info;
  fail_unless(gst_video_info_from_caps(&info, gst_sample_get_caps(s)));
  fail_unless_equals_int(GST_VIDEO_INFO_WIDTH(&info), 1280);
  GstBuffer *buf = gst_sample_get_buffer(s);
  GstTreeStereoGeometryMeta *g = gst_buffer_get_tree_stereo_geometry_meta(buf);
  fail_unless(g != nullptr);
  fail_unless(std::abs(g->baseline_mm - 50.0) < 0.1, "baseline %f", g->baseline_mm);
  /* the ground truth of the left frame travels with the pair */
  GstTreeStereoTruthMeta *t = gst_buffer_get_tree_stereo_truth_meta(buf);
  fail_unless(t != nullptr && t->truth.view == GST_TREE_STEREO_LEFT);
  GstVideoFrame frame;
  fail_unless(gst_video_frame_map(&frame, &info, buf, GST_MAP_READ));
  cv::Mat sbs(480, 1280, CV_8UC3, GST_VIDEO_FRAME_PLANE_DATA(&frame, 0),
              GST_VIDEO_FRAME_PLANE_STRIDE(&frame, 0));
  std::vector<double> dy = row_differences(sbs(cv::Rect(0, 0, 640, 480)).clone(),
                                           sbs(cv::Rect(640, 0, 640, 480)).clone());
  gst_video_frame_unmap(&frame);
  fail_unless(dy.size() >= 100, "only %zu matches", dy.size());
  const double med = median(dy);
  GST_INFO("stereorectify: %zu matches, median |dy| %.3f px", dy.size(), med);
  fail_unless(med < 0.3, "median |dy| %.3f px after stereorectify", med);
  for (GstSample *x : samples)
    gst_sample_unref(x);
  g_unlink((dir + "/rig.yml").c_str());
  g_rmdir(dir.c_str());
}
GST_END_TEST;

GST_START_TEST(test_fixtures_replay)
{
  const std::string fx = std::string(g_getenv("GST_TEST_FILES_PATH")) + "/seq-moving";
  const std::string src = " caps=\"image/jpeg,framerate=(fraction)7/1\" ! jpegdec ! "
                          "videoconvert ! video/x-raw,format=RGB";
  std::vector<GstSample *> samples =
      pull_all("stereorectify name=r calibration=" + fx + "/calibration.yml ! appsink " +
               "name=out sync=false multifilesrc location=" + fx + "/left_%04d.jpg" + src +
               " ! r.left multifilesrc location=" + fx + "/right_%04d.jpg" + src + " ! r.right");
  fail_unless_equals_int(samples.size(), 8);
  for (size_t i = 0; i < samples.size(); i++) {
    GstBuffer *buf = gst_sample_get_buffer(samples[i]);
    /* 7 fps from multifilesrc, to the nanosecond's rounding */
    const GstClockTimeDiff dt = GST_CLOCK_DIFF(gst_util_uint64_scale(i, GST_SECOND, 7),
                                               GST_BUFFER_PTS(buf));
    fail_unless(std::abs(dt) <= 10, "frame %zu at %" GST_TIME_FORMAT, i,
                GST_TIME_ARGS(GST_BUFFER_PTS(buf)));
    GstTreeStereoGeometryMeta *g = gst_buffer_get_tree_stereo_geometry_meta(buf);
    fail_unless(g != nullptr && g->view_width == 640 && g->view_height == 480);
    gst_sample_unref(samples[i]);
  }
}
GST_END_TEST;

static Suite *rectify_pipeline_suite(void)
{
  Suite *s = suite_create("rectify-pipeline");
  TCase *tc = tcase_create("general");
  tcase_set_timeout(tc, 300);
  suite_add_tcase(s, tc);
  tcase_add_test(tc, test_png_pair_rectifies_with_written_calibration);
  tcase_add_test(tc, test_stereorectify_rows);
  tcase_add_test(tc, test_fixtures_replay);
  return s;
}

GST_CHECK_MAIN(rectify_pipeline);
