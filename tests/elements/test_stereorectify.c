/* stereorectify with two harnesses (left, right): pairing by running time, drops, EOS, sizes. */
#include <gst/check/gstcheck.h>
#include <gst/check/gstharness.h>
#include <gst/video/video.h>
#include <gst/treestereo/treestereo-meta.h>

#include <glib/gstdio.h>
#include <string.h>
#include <unistd.h>

#define W 648
#define H 486
#define MS GST_MSECOND

static gchar *
example_calibration (void)
{
  return g_build_filename (g_getenv ("TREESTEREO_SOURCE_DIR"), "docs", "examples",
      "calibration-mer500.yml", NULL);
}

typedef struct
{
  GstHarness *left;
  GstHarness *right;
  GstBus *bus;
} Rig;

static void
rig_setup (Rig * rig, const gchar * format, gint w, gint h, gint rw, gint rh, gboolean rectify)
{
  gchar *calib = example_calibration ();
  gchar *lcaps, *rcaps;
  GstElement *e = gst_element_factory_make ("stereorectify", NULL);

  /* properties first: the harness starts the element at once */
  g_object_set (e, "calibration", calib, "rectify", rectify, NULL);
  g_free (calib);
  rig->bus = gst_bus_new ();
  gst_element_set_bus (e, rig->bus);
  rig->left = gst_harness_new_with_element (e, "left", "src");
  rig->right = gst_harness_new_with_element (e, "right", NULL);
  gst_object_unref (e);
  lcaps = g_strdup_printf ("video/x-raw,format=%s,width=%d,height=%d,framerate=25/1", format,
      w, h);
  rcaps = g_strdup_printf ("video/x-raw,format=%s,width=%d,height=%d,framerate=25/1", format,
      rw, rh);
  gst_harness_set_src_caps_str (rig->left, lcaps);
  gst_harness_set_src_caps_str (rig->right, rcaps);
  g_free (lcaps);
  g_free (rcaps);
}

static void
rig_teardown (Rig * rig)
{
  gst_element_set_bus (rig->left->element, NULL);
  gst_object_unref (rig->bus);
  gst_harness_teardown (rig->right);
  gst_harness_teardown (rig->left);
}

/* A frame of @bpp bytes per pixel with a recognisable value per view and frame. */
static GstBuffer *
frame (gint w, gint h, gint bpp, guint8 value, GstClockTime pts)
{
  GstBuffer *buf = gst_buffer_new_allocate (NULL, (gsize) GST_ROUND_UP_4 (w * bpp) * h, NULL);
  gst_buffer_memset (buf, 0, value, gst_buffer_get_size (buf));
  GST_BUFFER_PTS (buf) = pts;
  GST_BUFFER_DURATION (buf) = 40 * MS;
  return buf;
}

static void
push (GstHarness * h, gint w, gint hh, guint8 value, GstClockTime pts)
{
  fail_unless_equals_int (gst_harness_push (h, frame (w, hh, 3, value, pts)), GST_FLOW_OK);
}

GST_START_TEST (test_pairs_skewed_timestamps)
{
  Rig rig;
  GstBuffer *out;
  GstTreeStereoGeometryMeta *g;
  GstCaps *caps;
  GstVideoInfo info;

  rig_setup (&rig, "RGB", W, H, W, H, TRUE);
  /* the right camera runs 5 ms late: within the default max-skew of 20 ms */
  for (int i = 0; i < 3; i++) {
    push (rig.left, W, H, 100, i * 40 * MS);
    push (rig.right, W, H, 200, i * 40 * MS + 5 * MS);
  }
  for (int i = 0; i < 3; i++) {
    out = gst_harness_pull (rig.left);
    fail_unless (out != NULL);
    fail_unless_equals_uint64 (GST_BUFFER_PTS (out), i * 40 * MS);
    g = gst_buffer_get_tree_stereo_geometry_meta (out);
    fail_unless (g != NULL);
    fail_unless_equals_int (g->view_width, W);
    fail_unless_equals_int (g->view_height, H);
    fail_unless (g->side_by_side);
    fail_unless (g->rectified);
    fail_unless_equals_uint64 (g->pts[0], i * 40 * MS);
    fail_unless_equals_uint64 (g->pts[1], i * 40 * MS + 5 * MS);
    fail_unless_equals_int64 (g->skew_ns, 5 * MS);
    /* 50 mm rig of the example; the calibration is for 2592x1944, the stream a quarter */
    fail_unless (fabs (g->baseline_mm - 50.0) < 0.5);
    fail_unless (g->fx[0] > 3400 / 4.0 && g->fx[0] < 3600 / 4.0);
    fail_unless (g->Q[11] == g->fx[0]);
    gst_buffer_unref (out);
  }
  caps = gst_pad_get_current_caps (rig.left->sinkpad);
  fail_unless (gst_video_info_from_caps (&info, caps));
  fail_unless_equals_int (GST_VIDEO_INFO_WIDTH (&info), 2 * W);
  fail_unless_equals_int (GST_VIDEO_INFO_HEIGHT (&info), H);
  fail_unless_equals_int (GST_VIDEO_INFO_MULTIVIEW_MODE (&info),
      GST_VIDEO_MULTIVIEW_MODE_SIDE_BY_SIDE);
  gst_caps_unref (caps);
  rig_teardown (&rig);
}

