/* siftmatch through a GstHarness: side-by-side frames whose right view is the left view's texture
 * shifted by a known sub-pixel disparity, a geometry meta attached here; the matches meta and the
 * bus message against that truth; vegetation masks; errors; Middlebury Jadeplant. */
/* OpenCV first: gstcheck's macros (fail, ...) would break its headers. */
#include "treestereo/data_dir.hpp"
#include "treestereo/middlebury.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/imgproc.hpp>

#include <gst/check/gstcheck.h>
#include <gst/check/gstharness.h>
#include "expect_error.h"
#include <gst/video/video.h>
#include <gst/treestereo/treestereo-meta.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

using namespace treestereo;

namespace {

constexpr int W = 480, H = 360;         // one view
constexpr double FX = 1000, BASELINE = 50; // d = 50000 / Z: 500..10000 mm -> 5..100 px
constexpr double D_TRUE = 23.37;
/* Refinement's precision on this pair (siftmatch's defaults): the median error below 0.03 px,
 * 99% of the matches within 0.1 px and every one within MAX_ERROR. At contrast-threshold 0.02
 * the pair gives 2911 matches (2457 at 0.035), the weakest-textured of them refined to at most
 * 0.102 px (0.085 px at 0.035; median 0.014 px and 95th percentile 0.039 / 0.041 px with either
 * threshold). */
constexpr double MAX_ERROR = 0.15;

/* Smooth random texture (blurred noise stretched to 0..255), wider than the view so that both
 * views of the pair are cut from real texture (no border effects). */
cv::Mat texture(cv::Size size, std::uint64_t seed)
{
  cv::Mat noise(size, CV_32F);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::UNIFORM, 0.f, 1.f);
  cv::GaussianBlur(noise, noise, cv::Size(), 2.0);
  cv::normalize(noise, noise, 0, 255, cv::NORM_MINMAX);
  cv::Mat img;
  noise.convertTo(img, CV_8U);
  return img;
}

/* Grey pair: right(x) = left(x + d). */
void make_pair(double d, cv::Mat &left, cv::Mat &right)
{
  const int margin = 64;
  const cv::Mat wide = texture(cv::Size(W + 2 * margin, H), 7);
  /* Both views are resampled, by shifts whose fractional parts mirror each other, so both get
   * the same interpolation blur as two real cameras' optics would; their difference is d. */
  const double frac = d - std::floor(d);
  const double s0 = -frac / 2;
  cv::Mat views[2];
  for (int v = 0; v < 2; v++)
    cv::warpAffine(wide, views[v], cv::Matx23d(1, 0, -(s0 + (v ? d : 0.0)), 0, 1, 0), wide.size(),
                   cv::INTER_LINEAR, cv::BORDER_REFLECT);
  left = views[0](cv::Rect(margin, 0, W, H)).clone();
  right = views[1](cv::Rect(margin, 0, W, H)).clone();
}

/* A buffer of @format holding @l and @r (BGR or grey) side by side, with the real stride. */
GstBuffer *side_by_side(const char *format, const cv::Mat &l, const cv::Mat &r, GstClockTime pts)
{
  GstVideoInfo info;
  gst_video_info_set_format(&info, gst_video_format_from_string(format), guint(2 * l.cols),
                            guint(l.rows));
  GstBuffer *buf = gst_buffer_new_allocate(nullptr, GST_VIDEO_INFO_SIZE(&info), nullptr);
  GstVideoFrame frame;
  fail_unless(gst_video_frame_map(&frame, &info, buf, GST_MAP_WRITE));
  const int ch = GST_VIDEO_INFO_COMP_PSTRIDE(&info, 0);
  cv::Mat dst(l.rows, 2 * l.cols, CV_8UC(ch), GST_VIDEO_FRAME_PLANE_DATA(&frame, 0),
              size_t(GST_VIDEO_FRAME_PLANE_STRIDE(&frame, 0)));
  const std::string f(format);
  for (int v = 0; v < 2; v++) {
    const cv::Mat &src = v == 0 ? l : r;
    cv::Mat bgr = src, conv;
    if (src.channels() == 1)
      cv::cvtColor(src, bgr, cv::COLOR_GRAY2BGR);
    if (f == "GRAY8")
      cv::cvtColor(bgr, conv, cv::COLOR_BGR2GRAY);
    else if (f == "RGB")
      cv::cvtColor(bgr, conv, cv::COLOR_BGR2RGB);
    else if (f == "BGR")
      conv = bgr;
    else if (f == "BGRx")
      cv::cvtColor(bgr, conv, cv::COLOR_BGR2BGRA);
    else
      fail("side_by_side: format %s not handled by the test", format);
    fail_unless_equals_int(conv.channels(), ch);
    conv.copyTo(dst(cv::Rect(v * l.cols, 0, l.cols, l.rows)));
  }
  gst_video_frame_unmap(&frame);
  GST_BUFFER_PTS(buf) = pts;
  GST_BUFFER_DURATION(buf) = 40 * GST_MSECOND;
  return buf;
}

