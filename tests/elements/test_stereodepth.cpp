/* stereodepth: sparse triangulation of matches projected from known 3D points, with range and
 * outlier drops; dense SGBM on a side-by-side frame with a known constant disparity; errors. */
/* C++ and OpenCV headers first: gstcheck.h defines a macro named fail */
#include "treestereo/stats.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "element_props.h"
#include <gst/check/gstcheck.h>
#include <gst/check/gstharness.h>
#include "expect_error.h"
#include "../common/temp_dir.hpp"
#include <gst/treestereo/treestereo-meta.h>
#include <gst/video/video.h>


namespace {

/* A rectified pair: 1296x972 views, f 1100 px, baseline 50 mm, and principal points 8 px apart
 * so that the disparity offset doffs = cx[0] - cx[1] is exercised. */
struct Geometry {
  guint w = 1296, h = 972;
  double f = 1100, cxl = 648, cxr = 640, cy = 486, b = 50;
  double doffs() const { return cxl - cxr; }
};

void fill_geometry(GstBuffer *buf, const Geometry &g)
{
  GstTreeStereoGeometryMeta *m = gst_buffer_add_tree_stereo_geometry_meta(buf);
  m->view_width = g.w;
  m->view_height = g.h;
  m->side_by_side = TRUE;
  m->rectified = TRUE;
  for (int v = 0; v < 2; v++) {
    m->fx[v] = m->fy[v] = g.f;
    m->cy[v] = g.cy;
  }
  m->cx[0] = g.cxl;
  m->cx[1] = g.cxr;
  m->baseline_mm = g.b;
  /* cv::stereoRectify's Q with Tx = -b: [X Y Z W] = Q [x y d 1] */
  const double Q[16] = {1, 0, 0, -g.cxl, 0, 1, 0, -g.cy, 0, 0, 0, g.f, 0, 0, 1 / g.b,
                        -g.doffs() / g.b};
  for (int i = 0; i < 16; i++)
    m->Q[i] = Q[i];
  for (int i = 0; i < 9; i++)
    m->R1[i] = (i % 4 == 0) ? 1 : 0;
}

struct Rig {
  GstHarness *h = nullptr;
  GstBus *bus = nullptr;
};

Rig rig_new(const char *caps, const char *props)
{
  Rig r;
  GstElement *e = element_with_props("stereodepth", props);
  fail_unless(e != nullptr);
  r.bus = gst_bus_new();
  gst_element_set_bus(e, r.bus);
  r.h = gst_harness_new_with_element(e, "sink", "src");
  gst_object_unref(e);
  gst_harness_set_src_caps_str(r.h, caps);
  return r;
}

void rig_free(Rig &r)
{
  gst_element_set_bus(r.h->element, nullptr);
  gst_object_unref(r.bus);
  gst_harness_teardown(r.h);
}

/* The element message of the last buffer, parsed. */
void pop_depth_message(GstBus *bus, gboolean *dense, GstTreeStereoDepthStats *st,
                       GstTreeStereoTimes *times)
{
  GstMessage *msg = gst_bus_pop_filtered(bus, GST_MESSAGE_ELEMENT);
  fail_unless(msg != nullptr, "no stereodepth message");
  const GstStructure *s = gst_message_get_structure(msg);
  fail_unless(gst_tree_stereo_depth_message_parse(s, dense, st, times));
  gst_message_unref(msg);
}

void expect_stats_equal(const GstTreeStereoDepthStats &a, const GstTreeStereoDepthStats &b)
{
  fail_unless_equals_int(a.n_points, b.n_points);
  fail_unless_equals_int(a.n_valid, b.n_valid);
  fail_unless_equals_int(a.dropped_disparity, b.dropped_disparity);
  fail_unless_equals_int(a.dropped_range, b.dropped_range);
  fail_unless_equals_int(a.dropped_outlier, b.dropped_outlier);
  fail_unless_equals_float(a.median_z_mm, b.median_z_mm);
  fail_unless_equals_float(a.mad_z_mm, b.mad_z_mm);
  fail_unless_equals_float(a.p05_z_mm, b.p05_z_mm);
  fail_unless_equals_float(a.p95_z_mm, b.p95_z_mm);
  fail_unless_equals_float(a.accept_lo_mm, b.accept_lo_mm);
  fail_unless_equals_float(a.accept_hi_mm, b.accept_hi_mm);
}

bool near_rel(double got, double want, double rel)
{
  return std::abs(got - want) <= rel * std::max(std::abs(want), 1.0);
}

struct TruePoint {
  double x, y, z;
  enum Kind { INLIER, RANGE, OUTLIER, NO_DISPARITY } kind;
};

GstTreeStereoMatch project(const Geometry &g, const TruePoint &p)
{
  GstTreeStereoMatch m;
  const double xl = g.f * p.x / p.z + g.cxl, yl = g.f * p.y / p.z + g.cy;
  const double d = p.kind == TruePoint::NO_DISPARITY ? g.doffs() - 1.0 : g.f * g.b / p.z + g.doffs();
  m.xl = float(xl);
  m.yl = float(yl);
  m.xr = float(xl - d);
  m.yr = float(yl);
  m.score = 0.1f;
  return m;
}

const char *kSbsCaps = "video/x-raw,format=RGB,width=2592,height=972,framerate=10/1,"
                       "multiview-mode=side-by-side";

} // namespace

