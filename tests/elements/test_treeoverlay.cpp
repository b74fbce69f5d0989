/* treeoverlay: frames carrying constructed metas come out with the items drawn where the metas
 * put them and nothing changed elsewhere; views=left crops to the left view; channel orders
 * agree. */
#include <gst/check/gstcheck.h>
#include <gst/check/gstharness.h>
#include "expect_error.h"
#include <gst/video/video.h>
#include <gst/treestereo/treestereo-meta.h>

#include <cstring>
#include <vector>

#define VW 320 /* one view */
#define H 240

namespace {

struct Rgb {
  guint8 r, g, b;
};

const Rgb kBackground = {40, 90, 60};
const Rgb kYellow = {255, 230, 0}; /* contour */
const Rgb kCyan = {0, 230, 255};   /* box */
const Rgb kNear = {255, 0, 0};     /* depth colour map, t = 0 */
const Rgb kFar = {0, 85, 255};     /* t = 1 */

/* A packed frame in @format ("RGB" or "BGRx"), @w x H. */
struct Frame {
  int w = 0, bpp = 3, stride = 0;
  bool bgrx = false;
  std::vector<guint8> data;

  Frame(int width, const char *format) : w(width)
  {
    bgrx = g_str_equal(format, "BGRx");
    bpp = bgrx ? 4 : 3;
    stride = GST_ROUND_UP_4(w * bpp);
    data.assign(size_t(stride) * H, 0);
  }
  void set(int x, int y, Rgb c)
  {
    guint8 *p = &data[size_t(y) * stride + size_t(x) * bpp];
    if (bgrx) {
      p[0] = c.b, p[1] = c.g, p[2] = c.r, p[3] = 0;
    } else {
      p[0] = c.r, p[1] = c.g, p[2] = c.b;
    }
  }
  void fill(Rgb c)
  {
    for (int y = 0; y < H; y++)
      for (int x = 0; x < w; x++)
        set(x, y, c);
  }
  GstBuffer *buffer() const
  {
    GstBuffer *b = gst_buffer_new_allocate(nullptr, data.size(), nullptr);
    gst_buffer_fill(b, 0, data.data(), data.size());
    GST_BUFFER_PTS(b) = 0;
    GST_BUFFER_DURATION(b) = 40 * GST_MSECOND;
    return b;
  }
};

/* Pixel (x, y) of a mapped output buffer as RGB. */
Rgb at(GstBuffer *buf, int w, bool bgrx, int x, int y)
{
  GstMapInfo map;
  fail_unless(gst_buffer_map(buf, &map, GST_MAP_READ));
  const int bpp = bgrx ? 4 : 3, stride = GST_ROUND_UP_4(w * bpp);
  fail_unless(map.size >= size_t(stride) * H);
  const guint8 *p = map.data + size_t(y) * stride + size_t(x) * bpp;
  Rgb c = bgrx ? Rgb{p[2], p[1], p[0]} : Rgb{p[0], p[1], p[2]};
  gst_buffer_unmap(buf, &map);
  return c;
}

bool same(Rgb a, Rgb b) { return a.r == b.r && a.g == b.g && a.b == b.b; }

#define assert_rgb(buf, w, bgrx, x, y, c)                                                      \
  G_STMT_START                                                                                 \
  {                                                                                            \
    Rgb _got = at((buf), (w), (bgrx), (x), (y));                                               \
    fail_unless(same(_got, (c)), "pixel (%d, %d) is %d,%d,%d, expected %d,%d,%d", (x), (y),    \
                _got.r, _got.g, _got.b, (c).r, (c).g, (c).b);                                  \
  }                                                                                            \
  G_STMT_END

/* A square contour of half side 40 around (cx, 150) with a box 6 px outside it. */
void set_square(GstTreeStereoVegetationView *v, int cx)
{
  const int cy = 150, r = 40;
  const gint32 xy[8] = {cx - r, cy - r, cx + r, cy - r, cx + r, cy + r, cx - r, cy + r};
  v->present = TRUE;
  v->bbox_x = cx - r - 6;
  v->bbox_y = cy - r - 6;
  v->bbox_width = 2 * r + 13;
  v->bbox_height = 2 * r + 13;
  gst_tree_stereo_vegetation_view_set_contour(v, xy, 4);
}

/* Left square at x 240, right at 220; matches at depth 1.5 m (near) and 3.0 m (far); one band
 * X -0.2..0.1 m, Y 0.3..0.5 m at 2 m (f 300 px: x 130..175, y 165..195), depth 1.5 m. */
void add_metas(GstBuffer *buf, int n_views, bool with_metrics)
{
  GstTreeStereoGeometryMeta *g = gst_buffer_add_tree_stereo_geometry_meta(buf);
  g->view_width = VW;
  g->view_height = H;
  g->side_by_side = n_views == 2;
  for (int v = 0; v < 2; v++) {
    g->fx[v] = g->fy[v] = 300;
    g->cx[v] = 160;
    g->cy[v] = 120;
  }
  g->baseline_mm = 50;

  GstTreeStereoVegetationMeta *veg = gst_buffer_add_tree_stereo_vegetation_meta(buf, guint(n_views));
  set_square(&veg->views[0], 240);
  if (n_views == 2)
    set_square(&veg->views[1], 220);

  const GstTreeStereoMatch m[2] = {{60, 200, 40, 200, 0.1f}, {300, 220, 290, 222, 0.2f}};
  gst_buffer_add_tree_stereo_matches_meta(buf, GST_TREE_STEREO_MATCH_COSINE_NORM, 10, 12, m, 2);
  /* points listed out of order: match_index is what links a point to its match */
  const GstTreeStereoPoint p[2] = {{0, 0, 3000, 1, TRUE}, {0, 0, 1500, 0, TRUE}};
  gst_buffer_add_tree_stereo_points_meta(buf, p, 2, nullptr);

  if (!with_metrics)
    return;
  GstTreeStereoMetrics mt;
  memset(&mt, 0, sizeof mt);
  mt.tree_present = TRUE;
  mt.distance_m = 2.0;
  mt.height_m = 1.2;
  mt.width_m = 0.9;
  mt.thickness_m = 0.4;
  mt.centroid_m[2] = 2.0;
  mt.n_points = 2;
  mt.n_matches = 2;
  gst_tree_stereo_metrics_set_n_bands(&mt, 1);
  mt.bands[0] = {TRUE, 0.3, 0.5, -0.2, 0.1, 0.3, 1.5};
  gst_buffer_add_tree_stereo_metrics_meta(buf, &mt, nullptr);
  gst_tree_stereo_metrics_clear(&mt);
}

GstHarness *harness(const char *launch, const char *format, int w, bool sbs)
{
  GstHarness *h = gst_harness_new_parse(launch);
  gchar *caps = g_strdup_printf("video/x-raw,format=%s,width=%d,height=%d,framerate=25/1%s",
                                format, w, H, sbs ? ",multiview-mode=side-by-side" : "");
  gst_harness_set_src_caps_str(h, caps);
  g_free(caps);
  return h;
}

/* The frame drawn by treeoverlay (views=both) from the full set of metas, in @format. */
GstBuffer *draw_scene(const char *format)
{
  GstHarness *h = harness("treeoverlay", format, 2 * VW, true);
  Frame f(2 * VW, format);
  f.fill(kBackground);
  GstBuffer *in = f.buffer();
  add_metas(in, 2, true);
  GstBuffer *out = gst_harness_push_and_pull(h, in);
  fail_unless(out != nullptr);
  gst_harness_teardown(h);
  return out;
}

/* A GRAY8 mask of one view: 255 inside [x0, x1) x [y0, y1). */
GstBuffer *rect_mask(int x0, int x1, int y0, int y1)
{
  std::vector<guint8> m(size_t(VW) * H, 0);
  for (int y = y0; y < y1; y++)
    memset(&m[size_t(y) * VW + size_t(x0)], 255, size_t(x1 - x0));
  GstBuffer *b = gst_buffer_new_allocate(nullptr, m.size(), nullptr);
  gst_buffer_fill(b, 0, m.data(), m.size());
  return b;
}

} // namespace

