/* Unit tests of the meta library: add, get, copy with gst_buffer_copy (every field), scale
 * transform, free, and the element messages' round trip. */
#include <math.h>
#include <gst/check/gstcheck.h>
#include <gst/treestereo/treestereo-meta.h>

#include <string.h>

static void
fill_geometry (GstTreeStereoGeometryMeta * g)
{
  g->view_width = 640;
  g->view_height = 480;
  g->side_by_side = TRUE;
  g->rectified = TRUE;
  g->fx[0] = g->fx[1] = 865.25;
  g->fy[0] = g->fy[1] = 866.5;
  g->cx[0] = 320.5;
  g->cx[1] = 318.25;
  g->cy[0] = g->cy[1] = 240.75;
  g->baseline_mm = 50.0;
  for (int i = 0; i < 16; i++)
    g->Q[i] = 0.5 * i;
  for (int i = 0; i < 9; i++)
    g->R1[i] = (i % 4 == 0) ? 1.0 : 0.001 * i;
  g->pts[0] = 40 * GST_MSECOND;
  g->pts[1] = 41 * GST_MSECOND;
  g->skew_ns = GST_MSECOND;
}

/* Applies a video scale transform from in_w x in_h to out_w x out_h onto a new buffer. */
static GstBuffer *
scale_buffer (GstBuffer * in, gint in_w, gint in_h, gint out_w, gint out_h)
{
  GstVideoInfo in_info, out_info;
  GstVideoMetaTransform trans = { &in_info, &out_info };
  GstBuffer *out = gst_buffer_new ();
  gpointer state = NULL;
  GstMeta *meta;

  gst_video_info_set_format (&in_info, GST_VIDEO_FORMAT_RGB, in_w, in_h);
  gst_video_info_set_format (&out_info, GST_VIDEO_FORMAT_RGB, out_w, out_h);
  while ((meta = gst_buffer_iterate_meta (in, &state))) {
    if (meta->info->transform_func)
      meta->info->transform_func (out, meta, in, gst_video_meta_transform_scale_get_quark (),
          &trans);
  }
  return out;
}

GST_START_TEST (test_geometry_meta)
{
  GstBuffer *buf = gst_buffer_new (), *copy, *scaled;
  GstTreeStereoGeometryMeta *g, *c;

  g = gst_buffer_add_tree_stereo_geometry_meta (buf);
  fail_unless (g != NULL);
  fail_unless_equals_uint64 (g->pts[0], GST_CLOCK_TIME_NONE);
  fail_unless_equals_int (g->view_width, 0);
  fill_geometry (g);
  fail_unless (gst_buffer_get_tree_stereo_geometry_meta (buf) == g);
  fail_unless (gst_meta_api_type_has_tag (GST_TREE_STEREO_GEOMETRY_META_API_TYPE,
          g_quark_from_static_string (GST_META_TAG_VIDEO_SIZE_STR)));

  copy = gst_buffer_copy (buf);
  c = gst_buffer_get_tree_stereo_geometry_meta (copy);
  fail_unless (c != NULL && c != g);
  fail_unless (memcmp ((guint8 *) c + sizeof (GstMeta), (guint8 *) g + sizeof (GstMeta),
          sizeof (*g) - sizeof (GstMeta)) == 0);
  fail_unless_equals_float (gst_tree_stereo_geometry_meta_doffs (c), 2.25);

  /* side-by-side 1280x480 scaled to 640x240: everything in pixels halves */
  scaled = scale_buffer (buf, 1280, 480, 640, 240);
  c = gst_buffer_get_tree_stereo_geometry_meta (scaled);
  fail_unless (c != NULL);
  fail_unless_equals_int (c->view_width, 320);
  fail_unless_equals_int (c->view_height, 240);
  fail_unless_equals_float (c->fx[0], 865.25 / 2);
  fail_unless_equals_float (c->cx[1], 318.25 / 2);
  fail_unless_equals_float (c->baseline_mm, 50.0);
  /* Q stays consistent: depth of disparity d' = d/2 equals depth of d at full size */
  {
    gdouble d = 20.0, z_full, z_half;
    z_full = g->fx[0] * g->baseline_mm / (d - (g->cx[0] - g->cx[1]));
    z_half = c->Q[11] / (c->Q[14] * (d / 2) + c->Q[15]);
    fail_unless (fabs (z_full - z_half) < 1e-9 * z_full);
  }
  gst_buffer_unref (scaled);
  gst_buffer_unref (copy);
  gst_buffer_unref (buf);
}

GST_END_TEST;

static GstBuffer *
make_mask (guint w, guint h, guint stride)
{
  GstBuffer *mask = gst_buffer_new_allocate (NULL, (gsize) stride * h, NULL);
  GstMapInfo map;
  gst_buffer_map (mask, &map, GST_MAP_WRITE);
  memset (map.data, 0, map.size);
  /* left half canopy */
  for (guint y = 0; y < h; y++)
    memset (map.data + y * stride, 255, w / 2);
  gst_buffer_unmap (mask, &map);
  return mask;
}

GST_START_TEST (test_vegetation_meta)
{
  GstBuffer *buf = gst_buffer_new (), *copy, *scaled, *mask = make_mask (64, 48, 64);
  GstTreeStereoVegetationMeta *v, *c;
  gint32 contour[] = { 0, 0, 31, 0, 31, 47, 0, 47 };
  GstMapInfo map;

  v = gst_buffer_add_tree_stereo_vegetation_meta (buf, 2);
  fail_unless (v != NULL);
  fail_unless_equals_int (v->n_views, 2);
  v->index = GST_TREE_STEREO_INDEX_EXG_EXR;
  for (guint i = 0; i < 2; i++) {
    GstTreeStereoVegetationView *w = &v->views[i];
    w->present = TRUE;
    w->threshold = 12.5 + i;
    w->area_px = 1536;
    w->perimeter_px = 158;
    w->complexity = 1.29;
    w->centroid_x = 15.5 + i;
    w->centroid_y = 23.5;
    w->bbox_x = 0;
    w->bbox_y = 0;
    w->bbox_width = 32;
    w->bbox_height = 48;
    w->n_regions = 1;
    gst_tree_stereo_vegetation_view_set_contour (w, contour, 4);
    gst_tree_stereo_vegetation_view_set_mask (w, mask, 64, 48, 64);
  }
  gst_buffer_unref (mask);

  copy = gst_buffer_copy (buf);
  c = gst_buffer_get_tree_stereo_vegetation_meta (copy);
  fail_unless (c != NULL && c != v);
  fail_unless_equals_int (c->index, GST_TREE_STEREO_INDEX_EXG_EXR);
  for (guint i = 0; i < 2; i++) {
    fail_unless (c->views[i].present);
    fail_unless_equals_float (c->views[i].threshold, 12.5 + i);
    fail_unless_equals_float (c->views[i].area_px, 1536);
    fail_unless_equals_float (c->views[i].perimeter_px, 158);
    fail_unless_equals_float (c->views[i].complexity, 1.29);
    fail_unless_equals_float (c->views[i].centroid_x, 15.5 + i);
    fail_unless_equals_float (c->views[i].centroid_y, 23.5);
    fail_unless_equals_int (c->views[i].bbox_width, 32);
    fail_unless_equals_int (c->views[i].bbox_height, 48);
    fail_unless_equals_int (c->views[i].n_regions, 1);
    fail_unless_equals_int (c->views[i].n_contour, 4);
    fail_unless (c->views[i].contour != v->views[i].contour);
    fail_unless (memcmp (c->views[i].contour, contour, sizeof contour) == 0);
    fail_unless (c->views[i].mask == v->views[i].mask);
    fail_unless_equals_int (c->views[i].mask_width, 64);
  }

  scaled = scale_buffer (buf, 128, 48, 64, 24);
  c = gst_buffer_get_tree_stereo_vegetation_meta (scaled);
  fail_unless (c != NULL);
  fail_unless_equals_float (c->views[0].area_px, 1536 / 4.0);
  fail_unless_equals_float (c->views[0].centroid_x, 15.5 / 2);
  fail_unless_equals_int (c->views[0].contour[2], 16);
  fail_unless_equals_int (c->views[0].mask_width, 32);
  fail_unless_equals_int (c->views[0].mask_height, 24);
  fail_unless (gst_buffer_map (c->views[0].mask, &map, GST_MAP_READ));
  fail_unless_equals_int (map.size, 32 * 24);
  fail_unless_equals_int (map.data[5 * 32 + 15], 255);
  fail_unless_equals_int (map.data[5 * 32 + 16], 0);
  gst_buffer_unmap (c->views[0].mask, &map);

  gst_buffer_unref (scaled);
  gst_buffer_unref (copy);
  gst_buffer_unref (buf);
}