GST_END_TEST;

GST_START_TEST (test_missing_right_frame_drops_one)
{
  Rig rig;
  GstBuffer *out;
  guint64 dropped = 0, paired = 0;
  GstMessage *msg;

  rig_setup (&rig, "RGB", W, H, W, H, TRUE);
  /* the right camera misses the frame at 40 ms (an aggregator pad holds one buffer at a time
   * with no latency set, so the pushes interleave as two cameras' would) */
  push (rig.left, W, H, 1, 0);
  push (rig.right, W, H, 1, 0);
  push (rig.left, W, H, 2, 40 * MS);
  push (rig.right, W, H, 3, 80 * MS);
  push (rig.left, W, H, 3, 80 * MS);

  out = gst_harness_pull (rig.left);
  fail_unless_equals_uint64 (GST_BUFFER_PTS (out), 0);
  gst_buffer_unref (out);
  out = gst_harness_pull (rig.left);
  fail_unless_equals_uint64 (GST_BUFFER_PTS (out), 80 * MS);
  fail_unless_equals_uint64 (gst_buffer_get_tree_stereo_geometry_meta (out)->pts[1], 80 * MS);
  gst_buffer_unref (out);

  g_object_get (rig.left->element, "dropped", &dropped, "paired", &paired, NULL);
  fail_unless_equals_uint64 (dropped, 1);
  fail_unless_equals_uint64 (paired, 2);
  msg = gst_bus_pop_filtered (rig.bus, GST_MESSAGE_QOS);
  fail_unless (msg != NULL, "no QoS message for the dropped frame");
  gst_message_unref (msg);
  msg = gst_bus_pop_filtered (rig.bus, GST_MESSAGE_WARNING);
  fail_unless (msg != NULL, "no warning for the dropped frame");
  gst_message_unref (msg);

  /* the stream goes on */
  push (rig.left, W, H, 4, 120 * MS);
  push (rig.right, W, H, 4, 120 * MS);
  out = gst_harness_pull (rig.left);
  fail_unless_equals_uint64 (GST_BUFFER_PTS (out), 120 * MS);
  gst_buffer_unref (out);
  rig_teardown (&rig);
}

GST_END_TEST;

GST_START_TEST (test_eos_on_one_pad_ends_stream)
{
  Rig rig;
  GstBuffer *out;
  GstEvent *ev;
  gboolean got_eos = FALSE;

  rig_setup (&rig, "RGB", W, H, W, H, TRUE);
  push (rig.left, W, H, 1, 0);
  push (rig.right, W, H, 1, 0);
  out = gst_harness_pull (rig.left);
  gst_buffer_unref (out);
  push (rig.left, W, H, 2, 40 * MS);
  fail_unless (gst_harness_push_event (rig.right, gst_event_new_eos ()));
  /* the lone left frame is not pushed; EOS is */
  for (int i = 0; i < 50 && !got_eos; i++) {
    while ((ev = gst_harness_try_pull_event (rig.left))) {
      got_eos |= GST_EVENT_TYPE (ev) == GST_EVENT_EOS;
      gst_event_unref (ev);
    }
    if (!got_eos)
      g_usleep (20000);
  }
  fail_unless (got_eos, "EOS on the right pad did not end the stream");
  fail_unless_equals_int (gst_harness_buffers_in_queue (rig.left), 0);
  rig_teardown (&rig);
}

