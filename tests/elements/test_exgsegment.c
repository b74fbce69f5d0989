/* exgsegment in a harness: green discs of known centre and radius on soil, in both views of a
 * side-by-side frame and in a mono stream; every field of the vegetation meta, the "tree" ROI
 * and the element message is checked against the discs. */
#include <gst/check/gstcheck.h>
#include <gst/check/gstharness.h>
#include "expect_error.h"
#include <gst/video/video.h>
#include <gst/treestereo/treestereo-meta.h>

#include <math.h>
#include <string.h>

/* view size: 322 px rows make a 324-byte mask stride (rows padded to 4) */
#define W 322
#define H 240

static const guint8 LEAF[3] = { 60, 140, 50 };  /* R, G, B */
static const guint8 SOIL[3] = { 120, 90, 60 };
static const guint8 SKY[3] = { 150, 180, 220 };

typedef struct
{
  gdouble cx, cy, r;            /* in the view's own pixels */
} Disc;

/* two different discs: the left view's and the right view's */
static const Disc LEFT_DISC = { 120.0, 110.0, 60.0 };
static const Disc RIGHT_DISC = { 200.0, 130.0, 50.0 };

static gboolean
in_disc (const Disc * d, gint x, gint y)
{
  return (x - d->cx) * (x - d->cx) + (y - d->cy) * (y - d->cy) <= d->r * d->r;
}

/* 2g - r - b on chromatic coordinates (the default index, exg-norm) */
static gdouble
exg_norm (const guint8 c[3])
{
  return (2.0 * c[1] - c[0] - c[2]) / (c[0] + c[1] + c[2]);
}

/* A frame of @n_views views of W x H: soil (the top third sky when @sky), with @discs[v] (may
 * be NULL) in view v. Padding and alpha bytes are 255. */
static GstBuffer *
make_frame (GstVideoFormat format, gint n_views, const Disc * const *discs, gboolean sky,
    GstClockTime pts)
{
  GstVideoInfo info;
  GstVideoFrame frame;
  const GstVideoFormatInfo *finfo;
  GstBuffer *buf;
  gint pstride, stride, off[3];

  gst_video_info_set_format (&info, format, n_views * W, H);
  buf = gst_buffer_new_allocate (NULL, GST_VIDEO_INFO_SIZE (&info), NULL);
  fail_unless (gst_video_frame_map (&frame, &info, buf, GST_MAP_WRITE));
  finfo = info.finfo;
  pstride = GST_VIDEO_FORMAT_INFO_PSTRIDE (finfo, 0);
  stride = GST_VIDEO_FRAME_PLANE_STRIDE (&frame, 0);
  for (gint c = 0; c < 3; c++)
    off[c] = GST_VIDEO_FORMAT_INFO_POFFSET (finfo, c);
  memset (GST_VIDEO_FRAME_PLANE_DATA (&frame, 0), 255, (gsize) stride * H);
  for (gint y = 0; y < H; y++) {
    guint8 *row = (guint8 *) GST_VIDEO_FRAME_PLANE_DATA (&frame, 0) + (gsize) y * stride;
    for (gint x = 0; x < n_views * W; x++) {
      const gint v = x / W;
      const guint8 *col = (sky && y < H / 3) ? SKY : SOIL;
      if (discs && discs[v] && in_disc (discs[v], x - v * W, y))
        col = LEAF;
      for (gint c = 0; c < 3; c++)
        row[x * pstride + off[c]] = col[c];
    }
  }
  gst_video_frame_unmap (&frame);
  GST_BUFFER_PTS (buf) = pts;
  GST_BUFFER_DURATION (buf) = GST_SECOND / 7;
  return buf;
}

typedef struct
{
  GstHarness *h;
  GstBus *bus;
} Rig;

