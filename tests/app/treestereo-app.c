/* An application that embeds a treestereo pipeline, built with the installed header and
 * pkg-config file alone:
 *
 *   cc treestereo-app.c $(pkg-config --cflags --libs gsttreestereo-1.0) -o treestereo-app
 *
 * Two treetestsrc (a synthetic tree seen by a stereo rig) stand in for the cameras. The program
 * reads the tree metrics twice: from each buffer's GstTreeStereoMetricsMeta in a pad probe
 * behind treemetrics (where an application that forwards frames would read them), and from the
 * treemetrics bus messages (where an application that only wants the figures reads them). It
 * prints both and exits 0 when every frame was seen both ways, with a tree, and the two agree.
 *
 * Usage: treestereo-app [frames]   (default 3; the plugin must be on GST_PLUGIN_PATH or installed)
 */
#include <glib/gstdio.h>
#include <gst/gst.h>
#include <gst/treestereo/treestereo-meta.h>

#include <stdio.h>
#include <stdlib.h>

typedef struct {
  GstClockTime pts;
  gboolean tree_present;
  gdouble distance_m, height_m, width_m;
  guint n_points;
} Figures;

typedef struct {
  GMainLoop *loop;
  GMutex lock;
  GArray *from_meta;     /* Figures, written by the streaming thread (probe) */
  GArray *from_message;  /* Figures, written by the main loop (bus) */
  gboolean failed;
} App;

static Figures
figures_of (GstClockTime pts, const GstTreeStereoMetrics *m)
{
  Figures f = { pts, m->tree_present, m->distance_m, m->height_m, m->width_m, m->n_points };
  return f;
}

/* Streaming thread: every buffer leaving treemetrics carries the metrics meta. */
static GstPadProbeReturn
on_buffer (GstPad *pad, GstPadProbeInfo *info, gpointer user_data)
{
  App *app = user_data;
  GstBuffer *buf = GST_PAD_PROBE_INFO_BUFFER (info);
  GstTreeStereoMetricsMeta *meta = gst_buffer_get_tree_stereo_metrics_meta (buf);

  (void) pad;

  g_mutex_lock (&app->lock);
  if (meta) {
    Figures f = figures_of (GST_BUFFER_PTS (buf), &meta->metrics);
    g_array_append_val (app->from_meta, f);
  } else {
    fprintf (stderr, "a buffer without the metrics meta\n");
    app->failed = TRUE;
  }
  g_mutex_unlock (&app->lock);
  return GST_PAD_PROBE_OK;
}

/* Main loop: the treemetrics element messages, errors and the end of the stream. */
static gboolean
on_message (GstBus *bus, GstMessage *msg, gpointer user_data)
{
  App *app = user_data;
  const GstStructure *s = gst_message_get_structure (msg);

  (void) bus;

  switch (GST_MESSAGE_TYPE (msg)) {
    case GST_MESSAGE_ELEMENT:
      if (gst_structure_has_name (s, GST_TREE_STEREO_MESSAGE_TREEMETRICS)) {
        GstTreeStereoMetrics m = { 0 };
        GstTreeStereoTimes times;
        if (gst_tree_stereo_metrics_message_parse (s, &m, NULL, &times)) {
          Figures f = figures_of (times.timestamp, &m);
          g_array_append_val (app->from_message, f);
        } else {
          fprintf (stderr, "a malformed treemetrics message\n");
          app->failed = TRUE;
        }
        gst_tree_stereo_metrics_clear (&m);
      }
      break;
    case GST_MESSAGE_ERROR: {
      GError *err = NULL;
      gchar *dbg = NULL;
      gst_message_parse_error (msg, &err, &dbg);
      fprintf (stderr, "error from %s: %s\n%s\n", GST_OBJECT_NAME (msg->src), err->message,
          dbg ? dbg : "");
      g_clear_error (&err);
      g_free (dbg);
      app->failed = TRUE;
      g_main_loop_quit (app->loop);
      break;
    }
    case GST_MESSAGE_EOS:
      g_main_loop_quit (app->loop);
      break;
    default:
      break;
  }
  return TRUE;
}

static gboolean
on_timeout (gpointer user_data)
{
  App *app = user_data;
  fprintf (stderr, "timeout: the pipeline did not finish\n");
  app->failed = TRUE;
  g_main_loop_quit (app->loop);
  return G_SOURCE_REMOVE;
}

/* Runs a description to EOS (for the calibration writer); FALSE on an error. */
static gboolean
run_once (const gchar *desc)
{
  GstElement *p = gst_parse_launch (desc, NULL);
  GstMessage *msg;
  gboolean ok;

  if (!p)
    return FALSE;
  gst_element_set_state (p, GST_STATE_PLAYING);
  msg = gst_bus_timed_pop_filtered (GST_ELEMENT_BUS (p), 30 * GST_SECOND,
      GST_MESSAGE_EOS | GST_MESSAGE_ERROR);
  ok = msg && GST_MESSAGE_TYPE (msg) == GST_MESSAGE_EOS;
  if (msg)
    gst_message_unref (msg);
  gst_element_set_state (p, GST_STATE_NULL);
  gst_object_unref (p);
  return ok;
}

