/* spraycontrol on pushed buffers with a test clock: a flat canopy wall 2 m in front of the camera,
 * full height, at known stretches of the row, the rig's position in the metrics meta. The valve
 * commands are checked against the timing model (docs/spraying.md):
 *
 *   at_ns = (x + nozzle-offset - position(0)) / speed - valve-latency   (position = position(0)
 *   + speed * t)
 *
 * and the fail-safe is driven by cranking the test clock past hold-time. */
// OpenCV before gstcheck: gstcheck's fail macros clash with names in OpenCV's headers.
#include "treestereo/rowmap.hpp"
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include <gst/check/gstcheck.h>
#include <gst/check/gstharness.h>
#include "expect_error.h"
#include <gst/check/gsttestclock.h>
#include <gst/treestereo/treestereo-meta.h>
#include <glib/gstdio.h>

namespace {

/* The view: 20 mm per column and per row at 2 m (fx = fy = 100); the camera 1 m above the
 * ground, so the rows span 0.42-1.6 m above it: the row map's four bands, 0.4-1.6 m. */
const int kW = 100, kH = 60;
const double kZ = 2000, kF = 100, kCamHeight = 1.0;
/* Start position: column centres never fall on a 50 mm bin edge (the mask and the map agree). */
const double kP0 = 0.005;
/* A canopy edge is known to the pixel: within half a column (10 mm) of the true one. */
const double kHalfColumn = 0.5 * kZ / kF / 1000.0 + 1e-9;
const GstClockTime kFrame = 100 * GST_MSECOND;

using Canopy = std::vector<std::pair<double, double>>; // [start, end) along the row (m)

struct Harness {
  GstHarness *h = nullptr;
  GstBus *bus = nullptr;
};

Harness harness(const char *props)
{
  Harness r;
  GstElement *e = gst_parse_bin_from_description(
      (std::string("spraycontrol name=s ") + props).c_str(), FALSE, nullptr);
  fail_unless(e != nullptr);
  gst_object_ref_sink(e);
  GstElement *s = gst_bin_get_by_name(GST_BIN(e), "s");
  gst_object_unref(e);
  r.bus = gst_bus_new();
  gst_element_set_bus(s, r.bus);
  r.h = gst_harness_new_with_element(s, "sink", "src");
  gst_object_unref(s);
  gst_harness_use_testclock(r.h);
  gst_harness_set_src_caps_str(r.h, "video/x-raw,format=GRAY8,width=100,height=60,framerate=10/1");
  return r;
}

void harness_free(Harness &r)
{
  gst_element_set_bus(r.h->element, nullptr);
  gst_object_unref(r.bus);
  gst_harness_teardown(r.h);
}

bool in_canopy(const Canopy &c, double x)
{
  for (const auto &iv : c)
    if (x >= iv.first && x < iv.second)
      return true;
  return false;
}

/* A frame at @pts with the rig at @position_m (m) and the canopy where @canopy says. With a
 * finite @cut_lo_m (world x, m) the canopy meta is stereodepth's mode tree: the tree's part of the
 * row begins there, its mask holds the canopy from there on, and the points before it are kept
 * dropped (valid FALSE, as stereodepth drops a neighbour's); @row_view: the meta also has the
 * row view (all the canopy), as on a stream's first frame. */
GstBuffer *frame(GstClockTime pts, double position_m, const Canopy &canopy,
                 double cut_lo_m = -INFINITY, bool row_view = false)
{
  GstBuffer *b = gst_buffer_new_allocate(nullptr, kW * kH, nullptr);
  gst_buffer_memset(b, 0, 0, kW * kH);
  GST_BUFFER_PTS(b) = pts;
  GST_BUFFER_DURATION(b) = kFrame;
  GstTreeStereoGeometryMeta *g = gst_buffer_add_tree_stereo_geometry_meta(b);
  g->view_width = kW;
  g->view_height = kH;
  g->rectified = TRUE;
  g->fx[0] = g->fx[1] = g->fy[0] = g->fy[1] = kF;
  g->cx[0] = g->cx[1] = kW / 2.0;
  g->cy[0] = g->cy[1] = kH / 2.0;
  g->baseline_mm = 100;

  GstTreeStereoMetrics m{};
  m.position_m = position_m;
  gst_buffer_add_tree_stereo_metrics_meta(b, &m, nullptr);

  GstBuffer *mask = gst_buffer_new_allocate(nullptr, kW * kH, nullptr);
  GstBuffer *row = gst_buffer_new_allocate(nullptr, kW * kH, nullptr);
  GstMapInfo map, row_map;
  gst_buffer_map(mask, &map, GST_MAP_WRITE);
  gst_buffer_map(row, &row_map, GST_MAP_WRITE);
  std::memset(map.data, 0, kW * kH);
  std::memset(row_map.data, 0, kW * kH);
  std::vector<GstTreeStereoPoint> points;
  bool any_tree = false, any_row = false;
  for (int u = 0; u < kW; u++) {
    const double X = (u - kW / 2.0) / kF * kZ;
    const double x = (X + position_m * 1000.0) / 1000.0;
    if (!in_canopy(canopy, x))
      continue;
    const bool tree = x >= cut_lo_m;
    for (int v = 0; v < kH; v++) {
      map.data[v * kW + u] = tree ? 255 : 0;
      row_map.data[v * kW + u] = 255;
      if (v % 4 == 0) {
        GstTreeStereoPoint p{};
        p.x = float(X);
        p.y = float((v - kH / 2.0) / kF * kZ);
        p.z = float(kZ);
        p.match_index = guint32(v * kW + u);
        p.valid = tree;
        points.push_back(p);
      }
    }
    any_tree = any_tree || tree;
    any_row = true;
  }
  gst_buffer_unmap(mask, &map);
  gst_buffer_unmap(row, &row_map);
  GstTreeStereoPointsMeta *pm =
      gst_buffer_add_tree_stereo_points_meta(b, points.data(), guint(points.size()), nullptr);
  pm->dense = TRUE;
  const bool tree_mode = std::isfinite(cut_lo_m);
  GstTreeStereoCanopyMeta *c = gst_buffer_add_tree_stereo_canopy_meta(
      b, tree_mode ? GST_TREE_STEREO_CANOPY_TREE : GST_TREE_STEREO_CANOPY_ROW);
  c->near_m = 0.5 * kZ / 1000.0;
  c->far_m = 1.5 * kZ / 1000.0;
  if (tree_mode)
    c->cut_lo_m = cut_lo_m - position_m; // camera X at the row's depth
  if (row_view && any_row) {
    c->row_view.present = TRUE;
    gst_tree_stereo_vegetation_view_set_mask(&c->row_view, row, kW, kH, kW);
  }
  gst_buffer_unref(row);
  c->ground_found = TRUE;
  c->ground_normal[0] = 0;
  c->ground_normal[1] = -1; // y points down in the camera frame
  c->ground_normal[2] = 0;
  c->ground_d_m = kCamHeight;
  c->view.present = any_tree;
  if (c->view.present) {
    c->view.mask = mask;
    c->view.mask_width = kW;
    c->view.mask_height = kH;
    c->view.mask_stride = kW;
  } else {
    gst_buffer_unref(mask);
  }
  return b;
}

/* The section commands (and the count of warnings) on the bus so far. */
std::vector<GstTreeStereoSectionCommand> commands(GstBus *bus, int *warnings = nullptr,
                                                  std::string *warning_text = nullptr)
{
  std::vector<GstTreeStereoSectionCommand> out;
  while (GstMessage *msg = gst_bus_pop(bus)) {
    if (GST_MESSAGE_TYPE(msg) == GST_MESSAGE_ELEMENT) {
      GstTreeStereoSectionCommand c;
      if (gst_tree_stereo_section_message_parse(gst_message_get_structure(msg), &c))
        out.push_back(c);
    } else if (GST_MESSAGE_TYPE(msg) == GST_MESSAGE_WARNING) {
      if (warnings)
        (*warnings)++;
      GError *err = nullptr;
      gst_message_parse_warning(msg, &err, nullptr);
      if (warning_text && err)
        *warning_text = err->message;
      g_clear_error(&err);
    }
    gst_message_unref(msg);
  }
  return out;
}

/* Drives the rig at @speed (m/s) past @canopy for @seconds, then EOS; the commands of
 * section 0 (all four sections see the same full-height wall: checked equal). */
std::vector<GstTreeStereoSectionCommand> drive(const char *props, const Canopy &canopy,
                                               double speed, double seconds)
{
  Harness r = harness(props);
  const int n = int(std::lround(seconds / 0.1));
  for (int i = 0; i <= n; i++) {
    const GstClockTime t = GstClockTime(i) * kFrame;
    fail_unless_equals_int(gst_harness_push(r.h, frame(t, kP0 + speed * 0.1 * i, canopy)),
                           GST_FLOW_OK);
    gst_buffer_unref(gst_harness_pull(r.h));
  }
  fail_unless(gst_harness_push_event(r.h, gst_event_new_eos()));
  std::vector<GstTreeStereoSectionCommand> all = commands(r.bus), s0;
  harness_free(r);
  for (guint k = 0; k < 4; k++) {
    std::vector<GstTreeStereoSectionCommand> sk;
    for (const auto &c : all)
      if (c.section == k)
        sk.push_back(c);
    if (k == 0) {
      s0 = sk;
      continue;
    }
    fail_unless_equals_int(int(sk.size()), int(s0.size()));
    for (std::size_t i = 0; i < sk.size(); i++) {
      fail_unless_equals_int(sk[i].on, s0[i].on);
      fail_unless_equals_int64(sk[i].at_ns, s0[i].at_ns);
    }
  }
  return s0;
}

gint64 expected_at(double x, double offset, double speed, gint64 latency_ns)
{
  return gint64(std::llround((x + offset - kP0) / speed * 1e9)) - latency_ns;
}

} // namespace