GST_START_TEST(test_sparse_points_stats_and_drops)
{
  const Geometry g;
  cv::RNG rng(5);
  std::vector<TruePoint> truth;
  for (int i = 0; i < 200; i++)
    truth.push_back({rng.uniform(-800.0, 800.0), rng.uniform(-600.0, 600.0),
                     rng.uniform(2000.0, 3000.0), TruePoint::INLIER});
  /* out of [min-depth 500, max-depth 10000]; depth outliers at 0.7 m and 9 m (inside the range);
   * one match with d - doffs < 0 */
  truth.push_back({100, 50, 250, TruePoint::RANGE});
  truth.push_back({-300, 20, 15000, TruePoint::RANGE});
  truth.push_back({50, -40, 700, TruePoint::OUTLIER});
  truth.push_back({-200, 10, 9000, TruePoint::OUTLIER});
  truth.push_back({10, 10, 2500, TruePoint::NO_DISPARITY});
  std::vector<GstTreeStereoMatch> matches;
  for (const TruePoint &p : truth)
    matches.push_back(project(g, p));

  Rig r = rig_new(kSbsCaps, "min-depth=500 max-depth=10000");
  GstBuffer *in = gst_buffer_new(); /* sparse mode never looks at the pixels */
  GST_BUFFER_PTS(in) = 3 * GST_SECOND;
  fill_geometry(in, g);
  gst_buffer_add_tree_stereo_matches_meta(in, GST_TREE_STEREO_MATCH_COSINE_NORM, 400, 390,
                                          matches.data(), guint(matches.size()));
  GstBuffer *out = gst_harness_push_and_pull(r.h, in);
  fail_unless(out != nullptr);
  const GstTreeStereoPointsMeta *pm = gst_buffer_get_tree_stereo_points_meta(out);
  fail_unless(pm != nullptr);
  fail_if(pm->dense);
  fail_unless(pm->depth_map == nullptr);
  fail_unless_equals_int(pm->n_points, truth.size());

  /* every point against its true position, valid exactly when an inlier */
  std::vector<double> inlier_z, ranged_z;
  for (guint i = 0; i < pm->n_points; i++) {
    const GstTreeStereoPoint &p = pm->points[i];
    const TruePoint &t = truth[i];
    fail_unless_equals_int(p.match_index, i);
    fail_unless_equals_int(p.valid, t.kind == TruePoint::INLIER);
    if (t.kind == TruePoint::INLIER)
      inlier_z.push_back(t.z);
    if (t.kind == TruePoint::INLIER || t.kind == TruePoint::OUTLIER)
      ranged_z.push_back(t.z);
    if (t.kind == TruePoint::NO_DISPARITY)
      continue;
    const double norm = std::sqrt(t.x * t.x + t.y * t.y + t.z * t.z);
    fail_unless(std::abs(p.z - t.z) <= 1e-3 * t.z, "point %u: Z %f, true %f", i, p.z, t.z);
    fail_unless(std::abs(p.x - t.x) <= 1e-3 * norm, "point %u: X %f, true %f", i, p.x, t.x);
    fail_unless(std::abs(p.y - t.y) <= 1e-3 * norm, "point %u: Y %f, true %f", i, p.y, t.y);
  }

  /* the statistics by their definitions on the true depths */
  const GstTreeStereoDepthStats &st = pm->stats;
  fail_unless_equals_int(st.n_points, truth.size());
  fail_unless_equals_int(st.n_valid, 200);
  fail_unless_equals_int(st.dropped_disparity, 1);
  fail_unless_equals_int(st.dropped_range, 2);
  fail_unless_equals_int(st.dropped_outlier, 2);
  const treestereo::Summary s = treestereo::summarize(inlier_z);
  fail_unless(near_rel(st.median_z_mm, s.median, 1e-3), "median %f vs %f", st.median_z_mm,
              s.median);
  fail_unless(near_rel(st.p05_z_mm, s.p05, 1e-3), "p05 %f vs %f", st.p05_z_mm, s.p05);
  fail_unless(near_rel(st.p95_z_mm, s.p95, 1e-3), "p95 %f vs %f", st.p95_z_mm, s.p95);
  fail_unless(near_rel(st.mad_z_mm, s.mad, 1e-3), "MAD %f vs %f", st.mad_z_mm, s.mad);
  /* the outlier cut: median +- 3.5 * 1.4826 * MAD of the depths that passed the range */
  const treestereo::Summary rs = treestereo::summarize(ranged_z);
  const double band = 3.5 * 1.4826 * rs.mad;
  fail_unless(near_rel(st.accept_lo_mm, rs.median - band, 1e-3), "lo %f", st.accept_lo_mm);
  fail_unless(near_rel(st.accept_hi_mm, rs.median + band, 1e-3), "hi %f", st.accept_hi_mm);

  /* the message carries the meta's figures and the buffer's times */
  gboolean dense = TRUE;
  GstTreeStereoDepthStats ms{};
  GstTreeStereoTimes times;
  pop_depth_message(r.bus, &dense, &ms, &times);
  fail_if(dense);
  expect_stats_equal(ms, st);
  fail_unless_equals_uint64(times.timestamp, 3 * GST_SECOND);
  fail_unless_equals_uint64(times.running_time, 3 * GST_SECOND);
  fail_unless_equals_uint64(times.stream_time, 3 * GST_SECOND);
  gst_buffer_unref(out);

  /* outlier-k=0: the two depth outliers stay; the range still applies */
  g_object_set(r.h->element, "outlier-k", 0.0, "post-messages", FALSE, NULL);
  in = gst_buffer_new();
  fill_geometry(in, g);
  gst_buffer_add_tree_stereo_matches_meta(in, GST_TREE_STEREO_MATCH_COSINE_NORM, 400, 390,
                                          matches.data(), guint(matches.size()));
  out = gst_harness_push_and_pull(r.h, in);
  pm = gst_buffer_get_tree_stereo_points_meta(out);
  fail_unless_equals_int(pm->stats.n_valid, 202);
  fail_unless_equals_int(pm->stats.dropped_outlier, 0);
  fail_unless_equals_int(pm->stats.dropped_range, 2);
  fail_unless_equals_float(pm->stats.accept_lo_mm, 500.0);
  fail_unless_equals_float(pm->stats.accept_hi_mm, 10000.0);
  fail_unless(gst_bus_pop_filtered(r.bus, GST_MESSAGE_ELEMENT) == nullptr,
              "post-messages=false still posted");
  gst_buffer_unref(out);
  rig_free(r);
}
GST_END_TEST;

GST_START_TEST(test_sparse_no_matches_is_empty_not_nan)
{
  const Geometry g;
  Rig r = rig_new(kSbsCaps, nullptr);
  GstBuffer *in = gst_buffer_new();
  fill_geometry(in, g);
  gst_buffer_add_tree_stereo_matches_meta(in, GST_TREE_STEREO_MATCH_COSINE_NORM, 0, 0, nullptr, 0);
  GstBuffer *out = gst_harness_push_and_pull(r.h, in);
  const GstTreeStereoPointsMeta *pm = gst_buffer_get_tree_stereo_points_meta(out);
  fail_unless(pm != nullptr);
  fail_unless_equals_int(pm->n_points, 0);
  fail_unless_equals_int(pm->stats.n_valid, 0);
  fail_unless_equals_float(pm->stats.median_z_mm, 0.0);
  fail_unless_equals_float(pm->stats.p95_z_mm, 0.0);
  gboolean dense;
  GstTreeStereoDepthStats ms{};
  pop_depth_message(r.bus, &dense, &ms, nullptr);
  expect_stats_equal(ms, pm->stats);
  gst_buffer_unref(out);
  rig_free(r);
}
GST_END_TEST;

/* Pushes @in, expects GST_FLOW_ERROR and the error (domain, code, message, debug part). */
static void expect_push_error(Rig &r, GstBuffer *in, GQuark domain, gint code, const char *message,
                              const char *debug_part)
{
  fail_unless_equals_int(gst_harness_push(r.h, in), GST_FLOW_ERROR);
  expect_bus_error(r.bus, GST_MESSAGE_ERROR, domain, code, message, debug_part);
}

GST_START_TEST(test_missing_metas_are_errors_naming_upstream)
{
  const Geometry g;
  {
    Rig r = rig_new(kSbsCaps, nullptr);
    expect_push_error(r, gst_buffer_new(), GST_STREAM_ERROR, GST_STREAM_ERROR_FAILED,
                      "No stereo geometry on the buffer: stereodepth needs the geometry meta of "
                      "stereorectify upstream.",
                      "has no GstTreeStereoGeometryMeta");
    rig_free(r);
  }
  {
    Rig r = rig_new(kSbsCaps, nullptr);
    GstBuffer *in = gst_buffer_new();
    fill_geometry(in, g);
    expect_push_error(r, in, GST_STREAM_ERROR, GST_STREAM_ERROR_FAILED,
                      "No stereo matches on the buffer: stereodepth mode=sparse needs the "
                      "matches meta of siftmatch upstream (or use mode=dense).",
                      "has no GstTreeStereoMatchesMeta");
    rig_free(r);
  }
  {
    /* min-depth above max-depth: lib's BadSettings, its text in the debug string */
    Rig r = rig_new(kSbsCaps, "min-depth=5000 max-depth=1000");
    GstBuffer *in = gst_buffer_new();
    fill_geometry(in, g);
    GstTreeStereoMatch m = {700, 500, 680, 500, 0};
    gst_buffer_add_tree_stereo_matches_meta(in, GST_TREE_STEREO_MATCH_COSINE_NORM, 1, 1, &m, 1);
    expect_push_error(r, in, GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_SETTINGS,
                      "The settings of stereodepth cannot be used: change the property the debug "
                      "detail names.",
                      "need 0 < min-depth < max-depth");
    rig_free(r);
  }
  {
    /* dense on a single-view stream */
    Rig r = rig_new("video/x-raw,format=GRAY8,width=1296,height=972,framerate=10/1",
                    "mode=dense");
    GstBuffer *in = gst_buffer_new_allocate(nullptr, 1296 * 972, nullptr);
    fill_geometry(in, g);
    expect_push_error(r, in, GST_STREAM_ERROR, GST_STREAM_ERROR_FAILED,
                      "stereodepth mode=dense needs side-by-side stereo frames "
                      "(multiview-mode=side-by-side, as stereorectify produces): put "
                      "stereorectify upstream, or use mode=sparse.",
                      "one view per frame");
    rig_free(r);
  }
}
GST_END_TEST;

