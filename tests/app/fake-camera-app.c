/* An application driving the whole chain from an in-process Aravis camera: aravis's Fake
 * interface (arv_enable_interface ("Fake"), camera "Fake_1", 512x512 Mono8) is enabled in this
 * process, so aravissrc, loaded into the same process, finds it without any network. The one
 * camera feeds both pads of stereorectify through a tee; the test proves the in-process live
 * plumbing (camera -> pairing -> every analysis element -> messages), not the measurement.
 *
 *   fake-camera-app CALIBRATION.yml N
 * Exit 0 when N pairs went through with a treemetrics message each and nothing was dropped;
 * 77 when aravissrc is not installed. */
#include <arv.h>
#include <gst/gst.h>
#include <gst/treestereo/treestereo-meta.h>

#include <stdio.h>
#include <stdlib.h>

int
main (int argc, char **argv)
{
  GstElement *pipeline, *rect;
  GstBus *bus;
  GError *err = NULL;
  gchar *desc;
  guint n, metrics = 0, matches = 0;
  guint64 dropped = 0, paired = 0;
  gboolean eos = FALSE, failed = FALSE;

  gst_init (&argc, &argv);
  if (argc != 3) {
    fprintf (stderr, "usage: fake-camera-app CALIBRATION.yml N\n");
    return 2;
  }
  n = (guint) atoi (argv[2]);
  if (!gst_element_factory_find ("aravissrc")) {
    printf ("SKIP: aravissrc is not installed (gstreamer1.0-plugins-bad / libaravis)\n");
    return 77;
  }

  arv_enable_interface ("Fake");

  desc = g_strdup_printf ("stereorectify name=r calibration=\"%s\" latency=200000000 ! "
      "exgsegment ! siftmatch ! stereodepth ! treemetrics ! fakesink sync=false "
      "aravissrc camera-name=Fake_1 num-buffers=%u do-timestamp=true ! videoconvert ! "
      "video/x-raw,format=RGB ! tee name=t ! queue ! r.left t. ! queue ! r.right", argv[1], n);
  pipeline = gst_parse_launch (desc, &err);
  g_free (desc);
  if (!pipeline || err) {
    fprintf (stderr, "fake-camera-app: %s\n", err ? err->message : "no pipeline");
    return 1;
  }
  rect = gst_bin_get_by_name (GST_BIN (pipeline), "r");
  bus = gst_element_get_bus (pipeline);
  gst_element_set_state (pipeline, GST_STATE_PLAYING);

  while (!eos && !failed) {
    GstMessage *msg = gst_bus_timed_pop (bus, 30 * GST_SECOND);
    const GstStructure *s;

    if (!msg) {
      fprintf (stderr, "fake-camera-app: no message for 30 s\n");
      failed = TRUE;
      break;
    }
    switch (GST_MESSAGE_TYPE (msg)) {
      case GST_MESSAGE_ELEMENT:
        s = gst_message_get_structure (msg);
        if (gst_structure_has_name (s, GST_TREE_STEREO_MESSAGE_TREEMETRICS)) {
          GstTreeStereoMetrics m = { 0 };
          if (!gst_tree_stereo_metrics_message_parse (s, &m, NULL, NULL)) {
            fprintf (stderr, "fake-camera-app: malformed treemetrics message\n");
            failed = TRUE;
          }
          gst_tree_stereo_metrics_clear (&m);
          metrics++;
        } else if (gst_structure_has_name (s, GST_TREE_STEREO_MESSAGE_SIFTMATCH)) {
          matches++;
        }
        break;
      case GST_MESSAGE_ERROR:{
        gchar *dbg = NULL;
        gst_message_parse_error (msg, &err, &dbg);
        fprintf (stderr, "fake-camera-app: error: %s (%s)\n", err->message, dbg);
        g_clear_error (&err);
        g_free (dbg);
        failed = TRUE;
        break;
      }
      case GST_MESSAGE_EOS:
        eos = TRUE;
        break;
      default:
        break;
    }
    gst_message_unref (msg);
  }
  g_object_get (rect, "dropped", &dropped, "paired", &paired, NULL);
  gst_element_set_state (pipeline, GST_STATE_NULL);
  gst_object_unref (bus);
  gst_object_unref (rect);
  gst_object_unref (pipeline);

  printf ("fake-camera-app: %u frames from Fake_1, %" G_GUINT64_FORMAT " pairs, %"
      G_GUINT64_FORMAT " dropped, %u siftmatch and %u treemetrics messages\n", n, paired,
      dropped, matches, metrics);
  if (failed || paired != n || dropped != 0 || metrics != n || matches != n)
    return 1;
  return 0;
}