static void
rig_setup (Rig * rig, const gchar * format, gint n_views)
{
  GstElement *e = gst_element_factory_make ("exgsegment", NULL);
  gchar *caps;

  fail_unless (e != NULL, "exgsegment not found");
  rig->bus = gst_bus_new ();
  gst_element_set_bus (e, rig->bus);
  rig->h = gst_harness_new_with_element (e, "sink", "src");
  gst_object_unref (e);
  caps = g_strdup_printf ("video/x-raw,format=%s,width=%d,height=%d,framerate=7/1%s", format,
      n_views * W, H, n_views == 2 ? ",multiview-mode=side-by-side" : "");
  gst_harness_set_src_caps_str (rig->h, caps);
  g_free (caps);
}

static void
rig_teardown (Rig * rig)
{
  gst_element_set_bus (rig->h->element, NULL);
  gst_object_unref (rig->bus);
  gst_harness_teardown (rig->h);
}

static GstBuffer *
push_pull (Rig * rig, GstBuffer * in)
{
  GstBuffer *out;
  fail_unless_equals_int (gst_harness_push (rig->h, in), GST_FLOW_OK);
  out = gst_harness_pull (rig->h);
  fail_unless (out != NULL);
  return out;
}

/* The element message of the last frame, parsed; NULL when none was posted. */
static gboolean
pop_message (Rig * rig, GstTreeStereoVegetationMeta * parsed, GstTreeStereoTimes * times,
    GstStructure ** copy)
{
  GstMessage *msg = gst_bus_pop_filtered (rig->bus, GST_MESSAGE_ELEMENT);
  const GstStructure *s;

  if (!msg)
    return FALSE;
  s = gst_message_get_structure (msg);
  fail_unless (gst_structure_has_name (s, GST_TREE_STEREO_MESSAGE_EXGSEGMENT));
  memset (parsed, 0, sizeof (*parsed));
  fail_unless (gst_tree_stereo_vegetation_message_parse (s, parsed, times),
      "malformed message %" GST_PTR_FORMAT, s);
  if (copy)
    *copy = gst_structure_copy (s);
  gst_message_unref (msg);
  return TRUE;
}

/* Every figure of one view against its disc. */
static void
check_view (const GstTreeStereoVegetationView * v, const Disc * d, gdouble tmin, gdouble tmax)
{
  const gdouble area = G_PI * d->r * d->r, perimeter = 2 * G_PI * d->r;
  GstMapInfo map;
  gint inter = 0, uni = 0;

  fail_unless (v->present);
  fail_unless (v->threshold > tmin && v->threshold < tmax, "threshold %f not in (%f, %f)",
      v->threshold, tmin, tmax);
  fail_unless (fabs (v->area_px - area) < 0.02 * area, "area %f, disc %f", v->area_px, area);
  fail_unless (fabs (v->perimeter_px - perimeter) < 0.03 * perimeter, "perimeter %f, disc %f",
      v->perimeter_px, perimeter);
  fail_unless (fabs (v->complexity - 1.0) < 0.05, "complexity %f", v->complexity);
  fail_unless (fabs (v->complexity - v->perimeter_px * v->perimeter_px / (4 * G_PI *
              v->area_px)) < 1e-9);
  fail_unless (fabs (v->centroid_x - d->cx) < 0.5 && fabs (v->centroid_y - d->cy) < 0.5,
      "centroid (%f, %f), disc (%f, %f)", v->centroid_x, v->centroid_y, d->cx, d->cy);
  /* the disc's pixels span cx - r .. cx + r; opening may shave its one-pixel tips */
  fail_unless (abs (v->bbox_x - (gint) (d->cx - d->r)) <= 1, "bbox x %d", v->bbox_x);
  fail_unless (abs (v->bbox_y - (gint) (d->cy - d->r)) <= 1, "bbox y %d", v->bbox_y);
  fail_unless (abs (v->bbox_width - (gint) (2 * d->r + 1)) <= 2, "bbox w %d", v->bbox_width);
  fail_unless (abs (v->bbox_height - (gint) (2 * d->r + 1)) <= 2, "bbox h %d", v->bbox_height);
  fail_unless_equals_int (v->n_regions, 1);

  fail_unless (v->n_contour >= 8 && v->contour != NULL, "contour of %u points", v->n_contour);
  for (guint i = 0; i < v->n_contour; i++) {
    const gint x = v->contour[2 * i], y = v->contour[2 * i + 1];
    const gdouble rho = hypot (x - d->cx, y - d->cy);
    fail_unless (x >= v->bbox_x && x < v->bbox_x + v->bbox_width && y >= v->bbox_y &&
        y < v->bbox_y + v->bbox_height, "contour point (%d, %d) outside the box", x, y);
    fail_unless (fabs (rho - d->r) < 1.5, "contour point (%d, %d) at %f from the centre", x, y,
        rho);
  }

  fail_unless (v->mask != NULL);
  fail_unless_equals_int (v->mask_width, W);
  fail_unless_equals_int (v->mask_height, H);
  fail_unless_equals_int (v->mask_stride, GST_ROUND_UP_4 (W));
  fail_unless (gst_buffer_map (v->mask, &map, GST_MAP_READ));
  fail_unless (map.size >= (gsize) v->mask_stride * H);
  fail_unless_equals_int (map.data[(gint) d->cy * v->mask_stride + (gint) d->cx], 255);
  fail_unless_equals_int (map.data[5 * v->mask_stride + 5], 0);
  fail_unless_equals_int (map.data[(H - 1) * v->mask_stride + W - 1], 0);
  for (gint y = 0; y < H; y++)
    for (gint x = 0; x < W; x++) {
      const guint8 m = map.data[y * v->mask_stride + x];
      fail_unless (m == 0 || m == 255, "mask value %u", m);
      inter += (m && in_disc (d, x, y));
      uni += (m || in_disc (d, x, y));
    }
  gst_buffer_unmap (v->mask, &map);
  fail_unless ((gdouble) inter / uni >= 0.98, "mask IoU %f", (gdouble) inter / uni);
}