GST_END_TEST;

static gchar *
wait_error (GstBus * bus)
{
  GstMessage *msg = gst_bus_timed_pop_filtered (bus, 5 * GST_SECOND, GST_MESSAGE_ERROR);
  GError *err = NULL;
  gchar *dbg = NULL, *text;

  fail_unless (msg != NULL, "no error posted");
  gst_message_parse_error (msg, &err, &dbg);
  text = g_strdup_printf ("%s | %s", err->message, dbg ? dbg : "");
  g_error_free (err);
  g_free (dbg);
  gst_message_unref (msg);
  return text;
}

GST_START_TEST (test_wrong_size_names_both)
{
  Rig rig;
  gchar *text;

  rig_setup (&rig, "RGB", 1000, 1000, 1000, 1000, TRUE);
  gst_harness_push (rig.left, frame (1000, 1000, 3, 1, 0));
  gst_harness_push (rig.right, frame (1000, 1000, 3, 1, 0));
  text = wait_error (rig.bus);
  GST_INFO ("error: %s", text);
  fail_unless (strstr (text, "2592x1944") != NULL, "calibration size not named: %s", text);
  fail_unless (strstr (text, "1000x1000") != NULL, "stream size not named: %s", text);
  g_free (text);
  rig_teardown (&rig);
}

GST_END_TEST;

GST_START_TEST (test_left_right_differ)
{
  Rig rig;
  gchar *text;

  rig_setup (&rig, "RGB", W, H, W / 2, H / 2, TRUE);
  gst_harness_push (rig.left, frame (W, H, 3, 1, 0));
  gst_harness_push (rig.right, frame (W / 2, H / 2, 3, 1, 0));
  text = wait_error (rig.bus);
  fail_unless (strstr (text, "648x486") != NULL && strstr (text, "324x243") != NULL,
      "both sizes not named: %s", text);
  g_free (text);
  rig_teardown (&rig);
}

GST_END_TEST;

GST_START_TEST (test_missing_calibration_fails_state_change)
{
  GstElement *e = gst_element_factory_make ("stereorectify", NULL);
  GstBus *bus = gst_bus_new ();
  GstMessage *msg;
  GError *err = NULL;

  gst_element_set_bus (e, bus);
  g_object_set (e, "calibration", "/nonexistent/calib.yml", NULL);
  fail_unless_equals_int (gst_element_set_state (e, GST_STATE_PAUSED),
      GST_STATE_CHANGE_FAILURE);
  msg = gst_bus_pop_filtered (bus, GST_MESSAGE_ERROR);
  fail_unless (msg != NULL);
  gst_message_parse_error (msg, &err, NULL);
  fail_unless (g_error_matches (err, GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_OPEN_READ), "%s",
      err->message);
  fail_unless_equals_string (err->message, "Could not read the calibration "
      "\"/nonexistent/calib.yml\": check the path in the calibration property.");
  g_error_free (err);
  gst_message_unref (msg);
  gst_element_set_state (e, GST_STATE_NULL);
  gst_element_set_bus (e, NULL);
  gst_object_unref (bus);
  gst_object_unref (e);
}

GST_END_TEST;

/* No calibration property: RESOURCE/SETTINGS saying what to set. */
GST_START_TEST (test_no_calibration_is_a_settings_error)
{
  GstElement *e = gst_element_factory_make ("stereorectify", NULL);
  GstBus *bus = gst_bus_new ();
  GstMessage *msg;
  GError *err = NULL;
  gchar *dbg = NULL;

  gst_element_set_bus (e, bus);
  fail_unless_equals_int (gst_element_set_state (e, GST_STATE_PAUSED),
      GST_STATE_CHANGE_FAILURE);
  msg = gst_bus_pop_filtered (bus, GST_MESSAGE_ERROR);
  fail_unless (msg != NULL);
  gst_message_parse_error (msg, &err, &dbg);
  fail_unless (g_error_matches (err, GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_SETTINGS), "%s",
      err->message);
  fail_unless_equals_string (err->message, "stereorectify has no calibration: set the "
      "calibration property to an OpenCV YAML/XML file or a ROS pair 'left.yaml;right.yaml'.");
  fail_unless (g_str_has_suffix (dbg, "\nthe calibration property is empty"), "%s", dbg);
  g_error_free (err);
  g_free (dbg);
  gst_message_unref (msg);
  gst_element_set_state (e, GST_STATE_NULL);
  gst_element_set_bus (e, NULL);
  gst_object_unref (bus);
  gst_object_unref (e);
}