/* stereodepth kept the left half of the green square as the canopy: the right half is
 * vegetation depth rejected and is tinted grey-blue; the canopy's pixels are not; the canopy's
 * contour is drawn in yellow. */
GST_START_TEST(test_rejected_vegetation_is_tinted)
{
  const Rgb kTinted = {guint8((kBackground.r + 110 + 1) / 2), guint8((kBackground.g + 130 + 1) / 2),
                       guint8((kBackground.b + 170 + 1) / 2)};
  for (const char *format : {"RGB", "BGRx"}) {
    const bool bgrx = g_str_equal(format, "BGRx");
    GstHarness *h = harness("treeoverlay draw-box=false draw-matches=false draw-bands=false "
                            "draw-text=false",
                            format, 2 * VW, true);
    Frame f(2 * VW, format);
    f.fill(kBackground);
    GstBuffer *in = f.buffer();
    GstTreeStereoVegetationMeta *veg = gst_buffer_add_tree_stereo_vegetation_meta(in, 2);
    veg->views[0].present = TRUE;
    GstBuffer *vm = rect_mask(200, 280, 110, 190);
    gst_tree_stereo_vegetation_view_set_mask(&veg->views[0], vm, VW, H, VW);
    gst_buffer_unref(vm);
    GstTreeStereoCanopyMeta *c =
        gst_buffer_add_tree_stereo_canopy_meta(in, GST_TREE_STEREO_CANOPY_TREE);
    c->view.present = TRUE;
    const gint32 xy[8] = {200, 110, 239, 110, 239, 189, 200, 189};
    gst_tree_stereo_vegetation_view_set_contour(&c->view, xy, 4);
    GstBuffer *cm = rect_mask(200, 240, 110, 190);
    gst_tree_stereo_vegetation_view_set_mask(&c->view, cm, VW, H, VW);
    gst_buffer_unref(cm);

    GstBuffer *out = gst_harness_push_and_pull(h, in);
    assert_rgb(out, 2 * VW, bgrx, 260, 150, kTinted);    /* rejected vegetation */
    assert_rgb(out, 2 * VW, bgrx, 279, 189, kTinted);
    assert_rgb(out, 2 * VW, bgrx, 220, 150, kBackground); /* canopy */
    assert_rgb(out, 2 * VW, bgrx, 239, 150, kYellow);     /* the canopy's contour */
    assert_rgb(out, 2 * VW, bgrx, 290, 150, kBackground); /* no vegetation */
    assert_rgb(out, 2 * VW, bgrx, VW + 260, 150, kBackground); /* the right view: untouched */
    gst_buffer_unref(out);

    /* draw-contour=false switches the tint off too */
    gst_harness_set(h, "treeoverlay", "draw-contour", FALSE, NULL);
    in = f.buffer();
    gst_buffer_add_tree_stereo_canopy_meta(in, GST_TREE_STEREO_CANOPY_TREE);
    veg = gst_buffer_add_tree_stereo_vegetation_meta(in, 2);
    veg->views[0].present = TRUE;
    vm = rect_mask(200, 280, 110, 190);
    gst_tree_stereo_vegetation_view_set_mask(&veg->views[0], vm, VW, H, VW);
    gst_buffer_unref(vm);
    out = gst_harness_push_and_pull(h, in);
    assert_rgb(out, 2 * VW, bgrx, 260, 150, kBackground);
    gst_buffer_unref(out);
    gst_harness_teardown(h);
  }
}
GST_END_TEST;