GST_END_TEST;

GST_START_TEST (test_matches_and_points_meta)
{
  GstBuffer *buf = gst_buffer_new (), *copy, *scaled, *depth;
  GstTreeStereoMatch m[3] = { {10, 20, 5, 20.5f, 0.1f}, {100, 200, 90, 200, 0.2f},
  {1, 2, 0.5f, 2, 0.3f}
  };
  GstTreeStereoPoint p[2] = { {-100, 50, 2000, 0, TRUE}, {10, 20, 5000, 2, FALSE} };
  GstTreeStereoDepthStats st = { 2, 1, 1, 0, 2000, 0, 2000, 2000, 0, 2000, 2000 };
  GstTreeStereoMatchesMeta *mm, *mc;
  GstTreeStereoPointsMeta *pm, *pc;

  mm = gst_buffer_add_tree_stereo_matches_meta (buf, GST_TREE_STEREO_MATCH_COSINE_NORM, 300,
      280, m, 3);
  fail_unless (mm != NULL && mm->matches != m);
  pm = gst_buffer_add_tree_stereo_points_meta (buf, p, 2, &st);
  depth = gst_buffer_new_allocate (NULL, 8 * 4 * 2, NULL);
  gst_tree_stereo_points_meta_set_depth_map (pm, depth, 3, 4, 8, 4, 16);
  gst_buffer_unref (depth);
  pm->dense = TRUE;

  copy = gst_buffer_copy (buf);
  mc = gst_buffer_get_tree_stereo_matches_meta (copy);
  fail_unless (mc != NULL && mc != mm);
  fail_unless_equals_int (mc->method, GST_TREE_STEREO_MATCH_COSINE_NORM);
  fail_unless_equals_int (mc->n_keypoints[0], 300);
  fail_unless_equals_int (mc->n_keypoints[1], 280);
  fail_unless_equals_int (mc->n_matches, 3);
  fail_unless (memcmp (mc->matches, m, sizeof m) == 0);
  pc = gst_buffer_get_tree_stereo_points_meta (copy);
  fail_unless (pc != NULL && pc != pm);
  fail_unless_equals_int (pc->n_points, 2);
  fail_unless (memcmp (pc->points, p, sizeof p) == 0);
  fail_unless (memcmp (&pc->stats, &st, sizeof st) == 0);
  fail_unless (pc->dense);
  fail_unless (pc->depth_map == pm->depth_map);
  fail_unless_equals_int (pc->depth_x, 3);
  fail_unless_equals_int (pc->depth_y, 4);
  fail_unless_equals_int (pc->depth_stride, 16);

  scaled = scale_buffer (buf, 200, 100, 400, 200);
  mc = gst_buffer_get_tree_stereo_matches_meta (scaled);
  fail_unless_equals_float (mc->matches[1].xl, 200);
  fail_unless_equals_float (mc->matches[1].yr, 400);
  fail_unless_equals_float (mc->matches[1].score, 0.2f);
  pc = gst_buffer_get_tree_stereo_points_meta (scaled);
  fail_unless_equals_float (pc->points[0].z, 2000);
  fail_unless (pc->depth_map == NULL);

  gst_buffer_unref (scaled);
  gst_buffer_unref (copy);
  gst_buffer_unref (buf);
}

GST_END_TEST;

static void
fill_metrics (GstTreeStereoMetrics * m, gdouble k)
{
  memset (m, 0, sizeof (*m));
  m->tree_present = TRUE;
  m->distance_m = 2.0 * k;
  m->height_m = 1.215 * k;
  m->width_m = 0.48 * k;
  m->thickness_m = 0.3 * k;
  m->area_m2 = 0.45 * k;
  m->perimeter_m = 3.1 * k;
  m->complexity = 1.7 * k;
  m->centroid_m[0] = -0.1 * k;
  m->centroid_m[1] = 0.2 * k;
  m->centroid_m[2] = 2.1 * k;
  m->clipped = GST_TREE_STEREO_CLIPPED_TOP | GST_TREE_STEREO_CLIPPED_RIGHT;
  m->n_points = 321;
  m->n_matches = 400;
  m->confidence = 0.93 * k;
  m->canopy_mode = GST_TREE_STEREO_CANOPY_TREE;
  /* one travel per frame, raw and smoothed alike */
  m->travel_m = 0.1425;
  m->position_m = 3.5;
  m->travel_source = GST_TREE_STEREO_TRAVEL_STEREO;
  m->row_direction[0] = 0.9962;
  m->row_direction[1] = 0.0087;
  m->row_direction[2] = 0.0868;
  gst_tree_stereo_metrics_set_n_bands (m, 4);
  for (guint i = 0; i < 4; i++) {
    m->bands[i].present = i != 2;
    m->bands[i].top_m = -0.6 + 0.3 * i;
    m->bands[i].bottom_m = -0.3 + 0.3 * i;
    m->bands[i].left_m = -0.2 * k;
    m->bands[i].right_m = 0.25 * k;
    m->bands[i].width_m = 0.45 * k;
    m->bands[i].depth_m = 1.9 + 0.01 * i;
    m->bands[i].fill = i != 2 ? 0.6 + 0.1 * i * k : 0.0;
  }
}