/* The parsed message equals the meta, field by field. */
static void
check_message_equals_meta (const GstTreeStereoVegetationMeta * msg,
    const GstTreeStereoVegetationMeta * meta)
{
  fail_unless_equals_int (msg->n_views, meta->n_views);
  fail_unless_equals_int (msg->index, meta->index);
  for (guint i = 0; i < meta->n_views; i++) {
    const GstTreeStereoVegetationView *a = &msg->views[i], *b = &meta->views[i];
    fail_unless_equals_int (a->present, b->present);
    fail_unless_equals_float (a->threshold, b->threshold);
    fail_unless_equals_float (a->area_px, b->area_px);
    fail_unless_equals_float (a->perimeter_px, b->perimeter_px);
    fail_unless_equals_float (a->complexity, b->complexity);
    fail_unless_equals_float (a->centroid_x, b->centroid_x);
    fail_unless_equals_float (a->centroid_y, b->centroid_y);
    fail_unless_equals_int (a->bbox_x, b->bbox_x);
    fail_unless_equals_int (a->bbox_y, b->bbox_y);
    fail_unless_equals_int (a->bbox_width, b->bbox_width);
    fail_unless_equals_int (a->bbox_height, b->bbox_height);
    fail_unless_equals_int (a->n_regions, b->n_regions);
  }
}

static void
check_times (const GstTreeStereoTimes * t, GstClockTime pts)
{
  /* the harness's segment starts at 0: running and stream time equal the PTS */
  fail_unless_equals_uint64 (t->timestamp, pts);
  fail_unless_equals_uint64 (t->stream_time, pts);
  fail_unless_equals_uint64 (t->running_time, pts);
}

static void
check_tree_roi (GstBuffer * buf, const GstTreeStereoVegetationView * left)
{
  GstVideoRegionOfInterestMeta *roi = NULL;
  gpointer state = NULL;
  GstMeta *m;
  guint n = 0;

  while ((m = gst_buffer_iterate_meta_filtered (buf, &state,
              GST_VIDEO_REGION_OF_INTEREST_META_API_TYPE))) {
    roi = (GstVideoRegionOfInterestMeta *) m;
    n++;
  }
  fail_unless_equals_int (n, 1);
  fail_unless_equals_string (g_quark_to_string (roi->roi_type), "tree");
  fail_unless_equals_int (roi->x, left->bbox_x);
  fail_unless_equals_int (roi->y, left->bbox_y);
  fail_unless_equals_int (roi->w, left->bbox_width);
  fail_unless_equals_int (roi->h, left->bbox_height);
}