void add_geometry(GstBuffer *buf, int w, int h, double fx, double cx0, double cx1,
                  double baseline)
{
  GstTreeStereoGeometryMeta *g = gst_buffer_add_tree_stereo_geometry_meta(buf);
  g->view_width = guint(w);
  g->view_height = guint(h);
  g->side_by_side = TRUE;
  g->rectified = TRUE;
  for (int v = 0; v < 2; v++) {
    g->fx[v] = g->fy[v] = fx;
    g->cy[v] = h / 2.0;
  }
  g->cx[0] = cx0;
  g->cx[1] = cx1;
  g->baseline_mm = baseline;
}

struct Rig {
  GstHarness *h;
  GstBus *bus;
};

/* Properties are set before the harness starts the element. */
Rig rig_setup(const char *format, int w, int h, const char *props, bool side_by_side = true)
{
  GstElement *e = gst_element_factory_make("siftmatch", nullptr);
  fail_unless(e != nullptr);
  if (props && *props) {
    gchar **kv = g_strsplit(props, " ", -1);
    for (gchar **p = kv; *p; p++) {
      gchar **pair = g_strsplit(*p, "=", 2);
      gst_util_set_object_arg(G_OBJECT(e), pair[0], pair[1]);
      g_strfreev(pair);
    }
    g_strfreev(kv);
  }
  Rig rig;
  rig.bus = gst_bus_new();
  gst_element_set_bus(e, rig.bus);
  rig.h = gst_harness_new_with_element(e, "sink", "src");
  gst_object_unref(e);
  gchar *caps = g_strdup_printf("video/x-raw,format=%s,width=%d,height=%d,framerate=25/1%s",
                                format, 2 * w, h,
                                side_by_side ? ",multiview-mode=side-by-side" : "");
  gst_harness_set_src_caps_str(rig.h, caps);
  g_free(caps);
  return rig;
}

void rig_teardown(Rig &rig)
{
  gst_element_set_bus(rig.h->element, nullptr);
  gst_object_unref(rig.bus);
  gst_harness_teardown(rig.h);
}

GstTreeStereoMatchStats pop_stats(GstBus *bus, GstTreeStereoTimes *times)
{
  GstMessage *msg = gst_bus_pop_filtered(bus, GST_MESSAGE_ELEMENT);
  fail_unless(msg != nullptr, "no siftmatch message on the bus");
  GstTreeStereoMatchStats st{};
  fail_unless(gst_tree_stereo_match_message_parse(gst_message_get_structure(msg), &st, times));
  gst_message_unref(msg);
  return st;
}

/* Pushes the synthetic pair through siftmatch with @props (or the defaults) and checks matches,
 * meta and message against the truth. Returns the left view's keypoint count. */