static void
assert_metrics_equal (const GstTreeStereoMetrics * a, const GstTreeStereoMetrics * b)
{
  fail_unless_equals_int (a->tree_present, b->tree_present);
  fail_unless_equals_float (a->distance_m, b->distance_m);
  fail_unless_equals_float (a->height_m, b->height_m);
  fail_unless_equals_float (a->width_m, b->width_m);
  fail_unless_equals_float (a->thickness_m, b->thickness_m);
  fail_unless_equals_float (a->area_m2, b->area_m2);
  fail_unless_equals_float (a->perimeter_m, b->perimeter_m);
  fail_unless_equals_float (a->complexity, b->complexity);
  for (int i = 0; i < 3; i++)
    fail_unless_equals_float (a->centroid_m[i], b->centroid_m[i]);
  fail_unless_equals_int (a->clipped, b->clipped);
  fail_unless_equals_int (a->n_points, b->n_points);
  fail_unless_equals_int (a->n_matches, b->n_matches);
  fail_unless_equals_float (a->confidence, b->confidence);
  fail_unless_equals_int (a->canopy_mode, b->canopy_mode);
  fail_unless_equals_float (a->travel_m, b->travel_m);
  fail_unless_equals_float (a->position_m, b->position_m);
  fail_unless_equals_int (a->travel_source, b->travel_source);
  for (int i = 0; i < 3; i++)
    fail_unless_equals_float (a->row_direction[i], b->row_direction[i]);
  fail_unless_equals_int (a->n_bands, b->n_bands);
  for (guint i = 0; i < a->n_bands; i++)
    fail_unless_equals_float (a->bands[i].fill, b->bands[i].fill);
  if (a->n_bands)
    fail_unless (memcmp (a->bands, b->bands, sizeof (GstTreeStereoBand) * a->n_bands) == 0);
}

GST_START_TEST (test_metrics_and_truth_meta)
{
  GstBuffer *buf = gst_buffer_new (), *copy, *scaled, *mask;
  GstTreeStereoMetrics raw, smooth;
  GstTreeStereoMetricsMeta *mm, *mc;
  GstTreeStereoTruth t = { GST_TREE_STEREO_RIGHT, 7, 42, 2.05, 1.9, 2.3, 0.4, 1.2, 0.9, 2.3,
    {0.01, -0.2, 2.1}, 0.35, 50.0
  };
  GstTreeStereoTruthMeta *tm, *tc;

  fill_metrics (&raw, 1.0);
  fill_metrics (&smooth, 1.01);
  mm = gst_buffer_add_tree_stereo_metrics_meta (buf, &raw, &smooth);
  fail_unless (mm != NULL && mm->metrics.bands != raw.bands);
  mask = gst_buffer_new_allocate (NULL, 16, NULL);
  tm = gst_buffer_add_tree_stereo_truth_meta (buf, &t, NULL, mask, 4, 4);
  fail_unless (tm != NULL);
  gst_buffer_unref (mask);

  copy = gst_buffer_copy (buf);
  mc = gst_buffer_get_tree_stereo_metrics_meta (copy);
  fail_unless (mc != NULL && mc != mm);
  assert_metrics_equal (&mc->metrics, &raw);
  assert_metrics_equal (&mc->smoothed, &smooth);
  fail_unless (mc->metrics.bands != mm->metrics.bands);
  tc = gst_buffer_get_tree_stereo_truth_meta (copy);
  fail_unless (tc != NULL && tc != tm);
  fail_unless (memcmp (&tc->truth, &t, sizeof t) == 0);
  fail_unless (tc->mask == tm->mask && tc->depth == NULL);
  fail_unless_equals_int (tc->width, 4);

  /* metres survive a scale unchanged; per-pixel truth maps do not */
  scaled = scale_buffer (buf, 100, 100, 50, 50);
  mc = gst_buffer_get_tree_stereo_metrics_meta (scaled);
  fail_unless (mc != NULL);
  assert_metrics_equal (&mc->metrics, &raw);
  tc = gst_buffer_get_tree_stereo_truth_meta (scaled);
  fail_unless (tc != NULL && tc->mask == NULL);
  fail_unless_equals_float (tc->truth.distance_m, 2.05);

  /* no smoothed given: the smoothed figures equal the raw ones */
  gst_buffer_unref (scaled);
  scaled = gst_buffer_new ();
  mc = gst_buffer_add_tree_stereo_metrics_meta (scaled, &raw, NULL);
  assert_metrics_equal (&mc->smoothed, &raw);

  gst_tree_stereo_metrics_clear (&raw);
  gst_tree_stereo_metrics_clear (&smooth);
  fail_unless (raw.bands == NULL && raw.n_bands == 0 && !raw.tree_present);
  gst_buffer_unref (scaled);
  gst_buffer_unref (copy);
  gst_buffer_unref (buf);
}

GST_END_TEST;