static void
run_stereo_discs (const gchar * format_name)
{
  const Disc *discs[2] = { &LEFT_DISC, &RIGHT_DISC };
  const GstVideoFormat format = gst_video_format_from_string (format_name);
  const GstClockTime pts = 3 * GST_SECOND;
  Rig rig;
  GstBuffer *out;
  GstTreeStereoVegetationMeta *meta, parsed;
  GstTreeStereoTimes times;

  rig_setup (&rig, format_name, 2);
  out = push_pull (&rig, make_frame (format, 2, discs, FALSE, pts));
  meta = gst_buffer_get_tree_stereo_vegetation_meta (out);
  fail_unless (meta != NULL, "no vegetation meta (%s)", format_name);
  fail_unless_equals_int (meta->n_views, 2);
  fail_unless_equals_int (meta->index, GST_TREE_STEREO_INDEX_EXG_NORM);
  check_view (&meta->views[0], &LEFT_DISC, exg_norm (SOIL), exg_norm (LEAF));
  check_view (&meta->views[1], &RIGHT_DISC, exg_norm (SOIL), exg_norm (LEAF));
  check_tree_roi (out, &meta->views[0]);

  fail_unless (pop_message (&rig, &parsed, &times, NULL), "no exgsegment message");
  check_message_equals_meta (&parsed, meta);
  check_times (&times, pts);
  gst_buffer_unref (out);
  rig_teardown (&rig);
}

GST_START_TEST (test_stereo_discs_rgb)
{
  run_stereo_discs ("RGB");
}

GST_END_TEST;

GST_START_TEST (test_stereo_discs_bgrx)
{
  run_stereo_discs ("BGRx");
}

GST_END_TEST;

GST_START_TEST (test_mono_stream)
{
  const Disc *discs[1] = { &RIGHT_DISC };
  Rig rig;
  GstBuffer *out;
  GstTreeStereoVegetationMeta *meta, parsed;
  GstTreeStereoTimes times;
  GstStructure *s;

  rig_setup (&rig, "xBGR", 1);
  out = push_pull (&rig, make_frame (GST_VIDEO_FORMAT_xBGR, 1, discs, TRUE, 0));
  meta = gst_buffer_get_tree_stereo_vegetation_meta (out);
  fail_unless (meta != NULL);
  fail_unless_equals_int (meta->n_views, 1);
  check_view (&meta->views[0], &RIGHT_DISC, exg_norm (SOIL), exg_norm (LEAF));
  /* the second view is unused and empty */
  fail_if (meta->views[1].present);
  fail_unless (meta->views[1].mask == NULL && meta->views[1].contour == NULL);
  check_tree_roi (out, &meta->views[0]);

  fail_unless (pop_message (&rig, &parsed, &times, &s));
  check_message_equals_meta (&parsed, meta);
  check_times (&times, 0);
  /* one view: no left-/right- prefix */
  fail_unless (gst_structure_has_field (s, "present"));
  fail_unless (gst_structure_has_field (s, "centroid-x"));
  fail_if (gst_structure_has_field (s, "left-present"));
  fail_if (gst_structure_has_field (s, "right-present"));
  gst_structure_free (s);
  gst_buffer_unref (out);
  rig_teardown (&rig);
}

GST_END_TEST;

