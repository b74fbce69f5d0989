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

static void expect_error_naming(Rig &r, GstBuffer *in, const char *name)
{
  fail_unless_equals_int(gst_harness_push(r.h, in), GST_FLOW_ERROR);
  GstMessage *msg = gst_bus_pop_filtered(r.bus, GST_MESSAGE_ERROR);
  fail_unless(msg != nullptr);
  GError *err = nullptr;
  gst_message_parse_error(msg, &err, nullptr);
  fail_unless(strstr(err->message, name) != nullptr, "error '%s' does not name %s",
              err->message, name);
  g_error_free(err);
  gst_message_unref(msg);
}

GST_START_TEST(test_missing_metas_are_errors_naming_upstream)
{
  const Geometry g;
  {
    Rig r = rig_new(kSbsCaps, nullptr);
    expect_error_naming(r, gst_buffer_new(), "stereorectify");
    rig_free(r);
  }
  {
    Rig r = rig_new(kSbsCaps, nullptr);
    GstBuffer *in = gst_buffer_new();
    fill_geometry(in, g);
    expect_error_naming(r, in, "siftmatch");
    rig_free(r);
  }
  {
    /* min-depth above max-depth: lib's message reaches the bus */
    Rig r = rig_new(kSbsCaps, "min-depth=5000 max-depth=1000");
    GstBuffer *in = gst_buffer_new();
    fill_geometry(in, g);
    GstTreeStereoMatch m = {700, 500, 680, 500, 0};
    gst_buffer_add_tree_stereo_matches_meta(in, GST_TREE_STEREO_MATCH_COSINE_NORM, 1, 1, &m, 1);
    expect_error_naming(r, in, "depth");
    rig_free(r);
  }
  {
    /* dense on a single-view stream */
    Rig r = rig_new("video/x-raw,format=GRAY8,width=1296,height=972,framerate=10/1",
                    "mode=dense");
    GstBuffer *in = gst_buffer_new_allocate(nullptr, 1296 * 972, nullptr);
    fill_geometry(in, g);
    expect_error_naming(r, in, "side-by-side");
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
  return s;
}

GST_CHECK_MAIN(stereodepth)
