/* treecamerasrc without a camera: 127.0.0.9 on loopback, where no GigE Vision camera answers
 * (nothing leaves the machine; each attempt fails after aravis's ~2.5 s of retries).
 *   - no camera property: an error at READY saying what to set;
 *   - a camera that is not there: a WARNING naming it, a "lost" then "retry" messages with
 *     growing attempts, no ERROR; the latency query answers live meanwhile; NULL comes promptly
 *     (at most one attempt in progress to wait for);
 *   - EOS sent while it is missing reaches the bus;
 *   - reconnect-interval=0: the camera's error ends the pipeline, as a bare aravissrc's;
 *   - a camera name no camera has, reconnect-interval=0: an ERROR naming it, whatever cameras
 *     and network interfaces the machine has. */
#include <gst/check/gstcheck.h>
#include "expect_error.h"

#include <string.h>

static gboolean
have_aravis (void)
{
  GstPluginFeature *f = gst_registry_lookup_feature (gst_registry_get (), "aravissrc");
  if (!f) {
    g_print ("aravissrc is missing: the tests with a camera name are skipped\n");
    return FALSE;
  }
  gst_object_unref (f);
  return TRUE;
}

static GstElement *
make_pipeline (const gchar * props)
{
  gchar *desc = g_strdup_printf ("treecamerasrc name=cam camera=127.0.0.9 %s ! fakesink "
      "name=sink", props);
  GError *err = NULL;
  GstElement *p = gst_parse_launch (desc, &err);
  g_free (desc);
  fail_unless (p != NULL && err == NULL, "pipeline: %s", err ? err->message : "?");
  return p;
}

/* What came on the bus until @until says stop or @timeout_s passed. */
typedef struct
{
  guint warnings, errors, lost, retries, eos;
  guint max_attempt;
  gboolean warning_names_camera;
  gchar *error_text;
} Seen;

typedef gboolean (*Until) (const Seen * s);

static void
watch (GstElement * p, Seen * s, Until until, gdouble timeout_s)
{
  GstBus *bus = gst_element_get_bus (p);
  const gint64 end = g_get_monotonic_time () + (gint64) (timeout_s * G_USEC_PER_SEC);
  while (!until (s) && g_get_monotonic_time () < end) {
    GstMessage *m = gst_bus_timed_pop (bus, 100 * GST_MSECOND);
    if (!m)
      continue;
    switch (GST_MESSAGE_TYPE (m)) {
      case GST_MESSAGE_WARNING:{
        GError *e = NULL;
        gst_message_parse_warning (m, &e, NULL);
        s->warnings++;
        if (strstr (e->message, "camera '127.0.0.9'"))
          s->warning_names_camera = TRUE;
        g_error_free (e);
        break;
      }
      case GST_MESSAGE_ERROR:{
        GError *e = NULL;
        gst_message_parse_error (m, &e, NULL);
        s->errors++;
        g_free (s->error_text);
        s->error_text = g_strdup (e->message);
        g_error_free (e);
        break;
      }
      case GST_MESSAGE_EOS:
        s->eos++;
        break;
      case GST_MESSAGE_ELEMENT:{
        const GstStructure *st = gst_message_get_structure (m);
        if (gst_structure_has_name (st, "treestereo-camera")) {
          const gchar *state = gst_structure_get_string (st, "state");
          guint attempt = 0;
          fail_unless (gst_structure_get_uint (st, "attempt", &attempt));
          fail_unless_equals_string (gst_structure_get_string (st, "camera"), "127.0.0.9");
          fail_unless (gst_structure_has_field (st, "running-time"));
          fail_unless (gst_structure_get_string (st, "reason") != NULL);
          if (g_strcmp0 (state, "lost") == 0)
            s->lost++;
          else if (g_strcmp0 (state, "retry") == 0)
            s->retries++;
          else
            fail ("unexpected state %s", state);
          s->max_attempt = MAX (s->max_attempt, attempt);
        }
        break;
      }
      default:
        break;
    }
    gst_message_unref (m);
  }
  gst_object_unref (bus);
}

static gboolean
until_two_retries (const Seen * s)
{
  return s->retries >= 2 || s->errors > 0;
}

static gboolean
until_lost (const Seen * s)
{
  return s->lost > 0 || s->errors > 0;
}

static gboolean
until_eos (const Seen * s)
{
  return s->eos > 0 || s->errors > 0;
}

static gboolean
until_error (const Seen * s)
{
  return s->errors > 0;
}

/* Seconds to go to NULL. */
static gdouble
to_null (GstElement * p)
{
  const gint64 t0 = g_get_monotonic_time ();
  fail_unless (gst_element_set_state (p, GST_STATE_NULL) == GST_STATE_CHANGE_SUCCESS);
  return (g_get_monotonic_time () - t0) / 1e6;
}

GST_START_TEST (test_no_camera)
{
  GstElement *p = gst_parse_launch ("treecamerasrc ! fakesink", NULL);
  fail_unless (p != NULL);
  fail_unless (gst_element_set_state (p, GST_STATE_READY) == GST_STATE_CHANGE_FAILURE);
  GstBus *bus = gst_element_get_bus (p);
  expect_bus_error (bus, GST_MESSAGE_ERROR, GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_SETTINGS,
      "No camera: set treecamerasrc's camera property to the camera's name, serial number or IP "
      "address (arv-tool-0.8 lists the cameras it sees).", "the camera property is empty");
  gst_object_unref (bus);
  gst_element_set_state (p, GST_STATE_NULL);
  gst_object_unref (p);
}

GST_END_TEST;

