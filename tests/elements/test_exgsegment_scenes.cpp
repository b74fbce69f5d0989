/* exgsegment on the synthetic orchard (lib's SceneRenderer) at the paper's +-30 % light: the
 * canopy mask of each view against the renderer's ground-truth canopy mask of that view.
 *
 * The views are the rendered (unrectified) ones put side by side: the element does not care
 * about rectification, and each view is compared with its own truth. */
/* OpenCV first: check's fail() macros would rewrite identifiers in its headers */
#include "treestereo/scene.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdint>
#include <cstring>

#include <gst/check/gstcheck.h>
#include <gst/check/gstharness.h>
#include <gst/video/video.h>
#include <gst/treestereo/treestereo-meta.h>

using namespace treestereo;

namespace {

const cv::Size VIEW(640, 480);

struct Score {
  double iou = 0;          // against the renderer's canopy mask
  double iou_closed = 0;   // against that mask closed with the morph-size element (reported)
  double centroid_px = 0;  // distance between the measured and the true centroid
};

/* The element's mask of one view as a cv::Mat (a copy, the buffer is unmapped after). */
cv::Mat mask_of(const GstTreeStereoVegetationView *v)
{
  GstMapInfo map;
  fail_unless(v->mask != nullptr);
  fail_unless(gst_buffer_map(v->mask, &map, GST_MAP_READ));
  cv::Mat m = cv::Mat(int(v->mask_height), int(v->mask_width), CV_8UC1, map.data,
                      v->mask_stride)
                  .clone();
  gst_buffer_unmap(v->mask, &map);
  return m;
}

double iou(const cv::Mat &a, const cv::Mat &b)
{
  return double(cv::countNonZero(a & b)) / double(cv::countNonZero(a | b));
}

/* Which truth to compare with. The renderer's canopy mask marks the pixels whose first hit is a
 * leaf, so it has holes wherever the leaf shell has a gap and the soil, wall or sky behind shows
 * through. The element finds those holes too (their colour is not green) except where they are
 * narrower than its closing element. Closing the truth with the same element would be the
 * "silhouette" view of the canopy, but it scores lower (the element's opening keeps thin gaps
 * open) and is not what the issue asks for, so the test compares with the raw mask and only
 * reports the closed one. */
cv::Mat closed_truth(const cv::Mat &truth, int morph_size)
{
  cv::Mat closed;
  const cv::Mat k = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(morph_size, morph_size));
  cv::morphologyEx(truth, closed, cv::MORPH_CLOSE, k);
  return closed;
}

cv::Point2d centroid(const cv::Mat &mask)
{
  const cv::Moments m = cv::moments(mask, true);
  return {m.m10 / m.m00, m.m01 / m.m00};
}

/* Renders both views of one scene, pushes them side by side through exgsegment and scores
 * each view against its truth. */
void run_scene(GstHarness *h, std::uint64_t seed, double light, Score score[2])
{
  SceneParams p;
  p.seed = seed;
  p.light = light;
  p.image_size = VIEW;
  const SceneRenderer renderer(p);
  cv::Mat rgb[2];
  GroundTruth truth[2];
  for (int v = 0; v < 2; ++v)
    renderer.render(v, 0, rgb[v], &truth[v]);

  const gsize stride = gsize(GST_ROUND_UP_4(2 * VIEW.width * 3));
  GstBuffer *buf = gst_buffer_new_allocate(nullptr, stride * gsize(VIEW.height), nullptr);
  GstMapInfo map;
  fail_unless(gst_buffer_map(buf, &map, GST_MAP_WRITE));
  cv::Mat frame(VIEW.height, 2 * VIEW.width, CV_8UC3, map.data, stride);
  for (int v = 0; v < 2; ++v)
    rgb[v].copyTo(frame(cv::Rect(v * VIEW.width, 0, VIEW.width, VIEW.height)));
  gst_buffer_unmap(buf, &map);
  GST_BUFFER_PTS(buf) = 0;

  fail_unless_equals_int(gst_harness_push(h, buf), GST_FLOW_OK);
  GstBuffer *out = gst_harness_pull(h);
  fail_unless(out != nullptr);
  const GstTreeStereoVegetationMeta *meta = gst_buffer_get_tree_stereo_vegetation_meta(out);
  fail_unless(meta != nullptr && meta->n_views == 2);
  gint morph = 0;
  g_object_get(h->element, "morph-size", &morph, nullptr);
  for (int v = 0; v < 2; ++v) {
    const GstTreeStereoVegetationView *w = &meta->views[v];
    fail_unless(w->present, "no canopy found, seed %" G_GUINT64_FORMAT " light %.1f view %d",
                seed, light, v);
    const cv::Mat found = mask_of(w);
    score[v].iou = iou(found, truth[v].canopy_mask);
    score[v].iou_closed = iou(found, closed_truth(truth[v].canopy_mask, morph));
    /* the meta's centroid against the centroid of the canopy the renderer drew */
    const cv::Point2d c = centroid(truth[v].canopy_mask);
    score[v].centroid_px = cv::norm(cv::Point2d(w->centroid_x, w->centroid_y) - c);
    /* the meta's figures describe the mask it carries */
    fail_unless(std::abs(w->area_px - cv::countNonZero(found)) < 0.5);
  }
  gst_buffer_unref(out);
}

GstHarness *scene_harness()
{
  GstHarness *h = gst_harness_new("exgsegment");
  gchar *caps = g_strdup_printf("video/x-raw,format=RGB,width=%d,height=%d,framerate=7/1,"
                                "multiview-mode=side-by-side",
                                2 * VIEW.width, VIEW.height);
  gst_harness_set_src_caps_str(h, caps);
  g_free(caps);
  return h;
}

} // namespace

GST_START_TEST(test_canopy_matches_truth_under_light)
{
  const double lights[] = {0.7, 1.0, 1.3};
  const std::uint64_t seeds[] = {1, 2, 3};
  GstHarness *h = scene_harness();
  for (double light : lights)
    for (std::uint64_t seed : seeds) {
      Score s[2];
      run_scene(h, seed, light, s);
      for (int v = 0; v < 2; ++v) {
        g_print("light %.1f seed %" G_GUINT64_FORMAT " %s: IoU %.4f (closed truth %.4f), "
                "centroid off by %.2f px\n",
                light, seed, v == 0 ? "left " : "right", s[v].iou, s[v].iou_closed,
                s[v].centroid_px);
        fail_unless(s[v].iou >= 0.95, "IoU %.4f < 0.95 (light %.1f seed %" G_GUINT64_FORMAT
                    " view %d)", s[v].iou, light, seed, v);
        fail_unless(s[v].centroid_px <= 2.0, "centroid %.2f px off (light %.1f seed %"
                    G_GUINT64_FORMAT " view %d)", s[v].centroid_px, light, seed, v);
      }
    }
  gst_harness_teardown(h);
}

GST_END_TEST;

static Suite *exgsegment_scenes_suite(void)
{
  Suite *s = suite_create("exgsegment_scenes");
  TCase *tc = tcase_create("general");
  suite_add_tcase(s, tc);
  tcase_add_test(tc, test_canopy_matches_truth_under_light);
  return s;
}

GST_CHECK_MAIN(exgsegment_scenes);