GST_START_TEST(test_draws_items_where_the_metas_say)
{
  GstBuffer *out = draw_scene("RGB");
  const int w = 2 * VW;
  /* contour corners and edges in both views, box in both */
  assert_rgb(out, w, false, 200, 110, kYellow);
  assert_rgb(out, w, false, 280, 150, kYellow);
  assert_rgb(out, w, false, 240, 190, kYellow);
  assert_rgb(out, w, false, VW + 180, 110, kYellow);
  assert_rgb(out, w, false, VW + 260, 170, kYellow);
  assert_rgb(out, w, false, 194, 150, kCyan);
  assert_rgb(out, w, false, VW + 174, 150, kCyan);
  /* the near match red in both views, the far one blue */
  assert_rgb(out, w, false, 60, 200, kNear);
  assert_rgb(out, w, false, VW + 40, 200, kNear);
  assert_rgb(out, w, false, 300, 220, kFar);
  assert_rgb(out, w, false, VW + 290, 222, kFar);
  /* the band at y 180 from x 130 to 175, at the near depth */
  assert_rgb(out, w, false, 130, 180, kNear);
  assert_rgb(out, w, false, 150, 180, kNear);
  assert_rgb(out, w, false, 175, 170, kNear);
  /* the text panel at the top left is darker than the frame */
  Rgb panel = at(out, w, false, 5, 5);
  fail_unless(panel.g < kBackground.g && panel.r < kBackground.r);
  /* far from every item: untouched */
  assert_rgb(out, w, false, 240, 150, kBackground); /* inside the square */
  assert_rgb(out, w, false, 300, 20, kBackground);
  assert_rgb(out, w, false, VW + 300, 20, kBackground);
  assert_rgb(out, w, false, VW + 10, 100, kBackground);
  assert_rgb(out, w, false, 100, 230, kBackground);
  gst_buffer_unref(out);
}
GST_END_TEST;