guint check_synthetic(const char *format, const char *props = nullptr)
{
  cv::Mat l, r;
  make_pair(D_TRUE, l, r);
  Rig rig = rig_setup(format, W, H, props);
  GstBuffer *in = side_by_side(format, l, r, 120 * GST_MSECOND);
  add_geometry(in, W, H, FX, W / 2.0, W / 2.0, BASELINE);
  GstBuffer *out = gst_harness_push_and_pull(rig.h, in);
  fail_unless(out != nullptr);
  const GstTreeStereoMatchesMeta *m = gst_buffer_get_tree_stereo_matches_meta(out);
  fail_unless(m != nullptr);
  fail_unless_equals_int(m->method, GST_TREE_STEREO_MATCH_EUCLIDEAN);
  fail_unless(m->n_matches > 200, "%s: only %u matches", format, m->n_matches);
  fail_unless(m->n_keypoints[0] >= m->n_matches && m->n_keypoints[1] >= m->n_matches);
  std::vector<double> errors;
  for (guint i = 0; i < m->n_matches; i++) {
    const GstTreeStereoMatch &k = m->matches[i];
    const double d = double(k.xl) - double(k.xr);
    errors.push_back(std::abs(d - D_TRUE));
    fail_unless(std::abs(d - D_TRUE) < MAX_ERROR,
                "%s: match %u (%.2f, %.2f) disparity %.3f, true %.2f", format, i, k.xl, k.yl, d,
                D_TRUE);
    fail_unless(std::abs(k.yl - k.yr) < 0.5);
    /* each view's own coordinates: the right x is not offset by the side-by-side layout */
    fail_unless(k.xl >= 0 && k.xl < W && k.xr >= 0 && k.xr < W && k.yl >= 0 && k.yl < H);
    fail_unless(std::isfinite(k.score) && k.score >= 0);
  }

  const double med = median(errors), p95 = percentile(errors, 95);
  g_print("%s: %u matches, |disparity error| median %.3f px, 95th percentile %.3f px, max %.3f "
          "px\n",
          format, m->n_matches, med, p95, percentile(errors, 100));
  fail_unless(med < 0.03, "%s: median error %.3f px", format, med);
  fail_unless(percentile(errors, 99) < 0.1, "%s: 99th percentile error %.3f px", format,
              percentile(errors, 99));

  GstTreeStereoTimes times;
  const GstTreeStereoMatchStats st = pop_stats(rig.bus, &times);
  fail_unless_equals_int(st.method, GST_TREE_STEREO_MATCH_EUCLIDEAN);
  fail_unless_equals_int(st.keypoints_left, m->n_keypoints[0]);
  fail_unless_equals_int(st.keypoints_right, m->n_keypoints[1]);
  fail_unless_equals_int(st.matches, m->n_matches);
  /* every left keypoint is either matched (once per SIFT orientation) or dropped by one reason */
  const guint dropped = st.rejected_ratio + st.rejected_epipolar + st.rejected_disparity +
                        st.rejected_mutual;
  fail_unless(st.matches + st.rejected_refine + dropped <= st.keypoints_left);
  fail_unless(st.candidates_tested >= st.matches);
  fail_unless(st.detect_ms > 0 && st.match_ms > 0 && st.refine_ms > 0);
  fail_unless(st.total_ms >= st.detect_ms + st.match_ms + st.refine_ms);
  fail_unless_equals_uint64(times.timestamp, 120 * GST_MSECOND);
  fail_unless_equals_uint64(times.running_time, 120 * GST_MSECOND);
  const guint keypoints = m->n_keypoints[0];
  gst_buffer_unref(out);
  rig_teardown(rig);
  return keypoints;
}

/* A vegetation meta whose two views are @mask (GRAY8, view size) or, when empty, @box only. */
void add_vegetation(GstBuffer *buf, const cv::Mat &mask, const cv::Rect &box, bool present)
{
  GstTreeStereoVegetationMeta *veg = gst_buffer_add_tree_stereo_vegetation_meta(buf, 2);
  for (int v = 0; v < 2; v++) {
    GstTreeStereoVegetationView *view = &veg->views[v];
    view->present = present;
    if (!present)
      continue;
    view->bbox_x = box.x;
    view->bbox_y = box.y;
    view->bbox_width = box.width;
    view->bbox_height = box.height;
    view->area_px = box.area();
    if (mask.empty())
      continue;
    GstBuffer *mb = gst_buffer_new_allocate(nullptr, mask.total(), nullptr);
    gst_buffer_fill(mb, 0, mask.data, mask.total());
    gst_tree_stereo_vegetation_view_set_mask(view, mb, guint(mask.cols), guint(mask.rows),
                                             guint(mask.cols));
    gst_buffer_unref(mb);
  }
}