GST_START_TEST (test_metrics_message_round_trip)
{
  GstTreeStereoMetrics raw, smooth, r2 = { 0 }, s2 = { 0 };
  GstTreeStereoTimes t = { 5 * GST_SECOND, 4 * GST_SECOND, 3 * GST_SECOND }, t2;
  GstStructure *s;
  gchar *str;

  fill_metrics (&raw, 1.0);
  fill_metrics (&smooth, 0.99);
  s = gst_tree_stereo_metrics_message_structure (&raw, &smooth, &t);
  fail_unless (gst_structure_has_name (s, "treemetrics"));
  /* serialisable, as gst-launch -m prints it */
  str = gst_structure_to_string (s);
  fail_unless (strstr (str, "distance=(double)2") != NULL);
  fail_unless (strstr (str, "clipped-top=(boolean)true") != NULL);
  fail_unless (strstr (str, "canopy-mode=(string)tree") != NULL);
  fail_unless (strstr (str, "smoothed-canopy-mode=(string)tree") != NULL);
  fail_unless (strstr (str, "confidence=(double)0.9") != NULL);
  fail_unless (strstr (str, "smoothed-confidence=(double)") != NULL);
  fail_unless (strstr (str, "fill\\=\\(double\\)0.") != NULL);
  fail_unless (strstr (str, "travel-source=(string)stereo") != NULL);
  fail_unless (strstr (str, "smoothed-travel") == NULL);
  g_free (str);
  fail_unless (gst_tree_stereo_metrics_message_parse (s, &r2, &s2, &t2));
  assert_metrics_equal (&r2, &raw);
  assert_metrics_equal (&s2, &smooth);
  fail_unless_equals_uint64 (t2.timestamp, t.timestamp);
  fail_unless_equals_uint64 (t2.stream_time, t.stream_time);
  fail_unless_equals_uint64 (t2.running_time, t.running_time);
  /* the new figures are required: a message without them is malformed */
  {
    GstStructure *c = gst_structure_copy (s);
    gst_structure_remove_field (c, "confidence");
    fail_if (gst_tree_stereo_metrics_message_parse (c, &r2, NULL, NULL));
    gst_structure_free (c);
    c = gst_structure_copy (s);
    gst_structure_set (c, "canopy-mode", G_TYPE_STRING, "bogus", NULL);
    fail_if (gst_tree_stereo_metrics_message_parse (c, &r2, NULL, NULL));
    gst_structure_free (c);
    c = gst_structure_copy (s);
    gst_structure_set (c, "travel-source", G_TYPE_STRING, "bogus", NULL);
    fail_if (gst_tree_stereo_metrics_message_parse (c, &r2, NULL, NULL));
    gst_structure_free (c);
    c = gst_structure_copy (s);
    gst_structure_remove_field (c, "position-m");
    fail_if (gst_tree_stereo_metrics_message_parse (c, &r2, NULL, NULL));
    gst_structure_free (c);
    /* the row's direction is optional (older recordings): the x axis without it */
    c = gst_structure_copy (s);
    gst_structure_remove_fields (c, "row-direction-x", "row-direction-y", "row-direction-z",
        NULL);
    fail_unless (gst_tree_stereo_metrics_message_parse (c, &r2, NULL, NULL));
    fail_unless_equals_float (r2.row_direction[0], 1.0);
    fail_unless_equals_float (r2.row_direction[1], 0.0);
    fail_unless_equals_float (r2.row_direction[2], 0.0);
    gst_structure_free (c);
  }
  gst_structure_free (s);

  /* absent tree: no figures at all, and parsing gives zeros, not stale values; the travel is
   * there all the same (the rig moves between trees) */
  gst_tree_stereo_metrics_clear (&raw);
  raw.travel_m = 0.25;
  raw.position_m = 7.0;
  raw.travel_source = GST_TREE_STEREO_TRAVEL_SPEED;
  s = gst_tree_stereo_metrics_message_structure (&raw, NULL, NULL);
  fail_unless_equals_string (gst_structure_get_string (s, "travel-source"), "speed");
  fail_unless (!gst_structure_has_field (s, "distance"));
  fail_unless (!gst_structure_has_field (s, "bands"));
  fail_unless (!gst_structure_has_field (s, "confidence"));
  fail_unless_equals_string (gst_structure_get_string (s, "canopy-mode"), "colour");
  fail_unless (gst_tree_stereo_metrics_message_parse (s, &r2, NULL, &t2));
  fail_if (r2.tree_present);
  fail_unless_equals_float (r2.distance_m, 0.0);
  fail_unless_equals_float (r2.confidence, 0.0);
  fail_unless (r2.bands == NULL);
  fail_unless_equals_float (r2.travel_m, 0.25);
  fail_unless_equals_float (r2.position_m, 7.0);
  fail_unless_equals_int (r2.travel_source, GST_TREE_STEREO_TRAVEL_SPEED);
  fail_unless_equals_uint64 (t2.timestamp, GST_CLOCK_TIME_NONE);
  gst_structure_free (s);
  raw.travel_m = raw.position_m = 0;
  raw.travel_source = GST_TREE_STEREO_TRAVEL_NONE;

  /* absent tree in a 3D canopy mode: the mode still says what was looked for */
  raw.canopy_mode = GST_TREE_STEREO_CANOPY_ROW;
  s = gst_tree_stereo_metrics_message_structure (&raw, &raw, NULL);
  fail_unless (gst_tree_stereo_metrics_message_parse (s, &r2, &s2, NULL));
  fail_if (r2.tree_present);
  fail_unless_equals_int (r2.canopy_mode, GST_TREE_STEREO_CANOPY_ROW);
  fail_unless_equals_int (s2.canopy_mode, GST_TREE_STEREO_CANOPY_ROW);
  gst_structure_free (s);

  /* malformed: wrong name, a missing field */
  s = gst_structure_new ("treemetrics", "tree-present", G_TYPE_BOOLEAN, TRUE, NULL);
  fail_if (gst_tree_stereo_metrics_message_parse (s, &r2, NULL, NULL));
  gst_structure_set_name (s, "other");
  fail_if (gst_tree_stereo_metrics_message_parse (s, &r2, NULL, NULL));
  gst_structure_free (s);

  gst_tree_stereo_metrics_clear (&r2);
  gst_tree_stereo_metrics_clear (&s2);
  gst_tree_stereo_metrics_clear (&smooth);
}

GST_END_TEST;

static void
fill_canopy (GstTreeStereoCanopyMeta * c, GstBuffer * mask)
{
  gint32 contour[] = { 0, 0, 31, 0, 31, 47, 0, 47 };
  GstTreeStereoVegetationView *w = &c->view;

  w->present = TRUE;
  w->area_px = 1536;
  w->perimeter_px = 158;
  w->complexity = 1.29;
  w->centroid_x = 15.5;
  w->centroid_y = 23.5;
  w->bbox_width = 32;
  w->bbox_height = 48;
  w->n_regions = 1;
  gst_tree_stereo_vegetation_view_set_contour (w, contour, 4);
  gst_tree_stereo_vegetation_view_set_mask (w, mask, 64, 48, 64);
  c->near_m = 1.75;
  c->far_m = 2.65;
  c->zone_from_data = TRUE;
  c->ground_found = TRUE;
  c->ground_normal[0] = 0.01;
  c->ground_normal[1] = -0.99;
  c->ground_normal[2] = 0.14;
  c->ground_d_m = 1.2;
  c->n_segments = 3;
  c->left_m = -0.45;
  c->right_m = 0.5;
  c->n_points = 900;
  c->n_canopy_points = 610;
  c->n_seam_pixels = 77;
  c->n_stored_segments = 3;
  for (guint i = 0; i < 3; i++) {
    c->segments[i].lo_m = -1.5 + 1.1 * i;
    c->segments[i].hi_m = -0.9 + 1.1 * i;
    c->segments[i].near_m = 1.8 + 0.05 * i;
    c->segments[i].n_points = 100 + i;
    c->segments[i].selected = i == 1;
    c->segments[i].lo_z_m = 2.1 + 0.05 * i;
    c->segments[i].hi_z_m = 2.2 + 0.05 * i;
    c->segments[i].lo_clear_m = 0.03 + 0.1 * i;
    c->segments[i].hi_clear_m = -0.004 + 0.2 * i;
    c->segments[i].trunk_m = i == 1 ? -0.35 : NAN;
    c->segments[i].lo_y_m = -0.1 + 0.01 * i;
    c->segments[i].hi_y_m = -0.2 + 0.01 * i;
    c->segments[i].trunk_y_m = i == 1 ? 0.45 : 0.0;
  }
  c->cut_lo_m = -0.85;
  c->cut_hi_m = INFINITY;
}

