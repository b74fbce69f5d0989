/* A program built against the installed treestereo meta library alone
 * (cc consumer.c $(pkg-config --cflags --libs gsttreestereo-1.0)): attaches every meta to a
 * buffer, reads each back from a copy of the buffer, and round-trips a treemetrics message. */
#include <gst/treestereo/treestereo-meta.h>

#include <stdio.h>

#define CHECK(cond)                                                  \
  do {                                                               \
    if (!(cond)) {                                                   \
      fprintf (stderr, "consumer: check failed: %s (line %d)\n", #cond, __LINE__); \
      return 1;                                                      \
    }                                                                \
  } while (0)

int
main (int argc, char **argv)
{
  GstBuffer *buf, *copy;
  GstTreeStereoGeometryMeta *g;
  GstTreeStereoVegetationMeta *v;
  GstTreeStereoMatch match = { 120.5f, 80.0f, 100.25f, 80.0f, 0.05f };
  GstTreeStereoPoint point = { -10.0f, 20.0f, 2100.0f, 0, TRUE };
  GstTreeStereoMetrics metrics = { 0 }, parsed = { 0 };
  GstTreeStereoTruth truth = { 0 };
  GstStructure *s;

  gst_init (&argc, &argv);
  buf = gst_buffer_new ();

  g = gst_buffer_add_tree_stereo_geometry_meta (buf);
  g->view_width = 640;
  g->baseline_mm = 50.0;
  v = gst_buffer_add_tree_stereo_vegetation_meta (buf, 2);
  v->views[0].present = TRUE;
  v->views[0].area_px = 1234.0;
  gst_buffer_add_tree_stereo_matches_meta (buf, GST_TREE_STEREO_MATCH_COSINE_NORM, 10, 12,
      &match, 1);
  gst_buffer_add_tree_stereo_points_meta (buf, &point, 1, NULL);
  metrics.tree_present = TRUE;
  metrics.distance_m = 2.1;
  gst_tree_stereo_metrics_set_n_bands (&metrics, 4);
  metrics.bands[3].width_m = 0.5;
  gst_buffer_add_tree_stereo_metrics_meta (buf, &metrics, NULL);
  truth.distance_m = 2.05;
  gst_buffer_add_tree_stereo_truth_meta (buf, &truth, NULL, NULL, 0, 0);

  copy = gst_buffer_copy (buf);
  CHECK (gst_buffer_get_tree_stereo_geometry_meta (copy)->view_width == 640);
  CHECK (gst_buffer_get_tree_stereo_geometry_meta (copy)->baseline_mm == 50.0);
  CHECK (gst_buffer_get_tree_stereo_vegetation_meta (copy)->views[0].area_px == 1234.0);
  CHECK (gst_buffer_get_tree_stereo_matches_meta (copy)->matches[0].xr == 100.25f);
  CHECK (gst_buffer_get_tree_stereo_points_meta (copy)->points[0].z == 2100.0f);
  CHECK (gst_buffer_get_tree_stereo_metrics_meta (copy)->metrics.bands[3].width_m == 0.5);
  CHECK (gst_buffer_get_tree_stereo_truth_meta (copy)->truth.distance_m == 2.05);

  s = gst_tree_stereo_metrics_message_structure (&metrics, NULL, NULL);
  CHECK (gst_tree_stereo_metrics_message_parse (s, &parsed, NULL, NULL));
  CHECK (parsed.distance_m == 2.1 && parsed.n_bands == 4);
  gst_structure_free (s);

  gst_tree_stereo_metrics_clear (&metrics);
  gst_tree_stereo_metrics_clear (&parsed);
  gst_buffer_unref (copy);
  gst_buffer_unref (buf);
  printf ("consumer: every meta attached and read back\n");
  return 0;
}