GST_START_TEST(test_timing_two_speeds_two_latencies)
{
  const Canopy canopy = {{2.0, 3.0}};
  for (double speed : {0.5, 1.5})
    for (guint latency : {160u, 300u}) {
      const std::string props =
          "nozzle-offset=1.2 valve-latency=" + std::to_string(latency);
      const auto c = drive(props.c_str(), canopy, speed, (3.0 + 1.2 + 1.0) / speed);
      fail_unless_equals_int(int(c.size()), 2);
      fail_unless(c[0].on && !c[1].on);
      fail_unless(!c[0].fallback && !c[1].fallback);
      fail_unless_equals_float(c[0].rate, 1.0);
      fail_unless(std::abs(c[0].position_m - 2.0) <= kHalfColumn, "on at %f", c[0].position_m);
      fail_unless(std::abs(c[1].position_m - 3.0) <= kHalfColumn, "off at %f", c[1].position_m);
      // Each command timed exactly for its canopy slice.
      const gint64 lat = gint64(latency) * GST_MSECOND;
      const gint64 on_at = expected_at(c[0].position_m, 1.2, speed, lat);
      const gint64 off_at = expected_at(c[1].position_m, 1.2, speed, lat);
      fail_unless(std::llabs(c[0].at_ns - on_at) <= 2,
                  "speed %f latency %u: on at %" G_GINT64_FORMAT " expected %" G_GINT64_FORMAT,
                  speed, latency, c[0].at_ns, on_at);
      fail_unless(std::llabs(c[1].at_ns - off_at) <= 2,
                  "speed %f latency %u: off at %" G_GINT64_FORMAT " expected %" G_GINT64_FORMAT,
                  speed, latency, c[1].at_ns, off_at);
    }
}
GST_END_TEST;

