/* treetestsrc: caps, timestamps, the ground-truth meta, the written calibration, the stereo
 * rig (same seed = same scene), property ranges, the orchard scene. */
#include <gst/check/gstcheck.h>
#include <gst/check/gstharness.h>
#include "expect_error.h"
#include <gst/video/video.h>
#include <gst/treestereo/treestereo-meta.h>

#include <glib/gstdio.h>
#include <string.h>

static GstHarness *
source (const gchar * props, const gchar * caps)
{
  gchar *desc = g_strdup_printf ("treetestsrc %s", props);
  GstHarness *h = gst_harness_new_parse (desc);
  g_free (desc);
  gst_harness_set_sink_caps_str (h, caps);
  gst_harness_play (h);
  return h;
}

GST_START_TEST (test_frames_and_truth)
{
  GstHarness *h = source ("view=left seed=3 distance=2.2 speed=0.7",
      "video/x-raw,format=RGB,width=320,height=240,framerate=10/1");
  GstTreeStereoTruthMeta *t;
  GstBuffer *buf;
  GstMapInfo map;
  gdouble prev_offset = -1;

  for (guint i = 0; i < 3; i++) {
    buf = gst_harness_pull (h);
    fail_unless (buf != NULL);
    fail_unless_equals_int (gst_buffer_get_size (buf), GST_ROUND_UP_4 (320 * 3) * 240);
    fail_unless_equals_uint64 (GST_BUFFER_PTS (buf), i * GST_SECOND / 10);
    fail_unless_equals_uint64 (GST_BUFFER_DURATION (buf), GST_SECOND / 10);
    t = gst_buffer_get_tree_stereo_truth_meta (buf);
    fail_unless (t != NULL);
    fail_unless_equals_int (t->truth.view, GST_TREE_STEREO_LEFT);
    fail_unless_equals_uint64 (t->truth.frame, i);
    fail_unless_equals_int (t->truth.seed, 3);
    /* the scene's parameters come back exactly */
    fail_unless (fabs (t->truth.trunk_distance_m - 2.2) < 1e-6, "%f", t->truth.trunk_distance_m);
    fail_unless (fabs (t->truth.height_m - 0.9) < 1e-3);
    fail_unless (fabs (t->truth.width_m - 0.7) < 1e-3);
    fail_unless_equals_float (t->truth.baseline_mm, 50.0);
    /* the visible canopy surface lies in front of the trunk and behind its front face */
    fail_unless (t->truth.distance_m < 2.2 && t->truth.distance_m > 2.2 - 0.7,
        "distance %f", t->truth.distance_m);
    fail_unless (t->truth.depth_p05_m <= t->truth.distance_m);
    fail_unless (t->truth.depth_p95_m >= t->truth.distance_m);
    fail_unless (fabs (t->truth.thickness_m - (t->truth.depth_p95_m - t->truth.depth_p05_m)) <
        1e-9);
    /* the sprayer drives: 0.7 m/s at 10 fps is 7 cm a frame */
    if (prev_offset >= 0)
      fail_unless (fabs (fabs (t->truth.offset_x_m - prev_offset) - 0.07) < 1e-6,
          "offset step %f", t->truth.offset_x_m - prev_offset);
    prev_offset = t->truth.offset_x_m;
    /* per-pixel maps of this view */
    fail_unless_equals_int (t->width, 320);
    fail_unless_equals_int (t->height, 240);
    fail_unless (t->depth != NULL && t->mask != NULL);
    fail_unless_equals_int (gst_buffer_get_size (t->depth), 320 * 240 * sizeof (gfloat));
    fail_unless (gst_buffer_map (t->mask, &map, GST_MAP_READ));
    {
      guint canopy = 0;
      for (gsize k = 0; k < map.size; k++)
        canopy += map.data[k] == 255;
      /* a 0.7 x 0.9 m canopy at ~2 m fills a good part of a 4:3 view */
      fail_unless (canopy > map.size / 20 && canopy < map.size / 2, "canopy %u px", canopy);
    }
    gst_buffer_unmap (t->mask, &map);
    gst_buffer_unref (buf);
  }
  gst_harness_teardown (h);
}

