/* treemetrics: a sphere's silhouette and visible surface built analytically (as lib's
 * test_metrics does) through the element: every figure against the sphere's truth; the band
 * profile of a stepped flat canopy, exact; smoothing; no-tree frames; errors. */
/* C++ and OpenCV headers first: gstcheck.h defines a macro named fail */
#include "treestereo/canopy.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <functional>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "element_props.h"
#include <gst/check/gstcheck.h>
#include <gst/check/gstharness.h>
#include "expect_error.h"
#include <gst/treestereo/treestereo-meta.h>
#include <gst/video/video.h>


namespace {

const int W = 1296, H = 972;
const double F = 1100, CX = 648, CY = 486, B = 50;

/* A silhouette (left view) and the visible surface's points every `step` px. */
struct Scene {
  cv::Mat mask;
  std::vector<GstTreeStereoPoint> points;
  std::vector<double> u, v, z; /* pixel and true depth (mm) of each point */
};

using Caster = std::function<std::optional<double>(double tx, double ty)>;

/* A sphere of radius R (mm) at C: depth along the ray (tx, ty, 1) of the nearest hit. */
Caster sphere(cv::Vec3d C, double R)
{
  return [=](double tx, double ty) -> std::optional<double> {
    const cv::Vec3d r(tx, ty, 1.0);
    const double A = r.dot(r), Bq = r.dot(C), D = Bq * Bq - A * (C.dot(C) - R * R);
    if (D < 0)
      return std::nullopt;
    return (Bq - std::sqrt(D)) / A;
  };
}

Scene cast(const Caster &hit, int step)
{
  Scene s;
  s.mask = cv::Mat::zeros(H, W, CV_8U);
  for (int v = 0; v < H; v++)
    for (int u = 0; u < W; u++) {
      const double tx = (u - CX) / F, ty = (v - CY) / F;
      const std::optional<double> t = hit(tx, ty);
      if (!t)
        continue;
      s.mask.at<uchar>(v, u) = 255;
      if (u % step == 0 && v % step == 0) {
        GstTreeStereoPoint p = {float(tx * *t), float(ty * *t), float(*t),
                                guint32(s.points.size()), TRUE};
        s.points.push_back(p);
        s.u.push_back(u);
        s.v.push_back(v);
        s.z.push_back(*t);
      }
    }
  return s;
}

void add_geometry(GstBuffer *buf)
{
  GstTreeStereoGeometryMeta *m = gst_buffer_add_tree_stereo_geometry_meta(buf);
  m->view_width = W;
  m->view_height = H;
  m->side_by_side = TRUE;
  m->rectified = TRUE;
  for (int v = 0; v < 2; v++) {
    m->fx[v] = m->fy[v] = F;
    m->cx[v] = CX;
    m->cy[v] = CY;
  }
  m->baseline_mm = B;
  const double Q[16] = {1, 0, 0, -CX, 0, 1, 0, -CY, 0, 0, 0, F, 0, 0, 1 / B, 0};
  for (int i = 0; i < 16; i++)
    m->Q[i] = Q[i];
  for (int i = 0; i < 9; i++)
    m->R1[i] = (i % 4 == 0) ? 1 : 0;
}

void add_vegetation(GstBuffer *buf, const Scene *s)
{
  GstTreeStereoVegetationMeta *veg = gst_buffer_add_tree_stereo_vegetation_meta(buf, 2);
  GstTreeStereoVegetationView *lv = &veg->views[0];
  if (!s) {
    lv->present = FALSE;
    return;
  }
  const cv::Rect box = cv::boundingRect(s->mask);
  lv->present = TRUE;
  lv->area_px = cv::countNonZero(s->mask);
  lv->bbox_x = box.x;
  lv->bbox_y = box.y;
  lv->bbox_width = box.width;
  lv->bbox_height = box.height;
  lv->n_regions = 1;
  GstBuffer *mask = gst_buffer_new_allocate(nullptr, gsize(s->mask.total()), nullptr);
  gst_buffer_fill(mask, 0, s->mask.data, s->mask.total());
  gst_tree_stereo_vegetation_view_set_mask(lv, mask, W, H, W);
  gst_buffer_unref(mask);
}

void add_points(GstBuffer *buf, const Scene &s)
{
  gst_buffer_add_tree_stereo_points_meta(buf, s.points.data(), guint(s.points.size()), nullptr);
}

/* A frame as stereodepth hands it on: geometry, vegetation (or none) and points (or none). */
GstBuffer *frame(const Scene *veg, const Scene *pts, GstClockTime pts_time)
{
  GstBuffer *buf = gst_buffer_new(); /* treemetrics never looks at the pixels */
  GST_BUFFER_PTS(buf) = pts_time;
  add_geometry(buf);
  if (veg)
    add_vegetation(buf, veg);
  if (pts)
    add_points(buf, *pts);
  return buf;
}

struct Rig {
  GstHarness *h = nullptr;
  GstBus *bus = nullptr;
};

Rig rig_new(const char *props)
{
  Rig r;
  GstElement *e = element_with_props("treemetrics", props);
  fail_unless(e != nullptr);
  r.bus = gst_bus_new();
  gst_element_set_bus(e, r.bus);
  r.h = gst_harness_new_with_element(e, "sink", "src");
  gst_object_unref(e);
  gst_harness_set_src_caps_str(r.h, "video/x-raw,format=RGB,width=2592,height=972,"
                                    "framerate=10/1,multiview-mode=side-by-side");
  return r;
}

void rig_free(Rig &r)
{
  gst_element_set_bus(r.h->element, nullptr);
  gst_object_unref(r.bus);
  gst_harness_teardown(r.h);
}

/* The parsed message of the last buffer; the structure is returned for field checks. */
struct Message {
  GstTreeStereoMetrics raw{}, smoothed{};
  GstTreeStereoTimes times{};
  GstStructure *s = nullptr;
  Message() = default;
  Message(const Message &) = delete;
  Message &operator=(const Message &) = delete;
  ~Message()
  {
    gst_tree_stereo_metrics_clear(&raw);
    gst_tree_stereo_metrics_clear(&smoothed);
    if (s)
      gst_structure_free(s);
  }
};

/* Warnings seen on the way to an element message (gst_bus_pop_filtered would drop them). */
std::vector<std::string> g_warnings;

void pop_message(GstBus *bus, Message &m)
{
  GstMessage *msg;
  while ((msg = gst_bus_pop(bus)) && GST_MESSAGE_TYPE(msg) != GST_MESSAGE_ELEMENT) {
    if (GST_MESSAGE_TYPE(msg) == GST_MESSAGE_WARNING) {
      GError *err = nullptr;
      gst_message_parse_warning(msg, &err, nullptr);
      g_warnings.push_back(err->message);
      g_error_free(err);
    }
    gst_message_unref(msg);
  }
  fail_unless(msg != nullptr, "no treemetrics message");
  m.s = gst_structure_copy(gst_message_get_structure(msg));
  gst_message_unref(msg);
  fail_unless(gst_tree_stereo_metrics_message_parse(m.s, &m.raw, &m.smoothed, &m.times));
}

void expect_equal(const GstTreeStereoMetrics &a, const GstTreeStereoMetrics &b)
{
  fail_unless_equals_int(a.tree_present, b.tree_present);
  fail_unless_equals_float(a.distance_m, b.distance_m);
  fail_unless_equals_float(a.height_m, b.height_m);
  fail_unless_equals_float(a.width_m, b.width_m);
  fail_unless_equals_float(a.thickness_m, b.thickness_m);
  fail_unless_equals_float(a.area_m2, b.area_m2);
  fail_unless_equals_float(a.perimeter_m, b.perimeter_m);
  fail_unless_equals_float(a.complexity, b.complexity);
  for (int i = 0; i < 3; i++)
    fail_unless_equals_float(a.centroid_m[i], b.centroid_m[i]);
  fail_unless_equals_int(a.clipped, b.clipped);
  fail_unless_equals_int(a.n_points, b.n_points);
  fail_unless_equals_int(a.n_matches, b.n_matches);
  fail_unless_equals_float(a.confidence, b.confidence);
  fail_unless_equals_int(a.canopy_mode, b.canopy_mode);
  fail_unless_equals_int(a.n_bands, b.n_bands);
  for (guint i = 0; i < a.n_bands; i++) {
    const GstTreeStereoBand &x = a.bands[i], &y = b.bands[i];
    fail_unless_equals_int(x.present, y.present);
    fail_unless_equals_float(x.fill, y.fill);
    fail_unless_equals_float(x.top_m, y.top_m);
    fail_unless_equals_float(x.bottom_m, y.bottom_m);
    fail_unless_equals_float(x.left_m, y.left_m);
    fail_unless_equals_float(x.right_m, y.right_m);
    fail_unless_equals_float(x.width_m, y.width_m);
    fail_unless_equals_float(x.depth_m, y.depth_m);
  }
}

/* No tree: all zero, no band, nothing NaN. */
void expect_no_tree_meta(const GstTreeStereoMetrics &m)
{
  fail_if(m.tree_present);
  for (double v : {m.distance_m, m.height_m, m.width_m, m.thickness_m, m.area_m2, m.perimeter_m,
                   m.complexity, m.centroid_m[0], m.centroid_m[1], m.centroid_m[2],
                   m.confidence})
    fail_unless(v == 0.0, "a no-tree figure is %f", v);
  fail_unless_equals_int(m.clipped, 0);
  fail_unless_equals_int(m.n_points, 0);
  fail_unless_equals_int(m.n_matches, 0);
  fail_unless_equals_int(m.n_bands, 0);
  fail_unless(m.bands == nullptr);
}

/* The message of a no-tree frame: tree-present=false, the canopy mode, the times and the rig's
 * travel (it moves between trees too), nothing else. */
void expect_no_tree_message(const Message &m)
{
  const std::set<std::string> allowed = {"timestamp",    "stream-time",
                                         "running-time", "tree-present",
                                         "canopy-mode",  "smoothed-tree-present",
                                         "smoothed-canopy-mode", "travel-m",
                                         "position-m",   "travel-source",
                                         "row-direction-x", "row-direction-y",
                                         "row-direction-z"};
  for (int i = 0; i < gst_structure_n_fields(m.s); i++) {
    const std::string f = gst_structure_nth_field_name(m.s, guint(i));
    fail_unless(allowed.count(f) == 1, "no-tree message has field %s", f.c_str());
  }
  gboolean present = TRUE;
  fail_unless(gst_structure_get_boolean(m.s, "tree-present", &present));
  fail_if(present);
  fail_unless(gst_structure_get_boolean(m.s, "smoothed-tree-present", &present));
  fail_if(present);
}

double within(double got, double want, double tol)
{
  fail_unless(std::abs(got - want) <= tol, "%f, expected %f +- %f", got, want, tol);
  return got;
}

const cv::Vec3d kCentre(300, -200, 3000);
const double kR = 1000;

} // namespace