GST_START_TEST (test_missing_camera_retries)
{
  if (!have_aravis ())
    return;
  GstElement *p = make_pipeline ("timeout=500 reconnect-interval=100 reconnect-max=400");
  fail_if (gst_element_set_state (p, GST_STATE_PLAYING) == GST_STATE_CHANGE_FAILURE);
  Seen s = { 0 };
  watch (p, &s, until_two_retries, 20);
  fail_unless (s.errors == 0, "an error with reconnecting on: %s", s.error_text);
  fail_unless_equals_int (s.lost, 1);
  fail_unless (s.retries >= 2, "%u retries in 20 s", s.retries);
  fail_unless (s.max_attempt >= 3, "attempts %u", s.max_attempt);
  fail_unless_equals_int (s.warnings, 1);
  fail_unless (s.warning_names_camera);

  /* the aggregator downstream of a missing camera must be live: the query is answered so */
  GstElement *cam = gst_bin_get_by_name (GST_BIN (p), "cam");
  GstPad *pad = gst_element_get_static_pad (cam, "src");
  GstQuery *q = gst_query_new_latency ();
  fail_unless (gst_pad_query (pad, q));
  gboolean live = FALSE;
  gst_query_parse_latency (q, &live, NULL, NULL);
  fail_unless (live);
  gst_query_unref (q);
  gboolean connected = TRUE;
  guint64 reconnects = 1;
  g_object_get (cam, "connected", &connected, "reconnects", &reconnects, NULL);
  fail_if (connected);
  fail_unless_equals_uint64 (reconnects, 0);
  gst_object_unref (pad);
  gst_object_unref (cam);

  /* into the next attempt (100-400 ms after the last failure), then NULL */
  g_usleep (G_USEC_PER_SEC / 2);
  const gdouble t = to_null (p);
  /* an attempt in progress is waited for (aravis: ~2.5 s for an address nobody answers) */
  fail_unless (t < 4.0, "%.2f s to NULL", t);
  g_print ("missing camera: %u retries, attempt %u, NULL in %.2f s\n", s.retries,
      s.max_attempt, t);
  g_free (s.error_text);
  gst_object_unref (p);
}

GST_END_TEST;

GST_START_TEST (test_eos_while_missing)
{
  if (!have_aravis ())
    return;
  GstElement *p = make_pipeline ("timeout=500 reconnect-interval=100");
  fail_if (gst_element_set_state (p, GST_STATE_PLAYING) == GST_STATE_CHANGE_FAILURE);
  Seen s = { 0 };
  watch (p, &s, until_lost, 10);
  fail_unless_equals_int (s.lost, 1);
  const gint64 t0 = g_get_monotonic_time ();
  fail_unless (gst_element_send_event (p, gst_event_new_eos ()));
  watch (p, &s, until_eos, 10);
  fail_unless_equals_int (s.eos, 1);
  const gdouble t_eos = (g_get_monotonic_time () - t0) / 1e6;
  fail_unless (t_eos < 1.0, "EOS after %.2f s", t_eos);
  fail_unless_equals_int (s.errors, 0);
  const gdouble t = to_null (p);
  fail_unless (t < 4.0, "%.2f s to NULL", t);
  g_print ("EOS while missing: on the bus after %.3f s, NULL in %.2f s\n", t_eos, t);
  g_free (s.error_text);
  gst_object_unref (p);
}

GST_END_TEST;

GST_START_TEST (test_no_reconnect)
{
  if (!have_aravis ())
    return;
  GstElement *p = make_pipeline ("reconnect-interval=0");
  fail_if (gst_element_set_state (p, GST_STATE_PLAYING) == GST_STATE_CHANGE_FAILURE);
  Seen s = { 0 };
  watch (p, &s, until_error, 10);
  fail_unless_equals_int (s.errors, 1);
  fail_unless (strstr (s.error_text, "127.0.0.9") != NULL, "%s", s.error_text);
  fail_unless_equals_int (s.lost, 0);
  fail_unless_equals_int (s.warnings, 0);
  fail_unless (to_null (p) < 4.0);
  g_free (s.error_text);
  gst_object_unref (p);
}

GST_END_TEST;

/* A name no camera has: aravis's discovery finds no such device (with or without interfaces to
 * search) and, with no reconnecting, the error reaches the bus naming the camera. */
GST_START_TEST (test_unknown_camera_name)
{
  if (!have_aravis ())
    return;
  GstElement *p = gst_parse_launch ("treecamerasrc camera=no-such-camera-xyz "
      "reconnect-interval=0 ! fakesink", NULL);
  fail_unless (p != NULL);
  gst_element_set_state (p, GST_STATE_PLAYING);
  GstBus *bus = gst_element_get_bus (p);
  expect_bus_error_naming (bus, GST_MESSAGE_ERROR, 20 * GST_SECOND, GST_RESOURCE_ERROR,
      GST_RESOURCE_ERROR_NOT_FOUND, "\"no-such-camera-xyz\"", NULL);
  gst_object_unref (bus);
  fail_unless (to_null (p) < 4.0);
  gst_object_unref (p);
}

GST_END_TEST;

static Suite *
treecamerasrc_suite (void)
{
  Suite *s = suite_create ("treecamerasrc");
  TCase *tc = tcase_create ("general");
  tcase_set_timeout (tc, 60);
  suite_add_tcase (s, tc);
  tcase_add_test (tc, test_no_camera);
  tcase_add_test (tc, test_missing_camera_retries);
  tcase_add_test (tc, test_eos_while_missing);
  tcase_add_test (tc, test_no_reconnect);
  tcase_add_test (tc, test_unknown_camera_name);
  return s;
}

GST_CHECK_MAIN (treecamerasrc);