namespace {

/* A side-by-side RGB frame: a random texture whose right view is the left shifted by the
 * disparity d everywhere (a fronto-parallel plane), as in lib's dense test. */
struct DenseScene {
  Geometry g;
  double d = 35.4;
  cv::Rect box;
  cv::Mat left, right, mask;
  double z() const { return g.f * g.b / (d - g.doffs()); }
};

DenseScene dense_scene()
{
  DenseScene s;
  s.g.w = 480;
  s.g.h = 360;
  s.g.f = 700;
  s.g.b = 60;
  s.g.cxl = s.g.cxr = 240;
  s.g.cy = 180;
  const cv::Size size(int(s.g.w), int(s.g.h));
  cv::Mat noise(size, CV_8U);
  cv::RNG rng(11);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(noise, s.left, cv::Size(0, 0), 1.2);
  cv::normalize(s.left, s.left, 0, 255, cv::NORM_MINMAX);
  const cv::Matx23d shift(1, 0, s.d, 0, 1, 0); /* right(x) = left(x + d) */
  cv::warpAffine(s.left, s.right, shift, size, cv::INTER_CUBIC | cv::WARP_INVERSE_MAP,
                 cv::BORDER_REFLECT);
  s.box = cv::Rect(120, 72, 240, 216);
  s.mask = cv::Mat::zeros(size, CV_8U);
  cv::ellipse(s.mask, (s.box.tl() + s.box.br()) / 2, s.box.size() / 2, 0, 0, 360,
              cv::Scalar(255), cv::FILLED);
  return s;
}

GstBuffer *dense_frame(const DenseScene &s)
{
  const int w = int(s.g.w), h = int(s.g.h), stride = GST_ROUND_UP_4(2 * w * 3);
  GstBuffer *buf = gst_buffer_new_allocate(nullptr, gsize(stride) * gsize(h), nullptr);
  GstMapInfo map;
  gst_buffer_map(buf, &map, GST_MAP_WRITE);
  cv::Mat frame(h, 2 * w, CV_8UC3, map.data, size_t(stride));
  cv::Mat l, r;
  cv::cvtColor(s.left, l, cv::COLOR_GRAY2RGB);
  cv::cvtColor(s.right, r, cv::COLOR_GRAY2RGB);
  l.copyTo(frame(cv::Rect(0, 0, w, h)));
  r.copyTo(frame(cv::Rect(w, 0, w, h)));
  gst_buffer_unmap(buf, &map);
  fill_geometry(buf, s.g);
  return buf;
}

void add_vegetation(GstBuffer *buf, const DenseScene &s, bool present)
{
  GstTreeStereoVegetationMeta *v = gst_buffer_add_tree_stereo_vegetation_meta(buf, 2);
  GstTreeStereoVegetationView *lv = &v->views[0];
  lv->present = present;
  if (!present)
    return;
  lv->bbox_x = s.box.x;
  lv->bbox_y = s.box.y;
  lv->bbox_width = s.box.width;
  lv->bbox_height = s.box.height;
  lv->area_px = cv::countNonZero(s.mask);
  GstBuffer *mask = gst_buffer_new_allocate(nullptr, gsize(s.mask.total()), nullptr);
  gst_buffer_fill(mask, 0, s.mask.data, s.mask.total());
  gst_tree_stereo_vegetation_view_set_mask(lv, mask, guint(s.mask.cols), guint(s.mask.rows),
                                           guint(s.mask.cols));
  gst_buffer_unref(mask);
}

std::string dense_caps(const DenseScene &s)
{
  return "video/x-raw,format=RGB,width=" + std::to_string(2 * s.g.w) +
         ",height=" + std::to_string(s.g.h) + ",framerate=10/1,multiview-mode=side-by-side";
}

} // namespace

GST_START_TEST(test_dense_depth_map_on_the_canopy)
{
  const DenseScene s = dense_scene();
  const double z_true = s.z();
  Rig r = rig_new(dense_caps(s).c_str(), "mode=dense min-depth=800 max-depth=2500");
  GstBuffer *in = dense_frame(s);
  add_vegetation(in, s, true);
  GST_BUFFER_PTS(in) = GST_SECOND;
  GstBuffer *out = gst_harness_push_and_pull(r.h, in);
  const GstTreeStereoPointsMeta *pm = gst_buffer_get_tree_stereo_points_meta(out);
  fail_unless(pm != nullptr);
  fail_unless(pm->dense);
  fail_unless(pm->depth_map != nullptr);
  fail_unless_equals_int(pm->depth_x, s.box.x);
  fail_unless_equals_int(pm->depth_y, s.box.y);
  fail_unless_equals_int(pm->depth_width, s.box.width);
  fail_unless_equals_int(pm->depth_height, s.box.height);
  fail_unless_equals_int(pm->depth_stride, 2 * s.box.width);

  GstMapInfo map;
  fail_unless(gst_buffer_map(pm->depth_map, &map, GST_MAP_READ));
  fail_unless(map.size >= gsize(pm->depth_stride) * pm->depth_height);
  int in_mask = 0, good = 0, outside = 0;
  std::vector<double> z;
  for (guint v = 0; v < pm->depth_height; v++) {
    const guint16 *row = reinterpret_cast<const guint16 *>(map.data + v * pm->depth_stride);
    for (guint u = 0; u < pm->depth_width; u++) {
      const double dz = GUINT16_FROM_LE(row[u]);
      const bool m = s.mask.at<uchar>(int(v) + s.box.y, int(u) + s.box.x) != 0;
      in_mask += m;
      outside += (dz > 0 && !m);
      if (dz > 0 && m) {
        z.push_back(dz);
        good += std::abs(dz - z_true) <= 0.01 * z_true;
      }
    }
  }
  gst_buffer_unmap(pm->depth_map, &map);
  std::printf("[ dense ] true Z %.1f mm: %zu of %d mask pixels with depth, %d within 1%%\n", z_true,
              z.size(), in_mask, good);
  fail_unless_equals_int(outside, 0);
  fail_unless(good > 0.8 * in_mask, "only %d of %d canopy pixels within 1%%", good, in_mask);
  fail_unless(near_rel(treestereo::median(z), z_true, 0.01));

  /* the points: a grid of canopy pixels, each Z within 1%, stats median within 1% */
  fail_unless(pm->stats.n_valid > 500);
  fail_unless(near_rel(pm->stats.median_z_mm, z_true, 0.01), "median %f", pm->stats.median_z_mm);
  for (guint i = 0; i < pm->n_points; i++) {
    const GstTreeStereoPoint &p = pm->points[i];
    const int x = int(p.match_index % s.g.w), y = int(p.match_index / s.g.w);
    fail_unless(s.mask.at<uchar>(y, x) != 0);
    fail_unless_equals_int((x - s.box.x) % 4, 0);
    if (p.valid)
      fail_unless(std::abs(p.z - z_true) <= 0.02 * z_true, "point %u: Z %f", i, p.z);
  }
  gboolean dense = FALSE;
  GstTreeStereoDepthStats ms{};
  pop_depth_message(r.bus, &dense, &ms, nullptr);
  fail_unless(dense);
  expect_stats_equal(ms, pm->stats);
  gst_buffer_unref(out);

  /* no canopy in the vegetation meta: nothing matched, an empty meta */
  in = dense_frame(s);
  add_vegetation(in, s, false);
  out = gst_harness_push_and_pull(r.h, in);
  pm = gst_buffer_get_tree_stereo_points_meta(out);
  fail_unless(pm != nullptr && pm->dense);
  fail_unless_equals_int(pm->n_points, 0);
  fail_unless(pm->depth_map == nullptr);
  fail_unless_equals_float(pm->stats.median_z_mm, 0.0);
  gst_buffer_unref(out);
  rig_free(r);
}
GST_END_TEST;