static void
assert_canopy_figures_equal (const GstTreeStereoCanopyMeta * a, const GstTreeStereoCanopyMeta * b)
{
  fail_unless_equals_int (a->mode, b->mode);
  fail_unless_equals_float (a->near_m, b->near_m);
  fail_unless_equals_float (a->far_m, b->far_m);
  fail_unless_equals_int (a->zone_from_data, b->zone_from_data);
  fail_unless_equals_int (a->ground_found, b->ground_found);
  for (int i = 0; i < 3; i++)
    fail_unless_equals_float (a->ground_normal[i], b->ground_normal[i]);
  fail_unless_equals_float (a->ground_d_m, b->ground_d_m);
  fail_unless_equals_int (a->n_segments, b->n_segments);
  fail_unless_equals_float (a->left_m, b->left_m);
  fail_unless_equals_float (a->right_m, b->right_m);
  fail_unless_equals_int (a->n_points, b->n_points);
  fail_unless_equals_int (a->n_canopy_points, b->n_canopy_points);
  fail_unless_equals_int (a->n_seam_pixels, b->n_seam_pixels);
  fail_unless_equals_int (a->n_stored_segments, b->n_stored_segments);
  fail_unless (a->cut_lo_m == b->cut_lo_m && a->cut_hi_m == b->cut_hi_m);
  for (guint i = 0; i < a->n_stored_segments; i++) {
    fail_unless_equals_float (a->segments[i].lo_m, b->segments[i].lo_m);
    fail_unless_equals_float (a->segments[i].hi_m, b->segments[i].hi_m);
    fail_unless_equals_float (a->segments[i].near_m, b->segments[i].near_m);
    fail_unless_equals_int (a->segments[i].n_points, b->segments[i].n_points);
    fail_unless_equals_int (a->segments[i].selected, b->segments[i].selected);
    fail_unless_equals_float (a->segments[i].lo_z_m, b->segments[i].lo_z_m);
    fail_unless_equals_float (a->segments[i].hi_z_m, b->segments[i].hi_z_m);
    fail_unless_equals_float (a->segments[i].lo_clear_m, b->segments[i].lo_clear_m);
    fail_unless_equals_float (a->segments[i].hi_clear_m, b->segments[i].hi_clear_m);
    fail_unless (a->segments[i].trunk_m == b->segments[i].trunk_m ||
        (isnan (a->segments[i].trunk_m) && isnan (b->segments[i].trunk_m)));
    fail_unless_equals_float (a->segments[i].lo_y_m, b->segments[i].lo_y_m);
    fail_unless_equals_float (a->segments[i].hi_y_m, b->segments[i].hi_y_m);
    fail_unless_equals_float (a->segments[i].trunk_y_m, b->segments[i].trunk_y_m);
  }
}

GST_START_TEST (test_canopy_meta)
{
  GstBuffer *buf = gst_buffer_new (), *copy, *scaled, *mask = make_mask (64, 48, 64);
  GstTreeStereoCanopyMeta *c, *d;
  GstMapInfo map;

  c = gst_buffer_add_tree_stereo_canopy_meta (buf, GST_TREE_STEREO_CANOPY_TREE);
  fail_unless (c != NULL);
  fail_unless_equals_int (c->mode, GST_TREE_STEREO_CANOPY_TREE);
  fail_if (c->view.present);
  fail_unless (c->view.mask == NULL && c->view.contour == NULL);
  fail_unless_equals_float (c->near_m, 0.0);
  /* a segment's clearance from the view's edges and its trunk: unknown until given (0 would be
   * on the edge, on the optical axis) */
  fail_unless (isnan (c->segments[0].lo_clear_m) && isnan (c->segments[0].hi_clear_m));
  fail_unless (isnan (c->segments[GST_TREE_STEREO_MAX_SEGMENTS - 1].hi_clear_m));
  fail_unless (isnan (c->segments[0].trunk_m));
  fail_unless (isnan (c->segments[GST_TREE_STEREO_MAX_SEGMENTS - 1].trunk_m));
  /* no neighbour cut the tree's part of the row until said (0 would be the optical axis) */
  fail_unless (isinf (c->cut_lo_m) && c->cut_lo_m < 0);
  fail_unless (isinf (c->cut_hi_m) && c->cut_hi_m > 0);
  /* no row view until given (stereodepth gives one on a stream's first frame) */
  fail_if (c->row_view.present);
  fail_unless (c->row_view.mask == NULL && c->row_view.contour == NULL);
  fail_unless (gst_buffer_get_tree_stereo_canopy_meta (buf) == c);
  fail_unless (gst_meta_api_type_has_tag (GST_TREE_STEREO_CANOPY_META_API_TYPE,
          g_quark_from_static_string (GST_META_TAG_VIDEO_STR)));
  fail_unless (gst_meta_api_type_has_tag (GST_TREE_STEREO_CANOPY_META_API_TYPE,
          g_quark_from_static_string (GST_META_TAG_VIDEO_SIZE_STR)));
  fail_unless (gst_meta_api_type_has_tag (GST_TREE_STEREO_CANOPY_META_API_TYPE,
          g_quark_from_static_string (GST_META_TAG_VIDEO_ORIENTATION_STR)));
  fill_canopy (c, mask);
  /* the row view: the same mask, a wider box */
  c->row_view.present = TRUE;
  c->row_view.bbox_width = 64;
  c->row_view.bbox_height = 48;
  gst_tree_stereo_vegetation_view_set_mask (&c->row_view, mask, 64, 48, 64);
  gst_buffer_unref (mask);

  /* a copy: every figure, the contour copied, the mask shared */
  copy = gst_buffer_copy (buf);
  d = gst_buffer_get_tree_stereo_canopy_meta (copy);
  fail_unless (d != NULL && d != c);
  assert_canopy_figures_equal (d, c);
  fail_unless (d->view.present);
  fail_unless_equals_float (d->view.area_px, 1536);
  fail_unless_equals_float (d->view.perimeter_px, 158);
  fail_unless_equals_float (d->view.complexity, 1.29);
  fail_unless_equals_float (d->view.centroid_x, 15.5);
  fail_unless_equals_int (d->view.bbox_width, 32);
  fail_unless_equals_int (d->view.n_regions, 1);
  fail_unless_equals_int (d->view.n_contour, 4);
  fail_unless (d->view.contour != c->view.contour);
  fail_unless (memcmp (d->view.contour, c->view.contour, 8 * sizeof (gint32)) == 0);
  fail_unless (d->view.mask == c->view.mask);
  fail_unless_equals_int (d->view.mask_stride, 64);
  fail_unless (d->row_view.present && d->row_view.mask == c->row_view.mask);
  fail_unless_equals_int (d->row_view.bbox_width, 64);

  /* a scale (the side-by-side frame 128x48 to 64x24): the view's pixel figures and mask scale
   * as the vegetation meta's do, metres and counts stay */
  scaled = scale_buffer (buf, 128, 48, 64, 24);
  d = gst_buffer_get_tree_stereo_canopy_meta (scaled);
  fail_unless (d != NULL);
  assert_canopy_figures_equal (d, c);
  fail_unless_equals_float (d->view.area_px, 1536 / 4.0);
  fail_unless_equals_float (d->view.centroid_x, 15.5 / 2);
  fail_unless_equals_int (d->view.bbox_width, 16);
  fail_unless_equals_int (d->view.contour[2], 16);
  fail_unless_equals_int (d->view.mask_width, 32);
  fail_unless_equals_int (d->view.mask_height, 24);
  fail_unless (gst_buffer_map (d->view.mask, &map, GST_MAP_READ));
  fail_unless_equals_int (map.size, 32 * 24);
  fail_unless_equals_int (map.data[5 * 32 + 15], 255);
  fail_unless_equals_int (map.data[5 * 32 + 16], 0);
  gst_buffer_unmap (d->view.mask, &map);
  fail_unless (d->row_view.present);
  fail_unless_equals_int (d->row_view.bbox_width, 32);
  fail_unless_equals_int (d->row_view.mask_width, 32);
  fail_unless_equals_int (d->row_view.mask_height, 24);

  gst_buffer_unref (scaled);
  gst_buffer_unref (copy);
  gst_buffer_unref (buf);
}