/* Every match of @buf's meta has a disparity in [lo, hi]. */
bool disparities_within(GstBuffer *buf, double lo, double hi)
{
  const GstTreeStereoMatchesMeta *m = gst_buffer_get_tree_stereo_matches_meta(buf);
  fail_unless(m != nullptr);
  for (guint i = 0; i < m->n_matches; i++) {
    const double d = double(m->matches[i].xl) - double(m->matches[i].xr);
    if (d < lo || d > hi) {
      g_print("match %u: disparity %.2f outside [%.2f, %.2f]\n", i, d, lo, hi);
      return false;
    }
  }
  return true;
}

} // namespace

GST_START_TEST(test_synthetic_gray8)
{
  check_synthetic("GRAY8");
}
GST_END_TEST;

GST_START_TEST(test_synthetic_rgb)
{
  check_synthetic("RGB");
}
GST_END_TEST;

GST_START_TEST(test_synthetic_bgrx)
{
  check_synthetic("BGRx");
}
GST_END_TEST;

/* upright (the default, treestereo's SIFT) and upright=false (OpenCV's) both match the pair to
 * its true disparity; OpenCV's SIFT repeats a place once per dominant orientation, upright
 * describes it once. */
GST_START_TEST(test_upright_and_opencv_sift)
{
  const guint upright = check_synthetic("GRAY8");
  const guint opencv = check_synthetic("GRAY8", "upright=false");
  g_print("keypoints of the left view: upright %u, OpenCV's SIFT %u\n", upright, opencv);
  fail_unless(upright < opencv, "upright %u keypoints, OpenCV %u", upright, opencv);
  fail_unless(upright * 10 > opencv * 7, "upright %u keypoints, OpenCV %u", upright, opencv);
}
GST_END_TEST;

GST_START_TEST(test_vegetation_mask_restricts_detection)
{
  cv::Mat l, r;
  make_pair(D_TRUE, l, r);
  /* the canopy is the left half of each view: a mask in one frame, only the box in the next */
  const cv::Rect half(0, 0, W / 2, H);
  cv::Mat mask = cv::Mat::zeros(H, W, CV_8U);
  mask(half).setTo(255);
  Rig rig = rig_setup("GRAY8", W, H, nullptr);
  for (int with_mask = 1; with_mask >= 0; with_mask--) {
    GstBuffer *in = side_by_side("GRAY8", l, r, 0);
    add_geometry(in, W, H, FX, W / 2.0, W / 2.0, BASELINE);
    add_vegetation(in, with_mask ? mask : cv::Mat(), half, true);
    GstBuffer *out = gst_harness_push_and_pull(rig.h, in);
    const GstTreeStereoMatchesMeta *m = gst_buffer_get_tree_stereo_matches_meta(out);
    fail_unless(m != nullptr);
    fail_unless(m->n_matches > 50, "only %u matches in the half view", m->n_matches);
    for (guint i = 0; i < m->n_matches; i++) {
      fail_unless(m->matches[i].xl < W / 2.0, "match at xl %.1f outside the canopy",
                  m->matches[i].xl);
      fail_unless(m->matches[i].xr < W / 2.0);
      fail_unless(std::abs(double(m->matches[i].xl - m->matches[i].xr) - D_TRUE) < 0.1);
    }
    gst_buffer_unref(out);
  }
  /* mask-inset: no match within that many px (detection scale 1 here) of the canopy's edge at
   * x = W/2; with 0 there are some */
  for (int inset : {0, 20}) {
    g_object_set(rig.h->element, "mask-inset", inset, nullptr);
    GstBuffer *in = side_by_side("GRAY8", l, r, 0);
    add_geometry(in, W, H, FX, W / 2.0, W / 2.0, BASELINE);
    add_vegetation(in, mask, half, true);
    GstBuffer *out = gst_harness_push_and_pull(rig.h, in);
    const GstTreeStereoMatchesMeta *m = gst_buffer_get_tree_stereo_matches_meta(out);
    guint near_edge = 0;
    for (guint i = 0; i < m->n_matches; i++)
      near_edge += m->matches[i].xl > W / 2.0 - 19.0;
    if (inset == 0)
      fail_unless(near_edge >= 3, "only %u matches within 19 px of the edge", near_edge);
    else
      fail_unless(near_edge == 0 && m->n_matches > 30, "%u of %u matches within 19 px of the edge",
                  near_edge, m->n_matches);
    gst_buffer_unref(out);
  }
  g_object_set(rig.h->element, "mask-inset", 4, nullptr);
  /* a view without a canopy: nothing is searched, nothing matched */
  GstBuffer *in = side_by_side("GRAY8", l, r, 0);
  add_geometry(in, W, H, FX, W / 2.0, W / 2.0, BASELINE);
  add_vegetation(in, cv::Mat(), cv::Rect(), false);
  GstBuffer *out = gst_harness_push_and_pull(rig.h, in);
  const GstTreeStereoMatchesMeta *m = gst_buffer_get_tree_stereo_matches_meta(out);
  fail_unless_equals_int(m->n_matches, 0);
  fail_unless_equals_int(m->n_keypoints[0], 0);
  fail_unless_equals_int(m->n_keypoints[1], 0);
  gst_buffer_unref(out);
  /* use-mask=false: the whole view again */
  g_object_set(rig.h->element, "use-mask", FALSE, nullptr);
  in = side_by_side("GRAY8", l, r, 0);
  add_geometry(in, W, H, FX, W / 2.0, W / 2.0, BASELINE);
  add_vegetation(in, mask, half, true);
  out = gst_harness_push_and_pull(rig.h, in);
  m = gst_buffer_get_tree_stereo_matches_meta(out);
  bool right_half = false;
  for (guint i = 0; i < m->n_matches; i++)
    right_half = right_half || m->matches[i].xl > W / 2.0 + 20;
  fail_unless(right_half, "use-mask=false still restricted to the mask");
  gst_buffer_unref(out);
  rig_teardown(rig);
}
GST_END_TEST;