GST_START_TEST(test_eos_plans_the_canopy_the_rig_did_not_pass)
{
  // The data ends with the rig at 2.2 m: the canopy's end at 2.6 m is in view (to 3.2 m), in
  // bins the rig has not passed. At EOS they are planned too: the valve closes at 2.6 m, timed
  // with the last speed.
  const Canopy canopy = {{2.0, 2.6}};
  const auto c = drive("", canopy, 1.0, 2.2);
  fail_unless_equals_int(int(c.size()), 2);
  fail_unless(c[0].on && std::abs(c[0].position_m - 2.0) <= kHalfColumn);
  fail_unless(!c[1].on && std::abs(c[1].position_m - 2.6) <= kHalfColumn, "off at %f",
              c[1].position_m);
  const gint64 off_at = expected_at(c[1].position_m, 1.5, 1.0, 160 * GST_MSECOND);
  fail_unless(std::llabs(c[1].at_ns - off_at) <= 2, "off at %" G_GINT64_FORMAT " expected %"
              G_GINT64_FORMAT, c[1].at_ns, off_at);
}
GST_END_TEST;

GST_START_TEST(test_the_first_frames_row_view_sprays_the_canopy_behind_its_tree)
{
  // Mode tree: the tree in front stands at -0.5..0.5 m, its part of the row from -0.625 m on;
  // behind it a neighbour's crown ends at -0.94 m, and the first frame's view begins at -1.0 m.
  // The rig drives away from it: no later frame takes the neighbour for its tree. The first
  // frame's row view is all there is of it: its 6 cm in view are sprayed (the view cut them,
  // min-canopy does not apply).
  const Canopy canopy = {{-1.2, -0.94}, {-0.5, 0.5}};
  for (bool row_view : {true, false}) {
    Harness r = harness("");
    for (int i = 0; i <= 25; i++) {
      const GstClockTime t = GstClockTime(i) * kFrame;
      fail_unless_equals_int(
          gst_harness_push(r.h, frame(t, kP0 + 0.1 * i, canopy, -0.625, row_view && i == 0)),
          GST_FLOW_OK);
      gst_buffer_unref(gst_harness_pull(r.h));
    }
    fail_unless(gst_harness_push_event(r.h, gst_event_new_eos()));
    std::vector<GstTreeStereoSectionCommand> c;
    for (const auto &k : commands(r.bus))
      if (k.section == 0)
        c.push_back(k);
    harness_free(r);
    if (!row_view) { // the neighbour unseen: the tree alone
      fail_unless_equals_int(int(c.size()), 2);
      fail_unless(c[0].on && std::abs(c[0].position_m + 0.5) <= kHalfColumn);
      continue;
    }
    fail_unless_equals_int(int(c.size()), 4);
    fail_unless(c[0].on && std::abs(c[0].position_m + 1.0) <= kHalfColumn, "on at %f",
                c[0].position_m);
    fail_unless(!c[1].on && std::abs(c[1].position_m + 0.94) <= kHalfColumn, "off at %f",
                c[1].position_m);
    fail_unless(c[2].on && std::abs(c[2].position_m + 0.5) <= kHalfColumn);
    fail_unless(!c[3].on && std::abs(c[3].position_m - 0.5) <= kHalfColumn);
  }
}
GST_END_TEST;