GST_START_TEST(test_sphere_every_field_against_truth)
{
  const Scene s = cast(sphere(kCentre, kR), 4);
  Rig r = rig_new("extent-method=round-canopy");
  GstBuffer *out = gst_harness_push_and_pull(r.h, frame(&s, &s, 2 * GST_SECOND));
  const GstTreeStereoMetricsMeta *meta = gst_buffer_get_tree_stereo_metrics_meta(out);
  fail_unless(meta != nullptr);
  const GstTreeStereoMetrics &m = meta->metrics;
  fail_unless(m.tree_present);

  /* depth figures: the definitions on the true depths of the points */
  std::vector<double> z = s.z;
  const treestereo::Summary zs = treestereo::summarize(z);
  within(m.distance_m, zs.median * 1e-3, 5e-4);
  /* area-weighted order statistics of a grid-sampled surface: to a millimetre or two */
  within(m.thickness_m, (zs.p95 - zs.p05) * 1e-3, 2e-3);
  /* extents of a 2 m sphere within lib's 1.5% (the round-canopy model; tangent-points reads
   * a big smooth sphere low, see docs/elements/treemetrics.md) */
  within(m.width_m, 2.0, 0.03);
  within(m.height_m, 2.0, 0.03);
  /* a disc of radius R: area pi R^2 (3%), perimeter 2 pi R (pixel contours run long: 6%) */
  within(m.area_m2, CV_PI, 0.03 * CV_PI);
  within(m.perimeter_m, 2 * CV_PI, 0.06 * 2 * CV_PI);
  fail_unless(m.complexity >= 1.0 && m.complexity < 1.15, "complexity %f", m.complexity);
  within(m.centroid_m[0], 0.3, 0.005);
  within(m.centroid_m[1], -0.2, 0.005);
  within(m.centroid_m[2], 3.0, 0.03);
  fail_unless_equals_int(m.clipped, GST_TREE_STEREO_CLIPPED_NONE);
  fail_unless_equals_int(m.n_points, s.points.size());
  fail_unless_equals_int(m.n_matches, s.points.size());
  /* no canopy meta: the colour silhouette was measured; points every 4 px support all of it */
  fail_unless_equals_int(m.canopy_mode, GST_TREE_STEREO_CANOPY_COLOUR);
  within(m.confidence, 1.0, 1e-12);

  /* 4 bands top to bottom: contiguous, from the sphere's top (-1.2 m) to its bottom (0.8 m);
   * the two middle bands hold the equator: full width, edges at Xc -+ R */
  fail_unless_equals_int(m.n_bands, 4);
  within(m.bands[0].top_m, -1.2, 0.03);
  within(m.bands[3].bottom_m, 0.8, 0.03);
  const cv::Rect box = cv::boundingRect(s.mask);
  const double top = box.y - 0.5, step = box.height / 4.0;
  for (guint i = 0; i < 4; i++) {
    const GstTreeStereoBand &b = m.bands[i];
    fail_unless(b.present);
    fail_unless(b.top_m < b.bottom_m);
    if (i > 0)
      within(b.top_m, m.bands[i - 1].bottom_m, 1e-9);
    within(b.width_m, b.right_m - b.left_m, 1e-12);
    if (i == 1 || i == 2) {
      within(b.width_m, 2.0, 0.03);
      within(b.left_m, -0.7, 0.03);
      within(b.right_m, 1.3, 0.03);
    } else {
      /* widest at the band's inner edge, 0.5 m from the equator: the chord 2 sqrt(R^2 - 0.5^2);
       * the silhouette's edge rows there are not tangent in the row's plane: 3% */
      within(b.width_m, 2 * std::sqrt(1.0 - 0.25), 0.03 * 1.732);
    }
    /* nearest face: the 5th percentile of the depths of the band's rows' points */
    std::vector<double> bz;
    for (std::size_t k = 0; k < s.z.size(); k++) {
      const int bi = std::clamp(int(std::floor((s.v[k] - top) / step)), 0, 3);
      if (bi == int(i))
        bz.push_back(s.z[k]);
    }
    /* area-weighted like the distance (lib's metrics): a plain percentile to a millimetre */
    within(b.depth_m, treestereo::percentile(bz, 5.0) * 1e-3, 1e-3);
  }
  std::printf("[ sphere R=1 m at 3 m ] distance %.4f width %.4f height %.4f area %.4f "
              "perimeter %.4f complexity %.4f centroid (%.4f %.4f %.4f) band widths %.3f %.3f "
              "%.3f %.3f\n",
              m.distance_m, m.width_m, m.height_m, m.area_m2, m.perimeter_m, m.complexity,
              m.centroid_m[0], m.centroid_m[1], m.centroid_m[2], m.bands[0].width_m,
              m.bands[1].width_m, m.bands[2].width_m, m.bands[3].width_m);

  /* smoothing off: smoothed == raw; the message carries both and the times */
  expect_equal(meta->smoothed, m);
  Message msg;
  pop_message(r.bus, msg);
  expect_equal(msg.raw, m);
  expect_equal(msg.smoothed, m);
  fail_unless_equals_uint64(msg.times.timestamp, 2 * GST_SECOND);
  fail_unless_equals_uint64(msg.times.running_time, 2 * GST_SECOND);
  fail_unless_equals_uint64(msg.times.stream_time, 2 * GST_SECOND);
  fail_unless_equals_string(gst_structure_get_string(msg.s, "canopy-mode"), "colour");
  gst_buffer_unref(out);
  rig_free(r);
}
GST_END_TEST;