GST_START_TEST(test_properties_change_while_playing)
{
  cv::Mat l, r;
  make_pair(D_TRUE, l, r);
  Rig rig = rig_setup("GRAY8", W, H, "method=cosine-norm");
  /* the true disparity (23.37 px: 2.14 m) is outside 0..10 px: every match is rejected */
  g_object_set(rig.h->element, "min-disparity", 0.0, "max-disparity", 10.0, nullptr);
  GstBuffer *in = side_by_side("GRAY8", l, r, 0);
  add_geometry(in, W, H, FX, W / 2.0, W / 2.0, BASELINE);
  GstBuffer *out = gst_harness_push_and_pull(rig.h, in);
  fail_unless_equals_int(gst_buffer_get_tree_stereo_matches_meta(out)->method,
                         GST_TREE_STEREO_MATCH_COSINE_NORM);
  const guint outside = gst_buffer_get_tree_stereo_matches_meta(out)->n_matches;
  /* only look-alikes inside the range remain (refinement may move them by up to 2 px) */
  fail_unless(disparities_within(out, -2.5, 12.5));
  gst_buffer_unref(out);
  GstTreeStereoMatchStats st = pop_stats(rig.bus, nullptr);
  fail_unless_equals_int(st.method, GST_TREE_STEREO_MATCH_COSINE_NORM);
  fail_unless(st.rejected_disparity > 100);

  /* depth range 2.5..5 m -> 10..20 px: still outside; 2..2.5 m -> 20..25 px: inside */
  g_object_set(rig.h->element, "min-disparity", -1.0, "max-disparity", -1.0, "min-depth", 2500.0,
               "max-depth", 5000.0, nullptr);
  in = side_by_side("GRAY8", l, r, 0);
  add_geometry(in, W, H, FX, W / 2.0, W / 2.0, BASELINE);
  out = gst_harness_push_and_pull(rig.h, in);
  fail_unless(disparities_within(out, 10 - 2.5, 20 + 2.5));
  gst_buffer_unref(out);
  pop_stats(rig.bus, nullptr);
  g_object_set(rig.h->element, "min-depth", 2000.0, "max-depth", 2500.0, nullptr);
  in = side_by_side("GRAY8", l, r, 0);
  add_geometry(in, W, H, FX, W / 2.0, W / 2.0, BASELINE);
  out = gst_harness_push_and_pull(rig.h, in);
  const guint inside = gst_buffer_get_tree_stereo_matches_meta(out)->n_matches;
  fail_unless(inside > 200 && inside > 10 * outside, "%u matches in range, %u out", inside,
              outside);
  fail_unless(disparities_within(out, D_TRUE - MAX_ERROR, D_TRUE + MAX_ERROR));
  gst_buffer_unref(out);
  pop_stats(rig.bus, nullptr);

  /* post-messages=false: the meta still, no message */
  g_object_set(rig.h->element, "post-messages", FALSE, nullptr);
  in = side_by_side("GRAY8", l, r, 0);
  add_geometry(in, W, H, FX, W / 2.0, W / 2.0, BASELINE);
  out = gst_harness_push_and_pull(rig.h, in);
  fail_unless(gst_buffer_get_tree_stereo_matches_meta(out) != nullptr);
  gst_buffer_unref(out);
  fail_unless(gst_bus_pop_filtered(rig.bus, GST_MESSAGE_ELEMENT) == nullptr);
  rig_teardown(rig);
}
GST_END_TEST;