GST_START_TEST(test_dense_without_vegetation_uses_the_whole_view)
{
  const DenseScene s = dense_scene();
  Rig r = rig_new(dense_caps(s).c_str(), "mode=dense min-depth=800 max-depth=2500 sample-step=8");
  GstBuffer *out = gst_harness_push_and_pull(r.h, dense_frame(s));
  const GstTreeStereoPointsMeta *pm = gst_buffer_get_tree_stereo_points_meta(out);
  fail_unless(pm != nullptr && pm->depth_map != nullptr);
  fail_unless_equals_int(pm->depth_x, 0);
  fail_unless_equals_int(pm->depth_y, 0);
  fail_unless_equals_int(pm->depth_width, s.g.w);
  fail_unless_equals_int(pm->depth_height, s.g.h);
  fail_unless(near_rel(pm->stats.median_z_mm, s.z(), 0.01), "median %f", pm->stats.median_z_mm);
  for (guint i = 0; i < pm->n_points; i++)
    fail_unless_equals_int((pm->points[i].match_index % s.g.w) % 8, 0);
  gst_buffer_unref(out);
  rig_free(r);
}
GST_END_TEST;

/* Seeds on the plane of dense_scene(): exact matches at its disparity inside the ellipse. */
static std::vector<GstTreeStereoMatch> plane_matches(const DenseScene &s, int n)
{
  std::vector<GstTreeStereoMatch> m;
  for (int i = 0; i < n; i++) {
    const float x = float(s.box.x + 60 + 6 * i), y = float(s.box.y + 70 + 4 * i);
    m.push_back({x, y, float(x - s.d), y, 0.1f});
  }
  return m;
}

/* A frame of dense_scene() with its vegetation meta (canopy or none) and `seeds` as the
 * matches meta. */
static GstBuffer *seeded_frame(const DenseScene &s, const std::vector<GstTreeStereoMatch> &seeds,
                               bool canopy)
{
  GstBuffer *in = dense_frame(s);
  add_vegetation(in, s, canopy);
  gst_buffer_add_tree_stereo_matches_meta(in, GST_TREE_STEREO_MATCH_EUCLIDEAN, 100, 100,
                                          seeds.data(), guint(seeds.size()));
  return in;
}

GST_START_TEST(test_sparse_densify_grid_on_the_canopy)
{
  const DenseScene s = dense_scene();
  const double z_true = s.z();
  const std::vector<GstTreeStereoMatch> seeds = plane_matches(s, 20);
  Rig r = rig_new(dense_caps(s).c_str(), nullptr);
  gboolean densify = FALSE;
  g_object_get(r.h->element, "densify", &densify, NULL);
  fail_unless(densify, "densify is on by default");
  GstBuffer *in = seeded_frame(s, seeds, true);
  GstBuffer *out = gst_harness_push_and_pull(r.h, in);
  const GstTreeStereoPointsMeta *pm = gst_buffer_get_tree_stereo_points_meta(out);
  fail_unless(pm != nullptr);
  fail_if(pm->dense);
  fail_unless(pm->depth_map == nullptr);
  /* automatic step: about 4000 grid points on the ellipse (area ~ pi * 120 * 108 px) */
  const int area = cv::countNonZero(s.mask);
  const int step = int(std::lround(std::sqrt(area / 4000.0)));
  const guint n_grid = pm->stats.n_grid;
  fail_unless(n_grid > 0.8 * area / (step * step), "%u grid points of ~%d", n_grid,
              area / (step * step));
  fail_unless_equals_int(pm->n_points, seeds.size() + n_grid);
  for (guint i = 0; i < seeds.size(); i++) {
    fail_unless_equals_int(pm->points[i].match_index, i);
    fail_unless(std::abs(pm->points[i].z - z_true) <= 1e-3 * z_true);
  }
  /* the edge bands (default 0.04 of the box, every width / 648 px, at least 2) sample the
   * extremes finer */
  gdouble edge_band = 0;
  gint edge_step = -1;
  g_object_get(r.h->element, "edge-band", &edge_band, "edge-step", &edge_step, NULL);
  fail_unless(edge_band == 0.04 && edge_step == 0, "edge-band %f, edge-step %d", edge_band,
              edge_step);
  const cv::Rect box = cv::boundingRect(s.mask);
  const int fs = std::max(2, int(std::lround(s.g.w / 648.0))); /* automatic: width / 648, >= 2 */
  const int band_rows = int(std::ceil(0.04 * box.height)), band_cols = int(std::ceil(0.04 * box.width));
  const auto in_band = [&](int x, int y) {
    return y < box.y + band_rows || y >= box.br().y - band_rows || x < box.x + band_cols ||
           x >= box.br().x - band_cols;
  };
  guint n_band = 0;
  for (guint i = guint(seeds.size()); i < pm->n_points; i++) {
    const GstTreeStereoPoint &p = pm->points[i];
    const int x = int(p.match_index % s.g.w), y = int(p.match_index / s.g.w);
    fail_unless(s.mask.at<uchar>(y, x) != 0, "grid point %u off the mask", i);
    const bool coarse = x % step == step / 2 && y % step == step / 2;
    const bool fine = x % fs == fs / 2 && y % fs == fs / 2 && in_band(x, y);
    fail_unless(coarse || fine, "grid point %u (%d, %d) on neither grid", i, x, y);
    n_band += !coarse;
    fail_unless(p.valid);
    /* within 0.2 px of disparity (as lib's densify test), 0.56 % of depth here */
    fail_unless(std::abs(p.z - z_true) <= 0.2 / s.d * z_true, "grid point %u: Z %f, true %f", i,
                p.z, z_true);
    const double xl = x, yl = y;
    fail_unless(std::abs(p.x - (xl - s.g.cxl) * p.z / s.g.f) <= 1e-3 * p.z);
    fail_unless(std::abs(p.y - (yl - s.g.cy) * p.z / s.g.f) <= 1e-3 * p.z);
  }
  fail_unless(near_rel(pm->stats.median_z_mm, z_true, 0.03 / s.d), "median %f", pm->stats.median_z_mm);
  fail_unless(n_band > 0, "no point of the edge bands");
  gboolean dense = TRUE;
  GstTreeStereoDepthStats ms{};
  pop_depth_message(r.bus, &dense, &ms, nullptr);
  fail_if(dense);
  expect_stats_equal(ms, pm->stats);
  fail_unless_equals_int(ms.n_grid, n_grid);
  gst_buffer_unref(out);

  /* edge-band=0: the even grid alone, the band points gone */
  g_object_set(r.h->element, "edge-band", 0.0, NULL);
  in = seeded_frame(s, seeds, true);
  out = gst_harness_push_and_pull(r.h, in);
  pm = gst_buffer_get_tree_stereo_points_meta(out);
  fail_unless(pm != nullptr);
  fail_unless_equals_int(pm->stats.n_grid, n_grid - n_band);
  for (guint i = guint(seeds.size()); i < pm->n_points; i++) {
    const int x = int(pm->points[i].match_index % s.g.w), y = int(pm->points[i].match_index / s.g.w);
    fail_unless(x % step == step / 2 && y % step == step / 2, "(%d, %d) off the grid", x, y);
  }
  pop_depth_message(r.bus, &dense, &ms, nullptr);
  gst_buffer_unref(out);

  /* densify=false: the matches' points alone, the pixels untouched */
  g_object_set(r.h->element, "densify", FALSE, "post-messages", FALSE, NULL);
  in = seeded_frame(s, seeds, true);
  out = gst_harness_push_and_pull(r.h, in);
  pm = gst_buffer_get_tree_stereo_points_meta(out);
  fail_unless_equals_int(pm->n_points, seeds.size());
  fail_unless_equals_int(pm->stats.n_grid, 0);
  gst_buffer_unref(out);

  /* densify-step=8 and no canopy in the vegetation meta: no grid points */
  g_object_set(r.h->element, "densify", TRUE, "densify-step", 8, NULL);
  in = seeded_frame(s, seeds, false);
  out = gst_harness_push_and_pull(r.h, in);
  pm = gst_buffer_get_tree_stereo_points_meta(out);
  fail_unless_equals_int(pm->stats.n_grid, 0);
  gst_buffer_unref(out);
  in = seeded_frame(s, seeds, true);
  out = gst_harness_push_and_pull(r.h, in);
  pm = gst_buffer_get_tree_stereo_points_meta(out);
  fail_unless(pm->stats.n_grid > 0.8 * area / 64 && pm->stats.n_grid <= guint(area / 64 + 40));
  for (guint i = guint(seeds.size()); i < pm->n_points; i++)
    fail_unless_equals_int((pm->points[i].match_index % s.g.w) % 8, 4);
  gst_buffer_unref(out);
  fail_unless(gst_bus_pop_filtered(r.bus, GST_MESSAGE_WARNING) == nullptr);
  rig_free(r);
}
GST_END_TEST;