GST_END_TEST;

static GstBuffer *
first_frame (const gchar * props)
{
  GstHarness *h = source (props, "video/x-raw,format=GRAY8,width=160,height=120");
  GstBuffer *buf = gst_harness_pull (h);
  gst_harness_teardown (h);
  return buf;
}

GST_START_TEST (test_rig_and_determinism)
{
  GstBuffer *a = first_frame ("view=left seed=5");
  GstBuffer *b = first_frame ("view=left seed=5");
  GstBuffer *r = first_frame ("view=right seed=5");
  GstBuffer *o = first_frame ("view=left seed=6");

  {
    GstMapInfo ma, mb, mr, mo;
    gst_buffer_map (a, &ma, GST_MAP_READ);
    gst_buffer_map (b, &mb, GST_MAP_READ);
    gst_buffer_map (r, &mr, GST_MAP_READ);
    gst_buffer_map (o, &mo, GST_MAP_READ);
    fail_unless (ma.size == mb.size && memcmp (ma.data, mb.data, ma.size) == 0,
        "same seed and view must render the same frame");
    fail_if (memcmp (ma.data, mr.data, ma.size) == 0, "right view equals the left one");
    fail_if (memcmp (ma.data, mo.data, ma.size) == 0, "another seed rendered the same tree");
    gst_buffer_unmap (a, &ma);
    gst_buffer_unmap (b, &mb);
    gst_buffer_unmap (r, &mr);
    gst_buffer_unmap (o, &mo);
  }
  /* both views describe the same scene */
  fail_unless_equals_float (gst_buffer_get_tree_stereo_truth_meta (a)->truth.height_m,
      gst_buffer_get_tree_stereo_truth_meta (r)->truth.height_m);
  fail_unless_equals_int (gst_buffer_get_tree_stereo_truth_meta (r)->truth.view,
      GST_TREE_STEREO_RIGHT);
  gst_buffer_unref (a);
  gst_buffer_unref (b);
  gst_buffer_unref (r);
  gst_buffer_unref (o);
}

GST_END_TEST;

GST_START_TEST (test_calibration_out)
{
  gchar *dir = g_dir_make_tmp ("treetestsrc-XXXXXX", NULL);
  gchar *path = g_build_filename (dir, "rig.yml", NULL);
  gchar *props = g_strdup_printf ("view=left baseline=60 calibration-out=%s", path);
  gchar *text = NULL;
  GstBuffer *buf = first_frame (props);

  fail_unless (g_file_get_contents (path, &text, NULL, NULL), "no calibration written");
  fail_unless (strstr (text, "image_width: 160") != NULL, "%s", text);
  fail_unless (strstr (text, "image_height: 120") != NULL);
  /* T = (-baseline, ...) */
  fail_unless (strstr (text, "-60.") != NULL, "baseline 60 mm not in T: %s", text);
  g_free (text);
  gst_buffer_unref (buf);
  g_unlink (path);
  g_rmdir (dir);
  g_free (props);
  g_free (path);
  g_free (dir);
}

GST_END_TEST;

GST_START_TEST (test_property_ranges)
{
  GstElement *e = gst_element_factory_make ("treetestsrc", NULL);
  gdouble d;

  /* out of range values are refused by the param spec (and warned about) */
  ASSERT_WARNING (g_object_set (e, "distance", 100.0, NULL));
  g_object_get (e, "distance", &d, NULL);
  fail_unless_equals_float (d, 2.0);
  ASSERT_WARNING (g_object_set (e, "light", 0.0, NULL));
  g_object_set (e, "light", 0.7, NULL);
  g_object_get (e, "light", &d, NULL);
  fail_unless_equals_float (d, 0.7);
  gst_object_unref (e);
}

GST_END_TEST;

/* An orchard frame: the tree in front (the truth's canopy mask), other trees of its row beside
 * it, the row behind and grass, told apart by colour and the truth's depth map. */