GST_START_TEST(test_property_ranges)
{
  GstElement *e = gst_element_factory_make("siftmatch", nullptr);
  GObjectClass *klass = G_OBJECT_GET_CLASS(e);
  struct Range {
    const char *name;
    double min, max, def;
  };
  const Range ranges[] = {
      {"ratio", 0.01, 1.0, 0.8},
      {"epipolar-tolerance", -1.0, 1000.0, 2.0},
      {"min-disparity", -1.0, 100000.0, -1.0},
      {"max-disparity", -1.0, 100000.0, -1.0},
      {"min-depth", 1.0, 1e6, 500.0},
      {"max-depth", 1.0, 1e7, 10000.0},
      {"contrast-threshold", 0.001, 1.0, 0.02},
      {"scale", 0.0, 1.0, 0.0},
      {"min-zncc", -1.0, 1.0, 0.9},
      {"min-zncc-drop", 0.0, 2.0, 0.05},
      {"layer-tolerance", -1.0, 100.0, 0.5},
      {"layer-centre-tolerance", -1.0, 100.0, 0.7},
      {"layer-min-zncc", -1.0, 1.0, 0.7},
      {"layer-centre-min-zncc", -1.0, 1.0, 0.6},
      /* integer properties */
      {"mask-inset", 0, 64, 4},
      {"relocate", 0, 3, 1},
      {"layer-window", 1, 32, 5},
      {"layer-search", 1, 32, 3},
  };
  for (const Range &r : ranges) {
    GParamSpec *p = g_object_class_find_property(klass, r.name);
    fail_unless(p != nullptr && (G_IS_PARAM_SPEC_DOUBLE(p) || G_IS_PARAM_SPEC_INT(p)), "%s",
                r.name);
    fail_unless(p->flags & GST_PARAM_MUTABLE_PLAYING, "%s", r.name);
    GValue v = G_VALUE_INIT;
    g_value_init(&v, G_PARAM_SPEC_VALUE_TYPE(p));
    if (G_IS_PARAM_SPEC_DOUBLE(p)) {
      fail_unless_equals_float(G_PARAM_SPEC_DOUBLE(p)->minimum, r.min);
      fail_unless_equals_float(G_PARAM_SPEC_DOUBLE(p)->maximum, r.max);
      fail_unless_equals_float(G_PARAM_SPEC_DOUBLE(p)->default_value, r.def);
      g_value_set_double(&v, r.max + 1.0);
    } else {
      fail_unless_equals_int(G_PARAM_SPEC_INT(p)->minimum, int(r.min));
      fail_unless_equals_int(G_PARAM_SPEC_INT(p)->maximum, int(r.max));
      fail_unless_equals_int(G_PARAM_SPEC_INT(p)->default_value, int(r.def));
      g_value_set_int(&v, int(r.max) + 1);
    }
    /* an out-of-range value is refused by validation (g_object_set would warn and ignore it) */
    fail_unless(g_param_value_validate(p, &v), "%s accepts %g", r.name, r.max + 1.0);
    g_value_unset(&v);
  }
  GParamSpec *c = g_object_class_find_property(klass, "candidates");
  fail_unless_equals_int(G_PARAM_SPEC_INT(c)->minimum, 1);
  fail_unless_equals_int(G_PARAM_SPEC_INT(c)->default_value, 5);
  GParamSpec *n = g_object_class_find_property(klass, "nfeatures");
  fail_unless_equals_int(G_PARAM_SPEC_INT(n)->minimum, 0);
  fail_unless_equals_int(G_PARAM_SPEC_INT(n)->default_value, 0);
  gboolean mutual, use_mask, refine, post, upright;
  gint method;
  g_object_get(e, "mutual", &mutual, "use-mask", &use_mask, "refine", &refine, "post-messages",
               &post, "method", &method, "upright", &upright, nullptr);
  fail_unless(mutual && use_mask && refine && post && upright);
  fail_unless_equals_int(method, GST_TREE_STEREO_MATCH_EUCLIDEAN);
  gst_util_set_object_arg(G_OBJECT(e), "method", "cosine-norm");
  g_object_get(e, "method", &method, nullptr);
  fail_unless_equals_int(method, GST_TREE_STEREO_MATCH_COSINE_NORM);
  gst_object_unref(e);
}
GST_END_TEST;