GST_START_TEST(test_no_metas_no_change)
{
  /* documented: nothing measured this frame, so nothing is drawn, not even "no tree" */
  GstHarness *h = harness("treeoverlay", "RGB", 2 * VW, true);
  Frame f(2 * VW, "RGB");
  for (int y = 0; y < H; y++)
    for (int x = 0; x < 2 * VW; x++)
      f.set(x, y, {guint8(x), guint8(y), guint8(x + y)});
  GstBuffer *out = gst_harness_push_and_pull(h, f.buffer());
  GstMapInfo map;
  fail_unless(gst_buffer_map(out, &map, GST_MAP_READ));
  fail_unless_equals_int(map.size, f.data.size());
  fail_unless(memcmp(map.data, f.data.data(), map.size) == 0);
  gst_buffer_unmap(out, &map);
  gst_buffer_unref(out);
  gst_harness_teardown(h);
}
GST_END_TEST;

GST_START_TEST(test_no_tree_panel_only)
{
  GstHarness *h = harness("treeoverlay", "RGB", 2 * VW, true);
  Frame f(2 * VW, "RGB");
  f.fill(kBackground);
  GstBuffer *in = f.buffer();
  GstTreeStereoMetrics mt;
  memset(&mt, 0, sizeof mt);
  gst_buffer_add_tree_stereo_metrics_meta(in, &mt, nullptr); /* tree_present FALSE */
  GstBuffer *out = gst_harness_push_and_pull(h, in);
  /* the panel changed the top-left corner and nothing else */
  GstMapInfo map;
  fail_unless(gst_buffer_map(out, &map, GST_MAP_READ));
  int changed = 0, max_x = 0, max_y = 0;
  for (int y = 0; y < H; y++)
    for (int x = 0; x < 2 * VW; x++) {
      const guint8 *p = map.data + size_t(y) * GST_ROUND_UP_4(2 * VW * 3) + size_t(x) * 3;
      if (p[0] != kBackground.r || p[1] != kBackground.g || p[2] != kBackground.b) {
        changed++;
        max_x = MAX(max_x, x);
        max_y = MAX(max_y, y);
      }
    }
  gst_buffer_unmap(out, &map);
  fail_unless(changed > 200, "only %d pixels changed", changed);
  fail_unless(max_x < VW / 2 && max_y < H / 3, "panel reaches (%d, %d)", max_x, max_y);
  gst_buffer_unref(out);
  gst_harness_teardown(h);
}
GST_END_TEST;