GST_START_TEST(test_min_gap_and_min_canopy)
{
  // A 5 cm gap stays sprayed (min-gap 7.5 cm), a 10 cm gap closes the valve, a 5 cm twig of
  // canopy is not sprayed (min-canopy 10 cm).
  const Canopy canopy = {{2.0, 2.5}, {2.55, 3.0}, {3.1, 3.5}, {4.0, 4.05}};
  const auto c = drive("", canopy, 1.0, 7.0);
  fail_unless_equals_int(int(c.size()), 4);
  fail_unless(c[0].on && std::abs(c[0].position_m - 2.0) <= kHalfColumn);
  fail_unless(!c[1].on && std::abs(c[1].position_m - 3.0) <= kHalfColumn, "off at %f",
              c[1].position_m);
  fail_unless(c[2].on && std::abs(c[2].position_m - 3.1) <= kHalfColumn);
  fail_unless(!c[3].on && std::abs(c[3].position_m - 3.5) <= kHalfColumn);
  // The gap's closed time is its travel time at 1 m/s.
  const gint64 closed = gint64(std::llround((c[2].position_m - c[1].position_m) * 1e9));
  fail_unless(std::llabs(c[2].at_ns - c[1].at_ns - closed) <= 2);
  fail_unless(closed >= gint64(80 * GST_MSECOND), "the 10 cm gap closed %" G_GINT64_FORMAT " ns",
              closed);
  // With min-canopy 0 the twig is sprayed too.
  fail_unless_equals_int(int(drive("min-canopy=0", canopy, 1.0, 7.0).size()), 6);
}
GST_END_TEST;