GST_START_TEST (test_orchard_scene)
{
  GstHarness *h = source ("view=left scene=orchard seed=3 distance=2.0 noise=0",
      "video/x-raw,format=RGB,width=320,height=240,framerate=7/1");
  GstBuffer *buf = gst_harness_pull (h);
  GstTreeStereoTruthMeta *t = gst_buffer_get_tree_stereo_truth_meta (buf);
  GstMapInfo img, depth, mask;
  guint front = 0, row = 0, back = 0, grass = 0, dry = 0;
  guint stride = GST_ROUND_UP_4 (320 * 3);

  fail_unless (t != NULL && t->depth != NULL && t->mask != NULL);
  /* the truth is about the tree in front: its size as asked */
  fail_unless (fabs (t->truth.trunk_distance_m - 2.0) < 1e-6);
  fail_unless (fabs (t->truth.height_m - 0.9) < 1e-3);
  fail_unless (fabs (t->truth.width_m - 0.7) < 1e-3);
  fail_unless (fabs (t->truth.offset_x_m) < 1e-9);
  fail_unless (gst_buffer_map (buf, &img, GST_MAP_READ));
  fail_unless (gst_buffer_map (t->depth, &depth, GST_MAP_READ));
  fail_unless (gst_buffer_map (t->mask, &mask, GST_MAP_READ));
  for (guint y = 0; y < 240; y++)
    for (guint x = 0; x < 320; x++) {
      const guint8 *px = img.data + y * stride + 3 * x;
      const gint exg = 2 * px[1] - px[0] - px[2];
      const gfloat z = ((const gfloat *) depth.data)[y * 320 + x] / 1000.0f;
      if (mask.data[y * 320 + x] == 255) {
        front++;
        continue;
      }
      if (z >= 1.6f && z <= 2.4f && exg > 10)
        row++;                  /* a neighbour's leaves */
      else if (z >= 5.0f && z <= 6.0f && exg > 10)
        back++;                 /* the row behind (3.5 m further) */
      else if (y > 120 && ((z > 2.5f && z < 4.9f) || (z > 6.1f && z < 9.9f))) {
        /* only ground lies between the rows and between the back row and the wall (10 m) */
        grass += exg > 20;
        dry += exg < 10;
      }
    }
  gst_buffer_unmap (t->mask, &mask);
  gst_buffer_unmap (t->depth, &depth);
  gst_buffer_unmap (buf, &img);
  fail_unless (front > 320 * 240 / 20, "tree in front %u px", front);
  fail_unless (row > 50, "neighbours %u px", row);
  fail_unless (back > 200, "back row %u px", back);
  fail_unless (grass > 1000, "green grass %u px", grass);
  fail_unless (dry > 20, "dry grass %u px", dry);
  gst_buffer_unref (buf);
  gst_harness_teardown (h);
}

GST_END_TEST;

GST_START_TEST (test_scene_properties)
{
  GstElement *e = gst_element_factory_make ("treetestsrc", NULL);
  gdouble lo, hi, spacing;
  gint scene;

  /* defaults: the lab scene, the rows at the scene's defaults */
  g_object_get (e, "scene", &scene, "row-gap-min", &lo, "row-gap-max", &hi, "row-spacing",
      &spacing, NULL);
  fail_unless_equals_int (scene, 0);
  fail_unless_equals_float (lo, -1.0);
  fail_unless_equals_float (hi, -1.0);
  fail_unless_equals_float (spacing, -1.0);
  gst_util_set_object_arg (G_OBJECT (e), "scene", "hedgerow");
  g_object_set (e, "row-gap-min", 0.3, "row-gap-max", 0.5, "row-spacing", 4.0, NULL);
  g_object_get (e, "scene", &scene, "row-gap-min", &lo, "row-gap-max", &hi, "row-spacing",
      &spacing, NULL);
  fail_unless_equals_int (scene, 2);
  fail_unless_equals_float (lo, 0.3);
  fail_unless_equals_float (hi, 0.5);
  fail_unless_equals_float (spacing, 4.0);
  gst_util_set_object_arg (G_OBJECT (e), "scene", "orchard");
  g_object_set (e, "row-gap-min", -1.0, NULL);
  g_object_get (e, "scene", &scene, "row-gap-min", &lo, NULL);
  fail_unless_equals_int (scene, 1);
  fail_unless_equals_float (lo, -1.0);
  ASSERT_WARNING (g_object_set (e, "row-spacing", 9.0, NULL));
  g_object_get (e, "row-spacing", &spacing, NULL);
  fail_unless_equals_float (spacing, 4.0);
  gst_object_unref (e);
}