GST_START_TEST(test_missing_geometry_is_an_error)
{
  cv::Mat l, r;
  make_pair(D_TRUE, l, r);
  Rig rig = rig_setup("GRAY8", W, H, nullptr);
  fail_unless_equals_int(gst_harness_push(rig.h, side_by_side("GRAY8", l, r, 0)),
                         GST_FLOW_ERROR);
  /* the same kind of error as stereodepth's and treemetrics': STREAM/FAILED, a sentence that
   * names what is missing and the element upstream that adds it, the meta's type in the debug */
  expect_bus_error(rig.bus, GST_MESSAGE_ERROR, GST_STREAM_ERROR, GST_STREAM_ERROR_FAILED,
                   "No stereo geometry on the buffer: siftmatch needs the geometry meta of "
                   "stereorectify upstream.",
                   "has no GstTreeStereoGeometryMeta");
  rig_teardown(rig);
}
GST_END_TEST;

GST_START_TEST(test_bad_depth_range_is_an_error)
{
  cv::Mat l, r;
  make_pair(D_TRUE, l, r);
  Rig rig = rig_setup("GRAY8", W, H, "min-depth=5000 max-depth=1000");
  GstBuffer *in = side_by_side("GRAY8", l, r, 0);
  add_geometry(in, W, H, FX, W / 2.0, W / 2.0, BASELINE);
  fail_unless_equals_int(gst_harness_push(rig.h, in), GST_FLOW_ERROR);
  expect_bus_error(rig.bus, GST_MESSAGE_ERROR, GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_SETTINGS,
                   "siftmatch's max-depth must be above its min-depth: raise max-depth or lower "
                   "min-depth.",
                   "max-depth (1000.000000 mm) must be above min-depth (5000.000000 mm)");
  rig_teardown(rig);
}
GST_END_TEST;

/* min-disparity above max-disparity: a settings error naming both. */
GST_START_TEST(test_empty_disparity_range_is_a_settings_error)
{
  cv::Mat l, r;
  make_pair(D_TRUE, l, r);
  Rig rig = rig_setup("GRAY8", W, H, "min-disparity=60 max-disparity=20");
  GstBuffer *in = side_by_side("GRAY8", l, r, 0);
  add_geometry(in, W, H, FX, W / 2.0, W / 2.0, BASELINE);
  fail_unless_equals_int(gst_harness_push(rig.h, in), GST_FLOW_ERROR);
  expect_bus_error(rig.bus, GST_MESSAGE_ERROR, GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_SETTINGS,
                   "siftmatch's disparity range is empty: set min-disparity below "
                   "max-disparity, or min-depth and max-depth that leave a range.",
                   "min 60.000000 px > max 20.000000 px");
  rig_teardown(rig);
}
GST_END_TEST;

GST_START_TEST(test_mono_stream_is_an_error)
{
  cv::Mat l, r;
  make_pair(D_TRUE, l, r);
  Rig rig = rig_setup("GRAY8", W, H, nullptr, false);
  GstBuffer *in = side_by_side("GRAY8", l, r, 0);
  add_geometry(in, W, H, FX, W / 2.0, W / 2.0, BASELINE);
  fail_unless(gst_harness_push(rig.h, in) != GST_FLOW_OK);
  expect_bus_error(rig.bus, GST_MESSAGE_ERROR, GST_CORE_ERROR, GST_CORE_ERROR_NEGOTIATION,
                   "siftmatch needs side-by-side stereo frames (multiview-mode=side-by-side) "
                   "from stereorectify",
                   "caps");
  rig_teardown(rig);
}
GST_END_TEST;