GST_END_TEST;

static void
fill_record (GstTreeStereoTreeRecord * r)
{
  r->id = 7;
  r->mode = GST_TREE_STEREO_CANOPY_TREE;
  r->complete = TRUE;
  r->start_seen = TRUE;
  r->end_seen = TRUE;
  r->position_m = 12.345;
  r->start_m = 12.0;
  r->end_m = 12.69;
  r->has_height = TRUE;
  r->height_m = 0.91;
  r->has_width = TRUE;
  r->width_m = 0.69;
  r->has_depth = TRUE;
  r->distance_m = 1.86;
  r->thickness_m = 0.3;
  r->confidence = 0.97;
  gst_tree_stereo_tree_record_set_n_bands (r, 3);
  for (guint i = 0; i < 3; i++) {
    r->bands[i].present = i != 1;
    r->bands[i].top_m = -0.45 + 0.3 * i;
    r->bands[i].bottom_m = -0.15 + 0.3 * i;
    r->bands[i].left_m = 12.05;
    r->bands[i].right_m = 12.6 - 0.01 * i;
    r->bands[i].width_m = 0.55 - 0.01 * i;
    r->bands[i].depth_m = 1.77;
    r->bands[i].fill = i != 1 ? 0.9 : 0.0;
  }
  r->frames = 4;
  r->frames_seen = 11;
  r->has_spacing = TRUE;
  r->spacing_m = 1.06;
  r->gap_m = 0.4;
  r->lost = FALSE;
}

static void
assert_records_equal (const GstTreeStereoTreeRecord * a, const GstTreeStereoTreeRecord * b)
{
  fail_unless_equals_int (a->id, b->id);
  fail_unless_equals_int (a->mode, b->mode);
  fail_unless_equals_int (a->complete, b->complete);
  fail_unless_equals_int (a->start_seen, b->start_seen);
  fail_unless_equals_int (a->end_seen, b->end_seen);
  fail_unless_equals_float (a->position_m, b->position_m);
  fail_unless_equals_float (a->start_m, b->start_m);
  fail_unless_equals_float (a->end_m, b->end_m);
  fail_unless_equals_int (a->has_height, b->has_height);
  fail_unless_equals_float (a->height_m, b->height_m);
  fail_unless_equals_int (a->has_width, b->has_width);
  fail_unless_equals_float (a->width_m, b->width_m);
  fail_unless_equals_int (a->has_depth, b->has_depth);
  fail_unless_equals_float (a->distance_m, b->distance_m);
  fail_unless_equals_float (a->thickness_m, b->thickness_m);
  fail_unless_equals_float (a->confidence, b->confidence);
  fail_unless_equals_int (a->n_bands, b->n_bands);
  if (a->n_bands)
    fail_unless (memcmp (a->bands, b->bands, sizeof (GstTreeStereoBand) * a->n_bands) == 0);
  fail_unless_equals_int (a->frames, b->frames);
  fail_unless_equals_int (a->frames_seen, b->frames_seen);
  fail_unless_equals_int (a->has_spacing, b->has_spacing);
  fail_unless_equals_float (a->spacing_m, b->spacing_m);
  fail_unless_equals_float (a->gap_m, b->gap_m);
  fail_unless_equals_int (a->lost, b->lost);
}

GST_START_TEST (test_tree_message_round_trip)
{
  GstTreeStereoTreeRecord r = { 0 }, back = { 0 };
  GstTreeStereoTimes t = { 5 * GST_SECOND, 4 * GST_SECOND, 3 * GST_SECOND }, t2;
  GstStructure *s, *c;
  gchar *str;

  fill_record (&r);
  s = gst_tree_stereo_tree_message_structure (&r, &t);
  fail_unless (gst_structure_has_name (s, GST_TREE_STEREO_MESSAGE_TREE));
  fail_unless_equals_string (GST_TREE_STEREO_MESSAGE_TREE, "treestereo-tree");
  str = gst_structure_to_string (s);
  fail_unless (strstr (str, "position-m=(double)12.345") != NULL, "%s", str);
  fail_unless (strstr (str, "segment=(boolean)false") != NULL, "%s", str);
  fail_unless (strstr (str, "canopy-mode=(string)tree") != NULL, "%s", str);
  g_free (str);
  fail_unless (gst_tree_stereo_tree_message_parse (s, &back, &t2));
  assert_records_equal (&back, &r);
  fail_unless_equals_uint64 (t2.timestamp, t.timestamp);
  fail_unless_equals_uint64 (t2.running_time, t.running_time);
  /* malformed: a required field missing, a wrong type, another message */
  c = gst_structure_copy (s);
  gst_structure_remove_field (c, "end-m");
  fail_if (gst_tree_stereo_tree_message_parse (c, &back, NULL));
  gst_structure_free (c);
  c = gst_structure_copy (s);
  gst_structure_set (c, "height-m", G_TYPE_STRING, "tall", NULL);
  fail_if (gst_tree_stereo_tree_message_parse (c, &back, NULL));
  gst_structure_set_name (c, "treemetrics");
  fail_if (gst_tree_stereo_tree_message_parse (c, &back, NULL));
  gst_structure_free (c);
  gst_structure_free (s);

  /* a canopy segment of a hedgerow, first record, never fully in view: what it lacks is
   * absent, and parsing gives the has_ flags FALSE with zeros, not the previous parse's values */
  gst_tree_stereo_tree_record_clear (&r);
  r.id = 1;
  r.mode = GST_TREE_STEREO_CANOPY_ROW;
  r.start_seen = TRUE;
  r.position_m = 0.5;
  r.start_m = -0.2;
  r.end_m = 1.2;
  r.frames_seen = 3;
  s = gst_tree_stereo_tree_message_structure (&r, NULL);
  fail_unless (!gst_structure_has_field (s, "height-m"));
  fail_unless (!gst_structure_has_field (s, "distance-m"));
  fail_unless (!gst_structure_has_field (s, "bands"));
  fail_unless (!gst_structure_has_field (s, "spacing-m"));
  fail_unless (gst_tree_stereo_tree_message_parse (s, &back, &t2));
  assert_records_equal (&back, &r);
  fail_unless (back.bands == NULL);
  fail_unless_equals_uint64 (t2.timestamp, GST_CLOCK_TIME_NONE);
  {
    gboolean segment = FALSE;
    fail_unless (gst_structure_get_boolean (s, "segment", &segment) && segment);
  }
  gst_structure_free (s);
  gst_tree_stereo_tree_record_clear (&back);
  gst_tree_stereo_tree_record_clear (&r);
}