GST_END_TEST;

/* A bad row parameter stops the stream with an error naming it. */
GST_START_TEST (test_bad_row_parameters)
{
  GstHarness *h = gst_harness_new_parse ("treetestsrc scene=orchard row-gap-min=0.6 "
      "row-gap-max=0.2");
  GstBus *bus = gst_bus_new ();

  gst_element_set_bus (h->element, bus);
  gst_harness_set_sink_caps_str (h,
      "video/x-raw,format=RGB,width=160,height=120,framerate=7/1");
  gst_harness_play (h);
  /* lib's BadSettings: RESOURCE/SETTINGS, its text (naming the field) in the debug string */
  expect_bus_error (bus, GST_MESSAGE_ERROR, GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_SETTINGS,
      "The settings of treetestsrc cannot be used: change the property the debug detail "
      "names.", "row_gap_max_mm");
  gst_element_set_bus (h->element, NULL);
  gst_object_unref (bus);
  gst_harness_teardown (h);
}

GST_END_TEST;

/* Runs treetestsrc with @props to its first frame and expects the calibration-out error. */
static void
expect_calibration_out_error (const gchar * props, gint code, const gchar * message,
    const gchar * debug_part)
{
  GstHarness *h = gst_harness_new_parse (props);
  GstBus *bus = gst_bus_new ();

  gst_element_set_bus (h->element, bus);
  gst_harness_set_sink_caps_str (h,
      "video/x-raw,format=RGB,width=160,height=120,framerate=7/1");
  gst_harness_play (h);
  expect_bus_error (bus, GST_MESSAGE_ERROR, GST_RESOURCE_ERROR, code, message, debug_part);
  gst_element_set_bus (h->element, NULL);
  gst_object_unref (bus);
  gst_harness_teardown (h);
}

/* A calibration-out that cannot be written, and one that names no calibration format. */
GST_START_TEST (test_bad_calibration_out)
{
  expect_calibration_out_error ("treetestsrc calibration-out=/nonexistent-dir/rig.yml",
      GST_RESOURCE_ERROR_OPEN_WRITE, "Could not write the calibration to "
      "\"/nonexistent-dir/rig.yml\": check that its folder exists and is writable.",
      "/nonexistent-dir/rig.yml");
  expect_calibration_out_error ("treetestsrc calibration-out=/tmp/rig.txt",
      GST_RESOURCE_ERROR_SETTINGS, "treetestsrc's calibration-out must name an OpenCV "
      "YAML/XML file: end it in .yml, .yaml or .xml (optionally .gz).",
      "unknown extension");
}

GST_END_TEST;

static Suite *
treetestsrc_suite (void)
{
  Suite *s = suite_create ("treetestsrc");
  TCase *tc = tcase_create ("general");

  suite_add_tcase (s, tc);
  tcase_add_test (tc, test_frames_and_truth);
  tcase_add_test (tc, test_rig_and_determinism);
  tcase_add_test (tc, test_calibration_out);
  tcase_add_test (tc, test_property_ranges);
  tcase_add_test (tc, test_orchard_scene);
  tcase_add_test (tc, test_scene_properties);
  tcase_add_test (tc, test_bad_row_parameters);
  tcase_add_test (tc, test_bad_calibration_out);
  return s;
}

GST_CHECK_MAIN (treetestsrc);