GST_END_TEST;

/* ---- Bad calibration files: READY->PAUSED fails with an error naming the file and problem */

/* The example calibration's text with the first @from replaced by @to (@from must occur). */
static gchar *
example_text_with (const gchar * from, const gchar * to)
{
  gchar *path = example_calibration (), *text = NULL, *at, *out;
  gsize len = 0;

  fail_unless (g_file_get_contents (path, &text, &len, NULL), "cannot read %s", path);
  g_free (path);
  if (from == NULL)
    return text;
  at = strstr (text, from);
  fail_unless (at != NULL, "'%s' not in the example calibration", from);
  *at = '\0';
  out = g_strconcat (text, to, at + strlen (from), NULL);
  g_free (text);
  return out;
}

/* Sets @spec as calibration, expects READY->PAUSED to fail and an ERROR: RESOURCE/OPEN_READ
 * with the read advice for a file that cannot be read, else RESOURCE/SETTINGS with the content
 * advice; the message names @file, the debug string @problem. */
static void
expect_calibration_error (const gchar * spec, const gchar * file, const gchar * problem)
{
  GstElement *e = gst_element_factory_make ("stereorectify", NULL);
  GstBus *bus = gst_bus_new ();
  GstMessage *msg;
  GError *err = NULL;
  gchar *dbg = NULL;
  const gboolean unreadable = strstr (problem, "cannot be read") != NULL;

  gst_element_set_bus (e, bus);
  g_object_set (e, "calibration", spec, NULL);
  fail_unless_equals_int (gst_element_set_state (e, GST_STATE_READY), GST_STATE_CHANGE_SUCCESS);
  fail_unless_equals_int (gst_element_set_state (e, GST_STATE_PAUSED),
      GST_STATE_CHANGE_FAILURE);
  msg = gst_bus_pop_filtered (bus, GST_MESSAGE_ERROR);
  fail_unless (msg != NULL, "no error message for %s", spec);
  gst_message_parse_error (msg, &err, &dbg);
  GST_INFO ("%s -> %s | %s", spec, err->message, dbg);
  if (unreadable) {
    fail_unless (g_error_matches (err, GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_OPEN_READ),
        "%s: not a RESOURCE/OPEN_READ error: %s", spec, err->message);
    fail_unless (g_str_has_prefix (err->message, "Could not read the calibration \""),
        "%s", err->message);
    fail_unless (g_str_has_suffix (err->message,
            "\": check the path in the calibration property."), "%s", err->message);
  } else {
    fail_unless (g_error_matches (err, GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_SETTINGS),
        "%s: not a RESOURCE/SETTINGS error: %s", spec, err->message);
    fail_unless (g_str_has_prefix (err->message, "The calibration \""), "%s", err->message);
    fail_unless (g_str_has_suffix (err->message, "\" cannot be used: give stereorectify an "
            "OpenCV YAML/XML calibration (M1 D1 M2 D2 R T) or a ROS pair "
            "'left.yaml;right.yaml'."), "%s", err->message);
  }
  fail_unless (strstr (err->message, file) != NULL, "file %s not named: %s", file,
      err->message);
  fail_unless (dbg != NULL && strstr (dbg, problem) != NULL, "problem '%s' not in the debug "
      "string: %s", problem, dbg);
  g_error_free (err);
  g_free (dbg);
  gst_message_unref (msg);
  fail_unless_equals_int (gst_element_set_state (e, GST_STATE_NULL), GST_STATE_CHANGE_SUCCESS);
  gst_element_set_bus (e, NULL);
  gst_object_unref (bus);
  gst_object_unref (e);
}

/* Writes @len bytes of @text (-1: all) to @name in @dir and checks the element refuses it. */
static void
expect_file_error (const gchar * dir, const gchar * name, const gchar * text, gssize len,
    const gchar * problem)
{
  gchar *path = g_build_filename (dir, name, NULL);

  fail_unless (g_file_set_contents (path, text, len, NULL));
  expect_calibration_error (path, path, problem);
  g_unlink (path);
  g_free (path);
}