GST_START_TEST(test_sparse_densify_without_vegetation_warns_once)
{
  const DenseScene s = dense_scene();
  const std::vector<GstTreeStereoMatch> seeds = plane_matches(s, 20);
  Rig r = rig_new(dense_caps(s).c_str(), "post-messages=false");
  for (int i = 0; i < 2; i++) {
    GstBuffer *in = dense_frame(s);
    gst_buffer_add_tree_stereo_matches_meta(in, GST_TREE_STEREO_MATCH_EUCLIDEAN, 100, 100,
                                            seeds.data(), guint(seeds.size()));
    GstBuffer *out = gst_harness_push_and_pull(r.h, in);
    const GstTreeStereoPointsMeta *pm = gst_buffer_get_tree_stereo_points_meta(out);
    fail_unless_equals_int(pm->n_points, seeds.size());
    fail_unless_equals_int(pm->stats.n_grid, 0);
    gst_buffer_unref(out);
  }
  GstMessage *w = gst_bus_pop_filtered(r.bus, GST_MESSAGE_WARNING);
  fail_unless(w != nullptr, "no warning that densify cannot run");
  GError *err = nullptr;
  gst_message_parse_warning(w, &err, nullptr);
  fail_unless(strstr(err->message, "vegetation") != nullptr, "%s", err->message);
  g_error_free(err);
  gst_message_unref(w);
  fail_unless(gst_bus_pop_filtered(r.bus, GST_MESSAGE_WARNING) == nullptr, "warned twice");
  rig_free(r);
}
GST_END_TEST;


/* ---- The canopy in 3D on treetestsrc's orchard (a row of trees on grass, a row behind) ---- */