GST_START_TEST(test_views_left_crops)
{
  GstHarness *h = harness("treeoverlay views=left draw-text=false", "RGB", 2 * VW, true);
  Frame f(2 * VW, "RGB");
  for (int y = 0; y < H; y++)
    for (int x = 0; x < 2 * VW; x++)
      f.set(x, y, x < VW ? Rgb{guint8(x), guint8(y), guint8(x + y)} : Rgb{0, 0, 0});
  GstBuffer *in = f.buffer();
  add_metas(in, 2, true);
  GstBuffer *out = gst_harness_push_and_pull(h, in);

  GstCaps *caps = gst_pad_get_current_caps(h->sinkpad);
  GstVideoInfo info;
  fail_unless(gst_video_info_from_caps(&info, caps));
  fail_unless_equals_int(GST_VIDEO_INFO_WIDTH(&info), VW);
  fail_unless_equals_int(GST_VIDEO_INFO_HEIGHT(&info), H);
  fail_unless(!gst_structure_has_field(gst_caps_get_structure(caps, 0), "multiview-mode") ||
              GST_VIDEO_INFO_MULTIVIEW_MODE(&info) == GST_VIDEO_MULTIVIEW_MODE_MONO);
  gst_caps_unref(caps);

  /* drawn: the left contour and the near match (lines style not set: a dot) */
  assert_rgb(out, VW, false, 200, 110, kYellow);
  assert_rgb(out, VW, false, 60, 200, kNear);
  /* elsewhere the left half of the input, pixel for pixel */
  for (int y = 0; y < 60; y++)
    for (int x = 0; x < VW; x++)
      assert_rgb(out, VW, false, x, y, (Rgb{guint8(x), guint8(y), guint8(x + y)}));
  /* the metas came along; the geometry now says one view */
  GstTreeStereoGeometryMeta *g = gst_buffer_get_tree_stereo_geometry_meta(out);
  fail_unless(g != nullptr);
  fail_if(g->side_by_side);
  fail_unless(gst_buffer_get_tree_stereo_vegetation_meta(out) != nullptr);
  fail_unless(gst_buffer_get_tree_stereo_metrics_meta(out) != nullptr);
  gst_buffer_unref(out);
  gst_harness_teardown(h);
}
GST_END_TEST;

GST_START_TEST(test_views_left_without_metas_is_the_left_half)
{
  GstHarness *h = harness("treeoverlay views=left", "BGRx", 2 * VW, true);
  Frame f(2 * VW, "BGRx");
  for (int y = 0; y < H; y++)
    for (int x = 0; x < 2 * VW; x++)
      f.set(x, y, x < VW ? Rgb{guint8(3 * x), guint8(y), 7} : Rgb{255, 255, 255});
  GstBuffer *out = gst_harness_push_and_pull(h, f.buffer());
  for (int y = 0; y < H; y++)
    for (int x = 0; x < VW; x++)
      assert_rgb(out, VW, true, x, y, (Rgb{guint8(3 * x), guint8(y), 7}));
  gst_buffer_unref(out);
  gst_harness_teardown(h);
}
GST_END_TEST;

GST_START_TEST(test_mono_input_drawn_in_place_with_views_left)
{
  GstHarness *h = harness("treeoverlay views=left", "RGB", VW, false);
  Frame f(VW, "RGB");
  f.fill(kBackground);
  GstBuffer *in = f.buffer();
  add_metas(in, 1, false);
  GstBuffer *out = gst_harness_push_and_pull(h, in);
  GstCaps *caps = gst_pad_get_current_caps(h->sinkpad);
  GstVideoInfo info;
  fail_unless(gst_video_info_from_caps(&info, caps));
  fail_unless_equals_int(GST_VIDEO_INFO_WIDTH(&info), VW);
  gst_caps_unref(caps);
  assert_rgb(out, VW, false, 280, 150, kYellow);
  assert_rgb(out, VW, false, 300, 220, kFar);
  gst_buffer_unref(out);
  gst_harness_teardown(h);
}
GST_END_TEST;

