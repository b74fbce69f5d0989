/* An application that reads spraycontrol's valve commands and prints each nozzle section's
 * valve timeline, built with the installed header and pkg-config file alone:
 *
 *   cc valve-timeline.c $(pkg-config --cflags --libs gsttreestereo-1.0) -o valve-timeline
 *
 * Two treetestsrc drive past the synthetic orchard at 2 m/s (a real rig: two cameras). The
 * "treestereo-section" messages (gst_tree_stereo_section_message_parse) come in on the bus; at
 * EOS the program prints them, then one line per section with the valve open (#) or closed (.)
 * for every 50 ms of running time, the form a valve controller would follow. It exits 0 when
 * commands came and every section's commands alternate on/off in time order.
 *
 * Usage: valve-timeline [frames]   (default 16; the plugin must be on GST_PLUGIN_PATH or installed)
 */
#include <glib/gstdio.h>
#include <gst/gst.h>
#include <gst/treestereo/treestereo-meta.h>

#include <stdio.h>
#include <stdlib.h>

#define STEP_NS (50 * GST_MSECOND)  /* one character of the timeline */

typedef struct {
  GMainLoop *loop;
  GArray *commands;  /* GstTreeStereoSectionCommand, in the order posted */
  gboolean failed;
} App;

static gboolean
on_message (GstBus * bus, GstMessage * msg, gpointer data)
{
  App *app = data;
  (void) bus;
  switch (GST_MESSAGE_TYPE (msg)) {
    case GST_MESSAGE_ELEMENT:{
      GstTreeStereoSectionCommand c;
      const GstStructure *s = gst_message_get_structure (msg);
      if (s && gst_structure_has_name (s, GST_TREE_STEREO_MESSAGE_SECTION) &&
          gst_tree_stereo_section_message_parse (s, &c))
        g_array_append_val (app->commands, c);
      break;
    }
    case GST_MESSAGE_WARNING:{
      GError *err = NULL;
      gst_message_parse_warning (msg, &err, NULL);
      fprintf (stderr, "warning: %s\n", err->message);  /* e.g. the fail-safe */
      g_error_free (err);
      break;
    }
    case GST_MESSAGE_ERROR:{
      GError *err = NULL;
      gst_message_parse_error (msg, &err, NULL);
      fprintf (stderr, "error: %s\n", err->message);
      g_error_free (err);
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

/* Runs a description to EOS (for the calibration writer); FALSE on an error. */
static gboolean
run_once (const gchar * desc)
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

/* Prints the commands and the timeline; FALSE when a section's commands do not alternate. */
static gboolean
print_timeline (const GArray * commands)
{
  guint n_sections = 0, i, k;
  gint64 end = 0;
  gboolean ok = TRUE;

  for (i = 0; i < commands->len; i++) {
    const GstTreeStereoSectionCommand *c =
        &g_array_index (commands, GstTreeStereoSectionCommand, i);
    printf ("section %u %-3s rate %.2f at %" G_GINT64_FORMAT " ns  for canopy at %.2f m%s\n",
        c->section, c->on ? "on" : "off", c->rate, c->at_ns, c->position_m,
        c->fallback ? "  (fail-safe)" : "");
    n_sections = MAX (n_sections, c->section + 1);
    end = MAX (end, c->at_ns);
  }
  printf ("\nvalves, one character per %d ms of running time (# open, . closed):\n",
      (int) (STEP_NS / GST_MSECOND));
  for (k = n_sections; k-- > 0;) {  /* the highest section on top, as on the boom */
    GString *line = g_string_new (NULL);
    gboolean open = FALSE, seen = FALSE;
    gint64 t, last_at = G_MININT64;
    guint next = 0;
    for (t = 0; t <= end + (gint64) STEP_NS; t += STEP_NS) {
      for (; next < commands->len; next++) {
        const GstTreeStereoSectionCommand *c =
            &g_array_index (commands, GstTreeStereoSectionCommand, next);
        if (c->section != k)
          continue;
        if (c->at_ns > t)
          break;
        if (!c->fallback && c->at_ns <= last_at)
          ok = FALSE;  /* out of time order */
        if (!c->fallback && seen && c->on == open && c->rate == (open ? 1.0 : 0.0))
          ok = FALSE;  /* the same state twice (on/off model) */
        open = c->on;
        last_at = c->at_ns;
        seen = TRUE;
      }
      g_string_append_c (line, open ? '#' : '.');
    }
    printf ("section %u |%s|\n", k, line->str);
    g_string_free (line, TRUE);
  }
  return ok;
}

int
main (int argc, char **argv)
{
  const int frames = argc > 1 ? atoi (argv[1]) : 16;
  const char *size = "video/x-raw,width=640,height=480";
  const char *src = "treetestsrc scene=orchard speed=2";
  App app = { 0 };
  gchar *dir, *calib, *desc;
  GstElement *pipeline;
  guint bus_watch;

  gst_init (&argc, &argv);
  if (frames < 2) {
    fprintf (stderr, "usage: valve-timeline [frames >= 2]\n");
    return 2;
  }

  dir = g_dir_make_tmp ("valve-timeline-XXXXXX", NULL);
  calib = g_build_filename (dir, "rig.yml", NULL);
  desc = g_strdup_printf ("%s num-buffers=1 calibration-out=\"%s\" ! %s ! fakesink", src, calib,
      size);
  if (!dir || !run_once (desc)) {
    fprintf (stderr, "could not write the calibration (is the treestereo plugin found?)\n");
    return 1;
  }
  g_free (desc);

  desc = g_strdup_printf ("stereorectify name=r calibration=\"%s\" ! exgsegment ! siftmatch ! "
      "stereodepth ! treemetrics ! spraycontrol nozzle-offset=1.5 valve-latency=160 ! "
      "fakesink sync=false "
      "%s view=left num-buffers=%d ! %s ! r.left %s view=right num-buffers=%d ! %s ! r.right",
      calib, src, frames, size, src, frames, size);
  pipeline = gst_parse_launch (desc, NULL);
  g_free (desc);
  if (!pipeline) {
    fprintf (stderr, "could not build the pipeline (is the treestereo plugin found?)\n");
    return 1;
  }

  app.loop = g_main_loop_new (NULL, FALSE);
  app.commands = g_array_new (FALSE, TRUE, sizeof (GstTreeStereoSectionCommand));
  bus_watch = gst_bus_add_watch (GST_ELEMENT_BUS (pipeline), on_message, &app);
  gst_element_set_state (pipeline, GST_STATE_PLAYING);
  g_main_loop_run (app.loop);
  gst_element_set_state (pipeline, GST_STATE_NULL);

  if (!app.failed && app.commands->len == 0) {
    fprintf (stderr, "no section command in %d frames\n", frames);
    app.failed = TRUE;
  }
  if (!app.failed && !print_timeline (app.commands)) {
    fprintf (stderr, "a section's commands do not alternate in time order\n");
    app.failed = TRUE;
  }

  g_source_remove (bus_watch);
  gst_object_unref (pipeline);
  g_array_free (app.commands, TRUE);
  g_main_loop_unref (app.loop);
  g_unlink (calib);
  g_rmdir (dir);
  g_free (calib);
  g_free (dir);
  return app.failed ? 1 : 0;
}