namespace {

/* lib's stepped flat canopy at z0 = 2750 mm: four 400 mm steps, widths 0.6/1.0/1.4/1.8 m top to
 * bottom, centred at x = 1.25 mm; every edge on a pixel boundary, so the profile is exact. */
const double kZ0 = 2750, kXc = 1.25, kY0 = -798.75, kStep = 400;
const double kWidths[4] = {600, 1000, 1400, 1800};

Scene stepped()
{
  return cast(
      [](double tx, double ty) -> std::optional<double> {
        const double X = tx * kZ0, Y = ty * kZ0;
        const int band = int(std::floor((Y - kY0) / kStep));
        if (band < 0 || band > 3 || std::abs(X - kXc) > kWidths[band] / 2)
          return std::nullopt;
        return kZ0;
      },
      5);
}

} // namespace

/* A 0.6 m sphere whose top ray climbs about 20 degrees: its limb is 18 mm below its top.
 * round-limbs (default) gives back more than half of what the limb points alone miss
 * (lib's Metrics.RoundLimbsReachTheExtremeBeyondTheLimb has the geometry). */
GST_START_TEST(test_round_limbs_property)
{
  const Scene s = cast(sphere(cv::Vec3d(0, -400, 2000), 300), 3);
  double h[2], w[2];
  for (int on = 0; on < 2; ++on) {
    Rig r = rig_new(on ? "" : "round-limbs=false");
    GstBuffer *out = gst_harness_push_and_pull(r.h, frame(&s, &s, 0));
    const GstTreeStereoMetrics &m = gst_buffer_get_tree_stereo_metrics_meta(out)->metrics;
    fail_unless(m.tree_present);
    h[on] = m.height_m;
    w[on] = m.width_m;
    gst_buffer_unref(out);
    rig_free(r);
  }
  fail_unless(h[0] < 0.6 - 0.012, "limb points only: height %f", h[0]);
  fail_unless(std::abs(h[1] - 0.6) < 0.5 * std::abs(h[0] - 0.6), "height %f (%f)", h[1], h[0]);
  fail_unless(std::abs(w[1] - 0.6) < 0.5 * std::abs(w[0] - 0.6), "width %f (%f)", w[1], w[0]);
  fail_unless(h[1] < 0.6 && w[1] < 0.6);
}
GST_END_TEST;