GST_START_TEST(test_speed_change_halfway)
{
  // 1 m/s for 2 s, then 2 m/s. The canopy at 4.0-5.0 m reaches the nozzles (1.5 m behind) at
  // position 5.5 m and 6.5 m: 3.75 s and 4.25 s (the start offset kP0 taken off).
  Harness r = harness("");
  const Canopy canopy = {{4.0, 5.0}};
  double p = kP0;
  for (int i = 0; i <= 60; i++) {
    if (i > 0)
      p += (i <= 20 ? 1.0 : 2.0) * 0.1;
    fail_unless_equals_int(gst_harness_push(r.h, frame(GstClockTime(i) * kFrame, p, canopy)),
                           GST_FLOW_OK);
    gst_buffer_unref(gst_harness_pull(r.h));
  }
  std::vector<GstTreeStereoSectionCommand> c;
  for (const auto &x : commands(r.bus))
    if (x.section == 0)
      c.push_back(x);
  harness_free(r);
  fail_unless_equals_int(int(c.size()), 2);
  fail_unless(std::abs(c[0].position_m - 4.0) <= kHalfColumn, "on at %f", c[0].position_m);
  fail_unless(std::abs(c[1].position_m - 5.0) <= kHalfColumn, "off at %f", c[1].position_m);
  // At 2 m/s from 2 s on (position kP0 + 2 m then): slice x reaches the nozzles at
  // 2 + (x + 1.5 - kP0 - 2) / 2 s.
  auto when = [](double x) {
    return gint64(std::llround((2.0 + (x - 0.5 - kP0) / 2.0) * 1e9)) - 160 * GST_MSECOND;
  };
  const gint64 on = when(c[0].position_m), off = when(c[1].position_m);
  fail_unless(std::llabs(c[0].at_ns - on) <= 2, "on at %" G_GINT64_FORMAT, c[0].at_ns);
  fail_unless(std::llabs(c[1].at_ns - off) <= 2, "off at %" G_GINT64_FORMAT, c[1].at_ns);
}
GST_END_TEST;

GST_START_TEST(test_fail_safe_after_hold_time)
{
  for (const char *fallback : {"on", "off"}) {
    Harness r = harness((std::string("hold-time=500 fallback=") + fallback).c_str());
    const Canopy canopy = {{0.5, 5.0}};
    for (int i = 0; i <= 10; i++) {
      fail_unless_equals_int(
          gst_harness_push(r.h, frame(GstClockTime(i) * kFrame, kP0 + 0.1 * i, canopy)),
          GST_FLOW_OK);
      gst_buffer_unref(gst_harness_pull(r.h));
    }
    int warnings = 0;
    std::string text;
    fail_unless(commands(r.bus, &warnings).empty()); // the canopy is still ahead of the nozzles
    // Frames stop at 1.0 s: the callback due hold-time after the last arrival (the test clock
    // at 0) sets the fallback.
    fail_unless(gst_harness_crank_single_clock_wait(r.h));
    fail_unless_equals_uint64(gst_clock_get_time(GST_ELEMENT_CLOCK(r.h->element)),
                              500 * GST_MSECOND);
    const auto c = commands(r.bus, &warnings, &text);
    fail_unless_equals_int(warnings, 1);
    fail_unless(text.find("hold-time") != std::string::npos, "%s", text.c_str());
    fail_unless(text.find(fallback) != std::string::npos, "%s", text.c_str());
    fail_unless_equals_int(int(c.size()), 4);
    for (guint k = 0; k < 4; k++) {
      fail_unless_equals_int(c[k].section, k);
      fail_unless_equals_int(c[k].on, std::string(fallback) == "on");
      fail_unless(c[k].fallback);
      fail_unless_equals_int64(c[k].at_ns, gint64(1500 * GST_MSECOND));
    }
    // Frames again: control resumes (the canopy comes under the nozzles).
    for (int i = 20; i <= 80; i++) {
      fail_unless_equals_int(
          gst_harness_push(r.h, frame(GstClockTime(i) * kFrame, kP0 + 0.1 * i, canopy)),
          GST_FLOW_OK);
      gst_buffer_unref(gst_harness_pull(r.h));
    }
    bool canopy_command = false;
    for (const auto &x : commands(r.bus))
      canopy_command = canopy_command || !x.fallback;
    fail_unless(canopy_command, "no command after frames resumed (fallback %s)", fallback);
    harness_free(r);
  }
}
GST_END_TEST;

