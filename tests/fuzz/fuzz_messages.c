/* libFuzzer target: the element message parsers of the meta library (gst/meta). The input is
 * read as a serialized GstStructure (gst_structure_from_string); every parser gets it, and a
 * structure a parser accepts must come out of that parser's builder and parse again to the
 * same figures. A FALSE from a parser is the expected answer to a malformed structure; a
 * crash, a leak, undefined behaviour or a failed round trip is a bug. */
#include <gst/gst.h>
#include <gst/treestereo/treestereo-meta.h>

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static void
fail (const char *what)
{
  g_printerr ("round trip failed: %s\n", what);
  abort ();
}

static void
check_vegetation (const GstStructure * s)
{
  GstTreeStereoVegetationMeta m, m2;
  GstTreeStereoTimes t;
  GstStructure *again;

  memset (&m, 0, sizeof m);
  memset (&m2, 0, sizeof m2);
  if (gst_tree_stereo_vegetation_message_parse (s, &m, &t)) {
    again = gst_tree_stereo_vegetation_message_structure (&m, &t);
    if (!gst_tree_stereo_vegetation_message_parse (again, &m2, NULL))
      fail ("vegetation");
    if (m2.n_views != m.n_views || m2.views[0].present != m.views[0].present
        || m2.views[0].bbox_width != m.views[0].bbox_width)
      fail ("vegetation figures");
    gst_structure_free (again);
  }
  for (int i = 0; i < 2; i++) {
    gst_tree_stereo_vegetation_view_clear (&m.views[i]);
    gst_tree_stereo_vegetation_view_clear (&m2.views[i]);
  }
}

static void
check_match (const GstStructure * s)
{
  GstTreeStereoMatchStats st, st2;
  GstTreeStereoTimes t;
  GstStructure *again;

  memset (&st, 0, sizeof st);
  memset (&st2, 0, sizeof st2);
  if (!gst_tree_stereo_match_message_parse (s, &st, &t))
    return;
  again = gst_tree_stereo_match_message_structure (&st, &t);
  if (!gst_tree_stereo_match_message_parse (again, &st2, NULL))
    fail ("siftmatch");
  if (st2.matches != st.matches || st2.method != st.method)
    fail ("siftmatch figures");
  gst_structure_free (again);
}

static void
check_depth (const GstStructure * s)
{
  GstTreeStereoDepthStats st, st2;
  GstTreeStereoTimes t;
  gboolean dense = FALSE, dense2 = FALSE;
  GstStructure *again;

  memset (&st, 0, sizeof st);
  memset (&st2, 0, sizeof st2);
  if (!gst_tree_stereo_depth_message_parse (s, &dense, &st, &t))
    return;
  again = gst_tree_stereo_depth_message_structure (dense, &st, &t);
  if (!gst_tree_stereo_depth_message_parse (again, &dense2, &st2, NULL))
    fail ("stereodepth");
  if (dense2 != dense)
    fail ("stereodepth figures");
  gst_structure_free (again);
}

static void
check_metrics (const GstStructure * s)
{
  GstTreeStereoMetrics raw, smooth, raw2, smooth2;
  GstTreeStereoTimes t;
  GstStructure *again;

  memset (&raw, 0, sizeof raw);
  memset (&smooth, 0, sizeof smooth);
  memset (&raw2, 0, sizeof raw2);
  memset (&smooth2, 0, sizeof smooth2);
  if (gst_tree_stereo_metrics_message_parse (s, &raw, &smooth, &t)) {
    again = gst_tree_stereo_metrics_message_structure (&raw, &smooth, &t);
    if (!gst_tree_stereo_metrics_message_parse (again, &raw2, &smooth2, NULL))
      fail ("treemetrics");
    if (raw2.tree_present != raw.tree_present || raw2.n_bands != raw.n_bands)
      fail ("treemetrics figures");
    gst_structure_free (again);
  }
  /* without the smoothed half too: a different path through the parser */
  gst_tree_stereo_metrics_clear (&raw2);
  (void) gst_tree_stereo_metrics_message_parse (s, &raw2, NULL, NULL);
  gst_tree_stereo_metrics_clear (&raw);
  gst_tree_stereo_metrics_clear (&smooth);
  gst_tree_stereo_metrics_clear (&raw2);
  gst_tree_stereo_metrics_clear (&smooth2);
}

static void
check_tree (const GstStructure * s)
{
  GstTreeStereoTreeRecord r, r2;
  GstTreeStereoTimes t;
  GstStructure *again;

  memset (&r, 0, sizeof r);
  memset (&r2, 0, sizeof r2);
  if (gst_tree_stereo_tree_message_parse (s, &r, &t)) {
    again = gst_tree_stereo_tree_message_structure (&r, &t);
    if (!gst_tree_stereo_tree_message_parse (again, &r2, NULL))
      fail ("treestereo-tree");
    if (r2.id != r.id || r2.n_bands != r.n_bands || r2.has_depth != r.has_depth ||
        r2.has_spacing != r.has_spacing)
      fail ("treestereo-tree figures");
    gst_structure_free (again);
  }
  gst_tree_stereo_tree_record_clear (&r);
  gst_tree_stereo_tree_record_clear (&r2);
}

/* Real messages nest values two deep (an array of structures); GStreamer's own deserializer
 * recurses and leaks on malformed deeply nested values, which is not what this target tests. */
static gboolean
nesting_within (const gchar * text, int max_depth)
{
  int depth = 0;
  for (const gchar * c = text; *c; c++) {
    if (*c == '<' || *c == '{' || *c == '[' || *c == '(')
      depth++;
    else if (*c == '>' || *c == '}' || *c == ']' || *c == ')')
      depth--;
    if (depth > max_depth)
      return FALSE;
  }
  return TRUE;
}

int
LLVMFuzzerInitialize (int *argc, char ***argv)
{
  gst_init (NULL, NULL);
  return 0;
}

int
LLVMFuzzerTestOneInput (const uint8_t * data, size_t size)
{
  gchar *text = g_strndup ((const gchar *) data, size);
  GstStructure *s = nesting_within (text, 6) ? gst_structure_from_string (text, NULL) : NULL;

  g_free (text);
  if (!s)
    return 0;
  check_vegetation (s);
  check_match (s);
  check_depth (s);
  check_metrics (s);
  check_tree (s);
  gst_structure_free (s);
  return 0;
}