/* Two flat clusters facing the camera: the nearer (z 1.8 m) forms the silhouette's top, the
 * farther (z 2.4 m, beside it) reaches 50 mm higher but projects lower. extreme-points (default
 * 6) reads the height from its points; 0 leaves the silhouette's (the nearer card's) top. */
GST_START_TEST(test_extreme_points_property)
{
  const Caster two_cards = [](double tx, double ty) -> std::optional<double> {
    const double cards[2][5] = {{-250, 250, -400, 100, 1800}, {150, 550, -450, -50, 2400}};
    for (const auto &c : cards)
      if (tx * c[4] >= c[0] && tx * c[4] <= c[1] && ty * c[4] >= c[2] && ty * c[4] <= c[3])
        return c[4];
    return std::nullopt;
  };
  const Scene s = cast(two_cards, 2);
  const double height = 0.55;
  double h[2];
  for (int on = 0; on < 2; ++on) {
    Rig r = rig_new(on ? "" : "extreme-points=0");
    guint n = 0;
    g_object_get(r.h->element, "extreme-points", &n, NULL);
    fail_unless_equals_int(n, on ? 6 : 0);
    GstBuffer *out = gst_harness_push_and_pull(r.h, frame(&s, &s, 0));
    const GstTreeStereoMetrics &m = gst_buffer_get_tree_stereo_metrics_meta(out)->metrics;
    fail_unless(m.tree_present);
    h[on] = m.height_m;
    gst_buffer_unref(out);
    rig_free(r);
  }
  fail_unless(h[0] < 0.95 * height, "silhouette alone: height %f", h[0]);
  fail_unless(std::abs(h[1] - height) < 0.01 * height, "height %f (silhouette alone %f)", h[1],
              h[0]);
}
GST_END_TEST;