GST_START_TEST(test_fail_safe_on_a_gap_in_the_running_times)
{
  // Frames up to 1.0 s, the next at 1.6 s (a recording with frames missing): the fallback is
  // posted when that frame comes, before its own commands.
  Harness r = harness("hold-time=500");
  const Canopy canopy = {{0.5, 5.0}};
  for (int i = 0; i <= 10; i++) {
    fail_unless_equals_int(
        gst_harness_push(r.h, frame(GstClockTime(i) * kFrame, kP0 + 0.1 * i, canopy)),
        GST_FLOW_OK);
    gst_buffer_unref(gst_harness_pull(r.h));
  }
  int warnings = 0;
  fail_unless(commands(r.bus, &warnings).empty());
  fail_unless_equals_int(
      gst_harness_push(r.h, frame(16 * kFrame, kP0 + 1.6, canopy)), GST_FLOW_OK);
  gst_buffer_unref(gst_harness_pull(r.h));
  const auto c = commands(r.bus, &warnings);
  fail_unless_equals_int(warnings, 1);
  fail_unless(c.size() >= 4);
  for (guint k = 0; k < 4; k++) {
    fail_unless(c[k].fallback && c[k].on);
    fail_unless_equals_int64(c[k].at_ns, gint64(1600 * GST_MSECOND));
  }
  harness_free(r);
}
GST_END_TEST;

GST_START_TEST(test_bad_section_heights_is_a_named_error)
{
  GstElement *e = gst_element_factory_make("spraycontrol", nullptr);
  fail_unless(e != nullptr);
  GstBus *bus = gst_bus_new();
  gst_element_set_bus(e, bus);
  g_object_set(e, "section-heights", "0.4:0.7,0.7-1.0", nullptr);
  fail_unless_equals_int(gst_element_set_state(e, GST_STATE_PLAYING), GST_STATE_CHANGE_FAILURE);
  expect_bus_error(bus, GST_MESSAGE_ERROR, GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_SETTINGS,
                   "spraycontrol's section-heights cannot be used: give lo:hi pairs in m above "
                   "the ground, comma separated (e.g. 0.4:0.7,0.7:1.0), or an empty string for "
                   "the row map's bands.",
                   "invalid section-heights \"0.4:0.7,0.7-1.0\"");
  gst_element_set_state(e, GST_STATE_NULL);
  gst_element_set_bus(e, nullptr);
  gst_object_unref(bus);
  gst_object_unref(e);

  // A section count that matches neither the bands nor the ranges: an error at the first frame.
  Harness r = harness("sections=3");
  fail_unless_equals_int(gst_harness_push(r.h, frame(0, kP0, {{0.0, 1.0}})), GST_FLOW_ERROR);
  expect_bus_error(r.bus, GST_MESSAGE_ERROR, GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_SETTINGS,
                   "spraycontrol's sections does not match its section count: set sections=0 or "
                   "to that count.",
                   "sections=3 but the row map has 4 bands");
  harness_free(r);
}
GST_END_TEST;

/* Pushes @in, which spraycontrol cannot use: the buffer passes, one WARNING with @message and
 * @debug_part; a second such buffer passes without another. */