GST_END_TEST;

GST_START_TEST (test_canopy_message_round_trip)
{
  GstBuffer *buf = gst_buffer_new (), *mask = make_mask (64, 48, 64);
  GstTreeStereoCanopyMeta *c, back;
  GstTreeStereoDepthStats ds = { 300, 290, 4, 6, 2001.5, 12.25, 1900, 2200, 3, 1850.5, 2250.25,
    250 }, ds2;
  GstStructure *s;
  gboolean dense;

  c = gst_buffer_add_tree_stereo_canopy_meta (buf, GST_TREE_STEREO_CANOPY_ROW);
  fill_canopy (c, mask);
  gst_buffer_unref (mask);

  /* added to stereodepth's message, which still parses as it did */
  s = gst_tree_stereo_depth_message_structure (FALSE, &ds, NULL);
  gst_tree_stereo_canopy_message_add (s, c);
  fail_unless (gst_tree_stereo_depth_message_parse (s, &dense, &ds2, NULL));
  fail_unless_equals_string (gst_structure_get_string (s, "canopy-mode"), "row");
  memset (&back, 0, sizeof back);
  fail_unless (gst_tree_stereo_canopy_message_parse (s, &back));
  fail_unless (back.view.present);
  fail_unless_equals_int (back.mode, GST_TREE_STEREO_CANOPY_ROW);
  fail_unless_equals_float (back.near_m, 1.75);
  fail_unless_equals_float (back.far_m, 2.65);
  fail_unless (back.ground_found);
  fail_unless_equals_int (back.n_segments, 3);
  fail_unless_equals_int (back.n_canopy_points, 610);
  fail_unless (back.view.mask == NULL && back.view.contour == NULL);
  gst_structure_free (s);

  /* no canopy in the zone */
  c->view.present = FALSE;
  c->ground_found = FALSE;
  c->mode = GST_TREE_STEREO_CANOPY_TREE;
  s = gst_structure_new_empty ("stereodepth");
  gst_tree_stereo_canopy_message_add (s, c);
  fail_unless (gst_tree_stereo_canopy_message_parse (s, &back));
  fail_if (back.view.present);
  fail_if (back.ground_found);
  fail_unless_equals_int (back.mode, GST_TREE_STEREO_CANOPY_TREE);

  /* malformed: a field missing, an unknown mode; a message without any canopy field */
  gst_structure_remove_field (s, "segments");
  fail_if (gst_tree_stereo_canopy_message_parse (s, &back));
  gst_tree_stereo_canopy_message_add (s, c);
  gst_structure_set (s, "canopy-mode", G_TYPE_STRING, "colour-ish", NULL);
  fail_if (gst_tree_stereo_canopy_message_parse (s, &back));
  gst_structure_free (s);
  s = gst_tree_stereo_depth_message_structure (FALSE, &ds, NULL);
  fail_if (gst_tree_stereo_canopy_message_parse (s, &back));
  gst_structure_free (s);
  gst_buffer_unref (buf);
}

GST_END_TEST;

GST_START_TEST (test_other_messages_round_trip)
{
  GstTreeStereoVegetationMeta v = { 0 }, v2 = { 0 };
  GstTreeStereoMatchStats ms = { GST_TREE_STEREO_MATCH_COSINE_NORM, 500, 480, 300, 9000, 12,
    34, 5, 6, 7, 20.5, 3.25, 1.5, 26.0
  }, ms2;
  GstTreeStereoDepthStats ds = { 300, 290, 4, 6, 2001.5, 12.25, 1900, 2200, 3, 1850.5, 2250.25,
    250 },
      ds2;
  GstTreeStereoTimes t = { 1, 2, 3 }, t2;
  GstStructure *s;
  gboolean dense;

  /* vegetation, stereo */
  v.n_views = 2;
  v.index = GST_TREE_STEREO_INDEX_EXG_NORM;
  for (int i = 0; i < 2; i++) {
    v.views[i].present = i == 0;
    v.views[i].threshold = 0.1 * (i + 1);
    v.views[i].area_px = 1000 + i;
    v.views[i].perimeter_px = 120 + i;
    v.views[i].complexity = 1.1 + i;
    v.views[i].centroid_x = 50.5 + i;
    v.views[i].centroid_y = 60.5 + i;
    v.views[i].bbox_x = 10 + i;
    v.views[i].bbox_y = 11 + i;
    v.views[i].bbox_width = 80 + i;
    v.views[i].bbox_height = 90 + i;
    v.views[i].n_regions = 1 + i;
  }
  s = gst_tree_stereo_vegetation_message_structure (&v, &t);
  fail_unless (gst_structure_has_field (s, "left-area"));
  fail_unless (gst_structure_has_field (s, "right-bbox-height"));
  fail_unless (gst_tree_stereo_vegetation_message_parse (s, &v2, &t2));
  fail_unless_equals_int (v2.n_views, 2);
  fail_unless_equals_int (v2.index, GST_TREE_STEREO_INDEX_EXG_NORM);
  fail_unless (memcmp (&v2.views, &v.views, sizeof v.views) == 0);
  fail_unless_equals_uint64 (t2.running_time, 3);
  gst_structure_free (s);

  /* vegetation, one view: no prefix */
  v.n_views = 1;
  s = gst_tree_stereo_vegetation_message_structure (&v, &t);
  fail_unless (gst_structure_has_field (s, "area"));
  fail_if (gst_structure_has_field (s, "left-area"));
  fail_unless (gst_tree_stereo_vegetation_message_parse (s, &v2, NULL));
  fail_unless_equals_int (v2.n_views, 1);
  fail_unless (memcmp (&v2.views[0], &v.views[0], sizeof v.views[0]) == 0);
  gst_structure_remove_field (s, "complexity");
  fail_if (gst_tree_stereo_vegetation_message_parse (s, &v2, NULL));
  gst_structure_free (s);

  s = gst_tree_stereo_match_message_structure (&ms, &t);
  fail_unless_equals_string (gst_structure_get_string (s, "method"), "cosine-norm");
  memset (&ms2, 0, sizeof ms2);
  fail_unless (gst_tree_stereo_match_message_parse (s, &ms2, &t2));
  fail_unless (memcmp (&ms2, &ms, sizeof ms) == 0);
  gst_structure_set (s, "method", G_TYPE_STRING, "bogus", NULL);
  fail_if (gst_tree_stereo_match_message_parse (s, &ms2, NULL));
  gst_structure_free (s);

  s = gst_tree_stereo_depth_message_structure (TRUE, &ds, &t);
  memset (&ds2, 0, sizeof ds2);
  fail_unless (gst_tree_stereo_depth_message_parse (s, &dense, &ds2, &t2));
  fail_unless (dense);
  /* field by field: the struct has padding that memcmp would compare */
  fail_unless_equals_int (ds2.n_points, ds.n_points);
  fail_unless_equals_int (ds2.n_valid, ds.n_valid);
  fail_unless_equals_int (ds2.dropped_disparity, ds.dropped_disparity);
  fail_unless_equals_int (ds2.dropped_range, ds.dropped_range);
  fail_unless_equals_int (ds2.dropped_outlier, ds.dropped_outlier);
  fail_unless_equals_float (ds2.median_z_mm, ds.median_z_mm);
  fail_unless_equals_float (ds2.mad_z_mm, ds.mad_z_mm);
  fail_unless_equals_float (ds2.p05_z_mm, ds.p05_z_mm);
  fail_unless_equals_float (ds2.p95_z_mm, ds.p95_z_mm);
  fail_unless_equals_float (ds2.accept_lo_mm, ds.accept_lo_mm);
  fail_unless_equals_float (ds2.accept_hi_mm, ds.accept_hi_mm);
  fail_unless_equals_int (ds2.n_grid, ds.n_grid);
  gst_structure_remove_field (s, "dropped-disparity");
  fail_if (gst_tree_stereo_depth_message_parse (s, &dense, &ds2, NULL));
  gst_structure_free (s);
}