GST_START_TEST (test_no_vegetation)
{
  Rig rig;
  GstBuffer *out;
  GstTreeStereoVegetationMeta *meta, parsed;
  GstTreeStereoTimes times;
  GstStructure *s;

  rig_setup (&rig, "RGB", 2);
  /* soil and sky only: two modes for Otsu, neither green enough to pass the floor */
  out = push_pull (&rig, make_frame (GST_VIDEO_FORMAT_RGB, 2, NULL, TRUE, 0));
  meta = gst_buffer_get_tree_stereo_vegetation_meta (out);
  fail_unless (meta != NULL);
  fail_unless_equals_int (meta->n_views, 2);
  for (gint v = 0; v < 2; v++) {
    const GstTreeStereoVegetationView *w = &meta->views[v];
    fail_if (w->present);
    fail_unless (w->area_px == 0 && w->perimeter_px == 0 && w->complexity == 0);
    fail_unless (w->centroid_x == 0 && w->centroid_y == 0);
    fail_unless (w->bbox_x == 0 && w->bbox_y == 0 && w->bbox_width == 0 && w->bbox_height == 0);
    fail_unless (w->n_regions == 0 && w->n_contour == 0 && w->contour == NULL);
    fail_unless (w->mask == NULL);
    fail_unless (isfinite (w->threshold));
  }
  fail_if (gst_buffer_get_video_region_of_interest_meta (out) != NULL, "ROI without canopy");

  fail_unless (pop_message (&rig, &parsed, &times, &s));
  check_message_equals_meta (&parsed, meta);
  {
    gboolean present = TRUE;
    gdouble area = -1;
    fail_unless (gst_structure_get_boolean (s, "left-present", &present) && !present);
    fail_unless (gst_structure_get_boolean (s, "right-present", &present) && !present);
    fail_unless (gst_structure_get_double (s, "right-area", &area) && area == 0);
  }
  gst_structure_free (s);
  gst_buffer_unref (out);
  rig_teardown (&rig);
}

GST_END_TEST;

GST_START_TEST (test_keep_all_two_regions)
{
  /* two discs in the left view; keep=all (the default) takes both, keep=largest only the
   * bigger */
  static const Disc small = { 260.0, 180.0, 30.0 };
  Rig rig;
  GstBuffer *in, *out;
  GstTreeStereoVegetationMeta *meta, parsed;
  GstTreeStereoTimes times;
  GstVideoFrame frame;
  GstVideoInfo info;
  const Disc *discs[2] = { &LEFT_DISC, NULL };
  const gdouble a_big = G_PI * LEFT_DISC.r * LEFT_DISC.r, a_small = G_PI * small.r * small.r;

  rig_setup (&rig, "RGB", 2);
  g_object_set (rig.h->element, "keep", 0 /* largest */ , "post-messages", FALSE, NULL);
  in = make_frame (GST_VIDEO_FORMAT_RGB, 2, discs, FALSE, 0);
  /* paint the second disc into the left view */
  gst_video_info_set_format (&info, GST_VIDEO_FORMAT_RGB, 2 * W, H);
  fail_unless (gst_video_frame_map (&frame, &info, in, GST_MAP_WRITE));
  for (gint y = 0; y < H; y++)
    for (gint x = 0; x < W; x++)
      if (in_disc (&small, x, y))
        memcpy ((guint8 *) GST_VIDEO_FRAME_PLANE_DATA (&frame, 0) +
            y * GST_VIDEO_FRAME_PLANE_STRIDE (&frame, 0) + 3 * x, LEAF, 3);
  gst_video_frame_unmap (&frame);

  out = push_pull (&rig, gst_buffer_copy_deep (in));
  meta = gst_buffer_get_tree_stereo_vegetation_meta (out);
  fail_unless_equals_int (meta->views[0].n_regions, 1);
  fail_unless (fabs (meta->views[0].area_px - a_big) < 0.02 * a_big);
  fail_if (meta->views[1].present);
  gst_buffer_unref (out);
  fail_if (pop_message (&rig, &parsed, &times, NULL), "message with post-messages=false");

  g_object_set (rig.h->element, "keep", 1 /* all */ , "post-messages", TRUE, NULL);
  out = push_pull (&rig, in);
  meta = gst_buffer_get_tree_stereo_vegetation_meta (out);
  fail_unless_equals_int (meta->views[0].n_regions, 2);
  fail_unless (fabs (meta->views[0].area_px - a_big - a_small) < 0.02 * (a_big + a_small));
  /* the box spans both discs; the centroid is their area-weighted mean */
  fail_unless (abs (meta->views[0].bbox_x - (gint) (LEFT_DISC.cx - LEFT_DISC.r)) <= 1);
  fail_unless (abs (meta->views[0].bbox_x + meta->views[0].bbox_width - (gint) (small.cx +
              small.r + 1)) <= 1);
  fail_unless (fabs (meta->views[0].centroid_x - (a_big * LEFT_DISC.cx + a_small * small.cx) /
          (a_big + a_small)) < 0.5);
  /* the contour is the largest region's: inside the big disc's box */
  for (guint i = 0; i < meta->views[0].n_contour; i++)
    fail_unless (meta->views[0].contour[2 * i] <= LEFT_DISC.cx + LEFT_DISC.r + 1);
  fail_unless (pop_message (&rig, &parsed, &times, NULL));
  check_message_equals_meta (&parsed, meta);
  gst_buffer_unref (out);
  rig_teardown (&rig);
}