static void expect_one_warning(GstBuffer *in, const char *message, const char *debug_part)
{
  Harness r = harness("");
  GstBuffer *again = gst_buffer_copy(in);
  GST_BUFFER_PTS(again) = GST_BUFFER_PTS(in) == GST_CLOCK_TIME_NONE ? GST_CLOCK_TIME_NONE
                                                                      : GST_BUFFER_PTS(in) + kFrame;
  fail_unless_equals_int(gst_harness_push(r.h, in), GST_FLOW_OK);
  gst_buffer_unref(gst_harness_pull(r.h));
  expect_bus_error(r.bus, GST_MESSAGE_WARNING, GST_STREAM_ERROR, GST_STREAM_ERROR_FAILED, message,
                   debug_part);
  fail_unless_equals_int(gst_harness_push(r.h, again), GST_FLOW_OK);
  gst_buffer_unref(gst_harness_pull(r.h));
  fail_unless(gst_bus_pop_filtered(r.bus, GST_MESSAGE_WARNING) == nullptr);
  harness_free(r);
}

/* A buffer without treemetrics' metrics meta: one warning naming it, the buffer passes. */
GST_START_TEST(test_missing_metrics_meta_is_a_warning)
{
  GstBuffer *in = gst_buffer_new_allocate(nullptr, kW * kH, nullptr);
  GST_BUFFER_PTS(in) = 0;
  expect_one_warning(in,
                     "No rig position on the buffer: spraycontrol needs the metrics meta of "
                     "treemetrics upstream. Until it comes the sections keep their state, then "
                     "take the fallback after hold-time.",
                     "has no GstTreeStereoMetricsMeta");
}
GST_END_TEST;

/* The rig's position but no stereo geometry (no stereorectify upstream): a warning naming it. */
GST_START_TEST(test_missing_geometry_meta_is_a_warning)
{
  GstBuffer *in = gst_buffer_new_allocate(nullptr, kW * kH, nullptr);
  GST_BUFFER_PTS(in) = 0;
  GstTreeStereoMetrics m{};
  m.position_m = kP0;
  gst_buffer_add_tree_stereo_metrics_meta(in, &m, nullptr);
  expect_one_warning(in,
                     "No stereo geometry on the buffer: spraycontrol needs the geometry meta of "
                     "stereorectify upstream. Until it comes the sections keep their state, then "
                     "take the fallback after hold-time.",
                     "has no GstTreeStereoGeometryMeta");
}
GST_END_TEST;

/* Every meta but no timestamp: no running time to time the valves by, a warning saying so. */
GST_START_TEST(test_missing_timestamp_is_a_warning)
{
  GstBuffer *in = frame(0, kP0, {{0.0, 1.0}});
  GST_BUFFER_PTS(in) = GST_CLOCK_TIME_NONE;
  expect_one_warning(in,
                     "No timestamp on the buffer: spraycontrol needs the running time of each "
                     "frame; give the buffers timestamps upstream.",
                     "has no valid running time");
}
GST_END_TEST;

GST_START_TEST(test_section_message_round_trip)
{
  GstTreeStereoSectionCommand c{2, TRUE, 0.4, 1234567890123, 3.25, FALSE}, back;
  GstStructure *s = gst_tree_stereo_section_message_structure(&c);
  fail_unless(gst_structure_has_name(s, "treestereo-section"));
  fail_unless(gst_tree_stereo_section_message_parse(s, &back));
  fail_unless_equals_int(back.section, 2);
  fail_unless(back.on && !back.fallback);
  fail_unless_equals_float(back.rate, 0.4);
  fail_unless_equals_int64(back.at_ns, 1234567890123);
  fail_unless_equals_float(back.position_m, 3.25);
  gst_structure_remove_field(s, "at-ns");
  fail_if(gst_tree_stereo_section_message_parse(s, &back));
  gst_structure_free(s);
}
GST_END_TEST;

/* timeline-location: at EOS, the row map with one strip per section under it, the valve's open
 * stretches drawn where the canopy is; an unwritable location is a RESOURCE error naming it. */