static gboolean
same (double a, double b)
{
  return a == b;  /* the meta and the message carry the same doubles, not recomputed ones */
}

int
main (int argc, char **argv)
{
  const int frames = argc > 1 ? atoi (argv[1]) : 3;
  const char *size = "video/x-raw,width=640,height=480";
  App app = { 0 };
  gchar *dir, *calib, *desc;
  GstElement *pipeline, *metrics;
  GstPad *pad;
  guint bus_watch;
  int i;

  gst_init (&argc, &argv);
  if (frames < 1) {
    fprintf (stderr, "usage: treestereo-app [frames >= 1]\n");
    return 2;
  }

  /* The rig's calibration: treetestsrc writes its true one (a real rig: treestereo-calibrate). */
  dir = g_dir_make_tmp ("treestereo-app-XXXXXX", NULL);
  calib = g_build_filename (dir, "rig.yml", NULL);
  desc = g_strdup_printf ("treetestsrc num-buffers=1 calibration-out=\"%s\" ! %s ! fakesink",
      calib, size);
  if (!dir || !run_once (desc)) {
    fprintf (stderr, "could not write the calibration (is the treestereo plugin found?)\n");
    return 1;
  }
  g_free (desc);

  desc = g_strdup_printf ("stereorectify name=r calibration=\"%s\" ! exgsegment ! siftmatch ! "
      "stereodepth ! treemetrics name=metrics ! fakesink "
      "treetestsrc view=left num-buffers=%d ! %s ! r.left "
      "treetestsrc view=right num-buffers=%d ! %s ! r.right", calib, frames, size, frames, size);
  pipeline = gst_parse_launch (desc, NULL);
  g_free (desc);
  if (!pipeline) {
    fprintf (stderr, "could not build the pipeline (is the treestereo plugin found?)\n");
    return 1;
  }

  g_mutex_init (&app.lock);
  app.loop = g_main_loop_new (NULL, FALSE);
  app.from_meta = g_array_new (FALSE, TRUE, sizeof (Figures));
  app.from_message = g_array_new (FALSE, TRUE, sizeof (Figures));

  metrics = gst_bin_get_by_name (GST_BIN (pipeline), "metrics");
  pad = gst_element_get_static_pad (metrics, "src");
  gst_pad_add_probe (pad, GST_PAD_PROBE_TYPE_BUFFER, on_buffer, &app, NULL);
  gst_object_unref (pad);
  gst_object_unref (metrics);
  bus_watch = gst_bus_add_watch (GST_ELEMENT_BUS (pipeline), on_message, &app);
  g_timeout_add_seconds (120, on_timeout, &app);

  gst_element_set_state (pipeline, GST_STATE_PLAYING);
  g_main_loop_run (app.loop);
  gst_element_set_state (pipeline, GST_STATE_NULL);

  /* Element messages are posted before the buffer leaves the element: all are in by EOS. */
  if (app.from_meta->len != (guint) frames || app.from_message->len != (guint) frames) {
    fprintf (stderr, "%u frames from the meta, %u messages, expected %d of each\n",
        app.from_meta->len, app.from_message->len, frames);
    app.failed = TRUE;
  }
  for (i = 0; i < (int) MIN (app.from_meta->len, app.from_message->len); i++) {
    const Figures *a = &g_array_index (app.from_meta, Figures, i);
    const Figures *b = &g_array_index (app.from_message, Figures, i);
    const gboolean agree = a->pts == b->pts && a->tree_present == b->tree_present &&
        same (a->distance_m, b->distance_m) && same (a->height_m, b->height_m) &&
        same (a->width_m, b->width_m) && a->n_points == b->n_points;
    printf ("%" GST_TIME_FORMAT "  tree %s  distance %.3f m  height %.3f m  width %.3f m  "
        "points %u  (meta and message %s)\n", GST_TIME_ARGS (a->pts),
        a->tree_present ? "yes" : "no", a->distance_m, a->height_m, a->width_m, a->n_points,
        agree ? "agree" : "DISAGREE");
    if (!agree || !a->tree_present)
      app.failed = TRUE;
  }

  g_source_remove (bus_watch);
  gst_object_unref (pipeline);
  g_array_free (app.from_meta, TRUE);
  g_array_free (app.from_message, TRUE);
  g_main_loop_unref (app.loop);
  g_mutex_clear (&app.lock);
  g_unlink (calib);
  g_rmdir (dir);
  g_free (calib);
  g_free (dir);
  return app.failed ? 1 : 0;
}