GST_START_TEST (test_bad_calibration_files_fail_state_change)
{
  gchar *dir = g_dir_make_tmp ("treestereo-badcalib-XXXXXX", NULL);
  gchar *text, *missing, *subdir;
  static const guint8 png[] = { 0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 0, 0, 0, 13 };

  fail_unless (dir != NULL);
  /* missing, and a directory where a file should be */
  missing = g_build_filename (dir, "absent.yml", NULL);
  expect_calibration_error (missing, missing, "missing or cannot be read");
  g_free (missing);
  subdir = g_build_filename (dir, "adir.yml", NULL);
  fail_unless (g_mkdir (subdir, 0700) == 0);
  expect_calibration_error (subdir, subdir, "is a directory");
  g_rmdir (subdir);
  g_free (subdir);

  /* empty, truncated inside a matrix, an image, text that is not YAML */
  expect_file_error (dir, "empty.yml", "", 0, "file is empty");
  text = example_text_with (NULL, NULL);
  expect_file_error (dir, "truncated.yml", text, strstr (text, "3503.12") - text + 4,
      "not a valid OpenCV YAML/XML file");
  expect_file_error (dir, "cut-before-T.yml", text, strstr (text, "\nT:") - text,
      "T: missing key");
  g_free (text);
  expect_file_error (dir, "image.yml", (const gchar *) png, sizeof png, "this is an image");
  expect_file_error (dir, "words.yml", "just some words\n", -1, "not a valid OpenCV");
  expect_file_error (dir, "calib.xml", "<?xml version=\"1.0\"?>\n<opencv_storage>\n<M1>",
      -1, "not a valid OpenCV YAML/XML file");

  /* well-formed files with impossible values */
  text = example_text_with ("3503.12", ".nan");
  expect_file_error (dir, "nan.yml", text, -1, "M1: holds a non-finite value");
  g_free (text);
  text = example_text_with ("[ -50., 0., 0. ]", "[ -50., .inf, 0. ]");
  expect_file_error (dir, "inf.yml", text, -1, "T: holds a non-finite value");
  g_free (text);
  text = example_text_with ("0.999993555008", "0.5");
  expect_file_error (dir, "not-rotation.yml", text, -1, "R: is not a rotation matrix");
  g_free (text);
  text = example_text_with ("[ -50., 0., 0. ]", "[ 0., 0., 0. ]");
  expect_file_error (dir, "zero-baseline.yml", text, -1, "T: zero baseline");
  g_free (text);
  text = example_text_with ("rows: 3\n   cols: 3", "rows: 2\n   cols: 3");
  expect_file_error (dir, "shape.yml", text, -1, "M1");
  g_free (text);
  text = example_text_with ("image_width: 2592\nimage_height: 1944\n", "");
  expect_file_error (dir, "no-size.yml", text, -1, "image size missing");
  g_free (text);

  /* a pair whose first file is missing: named, not the second */
  missing = g_build_filename (dir, "absent-left.yaml", NULL);
  {
    gchar *right = g_build_filename (dir, "right.yaml", NULL);
    text = g_strconcat (missing, ";", right, NULL);
    fail_unless (g_file_set_contents (right, "image_width: 640\nimage_height: 480\n", -1, NULL));
    expect_calibration_error (text, "absent-left.yaml", "missing or cannot be read");
    g_unlink (right);
    g_free (right);
  }
  g_free (text);
  g_free (missing);

  /* unreadable: only meaningful when not root (root reads anything) */
  if (geteuid () != 0) {
    gchar *path = g_build_filename (dir, "unreadable.yml", NULL);
    text = example_text_with (NULL, NULL);
    fail_unless (g_file_set_contents (path, text, -1, NULL));
    fail_unless (g_chmod (path, 0) == 0);
    expect_calibration_error (path, path, "missing or cannot be read");
    g_unlink (path);
    g_free (path);
    g_free (text);
  }
  g_rmdir (dir);
  g_free (dir);
}

GST_END_TEST;

/* A calibration that is fine in itself but for another camera: refused when caps arrive, naming
 * both sizes (a 4:3 calibration cannot be scaled to 16:9). */