namespace {

const char *kOrchardCaps = "video/x-raw,format=RGB,width=640,height=480";

/* A rig calibration written by treetestsrc once per process (the orchard's cameras). */
std::string orchard_calibration()
{
  static const TempDir dir("stereodepth");
  static std::string path;
  if (!path.empty())
    return path;
  path = dir.file("rig.yml");
  const std::string desc = "treetestsrc view=left scene=orchard seed=3 num-buffers=1 "
                           "calibration-out=" + path + " ! " + kOrchardCaps + " ! fakesink";
  GError *err = nullptr;
  GstElement *p = gst_parse_launch(desc.c_str(), &err);
  fail_unless(p != nullptr && err == nullptr);
  gst_element_set_state(p, GST_STATE_PLAYING);
  GstBus *bus = gst_element_get_bus(p);
  GstMessage *m = gst_bus_timed_pop_filtered(bus, 60 * GST_SECOND,
                                             GstMessageType(GST_MESSAGE_EOS | GST_MESSAGE_ERROR));
  fail_unless(m != nullptr && GST_MESSAGE_TYPE(m) == GST_MESSAGE_EOS);
  gst_message_unref(m);
  gst_object_unref(bus);
  gst_element_set_state(p, GST_STATE_NULL);
  gst_object_unref(p);
  fail_unless(g_file_test(path.c_str(), G_FILE_TEST_EXISTS));
  return path;
}

/* What one orchard pair through rectify ! exgsegment ! siftmatch ! stereodepth ! treemetrics
 * gives. */
struct OrchardRun {
  bool buffer = false;
  bool canopy_meta = false;
  GstTreeStereoCanopyMode mode = GST_TREE_STEREO_CANOPY_COLOUR;
  bool canopy_present = false;
  double cut_lo_m = 0, cut_hi_m = 0; // the selected tree's part of the row
  int canopy_x = 0, canopy_w = 0; // the canopy meta's left-view box (px)
  int veg_x = 0, veg_w = 0;       // the vegetation meta's left-view box (px)
  double truth_width_m = 0, truth_z_m = 0, truth_x_m = 0, fx = 0, cx = 0;
  // The trunk's axis (offset_x_m, trunk_distance_m) at the canopy centre's height, left camera
  // frame (the axis is vertical there), and the rotation into the rectified-left frame.
  double trunk_camera_m[3] = {0, 0, 0};
  double R1[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}; // rectified-left from camera-left
  GstTreeStereoDepthStats stats{};
  guint n_points = 0, n_invalid = 0;
  guint valid_off_canopy = 0; // valid points whose left pixel is off the canopy mask
  guint invalid_on_canopy = 0;
  bool tree_present = false;
  bool message = false, message_canopy = false;
  GstTreeStereoDepthStats message_stats{};
  GstTreeStereoCanopyMeta message_fields{};
  std::vector<GstTreeStereoRowSegment> segments; // the canopy meta's
  bool row_view = false;          // the first buffer's canopy meta has a row view
  int row_x = 0, row_w = 0;       // its box (px)
  guint later_row_views = 0;      // buffers after the first with one
  GstMessage *error = nullptr;     // owned
  guint warnings = 0;
};

bool on_mask(const GstTreeStereoVegetationView &v, GstMapInfo &map, double x, double y)
{
  const int ix = int(std::lround(x)), iy = int(std::lround(y));
  if (ix < 0 || iy < 0 || ix >= int(v.mask_width) || iy >= int(v.mask_height))
    return false;
  return map.data[gsize(iy) * v.mask_stride + gsize(ix)] != 0;
}

void orchard_handoff(GstElement *, GstBuffer *buf, GstPad *, gpointer data)
{
  OrchardRun &r = *static_cast<OrchardRun *>(data);
  if (r.buffer) {
    const GstTreeStereoCanopyMeta *cm = gst_buffer_get_tree_stereo_canopy_meta(buf);
    r.later_row_views += cm && cm->row_view.present ? 1 : 0;
    return;
  }
  r.buffer = true;
  const GstTreeStereoGeometryMeta *gm = gst_buffer_get_tree_stereo_geometry_meta(buf);
  fail_unless(gm != nullptr);
  r.fx = gm->fx[0];
  r.cx = gm->cx[0];
  const GstTreeStereoTruthMeta *tm = gst_buffer_get_tree_stereo_truth_meta(buf);
  fail_unless(tm != nullptr, "the truth meta did not come through");
  r.truth_width_m = tm->truth.width_m;
  r.truth_z_m = tm->truth.centroid_m[2];
  r.truth_x_m = tm->truth.centroid_m[0];
  r.trunk_camera_m[0] = tm->truth.offset_x_m;
  r.trunk_camera_m[1] = tm->truth.centroid_m[1];
  r.trunk_camera_m[2] = tm->truth.trunk_distance_m;
  for (int i = 0; i < 9; i++)
    r.R1[i] = gm->R1[i];
  const GstTreeStereoVegetationMeta *vm = gst_buffer_get_tree_stereo_vegetation_meta(buf);
  fail_unless(vm != nullptr && vm->views[0].present);
  r.veg_x = vm->views[0].bbox_x;
  r.veg_w = vm->views[0].bbox_width;
  const GstTreeStereoPointsMeta *pm = gst_buffer_get_tree_stereo_points_meta(buf);
  fail_unless(pm != nullptr);
  r.stats = pm->stats;
  r.n_points = pm->n_points;
  for (guint i = 0; i < pm->n_points; i++)
    r.n_invalid += pm->points[i].valid ? 0 : 1;
  const GstTreeStereoMetricsMeta *mt = gst_buffer_get_tree_stereo_metrics_meta(buf);
  fail_unless(mt != nullptr);
  r.tree_present = mt->metrics.tree_present;
  const GstTreeStereoCanopyMeta *cm = gst_buffer_get_tree_stereo_canopy_meta(buf);
  if (!cm)
    return;
  r.canopy_meta = true;
  r.mode = cm->mode;
  r.segments.assign(cm->segments, cm->segments + cm->n_stored_segments);
  r.cut_lo_m = cm->cut_lo_m;
  r.cut_hi_m = cm->cut_hi_m;
  r.row_view = cm->row_view.present && cm->row_view.mask;
  r.row_x = cm->row_view.bbox_x;
  r.row_w = cm->row_view.bbox_width;
  r.canopy_present = cm->view.present;
  r.canopy_x = cm->view.bbox_x;
  r.canopy_w = cm->view.bbox_width;
  if (!cm->view.present || !cm->view.mask)
    return;
  /* every point at its left pixel: the grid points' match_index is the pixel index, the
   * seeds' the index of their match */
  const GstTreeStereoMatchesMeta *mm = gst_buffer_get_tree_stereo_matches_meta(buf);
  fail_unless(mm != nullptr);
  GstMapInfo map;
  fail_unless(gst_buffer_map(cm->view.mask, &map, GST_MAP_READ));
  const guint n_seeds = pm->n_points - pm->stats.n_grid;
  const guint w = gm->view_width;
  for (guint i = 0; i < pm->n_points; i++) {
    double x, y;
    if (i < n_seeds) {
      fail_unless(pm->points[i].match_index < mm->n_matches);
      x = mm->matches[pm->points[i].match_index].xl;
      y = mm->matches[pm->points[i].match_index].yl;
    } else {
      x = pm->points[i].match_index % w;
      y = pm->points[i].match_index / w;
    }
    const bool in = on_mask(cm->view, map, x, y);
    if (pm->points[i].valid && !in)
      r.valid_off_canopy++;
    if (!pm->points[i].valid && in)
      r.invalid_on_canopy++;
  }
  gst_buffer_unmap(cm->view.mask, &map);
}

/* Orchard pairs (seed 3, the tree in front at 2 m; one unless `buffers`) with these
 * stereodepth properties. */
OrchardRun run_orchard(const char *stereodepth_props, int buffers = 1)
{
  const std::string calib = orchard_calibration();
  const std::string src = std::string("treetestsrc scene=orchard seed=3 num-buffers=") +
                          std::to_string(buffers) + " ";
  const std::string desc =
      "stereorectify name=r calibration=" + calib + " ! exgsegment ! siftmatch ! stereodepth " +
      stereodepth_props + " ! treemetrics ! fakesink name=out signal-handoffs=true " + src +
      "view=left ! " + kOrchardCaps + " ! r.left " + src + "view=right ! " + kOrchardCaps +
      " ! r.right";
  GError *err = nullptr;
  GstElement *p = gst_parse_launch(desc.c_str(), &err);
  fail_unless(p != nullptr && err == nullptr, "%s", err ? err->message : desc.c_str());
  OrchardRun r;
  GstElement *sink = gst_bin_get_by_name(GST_BIN(p), "out");
  g_signal_connect(sink, "handoff", G_CALLBACK(orchard_handoff), &r);
  gst_object_unref(sink);
  GstBus *bus = gst_element_get_bus(p);
  gst_element_set_state(p, GST_STATE_PLAYING);
  for (;;) {
    GstMessage *m = gst_bus_timed_pop(bus, 120 * GST_SECOND);
    fail_unless(m != nullptr, "the pipeline did not finish");
    const GstMessageType t = GST_MESSAGE_TYPE(m);
    if (t == GST_MESSAGE_ELEMENT && gst_message_has_name(m, "stereodepth") && !r.message) {
      const GstStructure *st = gst_message_get_structure(m);
      gboolean dense = TRUE;
      r.message = gst_tree_stereo_depth_message_parse(st, &dense, &r.message_stats, nullptr);
      r.message_canopy = gst_tree_stereo_canopy_message_parse(st, &r.message_fields);
    } else if (t == GST_MESSAGE_WARNING) {
      r.warnings++;
    } else if (t == GST_MESSAGE_ERROR) {
      r.error = m;
      break;
    } else if (t == GST_MESSAGE_EOS) {
      gst_message_unref(m);
      break;
    }
    gst_message_unref(m);
  }
  gst_object_unref(bus);
  gst_element_set_state(p, GST_STATE_NULL);
  gst_object_unref(p);
  return r;
}

} // namespace