GST_START_TEST(test_band_profile_of_a_stepped_canopy)
{
  const Scene s = stepped();
  Rig r = rig_new("bands=4 extent-method=mid-depth");
  GstBuffer *out = gst_harness_push_and_pull(r.h, frame(&s, &s, 0));
  const GstTreeStereoMetrics &m = gst_buffer_get_tree_stereo_metrics_meta(out)->metrics;
  fail_unless(m.tree_present);
  within(m.height_m, 1.6, 1e-6);
  within(m.width_m, 1.8, 1e-6);
  within(m.thickness_m, 0.0, 1e-9);
  within(m.distance_m, 2.75, 1e-6);
  within(m.area_m2, 0.4 * 4.8, 1e-6);
  fail_unless_equals_int(m.n_bands, 4);
  for (guint i = 0; i < 4; i++) {
    const GstTreeStereoBand &b = m.bands[i];
    fail_unless(b.present);
    within(b.top_m, (kY0 + i * kStep) * 1e-3, 1e-6);
    within(b.bottom_m, (kY0 + (i + 1) * kStep) * 1e-3, 1e-6);
    within(b.width_m, kWidths[i] * 1e-3, 1e-6);
    within(b.left_m, (kXc - kWidths[i] / 2) * 1e-3, 1e-6);
    within(b.right_m, (kXc + kWidths[i] / 2) * 1e-3, 1e-6);
    within(b.depth_m, kZ0 * 1e-3, 1e-6);
    within(b.fill, 1.0, 0.0); /* each band is one full step */
  }
  Message msg;
  pop_message(r.bus, msg);
  expect_equal(msg.raw, m);
  gst_buffer_unref(out);

  /* bands=7: seven bands, still ordered top to bottom over the same 1.6 m */
  g_object_set(r.h->element, "bands", 7, NULL);
  out = gst_harness_push_and_pull(r.h, frame(&s, &s, 0));
  const GstTreeStereoMetrics &m7 = gst_buffer_get_tree_stereo_metrics_meta(out)->metrics;
  fail_unless_equals_int(m7.n_bands, 7);
  within(m7.bands[0].top_m, kY0 * 1e-3, 1e-6);
  within(m7.bands[6].bottom_m, (kY0 + 4 * kStep) * 1e-3, 1e-6);
  for (guint i = 1; i < 7; i++) {
    within(m7.bands[i].top_m, m7.bands[i - 1].bottom_m, 1e-9);
    fail_unless(m7.bands[i].width_m >= m7.bands[i - 1].width_m - 1e-9, "widths grow downwards");
  }
  gst_buffer_unref(out);
  rig_free(r);
}
GST_END_TEST;

namespace {

/* A flat card at kZ0 facing the camera: X in [x0, x1], Y in [y0, y1] (mm), without the columns
 * X in (gap0, gap1) below gap_y. Edges chosen on pixel boundaries (2.5 mm a pixel at kZ0). */
Caster card(double x0, double x1, double y0, double y1, double gap0 = 0, double gap1 = 0,
            double gap_y = 1e9)
{
  return [=](double tx, double ty) -> std::optional<double> {
    const double X = tx * kZ0, Y = ty * kZ0;
    if (X < x0 || X > x1 || Y < y0 || Y > y1)
      return std::nullopt;
    if (Y > gap_y && X > gap0 && X < gap1)
      return std::nullopt;
    return kZ0;
  };
}

/* stereodepth's canopy meta: the 3D canopy's mask as the left view (nullptr: none in the zone). */
void add_canopy(GstBuffer *buf, const cv::Mat *mask, GstTreeStereoCanopyMode mode)
{
  GstTreeStereoCanopyMeta *c = gst_buffer_add_tree_stereo_canopy_meta(buf, mode);
  c->near_m = 2.5;
  c->far_m = 3.0;
  c->zone_from_data = TRUE;
  if (!mask)
    return;
  const cv::Rect box = cv::boundingRect(*mask);
  c->view.present = TRUE;
  c->view.area_px = cv::countNonZero(*mask);
  c->view.bbox_x = box.x;
  c->view.bbox_y = box.y;
  c->view.bbox_width = box.width;
  c->view.bbox_height = box.height;
  c->view.n_regions = 1;
  GstBuffer *m = gst_buffer_new_allocate(nullptr, gsize(mask->total()), nullptr);
  gst_buffer_fill(m, 0, mask->data, mask->total());
  gst_tree_stereo_vegetation_view_set_mask(&c->view, m, W, H, W);
  gst_buffer_unref(m);
}

} // namespace

/* Colour finds a wide green wall (a row behind, the neighbours); depth kept a narrow tree of it.
 * treemetrics measures the canopy meta's silhouette: the tree's 1.2 m, not the wall's 2.4 m.
 * The tree's lower half has a gap of 10 % of its width (band fill 0.9), and the points cover
 * only the left half of the tree (confidence about one half). */