GST_START_TEST(test_middlebury_jadeplant)
{
  const std::string dir = data_dir() + "/middlebury2014-quarter/Jadeplant";
  if (!std::ifstream(dir + "/disp0GT.pfm").good()) {
    g_print("SKIP: Middlebury Jadeplant not found in %s (set TREESTEREO_DATA_DIR to the shared "
            "data directory)\n",
            dir.c_str());
    return;
  }
  const MiddleburyScene s = load_middlebury_scene(dir);
  const StereoGeometry g = s.calib.geometry();
  const int w = s.left.cols, h = s.left.rows;
  /* lib's test conditions: full-resolution detection, a 1 px band, depth 1.8..3.6 m */
  Rig rig = rig_setup("BGR", w, h, "scale=1 epipolar-tolerance=1 min-depth=1800 max-depth=3600");
  auto run = [&](GstClockTime pts) {
    GstBuffer *in = side_by_side("BGR", s.left, s.right, pts);
    add_geometry(in, w, h, g.fx, g.cx[0], g.cx[1], g.baseline_mm);
    GstBuffer *out = gst_harness_push_and_pull(rig.h, in);
    const GstTreeStereoMatchesMeta *m = gst_buffer_get_tree_stereo_matches_meta(out);
    fail_unless(m != nullptr);
    std::vector<StereoMatch> matches;
    for (guint i = 0; i < m->n_matches; i++) {
      const GstTreeStereoMatch &k = m->matches[i];
      matches.push_back(StereoMatch{k.xl, k.yl, k.xr, k.yr, k.score});
    }
    const MatchAccuracy acc = evaluate_matches(matches, s.disp_gt, s.mask_nocc, 1.0);
    g_print("Jadeplant through siftmatch: keypoints %u/%u, matches %u, evaluated %zu, correct "
            "%.2f%%\n",
            m->n_keypoints[0], m->n_keypoints[1], m->n_matches, acc.evaluated,
            100.0 * acc.correct_rate());
    gst_buffer_unref(out);
    return acc;
  };
  /* the defaults: the two-layer test drops most of the keypoints beside the branches that took
   * their disparity; the target is the paper's 98%, with siftmatch's defaults (contrast-threshold
   * 0.02: 170 evaluated, 3 wrong, 98.24%; at 0.035: 3 wrong of 114, 97.37%) */
  const MatchAccuracy layered = run(0);
  fail_unless(layered.evaluated > 140, "evaluated %zu", layered.evaluated);
  fail_unless(layered.correct_rate() >= 0.98, "correct %.3f", layered.correct_rate());

  /* without it, as lib's test: Jadeplant's thin branches before a far wall keep it below the
   * paper's 98% */
  g_object_set(rig.h->element, "layer-tolerance", -1.0, nullptr);
  const MatchAccuracy plain = run(GST_SECOND);
  fail_unless(plain.evaluated > 50);
  fail_unless(plain.correct_rate() >= 0.85, "correct %.3f", plain.correct_rate());
  fail_unless(layered.wrong() * 4 < plain.wrong(), "wrong %zu of %zu, without the test %zu",
              layered.wrong(), layered.evaluated, plain.wrong());
  rig_teardown(rig);
}
GST_END_TEST;

static Suite *siftmatch_suite(void)
{
  Suite *s = suite_create("siftmatch");
  TCase *tc = tcase_create("general");
  suite_add_tcase(s, tc);
  tcase_add_test(tc, test_synthetic_gray8);
  tcase_add_test(tc, test_synthetic_rgb);
  tcase_add_test(tc, test_synthetic_bgrx);
  tcase_add_test(tc, test_upright_and_opencv_sift);
  tcase_add_test(tc, test_vegetation_mask_restricts_detection);
  tcase_add_test(tc, test_properties_change_while_playing);
  tcase_add_test(tc, test_property_ranges);
  tcase_add_test(tc, test_missing_geometry_is_an_error);
  tcase_add_test(tc, test_bad_depth_range_is_an_error);
  tcase_add_test(tc, test_empty_disparity_range_is_a_settings_error);
  tcase_add_test(tc, test_mono_stream_is_an_error);
  tcase_add_test(tc, test_middlebury_jadeplant);
  return s;
}

GST_CHECK_MAIN(siftmatch);