GST_START_TEST(test_canopy_properties_round_trip)
{
  GstElement *e = gst_element_factory_make("stereodepth", nullptr);
  fail_unless(e != nullptr);
  gchar *canopy = nullptr, *ground = nullptr;
  gdouble zn = -1, zf = -1, hmin = -1, hmax = -1, ch = -1, cp = -1;
  auto read = [&] {
    GValue v = G_VALUE_INIT;
    g_free(canopy);
    g_free(ground);
    g_value_init(&v, g_type_from_name("GstStereoDepthCanopy"));
    g_object_get_property(G_OBJECT(e), "canopy", &v);
    canopy = g_strdup(g_enum_get_value(G_ENUM_CLASS(g_type_class_peek(G_VALUE_TYPE(&v))),
                                       g_value_get_enum(&v))->value_nick);
    g_value_unset(&v);
    g_value_init(&v, g_type_from_name("GstStereoDepthGround"));
    g_object_get_property(G_OBJECT(e), "ground", &v);
    ground = g_strdup(g_enum_get_value(G_ENUM_CLASS(g_type_class_peek(G_VALUE_TYPE(&v))),
                                       g_value_get_enum(&v))->value_nick);
    g_value_unset(&v);
    g_object_get(e, "zone-near", &zn, "zone-far", &zf, "min-height", &hmin, "max-height", &hmax,
                 "camera-height", &ch, "camera-pitch", &cp, NULL);
  };
  /* defaults: the tree in front, the zone and the ground from the data, grass below 25 cm */
  read();
  fail_unless_equals_string(canopy, "tree");
  fail_unless_equals_string(ground, "fit");
  fail_unless_equals_float(zn, 0.0);
  fail_unless_equals_float(zf, 0.0);
  fail_unless_equals_float(hmin, 250.0);
  fail_unless_equals_float(hmax, 0.0);
  fail_unless_equals_float(ch, 0.0);
  fail_unless_equals_float(cp, 0.0);
  /* every value round-trips */
  gst_util_set_object_arg(G_OBJECT(e), "canopy", "row");
  gst_util_set_object_arg(G_OBJECT(e), "ground", "rig");
  g_object_set(e, "zone-near", 1500.0, "zone-far", 2600.0, "min-height", -100.0, "max-height",
               3500.0, "camera-height", 1200.0, "camera-pitch", -12.5, NULL);
  read();
  fail_unless_equals_string(canopy, "row");
  fail_unless_equals_string(ground, "rig");
  fail_unless_equals_float(zn, 1500.0);
  fail_unless_equals_float(zf, 2600.0);
  fail_unless_equals_float(hmin, -100.0);
  fail_unless_equals_float(hmax, 3500.0);
  fail_unless_equals_float(ch, 1200.0);
  fail_unless_equals_float(cp, -12.5);
  gst_util_set_object_arg(G_OBJECT(e), "canopy", "off");
  gst_util_set_object_arg(G_OBJECT(e), "ground", "off");
  read();
  fail_unless_equals_string(canopy, "off");
  fail_unless_equals_string(ground, "off");
  /* the ranges' ends are taken, beyond them GLib refuses and keeps the value */
  g_object_set(e, "zone-near", 1e6, "zone-far", 0.0, "min-height", -1e5, "max-height", 1e5,
               "camera-height", 1e5, "camera-pitch", 80.0, NULL);
  read();
  fail_unless_equals_float(zn, 1e6);
  fail_unless_equals_float(hmin, -1e5);
  fail_unless_equals_float(hmax, 1e5);
  fail_unless_equals_float(ch, 1e5);
  fail_unless_equals_float(cp, 80.0);
  ASSERT_WARNING(g_object_set(e, "zone-near", -1.0, NULL));
  ASSERT_WARNING(g_object_set(e, "zone-far", 2e6, NULL));
  ASSERT_WARNING(g_object_set(e, "min-height", 2e5, NULL));
  ASSERT_WARNING(g_object_set(e, "max-height", -1.0, NULL));
  ASSERT_WARNING(g_object_set(e, "camera-height", -5.0, NULL));
  ASSERT_WARNING(g_object_set(e, "camera-pitch", 81.0, NULL));
  ASSERT_WARNING(g_object_set(e, "camera-pitch", -81.0, NULL));
  read();
  fail_unless_equals_float(zn, 1e6);
  fail_unless_equals_float(zf, 0.0);
  fail_unless_equals_float(hmin, -1e5);
  fail_unless_equals_float(hmax, 1e5);
  fail_unless_equals_float(ch, 1e5);
  fail_unless_equals_float(cp, 80.0);
  gst_util_set_object_arg(G_OBJECT(e), "canopy", "forest");
  read();
  fail_unless_equals_string(canopy, "off");
  g_free(canopy);
  g_free(ground);
  gst_object_unref(e);
}
GST_END_TEST;

GST_START_TEST(test_orchard_canopy_is_the_tree_in_front)
{
  OrchardRun r = run_orchard("");
  fail_unless(r.error == nullptr);
  fail_unless(r.buffer);
  fail_unless_equals_int(r.warnings, 0);
  fail_unless(r.canopy_meta, "no canopy meta with the default canopy=tree");
  fail_unless_equals_int(r.mode, GST_TREE_STEREO_CANOPY_TREE);
  fail_unless(r.canopy_present);
  /* the tree in front's width as the left camera sees it at its centre's depth */
  const double projected = r.truth_width_m * r.fx / r.truth_z_m;
  const double centre_px = r.cx + r.fx * r.truth_x_m / r.truth_z_m;
  g_print("[ orchard ] canopy box x %d w %d, vegetation box x %d w %d, tree projected %.1f px "
          "about x %.1f; %u points, %u invalid, dropped-zone %u, valid off the canopy %u, "
          "invalid on it %u\n",
          r.canopy_x, r.canopy_w, r.veg_x, r.veg_w, projected, centre_px, r.n_points,
          r.n_invalid, r.stats.dropped_zone, r.valid_off_canopy, r.invalid_on_canopy);
  fail_unless(std::abs(r.canopy_w - projected) <= 0.15 * projected, "canopy %d px, tree %.1f px",
              r.canopy_w, projected);
  fail_unless(std::abs(r.canopy_x + 0.5 * r.canopy_w - centre_px) <= 0.15 * projected,
              "canopy centred at %.1f px, the tree at %.1f px", r.canopy_x + 0.5 * r.canopy_w,
              centre_px);
  /* the colour mask holds the neighbours and the next row too */
  fail_unless(r.veg_w > 1.4 * r.canopy_w, "vegetation %d px, canopy %d px", r.veg_w, r.canopy_w);
  /* points off the canopy (neighbours, next row, grass) are kept invalid and counted */
  fail_unless(r.stats.dropped_zone > 0);
  fail_unless(r.n_invalid >= r.stats.dropped_zone);
  fail_unless_equals_int(r.n_invalid, r.stats.dropped_zone + r.stats.dropped_disparity +
                                          r.stats.dropped_range + r.stats.dropped_outlier);
  fail_unless(r.valid_off_canopy <= r.n_points / 100, "%u valid points off the canopy",
              r.valid_off_canopy);
  /* the message carries the same figures and the canopy fields */
  fail_unless(r.message && r.message_canopy, "the stereodepth message lacks the canopy fields");
  expect_stats_equal(r.message_stats, r.stats);
  fail_unless_equals_int(r.message_stats.dropped_zone, r.stats.dropped_zone);
  fail_unless_equals_int(r.message_fields.mode, GST_TREE_STEREO_CANOPY_TREE);
  fail_unless(r.message_fields.view.present);
  fail_unless(r.message_fields.near_m > 0 && r.message_fields.near_m < r.truth_z_m &&
                  r.message_fields.far_m > r.truth_z_m && r.message_fields.far_m < 4.0,
              "zone %.2f-%.2f m", r.message_fields.near_m, r.message_fields.far_m);
  fail_unless(r.message_fields.n_segments >= 1);
  fail_unless(r.message_fields.n_canopy_points > 0);
  fail_unless(r.tree_present);
  /* each segment says how far inside the view's edges its points keep; the tree in front is
   * whole in view (its box is the projected tree's, above), the outermost reach the edges */
  fail_unless(!r.segments.empty());
  for (const GstTreeStereoRowSegment &s : r.segments) {
    g_print("[ orchard ] segment %.3f..%.3f m: %.3f m inside the left edge, %.3f m inside the "
            "right one%s\n", s.lo_m, s.hi_m, s.lo_clear_m, s.hi_clear_m,
            s.selected ? " (the tree in front)" : "");
    fail_unless(std::isfinite(s.lo_clear_m) && std::isfinite(s.hi_clear_m));
    if (s.selected)
      fail_unless(s.lo_clear_m > 0.05 && s.hi_clear_m > 0.05);
    /* the trunk under the tree in front, where the scene stands it; no other segment has one */
    if (s.selected) {
      /* The axis is vertical in the camera's frame; rectification rotates it a little, so it
       * leans in the view: its X where it was read, at the Y the segment gives (the axis point
       * whose rectified Y that is), and at the crown's centre for comparison. */
      const double *R = r.R1, *t = r.trunk_camera_m;
      const double y = (s.trunk_y_m - R[3] * t[0] - R[5] * t[2]) / R[4];
      const double x = R[0] * t[0] + R[1] * y + R[2] * t[2];
      g_print("[ orchard ] trunk at x %.4f m, y %.3f m (truth there %.4f m; at the crown's "
              "centre %.4f m)\n", s.trunk_m, s.trunk_y_m, x,
              R[0] * t[0] + R[1] * t[1] + R[2] * t[2]);
      fail_unless(s.trunk_y_m > t[1] + 0.2, "trunk read at y %.3f m, above the crown's bottom",
                  s.trunk_y_m);
      fail_unless(std::abs(s.trunk_m - x) <= 0.005, "trunk at %.4f m, truth %.4f m", s.trunk_m,
                  x);
    } else {
      fail_unless(std::isnan(s.trunk_m));
    }
  }
  /* the tree in front's part of the row holds its segment and ends between it and each
   * neighbour's (here the next tree on the right; none in view on the left: no end there) */
  g_print("[ orchard ] the tree's part of the row: %.3f..%.3f m\n", r.cut_lo_m, r.cut_hi_m);
  for (std::size_t i = 0; i < r.segments.size(); ++i) {
    const GstTreeStereoRowSegment &s = r.segments[i];
    if (!s.selected)
      continue;
    fail_unless(r.cut_lo_m <= s.lo_m && s.hi_m <= r.cut_hi_m, "segment %.3f..%.3f m", s.lo_m,
                s.hi_m);
    if (i == 0)
      fail_unless(std::isinf(r.cut_lo_m) && r.cut_lo_m < 0);
    else
      fail_unless(std::isfinite(r.cut_lo_m) && r.segments[i - 1].hi_m <= r.cut_lo_m);
    if (i + 1 == r.segments.size())
      fail_unless(std::isinf(r.cut_hi_m) && r.cut_hi_m > 0);
    else
      fail_unless(std::isfinite(r.cut_hi_m) && r.cut_hi_m <= r.segments[i + 1].lo_m);
  }
  /* the next tree, entering the view on the right: its points reach the edge */
  fail_unless(!r.segments.back().selected && r.segments.back().hi_clear_m < 0.05,
              "the rightmost segment keeps %.3f m inside the right edge",
              r.segments.back().hi_clear_m);
}
GST_END_TEST;