GST_END_TEST;

GST_START_TEST (test_index_changes_while_playing)
{
  const Disc *discs[2] = { &LEFT_DISC, &RIGHT_DISC };
  Rig rig;
  GstBuffer *out;
  GstTreeStereoVegetationMeta *meta, parsed;
  GstTreeStereoTimes times;
  /* exg-exr = 3G - 2.4R - B in raw levels */
  const gdouble soil = 3.0 * SOIL[1] - 2.4 * SOIL[0] - SOIL[2];
  const gdouble leaf = 3.0 * LEAF[1] - 2.4 * LEAF[0] - LEAF[2];

  rig_setup (&rig, "RGB", 2);
  gst_util_set_object_arg (G_OBJECT (rig.h->element), "index", "exg-exr");
  out = push_pull (&rig, make_frame (GST_VIDEO_FORMAT_RGB, 2, discs, FALSE, 0));
  meta = gst_buffer_get_tree_stereo_vegetation_meta (out);
  fail_unless_equals_int (meta->index, GST_TREE_STEREO_INDEX_EXG_EXR);
  check_view (&meta->views[0], &LEFT_DISC, MAX (soil, 0.0), leaf);
  check_view (&meta->views[1], &RIGHT_DISC, MAX (soil, 0.0), leaf);
  fail_unless (pop_message (&rig, &parsed, &times, NULL));
  fail_unless_equals_int (parsed.index, GST_TREE_STEREO_INDEX_EXG_EXR);
  gst_buffer_unref (out);

  /* a fixed threshold above the leaf's index: nothing is canopy */
  g_object_set (rig.h->element, "threshold", leaf + 1.0, NULL);
  out = push_pull (&rig, make_frame (GST_VIDEO_FORMAT_RGB, 2, discs, FALSE, GST_SECOND));
  meta = gst_buffer_get_tree_stereo_vegetation_meta (out);
  fail_if (meta->views[0].present || meta->views[1].present);
  fail_unless_equals_float (meta->views[0].threshold, leaf + 1.0);
  gst_buffer_unref (out);
  rig_teardown (&rig);
}

GST_END_TEST;

GST_START_TEST (test_no_pixel_copy_with_shared_input)
{
  /* upstream keeps a ref (as a tee does): the buffer going out shares the input's memory */
  const Disc *discs[2] = { &LEFT_DISC, &RIGHT_DISC };
  Rig rig;
  GstBuffer *in, *out;
  GstMapInfo a, b;

  rig_setup (&rig, "RGB", 2);
  in = make_frame (GST_VIDEO_FORMAT_RGB, 2, discs, FALSE, 0);
  out = push_pull (&rig, gst_buffer_ref (in));
  fail_unless (gst_buffer_get_tree_stereo_vegetation_meta (out) != NULL);
  fail_unless (gst_buffer_get_tree_stereo_vegetation_meta (in) == NULL,
      "the meta went onto the buffer upstream still holds");
  fail_unless (gst_buffer_map (in, &a, GST_MAP_READ));
  fail_unless (gst_buffer_map (out, &b, GST_MAP_READ));
  fail_unless (a.data == b.data, "the pixels were copied");
  gst_buffer_unmap (out, &b);
  gst_buffer_unmap (in, &a);
  gst_buffer_unref (out);
  gst_buffer_unref (in);
  rig_teardown (&rig);
}