GST_START_TEST(test_timeline_picture_at_eos)
{
  gchar *dir = g_dir_make_tmp("spraycontrol-XXXXXX", nullptr);
  const std::string png = std::string(dir) + "/timeline.png";
  const Canopy canopy = {{1.0, 1.6}, {2.2, 2.8}};
  Harness r = harness(("timeline-location=" + png).c_str());
  for (int i = 0; i <= 40; i++) {
    const GstClockTime t = GstClockTime(i) * kFrame;
    fail_unless_equals_int(gst_harness_push(r.h, frame(t, kP0 + 0.1 * i, canopy)), GST_FLOW_OK);
    gst_buffer_unref(gst_harness_pull(r.h));
  }
  fail_unless(gst_harness_push_event(r.h, gst_event_new_eos()));
  harness_free(r);
  const cv::Mat img = cv::imread(png, cv::IMREAD_COLOR);
  fail_if(img.empty(), "no picture at %s", png.c_str());
  // Four sections of the default map: four strips under the map; the middle of the first
  // canopy is sprayed in the lowest strip, the middle of the gap is not.
  const int strips_top = img.rows - 4 * treestereo::RowMap::kStripHeight;
  const int y0 = strips_top + 3 * treestereo::RowMap::kStripHeight + treestereo::RowMap::kStripHeight / 2;
  int open_cols = 0;
  for (int x = treestereo::RowMap::kMarginLeft; x < img.cols - treestereo::RowMap::kMarginRight; x++) {
    const cv::Vec3b c = img.at<cv::Vec3b>(y0, x);
    if (c == cv::Vec3b(40, 120, 20))
      open_cols++;
  }
  // Two canopies of 0.6 m at 8 px per 5 cm bin: about 2 x 96 px open.
  fail_unless(open_cols > 150 && open_cols < 240, "%d columns open in section 0", open_cols);
  g_unlink(png.c_str());
  g_rmdir(dir);
  g_free(dir);

  // A location in a directory that does not exist.
  Harness bad = harness("timeline-location=/nonexistent-dir/timeline.png");
  for (int i = 0; i <= 5; i++) {
    fail_unless_equals_int(gst_harness_push(bad.h, frame(GstClockTime(i) * kFrame, kP0 + 0.1 * i, canopy)),
                           GST_FLOW_OK);
    gst_buffer_unref(gst_harness_pull(bad.h));
  }
  gst_harness_push_event(bad.h, gst_event_new_eos());
  expect_bus_error(bad.bus, GST_MESSAGE_ERROR, GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_OPEN_WRITE,
                   "Could not write the valve timeline to \"/nonexistent-dir/timeline.png\": "
                   "check that its folder exists, is writable and has room.",
                   "/nonexistent-dir/timeline.png");
  harness_free(bad);
}
GST_END_TEST

static Suite *spraycontrol_suite(void)
{
  Suite *s = suite_create("spraycontrol");
  TCase *tc = tcase_create("general");
  tcase_set_timeout(tc, 300);
  suite_add_tcase(s, tc);
  tcase_add_test(tc, test_timing_two_speeds_two_latencies);
  tcase_add_test(tc, test_the_first_frames_row_view_sprays_the_canopy_behind_its_tree);
  tcase_add_test(tc, test_min_gap_and_min_canopy);
  tcase_add_test(tc, test_speed_change_halfway);
  tcase_add_test(tc, test_fail_safe_after_hold_time);
  tcase_add_test(tc, test_fail_safe_on_a_gap_in_the_running_times);
  tcase_add_test(tc, test_bad_section_heights_is_a_named_error);
  tcase_add_test(tc, test_missing_metrics_meta_is_a_warning);
  tcase_add_test(tc, test_missing_geometry_meta_is_a_warning);
  tcase_add_test(tc, test_missing_timestamp_is_a_warning);
  tcase_add_test(tc, test_section_message_round_trip);
  tcase_add_test(tc, test_timeline_picture_at_eos);
  tcase_add_test(tc, test_eos_plans_the_canopy_the_rig_did_not_pass);
  return s;
}

GST_CHECK_MAIN(spraycontrol)