GST_START_TEST (test_calibration_for_other_aspect_fails_at_caps)
{
  Rig rig;
  gchar *text;

  GstMessage *msg;
  GError *err = NULL;

  rig_setup (&rig, "RGB", 1280, 720, 1280, 720, TRUE);
  gst_harness_push (rig.left, frame (1280, 720, 3, 1, 0));
  gst_harness_push (rig.right, frame (1280, 720, 3, 1, 0));
  msg = gst_bus_timed_pop_filtered (rig.bus, 5 * GST_SECOND, GST_MESSAGE_ERROR);
  fail_unless (msg != NULL, "no error posted");
  gst_message_parse_error (msg, &err, &text);
  /* the caps are what does not fit: CORE/NEGOTIATION, the message says what to change and the
   * debug string has lib's reason with both sizes */
  fail_unless (g_error_matches (err, GST_CORE_ERROR, GST_CORE_ERROR_NEGOTIATION), "%s",
      err->message);
  fail_unless (g_str_has_prefix (err->message, "stereorectify cannot rectify RGB 1280x720 "
          "frames with the calibration \""), "%s", err->message);
  fail_unless (g_str_has_suffix (err->message, "calibration-mer500.yml\": give it frames of "
          "the calibration's size (or a pure scale of it), or a calibration made at this "
          "size."), "%s", err->message);
  fail_unless (text != NULL && strstr (text, "2592x1944") != NULL
      && strstr (text, "1280x720") != NULL, "both sizes not named: %s", text);
  g_error_free (err);
  g_free (text);
  gst_message_unref (msg);
  rig_teardown (&rig);
}

GST_END_TEST;

GST_START_TEST (test_passthrough_keeps_pixels)
{
  Rig rig;
  GstBuffer *out, *l, *r;
  GstMapInfo map;
  GstVideoInfo info;

  rig_setup (&rig, "GRAY8", W, H, W, H, FALSE);
  gst_harness_set_src_caps_str (rig.left,
      "video/x-raw,format=GRAY8,width=648,height=486,framerate=25/1");
  gst_harness_set_src_caps_str (rig.right,
      "video/x-raw,format=GRAY8,width=648,height=486,framerate=25/1");
  gst_video_info_set_format (&info, GST_VIDEO_FORMAT_GRAY8, W, H);
  l = gst_buffer_new_allocate (NULL, GST_VIDEO_INFO_SIZE (&info), NULL);
  r = gst_buffer_new_allocate (NULL, GST_VIDEO_INFO_SIZE (&info), NULL);
  gst_buffer_memset (l, 0, 11, GST_VIDEO_INFO_SIZE (&info));
  gst_buffer_memset (r, 0, 22, GST_VIDEO_INFO_SIZE (&info));
  GST_BUFFER_PTS (l) = GST_BUFFER_PTS (r) = 0;
  gst_harness_push (rig.left, l);
  gst_harness_push (rig.right, r);
  out = gst_harness_pull (rig.left);
  fail_unless (out != NULL);
  fail_if (gst_buffer_get_tree_stereo_geometry_meta (out)->rectified);
  fail_unless (gst_buffer_map (out, &map, GST_MAP_READ));
  /* GRAY8 rows of 2W are 4-aligned already (1296) */
  for (int y = 0; y < H; y += 97) {
    fail_unless_equals_int (map.data[y * 2 * W + 10], 11);
    fail_unless_equals_int (map.data[y * 2 * W + W + 10], 22);
  }
  gst_buffer_unmap (out, &map);
  gst_buffer_unref (out);
  rig_teardown (&rig);
}

GST_END_TEST;

static Suite *
stereorectify_suite (void)
{
  Suite *s = suite_create ("stereorectify");
  TCase *tc = tcase_create ("general");

  suite_add_tcase (s, tc);
  tcase_add_test (tc, test_pairs_skewed_timestamps);
  tcase_add_test (tc, test_missing_right_frame_drops_one);
  tcase_add_test (tc, test_eos_on_one_pad_ends_stream);
  tcase_add_test (tc, test_wrong_size_names_both);
  tcase_add_test (tc, test_left_right_differ);
  tcase_add_test (tc, test_missing_calibration_fails_state_change);
  tcase_add_test (tc, test_no_calibration_is_a_settings_error);
  tcase_add_test (tc, test_passthrough_keeps_pixels);
  tcase_add_test (tc, test_bad_calibration_files_fail_state_change);
  tcase_add_test (tc, test_calibration_for_other_aspect_fails_at_caps);
  return s;
}

GST_CHECK_MAIN (stereorectify);