GST_END_TEST;

GST_START_TEST (test_times_from_buffer)
{
  GstBuffer *buf = gst_buffer_new ();
  GstSegment seg;
  GstTreeStereoTimes t;

  gst_segment_init (&seg, GST_FORMAT_TIME);
  seg.start = GST_SECOND;
  seg.time = 10 * GST_SECOND;
  seg.base = 100 * GST_SECOND;
  GST_BUFFER_PTS (buf) = 3 * GST_SECOND;
  gst_tree_stereo_times_from_buffer (&t, buf, &seg);
  fail_unless_equals_uint64 (t.timestamp, 3 * GST_SECOND);
  fail_unless_equals_uint64 (t.stream_time, 12 * GST_SECOND);
  fail_unless_equals_uint64 (t.running_time, 102 * GST_SECOND);
  gst_tree_stereo_times_from_buffer (&t, buf, NULL);
  fail_unless_equals_uint64 (t.running_time, GST_CLOCK_TIME_NONE);
  gst_buffer_unref (buf);
}

GST_END_TEST;

GST_START_TEST (test_enum_names)
{
  GstTreeStereoVegetationIndex idx;
  GstTreeStereoMatchMethod m;

  fail_unless_equals_string (gst_tree_stereo_vegetation_index_to_string
      (GST_TREE_STEREO_INDEX_EXG_EXR_NORM), "exg-exr-norm");
  fail_unless (gst_tree_stereo_vegetation_index_from_string ("exg", &idx));
  fail_unless_equals_int (idx, GST_TREE_STEREO_INDEX_EXG);
  fail_if (gst_tree_stereo_vegetation_index_from_string ("ndvi", &idx));
  fail_if (gst_tree_stereo_vegetation_index_from_string (NULL, &idx));
  fail_unless (gst_tree_stereo_vegetation_index_to_string (99) == NULL);
  fail_unless (gst_tree_stereo_match_method_from_string ("euclidean", &m));
  fail_unless_equals_int (m, GST_TREE_STEREO_MATCH_EUCLIDEAN);
  {
    GstTreeStereoCanopyMode cm;
    GEnumClass *klass;
    fail_unless_equals_string (gst_tree_stereo_canopy_mode_to_string
        (GST_TREE_STEREO_CANOPY_COLOUR), "colour");
    fail_unless_equals_string (gst_tree_stereo_canopy_mode_to_string
        (GST_TREE_STEREO_CANOPY_TREE), "tree");
    fail_unless_equals_string (gst_tree_stereo_canopy_mode_to_string
        (GST_TREE_STEREO_CANOPY_ROW), "row");
    fail_unless (gst_tree_stereo_canopy_mode_to_string (3) == NULL);
    {
      GstTreeStereoTravelSource ts;
      fail_unless_equals_string (gst_tree_stereo_travel_source_to_string
          (GST_TREE_STEREO_TRAVEL_NONE), "none");
      fail_unless_equals_string (gst_tree_stereo_travel_source_to_string
          (GST_TREE_STEREO_TRAVEL_STEREO), "stereo");
      fail_unless_equals_string (gst_tree_stereo_travel_source_to_string
          (GST_TREE_STEREO_TRAVEL_PREDICTED), "predicted");
      fail_unless (gst_tree_stereo_travel_source_to_string (4) == NULL);
      fail_unless (gst_tree_stereo_travel_source_from_string ("speed", &ts));
      fail_unless_equals_int (ts, GST_TREE_STEREO_TRAVEL_SPEED);
      fail_if (gst_tree_stereo_travel_source_from_string ("gnss", &ts));
      fail_if (gst_tree_stereo_travel_source_from_string (NULL, &ts));
    }
    fail_unless (gst_tree_stereo_canopy_mode_from_string ("row", &cm));
    fail_unless_equals_int (cm, GST_TREE_STEREO_CANOPY_ROW);
    fail_if (gst_tree_stereo_canopy_mode_from_string ("color", &cm));
    fail_if (gst_tree_stereo_canopy_mode_from_string (NULL, &cm));
    klass = g_type_class_ref (GST_TYPE_TREE_STEREO_CANOPY_MODE);
    fail_unless_equals_string (g_enum_get_value (klass, GST_TREE_STEREO_CANOPY_TREE)->value_nick,
        "tree");
    fail_unless (g_enum_get_value_by_nick (klass, "colour")->value ==
        GST_TREE_STEREO_CANOPY_COLOUR);
    g_type_class_unref (klass);
  }
}

GST_END_TEST;

static Suite *
meta_suite (void)
{
  Suite *s = suite_create ("treestereo-meta");
  TCase *tc = tcase_create ("general");

  suite_add_tcase (s, tc);
  tcase_add_test (tc, test_geometry_meta);
  tcase_add_test (tc, test_vegetation_meta);
  tcase_add_test (tc, test_matches_and_points_meta);
  tcase_add_test (tc, test_metrics_and_truth_meta);
  tcase_add_test (tc, test_metrics_message_round_trip);
  tcase_add_test (tc, test_canopy_meta);
  tcase_add_test (tc, test_canopy_message_round_trip);
  tcase_add_test (tc, test_tree_message_round_trip);
  tcase_add_test (tc, test_other_messages_round_trip);
  tcase_add_test (tc, test_times_from_buffer);
  tcase_add_test (tc, test_enum_names);
  return s;
}

GST_CHECK_MAIN (meta);