GST_START_TEST(test_canopy_meta_is_the_silhouette_measured)
{
  const Scene wall = cast(card(-1198.75, 1201.25, -798.75, 1.25), 1000);
  const Scene tree = cast(card(-598.75, 601.25, -798.75, 1.25, -58.75, 61.25, -398.75), 1000);
  /* points every 5 px on the wall's left, up to the tree's middle */
  const Scene pts = cast(card(-1198.75, 1.25, -798.75, 1.25), 5);
  const double tree_w = 1.2;
  fail_unless_equals_int(cv::boundingRect(tree.mask).width, 480);

  Rig r = rig_new("bands=2 extent-method=mid-depth");
  /* without the canopy meta: the wall, in colour mode */
  GstBuffer *out = gst_harness_push_and_pull(r.h, frame(&wall, &pts, 0));
  const GstTreeStereoMetrics &c = gst_buffer_get_tree_stereo_metrics_meta(out)->metrics;
  fail_unless(c.tree_present);
  within(c.width_m, 2.4, 1e-6);
  fail_unless_equals_int(c.canopy_mode, GST_TREE_STEREO_CANOPY_COLOUR);
  gst_buffer_unref(out);
  Message colour;
  pop_message(r.bus, colour);
  fail_unless_equals_int(colour.raw.canopy_mode, GST_TREE_STEREO_CANOPY_COLOUR);

  /* with it: the tree */
  GstBuffer *in = frame(&wall, &pts, GST_SECOND);
  add_canopy(in, &tree.mask, GST_TREE_STEREO_CANOPY_TREE);
  out = gst_harness_push_and_pull(r.h, in);
  const GstTreeStereoMetricsMeta *meta = gst_buffer_get_tree_stereo_metrics_meta(out);
  const GstTreeStereoMetrics &m = meta->metrics;
  fail_unless(m.tree_present);
  fail_unless_equals_int(m.canopy_mode, GST_TREE_STEREO_CANOPY_TREE);
  fail_unless_equals_int(meta->smoothed.canopy_mode, GST_TREE_STEREO_CANOPY_TREE);
  within(m.width_m, tree_w, 1e-6);
  within(m.height_m, 0.8, 1e-6);
  fail_unless_equals_int(m.n_bands, 2);
  within(m.bands[0].fill, 1.0, 0.0);
  within(m.bands[1].fill, 0.9, 1e-12);
  within(m.bands[1].width_m, tree_w, 1e-6);
  /* confidence by its definition: the share of the tree's pixels within 1.5 % of the view's
   * width (19.4 px) of a point on the tree (within a pixel of it) */
  cv::Mat near_tree;
  cv::dilate(tree.mask, near_tree, cv::Mat::ones(3, 3, CV_8U));
  std::vector<cv::Point2f> px;
  for (std::size_t k = 0; k < pts.u.size(); k++)
    if (near_tree.at<uchar>(int(pts.v[k]), int(pts.u[k])))
      px.emplace_back(float(pts.u[k]), float(pts.v[k]));
  const double want = treestereo::depth_support(tree.mask, px, 0.015 * W);
  within(m.confidence, want, 1e-9);
  /* about half: the left half, the 19 px the support reaches beyond the points, less the gap's
   * pixels (most of them in the supported half): 0.5175 */
  within(m.confidence, 0.5175, 0.01);
  Message msg;
  pop_message(r.bus, msg);
  expect_equal(msg.raw, m);
  expect_equal(msg.smoothed, meta->smoothed);
  fail_unless_equals_string(gst_structure_get_string(msg.s, "canopy-mode"), "tree");
  double conf = 0;
  fail_unless(gst_structure_get_double(msg.s, "confidence", &conf));
  within(conf, want, 1e-9);
  gst_buffer_unref(out);

  /* row mode: the same measurement, the mode says so */
  in = frame(&wall, &pts, 2 * GST_SECOND);
  add_canopy(in, &tree.mask, GST_TREE_STEREO_CANOPY_ROW);
  out = gst_harness_push_and_pull(r.h, in);
  fail_unless_equals_int(gst_buffer_get_tree_stereo_metrics_meta(out)->metrics.canopy_mode,
                         GST_TREE_STEREO_CANOPY_ROW);
  gst_buffer_unref(out);
  Message row;
  pop_message(r.bus, row);
  fail_unless_equals_string(gst_structure_get_string(row.s, "canopy-mode"), "row");
  rig_free(r);
}
GST_END_TEST;

/* Nothing in the spray zone: the canopy meta's view is not present, so there is no tree, though
 * colour found a wall and the points are on it. */