GST_END_TEST;

GST_START_TEST (test_gray8_refused)
{
  GstHarness *h = gst_harness_new ("exgsegment");
  GstCaps *gray = gst_caps_from_string ("video/x-raw,format=GRAY8,width=64,height=48,"
      "framerate=7/1");
  GstPad *sink = gst_element_get_static_pad (h->element, "sink");

  fail_if (gst_pad_query_accept_caps (sink, gray), "GRAY8 accepted");
  gst_harness_set_src_caps (h, gray);
  fail_unless_equals_int (gst_harness_push (h, gst_buffer_new_allocate (NULL, 64 * 48, NULL)),
      GST_FLOW_NOT_NEGOTIATED);
  gst_object_unref (sink);
  gst_harness_teardown (h);
}

GST_END_TEST;

/* exgsegment needs no meta from upstream, and its properties refuse bad values themselves
 * (test_invalid_property_values): what it can refuse at run time are caps and buffers. */

/* A side-by-side frame too narrow for two views: CORE/NEGOTIATION saying what to check. */
GST_START_TEST (test_narrow_side_by_side_is_a_negotiation_error)
{
  GstHarness *h = gst_harness_new ("exgsegment");
  GstBus *bus = gst_bus_new ();

  gst_element_set_bus (h->element, bus);
  gst_harness_set_src_caps_str (h, "video/x-raw,format=RGB,width=1,height=48,framerate=7/1,"
      "multiview-mode=side-by-side");
  fail_if (gst_harness_push (h, gst_buffer_new_allocate (NULL, 4 * 48, NULL)) == GST_FLOW_OK);
  expect_bus_error (bus, GST_MESSAGE_ERROR, GST_CORE_ERROR, GST_CORE_ERROR_NEGOTIATION,
      "A side-by-side frame 1 px wide has no room for two views: check the caps upstream.",
      "side-by-side");
  gst_element_set_bus (h->element, NULL);
  gst_object_unref (bus);
  gst_harness_teardown (h);
}

GST_END_TEST;

/* A buffer smaller than its caps say: STREAM/FAILED naming what to check, the sizes in the
 * debug string. */
GST_START_TEST (test_short_buffer_is_a_stream_error)
{
  GstHarness *h = gst_harness_new ("exgsegment");
  GstBus *bus = gst_bus_new ();

  gst_element_set_bus (h->element, bus);
  gst_harness_set_src_caps_str (h, "video/x-raw,format=RGB,width=64,height=48,framerate=7/1");
  fail_unless_equals_int (gst_harness_push (h, gst_buffer_new_allocate (NULL, 10, NULL)),
      GST_FLOW_ERROR);
  expect_bus_error (bus, GST_MESSAGE_ERROR, GST_STREAM_ERROR, GST_STREAM_ERROR_FAILED,
      "exgsegment could not read the frame: the buffer is smaller than its caps say; check the "
      "elements before it.", "buffer of 10 bytes for 64x48 RGB");
  gst_element_set_bus (h->element, NULL);
  gst_object_unref (bus);
  gst_harness_teardown (h);
}

GST_END_TEST;

static gboolean
spec_refuses (GObject * obj, const gchar * name, const GValue * value)
{
  GParamSpec *pspec = g_object_class_find_property (G_OBJECT_GET_CLASS (obj), name);
  GValue v = G_VALUE_INIT;
  gboolean changed;

  fail_unless (pspec != NULL, "no property %s", name);
  g_value_init (&v, G_PARAM_SPEC_VALUE_TYPE (pspec));
  fail_unless (g_value_transform (value, &v));
  /* g_param_value_validate() returns TRUE when it had to change the value: out of range */
  changed = g_param_value_validate (pspec, &v);
  g_value_unset (&v);
  return changed;
}