GST_START_TEST(test_bgrx_and_rgb_agree)
{
  GstBuffer *rgb = draw_scene("RGB");
  GstBuffer *bgrx = draw_scene("BGRx");
  for (int y = 0; y < H; y++)
    for (int x = 0; x < 2 * VW; x++) {
      const Rgb a = at(rgb, 2 * VW, false, x, y), b = at(bgrx, 2 * VW, true, x, y);
      fail_unless(same(a, b), "(%d, %d): RGB %d,%d,%d vs BGRx %d,%d,%d", x, y, a.r, a.g, a.b,
                  b.r, b.g, b.b);
    }
  gst_buffer_unref(rgb);
  gst_buffer_unref(bgrx);
}
GST_END_TEST;

GST_START_TEST(test_layers_switch_off)
{
  GstHarness *h = harness("treeoverlay draw-contour=false draw-box=false draw-matches=false "
                          "draw-bands=false draw-text=false",
                          "RGB", 2 * VW, true);
  Frame f(2 * VW, "RGB");
  f.fill(kBackground);
  GstBuffer *in = f.buffer();
  add_metas(in, 2, true);
  GstBuffer *out = gst_harness_push_and_pull(h, in);
  GstMapInfo map;
  fail_unless(gst_buffer_map(out, &map, GST_MAP_READ));
  fail_unless(memcmp(map.data, f.data.data(), f.data.size()) == 0);
  gst_buffer_unmap(out, &map);
  gst_buffer_unref(out);

  /* match-style=lines joins the near match's points across the halves */
  gst_harness_set(h, "treeoverlay", "draw-matches", TRUE, "match-style", 1, NULL);
  in = f.buffer();
  add_metas(in, 2, true);
  out = gst_harness_push_and_pull(h, in);
  for (int x : {60, 200, VW, VW + 40})
    assert_rgb(out, 2 * VW, false, x, 200, kNear);
  gst_buffer_unref(out);
  gst_harness_teardown(h);
}
GST_END_TEST;

/* treeoverlay draws whatever metas are there (no meta is required), and its properties refuse
 * bad values themselves: what it can refuse at run time is a frame. A side-by-side frame of odd
 * width has no two equal views: lib's BadInput, STREAM/FAILED. */
GST_START_TEST(test_odd_side_by_side_is_a_stream_error)
{
  GstHarness *h = harness("treeoverlay", "RGB", 2 * VW + 1, true);
  GstBus *bus = gst_bus_new();
  gst_element_set_bus(h->element, bus);
  GstBuffer *in =
      gst_buffer_new_allocate(nullptr, gsize(GST_ROUND_UP_4((2 * VW + 1) * 3)) * H, nullptr);
  fail_unless_equals_int(gst_harness_push(h, in), GST_FLOW_ERROR);
  expect_bus_error(bus, GST_MESSAGE_ERROR, GST_STREAM_ERROR, GST_STREAM_ERROR_FAILED,
                   "treeoverlay cannot use what arrived from upstream: check the elements "
                   "before it.",
                   "overlay: a side-by-side frame must have an even width");
  gst_element_set_bus(h->element, nullptr);
  gst_object_unref(bus);
  gst_harness_teardown(h);
}
GST_END_TEST;

static Suite *treeoverlay_suite(void)
{
  Suite *s = suite_create("treeoverlay");
  TCase *tc = tcase_create("general");
  suite_add_tcase(s, tc);
  tcase_add_test(tc, test_draws_items_where_the_metas_say);
  tcase_add_test(tc, test_no_metas_no_change);
  tcase_add_test(tc, test_no_tree_panel_only);
  tcase_add_test(tc, test_views_left_crops);
  tcase_add_test(tc, test_views_left_without_metas_is_the_left_half);
  tcase_add_test(tc, test_mono_input_drawn_in_place_with_views_left);
  tcase_add_test(tc, test_bgrx_and_rgb_agree);
  tcase_add_test(tc, test_layers_switch_off);
  tcase_add_test(tc, test_odd_side_by_side_is_a_stream_error);
  tcase_add_test(tc, test_rejected_vegetation_is_tinted);
  return s;
}

GST_CHECK_MAIN(treeoverlay);