GST_START_TEST(test_canopy_meta_without_canopy_means_no_tree)
{
  const Scene wall = cast(card(-1198.75, 1201.25, -798.75, 1.25), 5);
  Rig r = rig_new("smoothing=0.5");
  GstBuffer *out = gst_harness_push_and_pull(r.h, frame(&wall, &wall, 0));
  fail_unless(gst_buffer_get_tree_stereo_metrics_meta(out)->metrics.tree_present);
  gst_buffer_unref(out);
  Message first;
  pop_message(r.bus, first);

  GstBuffer *in = frame(&wall, &wall, GST_SECOND);
  add_canopy(in, nullptr, GST_TREE_STEREO_CANOPY_TREE);
  out = gst_harness_push_and_pull(r.h, in);
  const GstTreeStereoMetricsMeta *meta = gst_buffer_get_tree_stereo_metrics_meta(out);
  expect_no_tree_meta(meta->metrics);
  expect_no_tree_meta(meta->smoothed);
  fail_unless_equals_int(meta->metrics.canopy_mode, GST_TREE_STEREO_CANOPY_TREE);
  Message msg;
  pop_message(r.bus, msg);
  expect_no_tree_message(msg);
  fail_unless_equals_string(gst_structure_get_string(msg.s, "canopy-mode"), "tree");
  fail_unless_equals_int(msg.raw.canopy_mode, GST_TREE_STEREO_CANOPY_TREE);
  gst_buffer_unref(out);
  rig_free(r);
}
GST_END_TEST;

GST_START_TEST(test_smoothing_converges_and_resets_without_a_tree)
{
  const Scene a = cast(sphere(kCentre, kR), 8);
  const Scene b = cast(sphere(kCentre + cv::Vec3d(0, 0, 400), kR), 8);
  Rig r = rig_new("smoothing=0.5");
  const double alpha = 0.5;

  GstBuffer *out = gst_harness_push_and_pull(r.h, frame(&a, &a, 0));
  const GstTreeStereoMetricsMeta *meta = gst_buffer_get_tree_stereo_metrics_meta(out);
  expect_equal(meta->smoothed, meta->metrics); /* the first frame has no history */
  double prev_d = meta->smoothed.distance_m, prev_w = meta->smoothed.width_m;
  const double dist_a = meta->metrics.distance_m;
  gst_buffer_unref(out);
  Message m0;
  pop_message(r.bus, m0);

  double dist_b = 0;
  for (int k = 1; k <= 5; k++) {
    out = gst_harness_push_and_pull(r.h, frame(&b, &b, k * GST_SECOND / 10));
    meta = gst_buffer_get_tree_stereo_metrics_meta(out);
    const GstTreeStereoMetrics &raw = meta->metrics, &sm = meta->smoothed;
    dist_b = raw.distance_m;
    /* the raw figures are this frame's own; the smoothed ones follow the definition */
    std::vector<double> bz = b.z;
    within(raw.distance_m, treestereo::median(bz) * 1e-3, 1e-5);
    within(sm.distance_m, alpha * prev_d + (1 - alpha) * raw.distance_m, 1e-12);
    within(sm.width_m, alpha * prev_w + (1 - alpha) * raw.width_m, 1e-12);
    fail_unless_equals_int(sm.n_points, raw.n_points);
    /* converging: the gap to the current value halves each frame */
    within(std::abs(sm.distance_m - raw.distance_m), std::pow(alpha, k) * std::abs(dist_b - dist_a),
           1e-9);
    prev_d = sm.distance_m;
    prev_w = sm.width_m;
    Message msg;
    pop_message(r.bus, msg);
    expect_equal(msg.raw, raw);
    expect_equal(msg.smoothed, sm);
    gst_buffer_unref(out);
  }
  within(prev_d, dist_b, std::abs(dist_b - dist_a) / 16);

  /* a frame without a tree: no tree raw or smoothed, no stale value */
  out = gst_harness_push_and_pull(r.h, frame(nullptr, &b, GST_SECOND));
  meta = gst_buffer_get_tree_stereo_metrics_meta(out);
  expect_no_tree_meta(meta->metrics);
  expect_no_tree_meta(meta->smoothed);
  gst_buffer_unref(out);
  {
    Message msg;
    pop_message(r.bus, msg);
    expect_no_tree_message(msg);
  }
  /* the next tree starts afresh */
  out = gst_harness_push_and_pull(r.h, frame(&a, &a, 2 * GST_SECOND));
  meta = gst_buffer_get_tree_stereo_metrics_meta(out);
  expect_equal(meta->smoothed, meta->metrics);
  within(meta->metrics.distance_m, dist_a, 1e-12);
  gst_buffer_unref(out);
  rig_free(r);
}
GST_END_TEST;