GST_START_TEST(test_orchard_canopy_off_row_and_empty_zone)
{
  /* canopy=off: no canopy meta, nothing dropped for the zone, treemetrics measures colour */
  OrchardRun off = run_orchard("canopy=off");
  fail_unless(off.error == nullptr && off.buffer);
  fail_if(off.canopy_meta);
  fail_unless_equals_int(off.stats.dropped_zone, 0);
  fail_unless(off.message);
  fail_if(off.message_canopy, "canopy fields with canopy=off");
  fail_unless_equals_int(off.warnings, 0);

  /* canopy=row: the near row in view, wider than the tree in front */
  OrchardRun tree = run_orchard("canopy=tree");
  OrchardRun row = run_orchard("canopy=row");
  fail_unless(row.error == nullptr && row.canopy_meta && row.canopy_present);
  fail_unless_equals_int(row.mode, GST_TREE_STEREO_CANOPY_ROW);
  /* the whole near row in view: nothing cut */
  fail_unless(std::isinf(row.cut_lo_m) && row.cut_lo_m < 0 && std::isinf(row.cut_hi_m) &&
              row.cut_hi_m > 0);
  fail_unless(row.message_canopy && row.message_fields.mode == GST_TREE_STEREO_CANOPY_ROW);
  g_print("[ orchard ] canopy box width: tree %d px, row %d px\n", tree.canopy_w, row.canopy_w);
  fail_unless(row.canopy_w > 1.3 * tree.canopy_w, "row %d px, tree %d px", row.canopy_w,
              tree.canopy_w);
  /* canopy=tree: the stream's first frame also carries the near row's canopy as canopy=row
   * decides it (the row map's part of the row behind the first tree); the next frame does not.
   * canopy=row: none (its view is the row) */
  OrchardRun two = run_orchard("canopy=tree", 2);
  fail_unless(two.error == nullptr && two.row_view, "no row view on the first frame");
  g_print("[ orchard ] row view box x %d width %d px, canopy=row's x %d width %d px\n", two.row_x,
          two.row_w, row.canopy_x, row.canopy_w);
  fail_unless(two.row_x == row.canopy_x && two.row_w == row.canopy_w);
  fail_unless_equals_int(two.later_row_views, 0);
  fail_if(row.row_view, "a row view with canopy=row");

  /* a spray zone where nothing stands (the next row is at 5.5 m): no canopy, and treemetrics
   * says no tree */
  OrchardRun empty = run_orchard("zone-near=20000 zone-far=25000");
  fail_unless(empty.error == nullptr && empty.canopy_meta);
  fail_if(empty.canopy_present);
  fail_unless(empty.message_canopy);
  fail_if(empty.message_fields.view.present);
  fail_unless_equals_float(empty.message_fields.near_m, 20.0);
  fail_unless_equals_float(empty.message_fields.far_m, 25.0);
  fail_if(empty.tree_present, "treemetrics found a tree where the zone holds none");
}
GST_END_TEST;

GST_START_TEST(test_canopy_settings_that_cannot_run_are_errors)
{
  struct Case {
    const char *props, *names;
  } cases[] = {
      {"ground=rig", "camera-height"},
      {"zone-near=3000 zone-far=2000", "zone-far"},
      {"min-height=500 max-height=400", "max-height"},
  };
  for (const Case &c : cases) {
    OrchardRun r = run_orchard(c.props);
    fail_unless(r.error != nullptr, "%s: no error", c.props);
    GError *err = nullptr;
    gchar *dbg = nullptr;
    gst_message_parse_error(r.error, &err, &dbg);
    fail_unless(err->domain == GST_RESOURCE_ERROR, "%s: domain %s", c.props,
                g_quark_to_string(err->domain));
    fail_unless_equals_int(err->code, GST_RESOURCE_ERROR_SETTINGS);
    fail_unless(strstr(err->message, c.names) != nullptr, "%s: %s", c.props, err->message);
    fail_unless(dbg != nullptr && strstr(dbg, "canopy settings: ground") != nullptr, "%s: %s",
                c.props, dbg);
    fail_unless(g_str_has_prefix(GST_OBJECT_NAME(GST_MESSAGE_SRC(r.error)), "stereodepth"));
    g_error_free(err);
    g_free(dbg);
    gst_message_unref(r.error);
  }
  /* ground=rig with camera-height runs */
  OrchardRun ok = run_orchard("ground=rig camera-height=1000");
  fail_unless(ok.error == nullptr && ok.canopy_meta);
  /* canopy=off does not use them: no error */
  OrchardRun off = run_orchard("canopy=off ground=rig");
  fail_unless(off.error == nullptr && !off.canopy_meta);
}
GST_END_TEST;

static Suite *stereodepth_suite(void)
{
  Suite *s = suite_create("stereodepth");
  TCase *tc = tcase_create("general");
  suite_add_tcase(s, tc);
  tcase_add_test(tc, test_sparse_points_stats_and_drops);
  tcase_add_test(tc, test_sparse_no_matches_is_empty_not_nan);
  tcase_add_test(tc, test_missing_metas_are_errors_naming_upstream);
  tcase_add_test(tc, test_dense_depth_map_on_the_canopy);
  tcase_add_test(tc, test_dense_without_vegetation_uses_the_whole_view);
  tcase_add_test(tc, test_sparse_densify_grid_on_the_canopy);
  tcase_add_test(tc, test_sparse_densify_without_vegetation_warns_once);
  tcase_add_test(tc, test_canopy_properties_round_trip);
  tcase_add_test(tc, test_orchard_canopy_is_the_tree_in_front);
  tcase_add_test(tc, test_orchard_canopy_off_row_and_empty_zone);
  tcase_add_test(tc, test_canopy_settings_that_cannot_run_are_errors);
  return s;
}

GST_CHECK_MAIN(stereodepth)