GST_START_TEST (test_invalid_property_values)
{
  GstElement *e = gst_element_factory_make ("exgsegment", NULL);
  GValue v = G_VALUE_INIT;
  gint index = -1, keep = -1, morph = -1;
  gdouble threshold = 0, min_area = 0;
  gboolean post = FALSE, reconstruct = FALSE;

  /* defaults */
  g_object_get (e, "index", &index, "keep", &keep, "morph-size", &morph, "threshold",
      &threshold, "min-area", &min_area, "post-messages", &post, "reconstruct",
      &reconstruct, NULL);
  fail_unless_equals_int (index, GST_TREE_STEREO_INDEX_EXG_NORM);
  fail_unless_equals_int (keep, 1);   /* all: depth decides the canopy */
  fail_unless_equals_int (morph, 5);
  fail_unless_equals_float (threshold, -1.0);
  fail_unless_equals_float (min_area, 64.0);
  fail_unless (post);
  fail_unless (reconstruct);

  g_value_init (&v, G_TYPE_INT);
  g_value_set_int (&v, 256);
  fail_unless (spec_refuses (G_OBJECT (e), "morph-size", &v));
  g_value_set_int (&v, 7);
  fail_if (spec_refuses (G_OBJECT (e), "morph-size", &v));
  g_value_unset (&v);
  g_value_init (&v, G_TYPE_DOUBLE);
  g_value_set_double (&v, -5.0);
  fail_unless (spec_refuses (G_OBJECT (e), "threshold", &v));
  g_value_set_double (&v, -1.0);
  fail_if (spec_refuses (G_OBJECT (e), "threshold", &v));
  g_value_set_double (&v, -0.5);
  fail_unless (spec_refuses (G_OBJECT (e), "min-area", &v));
  g_value_unset (&v);

  /* an unknown index name or value is not taken */
  gst_util_set_object_arg (G_OBJECT (e), "index", "super-green");
  g_object_get (e, "index", &index, NULL);
  fail_unless_equals_int (index, GST_TREE_STEREO_INDEX_EXG_NORM);
  {
    GParamSpec *pspec = g_object_class_find_property (G_OBJECT_GET_CLASS (e), "index");
    g_value_init (&v, G_PARAM_SPEC_VALUE_TYPE (pspec));
    g_value_set_enum (&v, 17);
    fail_unless (g_param_value_validate (pspec, &v));
    g_value_unset (&v);
  }
  gst_util_set_object_arg (G_OBJECT (e), "index", "exg-exr-norm");
  gst_util_set_object_arg (G_OBJECT (e), "keep", "largest");
  g_object_get (e, "index", &index, "keep", &keep, NULL);
  fail_unless_equals_int (index, GST_TREE_STEREO_INDEX_EXG_EXR_NORM);
  fail_unless_equals_int (keep, 0);
  gst_object_unref (e);
}

GST_END_TEST;

static Suite *
exgsegment_suite (void)
{
  Suite *s = suite_create ("exgsegment");
  TCase *tc = tcase_create ("general");

  suite_add_tcase (s, tc);
  tcase_add_test (tc, test_stereo_discs_rgb);
  tcase_add_test (tc, test_stereo_discs_bgrx);
  tcase_add_test (tc, test_mono_stream);
  tcase_add_test (tc, test_no_vegetation);
  tcase_add_test (tc, test_keep_all_two_regions);
  tcase_add_test (tc, test_index_changes_while_playing);
  tcase_add_test (tc, test_no_pixel_copy_with_shared_input);
  tcase_add_test (tc, test_gray8_refused);
  tcase_add_test (tc, test_narrow_side_by_side_is_a_negotiation_error);
  tcase_add_test (tc, test_short_buffer_is_a_stream_error);
  tcase_add_test (tc, test_invalid_property_values);
  return s;
}

GST_CHECK_MAIN (exgsegment);