GST_START_TEST(test_no_tree_cases)
{
  const Scene s = cast(sphere(kCentre, kR), 8);
  Scene invalid = s;
  for (GstTreeStereoPoint &p : invalid.points)
    p.valid = FALSE;
  Rig r = rig_new("smoothing=0.3");
  g_warnings.clear();
  struct Case {
    const char *what;
    const Scene *veg;
    bool veg_meta;
    const Scene *pts;
  } cases[] = {
      {"vegetation present=false", nullptr, true, &s},
      {"no points meta", &s, true, nullptr},
      {"no vegetation meta", nullptr, false, &s},
      {"no valid point", &s, true, &invalid},
  };
  for (const Case &c : cases) {
    /* a tree frame first, so a stale value would show */
    GstBuffer *out = gst_harness_push_and_pull(r.h, frame(&s, &s, 0));
    fail_unless(gst_buffer_get_tree_stereo_metrics_meta(out)->metrics.tree_present, "%s", c.what);
    gst_buffer_unref(out);
    Message tree;
    pop_message(r.bus, tree);

    GstBuffer *in = gst_buffer_new();
    add_geometry(in);
    if (c.veg_meta)
      add_vegetation(in, c.veg);
    if (c.pts)
      add_points(in, *c.pts);
    out = gst_harness_push_and_pull(r.h, in);
    const GstTreeStereoMetricsMeta *meta = gst_buffer_get_tree_stereo_metrics_meta(out);
    fail_unless(meta != nullptr, "%s: no meta", c.what);
    expect_no_tree_meta(meta->metrics);
    expect_no_tree_meta(meta->smoothed);
    Message msg;
    pop_message(r.bus, msg);
    expect_no_tree_message(msg);
    gst_buffer_unref(out);
  }
  /* the missing upstream elements were warned about once, naming the first one missing */
  fail_unless_equals_int(g_warnings.size(), 1);
  fail_unless_equals_string(g_warnings[0].c_str(),
                            "No 3D points on the buffer: treemetrics needs the points meta of "
                            "stereodepth upstream. Reporting tree-present=false.");
  rig_free(r);
}
GST_END_TEST;

GST_START_TEST(test_missing_geometry_is_an_error)
{
  Rig r = rig_new(nullptr);
  fail_unless_equals_int(gst_harness_push(r.h, gst_buffer_new()), GST_FLOW_ERROR);
  expect_bus_error(r.bus, GST_MESSAGE_ERROR, GST_STREAM_ERROR, GST_STREAM_ERROR_FAILED,
                   "No stereo geometry on the buffer: treemetrics needs the geometry meta of "
                   "stereorectify upstream.",
                   "has no GstTreeStereoGeometryMeta");
  rig_free(r);
}
GST_END_TEST;

/* Geometry but no vegetation meta: a warning naming exgsegment, and the frame goes on. */
GST_START_TEST(test_missing_vegetation_is_a_warning)
{
  Rig r = rig_new(nullptr);
  GstBuffer *in = gst_buffer_new();
  add_geometry(in);
  GstBuffer *out = gst_harness_push_and_pull(r.h, in);
  fail_unless(out != nullptr);
  gst_buffer_unref(out);
  expect_bus_error(r.bus, GST_MESSAGE_WARNING, GST_STREAM_ERROR, GST_STREAM_ERROR_FAILED,
                   "No vegetation mask on the buffer: treemetrics needs the vegetation meta of "
                   "exgsegment upstream. Reporting tree-present=false.",
                   "has no GstTreeStereoVegetationMeta");
  rig_free(r);
}
GST_END_TEST;

GST_START_TEST(test_properties)
{
  GstElement *e = gst_element_factory_make("treemetrics", nullptr);
  gint bands = 0;
  gdouble smoothing = -1;
  g_object_get(e, "bands", &bands, "smoothing", &smoothing, NULL);
  fail_unless_equals_int(bands, 4);
  fail_unless_equals_float(smoothing, 0.0);
  GValue v = G_VALUE_INIT;
  g_value_init(&v, g_type_from_name("GstTreeMetricsExtent"));
  g_object_get_property(G_OBJECT(e), "extent-method", &v);
  GEnumValue *ev = g_enum_get_value(G_ENUM_CLASS(g_type_class_peek(G_VALUE_TYPE(&v))),
                                    g_value_get_enum(&v));
  fail_unless_equals_string(ev->value_nick, "tangent-points");
  g_value_unset(&v);
  /* out of range: GLib refuses and keeps the value */
  ASSERT_WARNING(g_object_set(e, "bands", 0, NULL));
  ASSERT_WARNING(g_object_set(e, "smoothing", 1.0, NULL));
  g_object_get(e, "bands", &bands, "smoothing", &smoothing, NULL);
  fail_unless_equals_int(bands, 4);
  fail_unless_equals_float(smoothing, 0.0);
  gst_object_unref(e);
}
GST_END_TEST;

static Suite *treemetrics_suite(void)
{
  Suite *s = suite_create("treemetrics");
  TCase *tc = tcase_create("general");
  suite_add_tcase(s, tc);
  tcase_add_test(tc, test_sphere_every_field_against_truth);
  tcase_add_test(tc, test_round_limbs_property);
  tcase_add_test(tc, test_extreme_points_property);
  tcase_add_test(tc, test_band_profile_of_a_stepped_canopy);
  tcase_add_test(tc, test_canopy_meta_is_the_silhouette_measured);
  tcase_add_test(tc, test_canopy_meta_without_canopy_means_no_tree);
  tcase_add_test(tc, test_smoothing_converges_and_resets_without_a_tree);
  tcase_add_test(tc, test_no_tree_cases);
  tcase_add_test(tc, test_missing_geometry_is_an_error);
  tcase_add_test(tc, test_missing_vegetation_is_a_warning);
  tcase_add_test(tc, test_properties);
  return s;
}

GST_CHECK_MAIN(treemetrics)
