/* treestereo: metas and element messages
 *
 * In the style of gst-plugins-base's gstvideometa.c: each meta registers an API type with its
 * tags and a GstMetaInfo with init/free/transform. Pixel coordinates are rescaled on a video
 * scale transform; everything is deep copied (GstBuffers such as masks are shared by reference,
 * they are never written after being attached).
 */
#ifdef HAVE_CONFIG_H
#include "config.h"
#endif

#include "gst/treestereo/treestereo-meta.h"

#include <math.h>
#include <string.h>

static const gchar *pixel_tags[] = { GST_META_TAG_VIDEO_STR, GST_META_TAG_VIDEO_SIZE_STR,
  GST_META_TAG_VIDEO_ORIENTATION_STR, NULL
};

static const gchar *no_tags[] = { NULL };

/* Registers an API type once. */
#define DEFINE_API_TYPE(func, name, tags)                           \
  GType func (void)                                                 \
  {                                                                 \
    static GType type = 0;                                          \
    if (g_once_init_enter (&type)) {                                \
      GType _type = gst_meta_api_type_register (name, tags);        \
      g_once_init_leave (&type, _type);                             \
    }                                                               \
    return type;                                                    \
  }

/* Registers a GstMetaInfo once. */
#define DEFINE_META_INFO(func, api, impl_name, ctype, init, free_fn, transform) \
  const GstMetaInfo *func (void)                                    \
  {                                                                 \
    static const GstMetaInfo *info = NULL;                          \
    if (g_once_init_enter ((GstMetaInfo **) & info)) {              \
      const GstMetaInfo *mi = gst_meta_register (api (), impl_name, \
          sizeof (ctype), (GstMetaInitFunction) init,               \
          (GstMetaFreeFunction) free_fn,                            \
          (GstMetaTransformFunction) transform);                    \
      g_once_init_leave ((GstMetaInfo **) & info, (GstMetaInfo *) mi); \
    }                                                               \
    return info;                                                    \
  }

/* The x and y factors of a video scale transform, FALSE when @type is not one. */
static gboolean
scale_factors (GQuark type, gpointer data, gdouble * sx, gdouble * sy)
{
  GstVideoMetaTransform *trans;

  if (!GST_VIDEO_META_TRANSFORM_IS_SCALE (type))
    return FALSE;
  trans = (GstVideoMetaTransform *) data;
  if (GST_VIDEO_INFO_WIDTH (trans->in_info) <= 0 || GST_VIDEO_INFO_HEIGHT (trans->in_info) <= 0)
    return FALSE;
  *sx = (gdouble) GST_VIDEO_INFO_WIDTH (trans->out_info) / GST_VIDEO_INFO_WIDTH (trans->in_info);
  *sy = (gdouble) GST_VIDEO_INFO_HEIGHT (trans->out_info) /
      GST_VIDEO_INFO_HEIGHT (trans->in_info);
  return TRUE;
}

/* Nearest-neighbour resample of a GRAY8 mask; NULL when @src is NULL or unreadable. */
static GstBuffer *
resample_mask (GstBuffer * src, guint w, guint h, guint stride, guint nw, guint nh)
{
  GstMapInfo in, out;
  GstBuffer *dst;
  guint x, y;

  if (!src || nw == 0 || nh == 0 || w == 0 || h == 0)
    return NULL;
  if (!gst_buffer_map (src, &in, GST_MAP_READ))
    return NULL;
  if (in.size < (gsize) stride * (h - 1) + w) {
    gst_buffer_unmap (src, &in);
    return NULL;
  }
  dst = gst_buffer_new_allocate (NULL, (gsize) nw * nh, NULL);
  gst_buffer_map (dst, &out, GST_MAP_WRITE);
  for (y = 0; y < nh; y++) {
    guint sy = MIN ((guint) (((guint64) y * h) / nh), h - 1);
    const guint8 *srow = in.data + (gsize) sy * stride;
    guint8 *drow = out.data + (gsize) y * nw;
    for (x = 0; x < nw; x++)
      drow[x] = srow[MIN ((guint) (((guint64) x * w) / nw), w - 1)];
  }
  gst_buffer_unmap (dst, &out);
  gst_buffer_unmap (src, &in);
  return dst;
}

/* ---------------------------------------------------------------------------------------------
 * Geometry
 * --------------------------------------------------------------------------------------------- */

static gboolean
geometry_init (GstTreeStereoGeometryMeta * meta, gpointer params, GstBuffer * buffer)
{
  memset ((guint8 *) meta + sizeof (GstMeta), 0, sizeof (*meta) - sizeof (GstMeta));
  meta->pts[0] = meta->pts[1] = GST_CLOCK_TIME_NONE;
  return TRUE;
}

static void
geometry_free (GstTreeStereoGeometryMeta * meta, GstBuffer * buffer)
{
}

static gboolean
geometry_transform (GstBuffer * dest, GstMeta * meta, GstBuffer * buffer, GQuark type,
    gpointer data)
{
  GstTreeStereoGeometryMeta *src = (GstTreeStereoGeometryMeta *) meta, *dmeta;
  gdouble sx = 1.0, sy = 1.0;
  gboolean scale = FALSE;
  guint i;

  if (!GST_META_TRANSFORM_IS_COPY (type) && !(scale = scale_factors (type, data, &sx, &sy)))
    return FALSE;

  dmeta = gst_buffer_add_tree_stereo_geometry_meta (dest);
  if (!dmeta)
    return FALSE;
  memcpy ((guint8 *) dmeta + sizeof (GstMeta), (guint8 *) src + sizeof (GstMeta),
      sizeof (*src) - sizeof (GstMeta));
  if (scale) {
    dmeta->view_width = (guint) lround (src->view_width * sx);
    dmeta->view_height = (guint) lround (src->view_height * sy);
    for (i = 0; i < 2; i++) {
      dmeta->fx[i] *= sx;
      dmeta->fy[i] *= sy;
      dmeta->cx[i] *= sx;
      dmeta->cy[i] *= sy;
    }
    /* Q maps (x, y, d, 1) to (X, Y, Z, W): with x, y, d scaled by s (isotropic scale) the same
     * point needs Q' = Q with the translation column and focal row scaled. Recompute from the
     * scaled intrinsics instead of patching, the form stereoRectify uses. */
    memset (dmeta->Q, 0, sizeof (dmeta->Q));
    dmeta->Q[0] = 1.0;
    dmeta->Q[3] = -dmeta->cx[0];
    dmeta->Q[5] = 1.0;
    dmeta->Q[7] = -dmeta->cy[0];
    dmeta->Q[11] = dmeta->fx[0];
    if (dmeta->baseline_mm > 0) {
      dmeta->Q[14] = 1.0 / dmeta->baseline_mm;
      dmeta->Q[15] = -(dmeta->cx[0] - dmeta->cx[1]) / dmeta->baseline_mm;
    }
  }
  return TRUE;
}

DEFINE_API_TYPE (gst_tree_stereo_geometry_meta_api_get_type, "GstTreeStereoGeometryMetaAPI",
    pixel_tags);
DEFINE_META_INFO (gst_tree_stereo_geometry_meta_get_info,
    gst_tree_stereo_geometry_meta_api_get_type, "GstTreeStereoGeometryMeta",
    GstTreeStereoGeometryMeta, geometry_init, geometry_free, geometry_transform);

GstTreeStereoGeometryMeta *
gst_buffer_add_tree_stereo_geometry_meta (GstBuffer * buffer)
{
  g_return_val_if_fail (GST_IS_BUFFER (buffer), NULL);
  return (GstTreeStereoGeometryMeta *) gst_buffer_add_meta (buffer,
      GST_TREE_STEREO_GEOMETRY_META_INFO, NULL);
}

gdouble
gst_tree_stereo_geometry_meta_doffs (const GstTreeStereoGeometryMeta * meta)
{
  g_return_val_if_fail (meta != NULL, 0.0);
  return meta->cx[0] - meta->cx[1];
}

/* ---------------------------------------------------------------------------------------------
 * Vegetation
 * --------------------------------------------------------------------------------------------- */

void
gst_tree_stereo_vegetation_view_set_contour (GstTreeStereoVegetationView * view,
    const gint32 * xy, guint n)
{
  g_return_if_fail (view != NULL);
  g_return_if_fail (n == 0 || xy != NULL);
  g_free (view->contour);
  view->contour = n ? g_memdup2 (xy, (gsize) n * 2 * sizeof (gint32)) : NULL;
  view->n_contour = n;
}

void
gst_tree_stereo_vegetation_view_set_mask (GstTreeStereoVegetationView * view, GstBuffer * mask,
    guint width, guint height, guint stride)
{
  g_return_if_fail (view != NULL);
  gst_clear_buffer (&view->mask);
  view->mask = mask ? gst_buffer_ref (mask) : NULL;
  view->mask_width = mask ? width : 0;
  view->mask_height = mask ? height : 0;
  view->mask_stride = mask ? stride : 0;
}

void
gst_tree_stereo_vegetation_view_clear (GstTreeStereoVegetationView * view)
{
  g_return_if_fail (view != NULL);
  g_free (view->contour);
  gst_clear_buffer (&view->mask);
  memset (view, 0, sizeof (*view));
}

void
gst_tree_stereo_vegetation_view_copy (GstTreeStereoVegetationView * dest,
    const GstTreeStereoVegetationView * src)
{
  g_return_if_fail (dest != NULL && src != NULL);
  if (dest == src)
    return;
  gst_tree_stereo_vegetation_view_clear (dest);
  *dest = *src;
  dest->contour = NULL;
  dest->mask = NULL;
  gst_tree_stereo_vegetation_view_set_contour (dest, src->contour, src->n_contour);
  gst_tree_stereo_vegetation_view_set_mask (dest, src->mask, src->mask_width, src->mask_height,
      src->mask_stride);
}

static gboolean
vegetation_init (GstTreeStereoVegetationMeta * meta, gpointer params, GstBuffer * buffer)
{
  memset ((guint8 *) meta + sizeof (GstMeta), 0, sizeof (*meta) - sizeof (GstMeta));
  return TRUE;
}

static void
vegetation_free (GstTreeStereoVegetationMeta * meta, GstBuffer * buffer)
{
  gst_tree_stereo_vegetation_view_clear (&meta->views[0]);
  gst_tree_stereo_vegetation_view_clear (&meta->views[1]);
}

static void
vegetation_view_scale (GstTreeStereoVegetationView * v, gdouble sx, gdouble sy)
{
  guint i;
  GstBuffer *mask;

  v->area_px *= sx * sy;
  /* exact for a scale equal on both axes; an approximation otherwise */
  v->perimeter_px *= sqrt (sx * sy);
  v->centroid_x *= sx;
  v->centroid_y *= sy;
  v->bbox_x = (gint) lround (v->bbox_x * sx);
  v->bbox_y = (gint) lround (v->bbox_y * sy);
  v->bbox_width = (gint) lround (v->bbox_width * sx);
  v->bbox_height = (gint) lround (v->bbox_height * sy);
  for (i = 0; i < v->n_contour; i++) {
    v->contour[2 * i] = (gint32) lround (v->contour[2 * i] * sx);
    v->contour[2 * i + 1] = (gint32) lround (v->contour[2 * i + 1] * sy);
  }
  if (v->mask) {
    guint nw = (guint) lround (v->mask_width * sx), nh = (guint) lround (v->mask_height * sy);
    mask = resample_mask (v->mask, v->mask_width, v->mask_height, v->mask_stride, nw, nh);
    gst_tree_stereo_vegetation_view_set_mask (v, mask, nw, nh, nw);
    gst_clear_buffer (&mask);
  }
}

static gboolean
vegetation_transform (GstBuffer * dest, GstMeta * meta, GstBuffer * buffer, GQuark type,
    gpointer data)
{
  GstTreeStereoVegetationMeta *src = (GstTreeStereoVegetationMeta *) meta, *dmeta;
  gdouble sx = 1.0, sy = 1.0;
  gboolean scale = FALSE;
  guint i;

  if (!GST_META_TRANSFORM_IS_COPY (type) && !(scale = scale_factors (type, data, &sx, &sy)))
    return FALSE;

  dmeta = gst_buffer_add_tree_stereo_vegetation_meta (dest, src->n_views);
  if (!dmeta)
    return FALSE;
  dmeta->index = src->index;
  for (i = 0; i < src->n_views; i++) {
    gst_tree_stereo_vegetation_view_copy (&dmeta->views[i], &src->views[i]);
    if (scale)
      vegetation_view_scale (&dmeta->views[i], sx, sy);
  }
  return TRUE;
}

DEFINE_API_TYPE (gst_tree_stereo_vegetation_meta_api_get_type,
    "GstTreeStereoVegetationMetaAPI", pixel_tags);
DEFINE_META_INFO (gst_tree_stereo_vegetation_meta_get_info,
    gst_tree_stereo_vegetation_meta_api_get_type, "GstTreeStereoVegetationMeta",
    GstTreeStereoVegetationMeta, vegetation_init, vegetation_free, vegetation_transform);

GstTreeStereoVegetationMeta *
gst_buffer_add_tree_stereo_vegetation_meta (GstBuffer * buffer, guint n_views)
{
  GstTreeStereoVegetationMeta *meta;

  g_return_val_if_fail (GST_IS_BUFFER (buffer), NULL);
  g_return_val_if_fail (n_views == 1 || n_views == 2, NULL);
  meta = (GstTreeStereoVegetationMeta *) gst_buffer_add_meta (buffer,
      GST_TREE_STEREO_VEGETATION_META_INFO, NULL);
  if (meta)
    meta->n_views = n_views;
  return meta;
}

/* ---------------------------------------------------------------------------------------------
 * Matches
 * --------------------------------------------------------------------------------------------- */

static gboolean
matches_init (GstTreeStereoMatchesMeta * meta, gpointer params, GstBuffer * buffer)
{
  memset ((guint8 *) meta + sizeof (GstMeta), 0, sizeof (*meta) - sizeof (GstMeta));
  return TRUE;
}

static void
matches_free (GstTreeStereoMatchesMeta * meta, GstBuffer * buffer)
{
  g_free (meta->matches);
  meta->matches = NULL;
  meta->n_matches = 0;
}

static gboolean
matches_transform (GstBuffer * dest, GstMeta * meta, GstBuffer * buffer, GQuark type,
    gpointer data)
{
  GstTreeStereoMatchesMeta *src = (GstTreeStereoMatchesMeta *) meta, *dmeta;
  gdouble sx = 1.0, sy = 1.0;
  gboolean scale = FALSE;
  guint i;

  if (!GST_META_TRANSFORM_IS_COPY (type) && !(scale = scale_factors (type, data, &sx, &sy)))
    return FALSE;
  dmeta = gst_buffer_add_tree_stereo_matches_meta (dest, src->method, src->n_keypoints[0],
      src->n_keypoints[1], src->matches, src->n_matches);
  if (!dmeta)
    return FALSE;
  if (scale) {
    for (i = 0; i < dmeta->n_matches; i++) {
      dmeta->matches[i].xl *= sx;
      dmeta->matches[i].xr *= sx;
      dmeta->matches[i].yl *= sy;
      dmeta->matches[i].yr *= sy;
    }
  }
  return TRUE;
}

DEFINE_API_TYPE (gst_tree_stereo_matches_meta_api_get_type, "GstTreeStereoMatchesMetaAPI",
    pixel_tags);
DEFINE_META_INFO (gst_tree_stereo_matches_meta_get_info,
    gst_tree_stereo_matches_meta_api_get_type, "GstTreeStereoMatchesMeta",
    GstTreeStereoMatchesMeta, matches_init, matches_free, matches_transform);

GstTreeStereoMatchesMeta *
gst_buffer_add_tree_stereo_matches_meta (GstBuffer * buffer, GstTreeStereoMatchMethod method,
    guint n_keypoints_left, guint n_keypoints_right, const GstTreeStereoMatch * matches,
    guint n_matches)
{
  GstTreeStereoMatchesMeta *meta;

  g_return_val_if_fail (GST_IS_BUFFER (buffer), NULL);
  g_return_val_if_fail (n_matches == 0 || matches != NULL, NULL);
  meta = (GstTreeStereoMatchesMeta *) gst_buffer_add_meta (buffer,
      GST_TREE_STEREO_MATCHES_META_INFO, NULL);
  if (!meta)
    return NULL;
  meta->method = method;
  meta->n_keypoints[0] = n_keypoints_left;
  meta->n_keypoints[1] = n_keypoints_right;
  meta->n_matches = n_matches;
  meta->matches = n_matches ? g_memdup2 (matches, sizeof (GstTreeStereoMatch) * n_matches) : NULL;
  return meta;
}

/* ---------------------------------------------------------------------------------------------
 * Points
 * --------------------------------------------------------------------------------------------- */

static gboolean
points_init (GstTreeStereoPointsMeta * meta, gpointer params, GstBuffer * buffer)
{
  memset ((guint8 *) meta + sizeof (GstMeta), 0, sizeof (*meta) - sizeof (GstMeta));
  return TRUE;
}

static void
points_free (GstTreeStereoPointsMeta * meta, GstBuffer * buffer)
{
  g_free (meta->points);
  meta->points = NULL;
  meta->n_points = 0;
  gst_clear_buffer (&meta->depth_map);
}

static gboolean
points_transform (GstBuffer * dest, GstMeta * meta, GstBuffer * buffer, GQuark type,
    gpointer data)
{
  GstTreeStereoPointsMeta *src = (GstTreeStereoPointsMeta *) meta, *dmeta;
  gdouble sx = 1.0, sy = 1.0;
  gboolean scale = FALSE;

  if (!GST_META_TRANSFORM_IS_COPY (type) && !(scale = scale_factors (type, data, &sx, &sy)))
    return FALSE;
  dmeta = gst_buffer_add_tree_stereo_points_meta (dest, src->points, src->n_points, &src->stats);
  if (!dmeta)
    return FALSE;
  dmeta->dense = src->dense;
  /* The 3D points do not depend on the picture's size; the depth map is per pixel and is
   * dropped by a scale rather than resampled (depth edges would blend). */
  if (!scale)
    gst_tree_stereo_points_meta_set_depth_map (dmeta, src->depth_map, src->depth_x,
        src->depth_y, src->depth_width, src->depth_height, src->depth_stride);
  return TRUE;
}

DEFINE_API_TYPE (gst_tree_stereo_points_meta_api_get_type, "GstTreeStereoPointsMetaAPI",
    pixel_tags);
DEFINE_META_INFO (gst_tree_stereo_points_meta_get_info,
    gst_tree_stereo_points_meta_api_get_type, "GstTreeStereoPointsMeta",
    GstTreeStereoPointsMeta, points_init, points_free, points_transform);

GstTreeStereoPointsMeta *
gst_buffer_add_tree_stereo_points_meta (GstBuffer * buffer, const GstTreeStereoPoint * points,
    guint n_points, const GstTreeStereoDepthStats * stats)
{
  GstTreeStereoPointsMeta *meta;

  g_return_val_if_fail (GST_IS_BUFFER (buffer), NULL);
  g_return_val_if_fail (n_points == 0 || points != NULL, NULL);
  meta = (GstTreeStereoPointsMeta *) gst_buffer_add_meta (buffer,
      GST_TREE_STEREO_POINTS_META_INFO, NULL);
  if (!meta)
    return NULL;
  meta->n_points = n_points;
  meta->points = n_points ? g_memdup2 (points, sizeof (GstTreeStereoPoint) * n_points) : NULL;
  if (stats)
    meta->stats = *stats;
  return meta;
}

void
gst_tree_stereo_points_meta_set_depth_map (GstTreeStereoPointsMeta * meta, GstBuffer * map,
    gint x, gint y, guint width, guint height, guint stride)
{
  g_return_if_fail (meta != NULL);
  gst_clear_buffer (&meta->depth_map);
  meta->depth_map = map ? gst_buffer_ref (map) : NULL;
  meta->depth_x = map ? x : 0;
  meta->depth_y = map ? y : 0;
  meta->depth_width = map ? width : 0;
  meta->depth_height = map ? height : 0;
  meta->depth_stride = map ? stride : 0;
}

/* ---------------------------------------------------------------------------------------------
 * The 3D canopy
 * --------------------------------------------------------------------------------------------- */

static gboolean
canopy_init (GstTreeStereoCanopyMeta * meta, gpointer params, GstBuffer * buffer)
{
  memset ((guint8 *) meta + sizeof (GstMeta), 0, sizeof (*meta) - sizeof (GstMeta));
  return TRUE;
}

static void
canopy_free (GstTreeStereoCanopyMeta * meta, GstBuffer * buffer)
{
  gst_tree_stereo_vegetation_view_clear (&meta->view);
  gst_tree_stereo_vegetation_view_clear (&meta->row_view);
}

static gboolean
canopy_transform (GstBuffer * dest, GstMeta * meta, GstBuffer * buffer, GQuark type,
    gpointer data)
{
  GstTreeStereoCanopyMeta *src = (GstTreeStereoCanopyMeta *) meta, *dmeta;
  gdouble sx = 1.0, sy = 1.0;
  gboolean scale = FALSE;

  if (!GST_META_TRANSFORM_IS_COPY (type) && !(scale = scale_factors (type, data, &sx, &sy)))
    return FALSE;
  dmeta = gst_buffer_add_tree_stereo_canopy_meta (dest, src->mode);
  if (!dmeta)
    return FALSE;
  /* the figures after the view (metres, counts) do not depend on the picture's size */
  dmeta->near_m = src->near_m;
  dmeta->far_m = src->far_m;
  dmeta->zone_from_data = src->zone_from_data;
  dmeta->ground_found = src->ground_found;
  memcpy (dmeta->ground_normal, src->ground_normal, sizeof (src->ground_normal));
  dmeta->ground_d_m = src->ground_d_m;
  dmeta->n_segments = src->n_segments;
  dmeta->left_m = src->left_m;
  dmeta->right_m = src->right_m;
  dmeta->n_points = src->n_points;
  dmeta->n_canopy_points = src->n_canopy_points;
  dmeta->n_seam_pixels = src->n_seam_pixels;
  dmeta->n_stored_segments = MIN (src->n_stored_segments, GST_TREE_STEREO_MAX_SEGMENTS);
  memcpy (dmeta->segments, src->segments, sizeof (src->segments));
  dmeta->cut_lo_m = src->cut_lo_m;
  dmeta->cut_hi_m = src->cut_hi_m;
  gst_tree_stereo_vegetation_view_copy (&dmeta->view, &src->view);
  gst_tree_stereo_vegetation_view_copy (&dmeta->row_view, &src->row_view);
  if (scale) {
    vegetation_view_scale (&dmeta->view, sx, sy);
    vegetation_view_scale (&dmeta->row_view, sx, sy);
  }
  return TRUE;
}

DEFINE_API_TYPE (gst_tree_stereo_canopy_meta_api_get_type, "GstTreeStereoCanopyMetaAPI",
    pixel_tags);
DEFINE_META_INFO (gst_tree_stereo_canopy_meta_get_info,
    gst_tree_stereo_canopy_meta_api_get_type, "GstTreeStereoCanopyMeta",
    GstTreeStereoCanopyMeta, canopy_init, canopy_free, canopy_transform);

GstTreeStereoCanopyMeta *
gst_buffer_add_tree_stereo_canopy_meta (GstBuffer * buffer, GstTreeStereoCanopyMode mode)
{
  GstTreeStereoCanopyMeta *meta;

  g_return_val_if_fail (GST_IS_BUFFER (buffer), NULL);
  meta = (GstTreeStereoCanopyMeta *) gst_buffer_add_meta (buffer,
      GST_TREE_STEREO_CANOPY_META_INFO, NULL);
  if (meta) {
    guint i;
    meta->mode = mode;
    for (i = 0; i < GST_TREE_STEREO_MAX_SEGMENTS; i++)
      meta->segments[i].lo_clear_m = meta->segments[i].hi_clear_m =
          meta->segments[i].trunk_m = NAN;
    meta->cut_lo_m = -INFINITY;
    meta->cut_hi_m = INFINITY;
  }
  return meta;
}

/* ---------------------------------------------------------------------------------------------
 * Tree metrics
 * --------------------------------------------------------------------------------------------- */

void
gst_tree_stereo_metrics_clear (GstTreeStereoMetrics * m)
{
  g_return_if_fail (m != NULL);
  g_free (m->bands);
  memset (m, 0, sizeof (*m));
}

void
gst_tree_stereo_metrics_set_n_bands (GstTreeStereoMetrics * m, guint n)
{
  g_return_if_fail (m != NULL);
  g_free (m->bands);
  m->bands = n ? g_new0 (GstTreeStereoBand, n) : NULL;
  m->n_bands = n;
}

void
gst_tree_stereo_metrics_copy (GstTreeStereoMetrics * dest, const GstTreeStereoMetrics * src)
{
  g_return_if_fail (dest != NULL && src != NULL);
  if (dest == src)
    return;
  gst_tree_stereo_metrics_clear (dest);
  *dest = *src;
  dest->bands = src->n_bands ? g_memdup2 (src->bands, sizeof (GstTreeStereoBand) * src->n_bands)
      : NULL;
}

static gboolean
metrics_init (GstTreeStereoMetricsMeta * meta, gpointer params, GstBuffer * buffer)
{
  memset ((guint8 *) meta + sizeof (GstMeta), 0, sizeof (*meta) - sizeof (GstMeta));
  return TRUE;
}

static void
metrics_free (GstTreeStereoMetricsMeta * meta, GstBuffer * buffer)
{
  gst_tree_stereo_metrics_clear (&meta->metrics);
  gst_tree_stereo_metrics_clear (&meta->smoothed);
}

static gboolean
metrics_transform (GstBuffer * dest, GstMeta * meta, GstBuffer * buffer, GQuark type,
    gpointer data)
{
  GstTreeStereoMetricsMeta *src = (GstTreeStereoMetricsMeta *) meta;

  /* metres do not change with the picture's size: a scale is a copy */
  if (!GST_META_TRANSFORM_IS_COPY (type) && !GST_VIDEO_META_TRANSFORM_IS_SCALE (type))
    return FALSE;
  return gst_buffer_add_tree_stereo_metrics_meta (dest, &src->metrics, &src->smoothed) != NULL;
}

DEFINE_API_TYPE (gst_tree_stereo_metrics_meta_api_get_type, "GstTreeStereoMetricsMetaAPI",
    no_tags);
DEFINE_META_INFO (gst_tree_stereo_metrics_meta_get_info,
    gst_tree_stereo_metrics_meta_api_get_type, "GstTreeStereoMetricsMeta",
    GstTreeStereoMetricsMeta, metrics_init, metrics_free, metrics_transform);

GstTreeStereoMetricsMeta *
gst_buffer_add_tree_stereo_metrics_meta (GstBuffer * buffer, const GstTreeStereoMetrics * metrics,
    const GstTreeStereoMetrics * smoothed)
{
  GstTreeStereoMetricsMeta *meta;

  g_return_val_if_fail (GST_IS_BUFFER (buffer), NULL);
  g_return_val_if_fail (metrics != NULL, NULL);
  meta = (GstTreeStereoMetricsMeta *) gst_buffer_add_meta (buffer,
      GST_TREE_STEREO_METRICS_META_INFO, NULL);
  if (!meta)
    return NULL;
  gst_tree_stereo_metrics_copy (&meta->metrics, metrics);
  gst_tree_stereo_metrics_copy (&meta->smoothed, smoothed ? smoothed : metrics);
  return meta;
}

/* ---------------------------------------------------------------------------------------------
 * Ground truth
 * --------------------------------------------------------------------------------------------- */

static gboolean
truth_init (GstTreeStereoTruthMeta * meta, gpointer params, GstBuffer * buffer)
{
  memset ((guint8 *) meta + sizeof (GstMeta), 0, sizeof (*meta) - sizeof (GstMeta));
  return TRUE;
}

static void
truth_free (GstTreeStereoTruthMeta * meta, GstBuffer * buffer)
{
  gst_clear_buffer (&meta->depth);
  gst_clear_buffer (&meta->mask);
}

static gboolean
truth_transform (GstBuffer * dest, GstMeta * meta, GstBuffer * buffer, GQuark type,
    gpointer data)
{
  GstTreeStereoTruthMeta *src = (GstTreeStereoTruthMeta *) meta;

  /* The scene's values do not depend on the picture; the per-pixel maps do and are dropped by
   * a scale. */
  if (GST_META_TRANSFORM_IS_COPY (type))
    return gst_buffer_add_tree_stereo_truth_meta (dest, &src->truth, src->depth, src->mask,
        src->width, src->height) != NULL;
  if (GST_VIDEO_META_TRANSFORM_IS_SCALE (type))
    return gst_buffer_add_tree_stereo_truth_meta (dest, &src->truth, NULL, NULL, 0, 0) != NULL;
  return FALSE;
}

DEFINE_API_TYPE (gst_tree_stereo_truth_meta_api_get_type, "GstTreeStereoTruthMetaAPI",
    no_tags);
DEFINE_META_INFO (gst_tree_stereo_truth_meta_get_info, gst_tree_stereo_truth_meta_api_get_type,
    "GstTreeStereoTruthMeta", GstTreeStereoTruthMeta, truth_init, truth_free, truth_transform);

GstTreeStereoTruthMeta *
gst_buffer_add_tree_stereo_truth_meta (GstBuffer * buffer, const GstTreeStereoTruth * truth,
    GstBuffer * depth, GstBuffer * mask, guint width, guint height)
{
  GstTreeStereoTruthMeta *meta;

  g_return_val_if_fail (GST_IS_BUFFER (buffer), NULL);
  g_return_val_if_fail (truth != NULL, NULL);
  meta = (GstTreeStereoTruthMeta *) gst_buffer_add_meta (buffer,
      GST_TREE_STEREO_TRUTH_META_INFO, NULL);
  if (!meta)
    return NULL;
  meta->truth = *truth;
  meta->depth = depth ? gst_buffer_ref (depth) : NULL;
  meta->mask = mask ? gst_buffer_ref (mask) : NULL;
  meta->width = (depth || mask) ? width : 0;
  meta->height = (depth || mask) ? height : 0;
  return meta;
}

/* ---------------------------------------------------------------------------------------------
 * Names
 * --------------------------------------------------------------------------------------------- */

static const gchar *index_names[] = { "exg", "exg-exr", "exg-norm", "exg-exr-norm" };
static const gchar *method_names[] = { "euclidean", "cosine-norm" };
static const gchar *canopy_mode_names[] = { "colour", "tree", "row" };
static const gchar *travel_source_names[] = { "none", "stereo", "speed", "predicted" };

const gchar *
gst_tree_stereo_vegetation_index_to_string (GstTreeStereoVegetationIndex index)
{
  return ((guint) index < G_N_ELEMENTS (index_names)) ? index_names[index] : NULL;
}

gboolean
gst_tree_stereo_vegetation_index_from_string (const gchar * s,
    GstTreeStereoVegetationIndex * index)
{
  guint i;
  for (i = 0; s && i < G_N_ELEMENTS (index_names); i++) {
    if (g_strcmp0 (s, index_names[i]) == 0) {
      *index = (GstTreeStereoVegetationIndex) i;
      return TRUE;
    }
  }
  return FALSE;
}

const gchar *
gst_tree_stereo_match_method_to_string (GstTreeStereoMatchMethod method)
{
  return ((guint) method < G_N_ELEMENTS (method_names)) ? method_names[method] : NULL;
}

gboolean
gst_tree_stereo_match_method_from_string (const gchar * s, GstTreeStereoMatchMethod * method)
{
  guint i;
  for (i = 0; s && i < G_N_ELEMENTS (method_names); i++) {
    if (g_strcmp0 (s, method_names[i]) == 0) {
      *method = (GstTreeStereoMatchMethod) i;
      return TRUE;
    }
  }
  return FALSE;
}

const gchar *
gst_tree_stereo_canopy_mode_to_string (GstTreeStereoCanopyMode mode)
{
  return ((guint) mode < G_N_ELEMENTS (canopy_mode_names)) ? canopy_mode_names[mode] : NULL;
}

gboolean
gst_tree_stereo_canopy_mode_from_string (const gchar * s, GstTreeStereoCanopyMode * mode)
{
  guint i;
  for (i = 0; s && i < G_N_ELEMENTS (canopy_mode_names); i++) {
    if (g_strcmp0 (s, canopy_mode_names[i]) == 0) {
      *mode = (GstTreeStereoCanopyMode) i;
      return TRUE;
    }
  }
  return FALSE;
}

const gchar *
gst_tree_stereo_travel_source_to_string (GstTreeStereoTravelSource source)
{
  return ((guint) source < G_N_ELEMENTS (travel_source_names)) ? travel_source_names[source] :
      NULL;
}

gboolean
gst_tree_stereo_travel_source_from_string (const gchar * s, GstTreeStereoTravelSource * source)
{
  guint i;
  for (i = 0; s && i < G_N_ELEMENTS (travel_source_names); i++) {
    if (g_strcmp0 (s, travel_source_names[i]) == 0) {
      if (source)
        *source = (GstTreeStereoTravelSource) i;
      return TRUE;
    }
  }
  return FALSE;
}

GType
gst_tree_stereo_canopy_mode_get_type (void)
{
  static GType type = 0;
  static const GEnumValue values[] = {
    {GST_TREE_STEREO_CANOPY_COLOUR, "The colour silhouette (no 3D canopy upstream)", "colour"},
    {GST_TREE_STEREO_CANOPY_TREE, "The tree in front, decided in 3D", "tree"},
    {GST_TREE_STEREO_CANOPY_ROW, "The near row's vegetation, decided in 3D", "row"},
    {0, NULL, NULL},
  };
  if (g_once_init_enter (&type)) {
    GType t = g_enum_register_static ("GstTreeStereoCanopyMode", values);
    g_once_init_leave (&type, t);
  }
  return type;
}

/* ---------------------------------------------------------------------------------------------
 * Messages
 * --------------------------------------------------------------------------------------------- */

void
gst_tree_stereo_times_from_buffer (GstTreeStereoTimes * times, GstBuffer * buffer,
    const GstSegment * segment)
{
  GstClockTime ts;

  g_return_if_fail (times != NULL && GST_IS_BUFFER (buffer));
  ts = GST_BUFFER_PTS_IS_VALID (buffer) ? GST_BUFFER_PTS (buffer) : GST_BUFFER_DTS (buffer);
  times->timestamp = ts;
  times->stream_time = GST_CLOCK_TIME_NONE;
  times->running_time = GST_CLOCK_TIME_NONE;
  if (segment && segment->format == GST_FORMAT_TIME && GST_CLOCK_TIME_IS_VALID (ts)) {
    times->stream_time = gst_segment_to_stream_time (segment, GST_FORMAT_TIME, ts);
    times->running_time = gst_segment_to_running_time (segment, GST_FORMAT_TIME, ts);
  }
}

static void
set_times (GstStructure * s, const GstTreeStereoTimes * times)
{
  GstTreeStereoTimes none = { GST_CLOCK_TIME_NONE, GST_CLOCK_TIME_NONE, GST_CLOCK_TIME_NONE };
  if (!times)
    times = &none;
  gst_structure_set (s, "timestamp", G_TYPE_UINT64, times->timestamp,
      "stream-time", G_TYPE_UINT64, times->stream_time,
      "running-time", G_TYPE_UINT64, times->running_time, NULL);
}

static gboolean
get_times (const GstStructure * s, GstTreeStereoTimes * times)
{
  if (!times)
    return TRUE;
  return gst_structure_get (s, "timestamp", G_TYPE_UINT64, &times->timestamp,
      "stream-time", G_TYPE_UINT64, &times->stream_time,
      "running-time", G_TYPE_UINT64, &times->running_time, NULL);
}

/* Field name with a view prefix: "left-area", or "area" with one view. */
static const gchar *
view_field (gchar * buf, gsize len, guint n_views, guint view, const gchar * name)
{
  if (n_views == 1)
    g_strlcpy (buf, name, len);
  else
    g_snprintf (buf, len, "%s-%s", view == 0 ? "left" : "right", name);
  return buf;
}

GstStructure *
gst_tree_stereo_vegetation_message_structure (const GstTreeStereoVegetationMeta * meta,
    const GstTreeStereoTimes * times)
{
  GstStructure *s;
  guint v;
  gchar f[64];
  const gchar *index;

  g_return_val_if_fail (meta != NULL, NULL);
  g_return_val_if_fail (meta->n_views == 1 || meta->n_views == 2, NULL);
  index = gst_tree_stereo_vegetation_index_to_string (meta->index);
  s = gst_structure_new (GST_TREE_STEREO_MESSAGE_EXGSEGMENT, "n-views", G_TYPE_UINT,
      meta->n_views, "index", G_TYPE_STRING, index ? index : "unknown", NULL);
  set_times (s, times);
  for (v = 0; v < meta->n_views; v++) {
    const GstTreeStereoVegetationView *w = &meta->views[v];
    gst_structure_set (s,
        view_field (f, sizeof f, meta->n_views, v, "present"), G_TYPE_BOOLEAN, w->present, NULL);
    gst_structure_set (s,
        view_field (f, sizeof f, meta->n_views, v, "threshold"), G_TYPE_DOUBLE, w->threshold, NULL);
    gst_structure_set (s,
        view_field (f, sizeof f, meta->n_views, v, "area"), G_TYPE_DOUBLE, w->area_px, NULL);
    gst_structure_set (s,
        view_field (f, sizeof f, meta->n_views, v, "perimeter"), G_TYPE_DOUBLE, w->perimeter_px,
        NULL);
    gst_structure_set (s,
        view_field (f, sizeof f, meta->n_views, v, "complexity"), G_TYPE_DOUBLE, w->complexity,
        NULL);
    gst_structure_set (s,
        view_field (f, sizeof f, meta->n_views, v, "centroid-x"), G_TYPE_DOUBLE, w->centroid_x,
        NULL);
    gst_structure_set (s,
        view_field (f, sizeof f, meta->n_views, v, "centroid-y"), G_TYPE_DOUBLE, w->centroid_y,
        NULL);
    gst_structure_set (s,
        view_field (f, sizeof f, meta->n_views, v, "bbox-x"), G_TYPE_INT, w->bbox_x, NULL);
    gst_structure_set (s,
        view_field (f, sizeof f, meta->n_views, v, "bbox-y"), G_TYPE_INT, w->bbox_y, NULL);
    gst_structure_set (s,
        view_field (f, sizeof f, meta->n_views, v, "bbox-width"), G_TYPE_INT, w->bbox_width, NULL);
    gst_structure_set (s,
        view_field (f, sizeof f, meta->n_views, v, "bbox-height"), G_TYPE_INT, w->bbox_height,
        NULL);
    gst_structure_set (s,
        view_field (f, sizeof f, meta->n_views, v, "regions"), G_TYPE_UINT, w->n_regions, NULL);
  }
  return s;
}

gboolean
gst_tree_stereo_vegetation_message_parse (const GstStructure * s,
    GstTreeStereoVegetationMeta * meta, GstTreeStereoTimes * times)
{
  guint v, n_views;
  gchar f[6][64];
  const gchar *index;

  g_return_val_if_fail (s != NULL && meta != NULL, FALSE);
  if (!gst_structure_has_name (s, GST_TREE_STEREO_MESSAGE_EXGSEGMENT))
    return FALSE;
  if (!gst_structure_get_uint (s, "n-views", &n_views) || (n_views != 1 && n_views != 2))
    return FALSE;
  index = gst_structure_get_string (s, "index");
  if (!index || !gst_tree_stereo_vegetation_index_from_string (index, &meta->index))
    return FALSE;
  if (!get_times (s, times))
    return FALSE;
  meta->n_views = n_views;
  for (v = 0; v < n_views; v++) {
    GstTreeStereoVegetationView *w = &meta->views[v];
    gst_tree_stereo_vegetation_view_clear (w);
    if (!gst_structure_get (s,
            view_field (f[0], 64, n_views, v, "present"), G_TYPE_BOOLEAN, &w->present,
            view_field (f[1], 64, n_views, v, "threshold"), G_TYPE_DOUBLE, &w->threshold,
            view_field (f[2], 64, n_views, v, "area"), G_TYPE_DOUBLE, &w->area_px,
            view_field (f[3], 64, n_views, v, "perimeter"), G_TYPE_DOUBLE, &w->perimeter_px,
            view_field (f[4], 64, n_views, v, "complexity"), G_TYPE_DOUBLE, &w->complexity,
            view_field (f[5], 64, n_views, v, "centroid-x"), G_TYPE_DOUBLE, &w->centroid_x,
            NULL))
      return FALSE;
    if (!gst_structure_get (s,
            view_field (f[0], 64, n_views, v, "centroid-y"), G_TYPE_DOUBLE, &w->centroid_y,
            view_field (f[1], 64, n_views, v, "bbox-x"), G_TYPE_INT, &w->bbox_x,
            view_field (f[2], 64, n_views, v, "bbox-y"), G_TYPE_INT, &w->bbox_y,
            view_field (f[3], 64, n_views, v, "bbox-width"), G_TYPE_INT, &w->bbox_width,
            view_field (f[4], 64, n_views, v, "bbox-height"), G_TYPE_INT, &w->bbox_height,
            view_field (f[5], 64, n_views, v, "regions"), G_TYPE_UINT, &w->n_regions, NULL))
      return FALSE;
  }
  return TRUE;
}

GstStructure *
gst_tree_stereo_match_message_structure (const GstTreeStereoMatchStats * st,
    const GstTreeStereoTimes * times)
{
  GstStructure *s;
  const gchar *method;

  g_return_val_if_fail (st != NULL, NULL);
  method = gst_tree_stereo_match_method_to_string (st->method);
  s = gst_structure_new (GST_TREE_STEREO_MESSAGE_SIFTMATCH,
      "method", G_TYPE_STRING, method ? method : "unknown",
      "keypoints-left", G_TYPE_UINT, st->keypoints_left,
      "keypoints-right", G_TYPE_UINT, st->keypoints_right,
      "matches", G_TYPE_UINT, st->matches,
      "candidates-tested", G_TYPE_UINT, st->candidates_tested,
      "rejected-ratio", G_TYPE_UINT, st->rejected_ratio,
      "rejected-epipolar", G_TYPE_UINT, st->rejected_epipolar,
      "rejected-disparity", G_TYPE_UINT, st->rejected_disparity,
      "rejected-mutual", G_TYPE_UINT, st->rejected_mutual,
      "rejected-refine", G_TYPE_UINT, st->rejected_refine,
      "detect-ms", G_TYPE_DOUBLE, st->detect_ms,
      "match-ms", G_TYPE_DOUBLE, st->match_ms,
      "refine-ms", G_TYPE_DOUBLE, st->refine_ms,
      "total-ms", G_TYPE_DOUBLE, st->total_ms, NULL);
  set_times (s, times);
  return s;
}

gboolean
gst_tree_stereo_match_message_parse (const GstStructure * s, GstTreeStereoMatchStats * st,
    GstTreeStereoTimes * times)
{
  const gchar *method;

  g_return_val_if_fail (s != NULL && st != NULL, FALSE);
  if (!gst_structure_has_name (s, GST_TREE_STEREO_MESSAGE_SIFTMATCH))
    return FALSE;
  method = gst_structure_get_string (s, "method");
  if (!method || !gst_tree_stereo_match_method_from_string (method, &st->method))
    return FALSE;
  return gst_structure_get (s,
      "keypoints-left", G_TYPE_UINT, &st->keypoints_left,
      "keypoints-right", G_TYPE_UINT, &st->keypoints_right,
      "matches", G_TYPE_UINT, &st->matches,
      "candidates-tested", G_TYPE_UINT, &st->candidates_tested,
      "rejected-ratio", G_TYPE_UINT, &st->rejected_ratio,
      "rejected-epipolar", G_TYPE_UINT, &st->rejected_epipolar,
      "rejected-disparity", G_TYPE_UINT, &st->rejected_disparity,
      "rejected-mutual", G_TYPE_UINT, &st->rejected_mutual,
      "rejected-refine", G_TYPE_UINT, &st->rejected_refine,
      "detect-ms", G_TYPE_DOUBLE, &st->detect_ms,
      "match-ms", G_TYPE_DOUBLE, &st->match_ms,
      "refine-ms", G_TYPE_DOUBLE, &st->refine_ms,
      "total-ms", G_TYPE_DOUBLE, &st->total_ms, NULL) && get_times (s, times);
}

GstStructure *
gst_tree_stereo_depth_message_structure (gboolean dense, const GstTreeStereoDepthStats * st,
    const GstTreeStereoTimes * times)
{
  GstStructure *s;

  g_return_val_if_fail (st != NULL, NULL);
  s = gst_structure_new (GST_TREE_STEREO_MESSAGE_STEREODEPTH,
      "mode", G_TYPE_STRING, dense ? "dense" : "sparse",
      "points", G_TYPE_UINT, st->n_points,
      "valid", G_TYPE_UINT, st->n_valid,
      "dropped-disparity", G_TYPE_UINT, st->dropped_disparity,
      "dropped-range", G_TYPE_UINT, st->dropped_range,
      "dropped-outlier", G_TYPE_UINT, st->dropped_outlier,
      "median-depth", G_TYPE_DOUBLE, st->median_z_mm,
      "mad-depth", G_TYPE_DOUBLE, st->mad_z_mm,
      "p05-depth", G_TYPE_DOUBLE, st->p05_z_mm,
      "p95-depth", G_TYPE_DOUBLE, st->p95_z_mm,
      "accept-min-depth", G_TYPE_DOUBLE, st->accept_lo_mm,
      "accept-max-depth", G_TYPE_DOUBLE, st->accept_hi_mm,
      "grid-points", G_TYPE_UINT, st->n_grid,
      "dropped-zone", G_TYPE_UINT, st->dropped_zone, NULL);
  set_times (s, times);
  return s;
}

gboolean
gst_tree_stereo_depth_message_parse (const GstStructure * s, gboolean * dense,
    GstTreeStereoDepthStats * st, GstTreeStereoTimes * times)
{
  const gchar *mode;

  g_return_val_if_fail (s != NULL && st != NULL, FALSE);
  if (!gst_structure_has_name (s, GST_TREE_STEREO_MESSAGE_STEREODEPTH))
    return FALSE;
  mode = gst_structure_get_string (s, "mode");
  if (!mode || (strcmp (mode, "dense") != 0 && strcmp (mode, "sparse") != 0))
    return FALSE;
  if (dense)
    *dense = strcmp (mode, "dense") == 0;
  return gst_structure_get (s,
      "points", G_TYPE_UINT, &st->n_points,
      "valid", G_TYPE_UINT, &st->n_valid,
      "dropped-disparity", G_TYPE_UINT, &st->dropped_disparity,
      "dropped-range", G_TYPE_UINT, &st->dropped_range,
      "dropped-outlier", G_TYPE_UINT, &st->dropped_outlier,
      "median-depth", G_TYPE_DOUBLE, &st->median_z_mm,
      "mad-depth", G_TYPE_DOUBLE, &st->mad_z_mm,
      "p05-depth", G_TYPE_DOUBLE, &st->p05_z_mm,
      "p95-depth", G_TYPE_DOUBLE, &st->p95_z_mm,
      "accept-min-depth", G_TYPE_DOUBLE, &st->accept_lo_mm,
      "accept-max-depth", G_TYPE_DOUBLE, &st->accept_hi_mm,
      "grid-points", G_TYPE_UINT, &st->n_grid,
      "dropped-zone", G_TYPE_UINT, &st->dropped_zone, NULL) && get_times (s, times);
}

/* Field names of the metrics, raw ("distance") or smoothed ("smoothed-distance"). */
static const gchar *
mfield (gchar * buf, gsize len, const gchar * prefix, const gchar * name)
{
  g_snprintf (buf, len, "%s%s", prefix, name);
  return buf;
}

/* One band as a "band" structure appended to the GstValueArray @bands (treemetrics' bands and
 * the tree records' share the layout). */
static void
append_band (GValue * bands, const GstTreeStereoBand * b)
{
  GValue v = G_VALUE_INIT;
  GstStructure *bs = gst_structure_new ("band",
      "present", G_TYPE_BOOLEAN, b->present,
      "top", G_TYPE_DOUBLE, b->top_m,
      "bottom", G_TYPE_DOUBLE, b->bottom_m,
      "left", G_TYPE_DOUBLE, b->left_m,
      "right", G_TYPE_DOUBLE, b->right_m,
      "width", G_TYPE_DOUBLE, b->width_m,
      "depth", G_TYPE_DOUBLE, b->depth_m,
      "fill", G_TYPE_DOUBLE, b->fill, NULL);
  g_value_init (&v, GST_TYPE_STRUCTURE);
  gst_value_set_structure (&v, bs);
  gst_structure_free (bs);
  gst_value_array_append_and_take_value (bands, &v);
}

static gboolean
parse_band (const GValue * v, GstTreeStereoBand * b)
{
  const GstStructure *bs;

  if (!v || !GST_VALUE_HOLDS_STRUCTURE (v))
    return FALSE;
  bs = gst_value_get_structure (v);
  return gst_structure_get (bs, "present", G_TYPE_BOOLEAN, &b->present,
      "top", G_TYPE_DOUBLE, &b->top_m, "bottom", G_TYPE_DOUBLE, &b->bottom_m,
      "left", G_TYPE_DOUBLE, &b->left_m, "right", G_TYPE_DOUBLE, &b->right_m,
      "width", G_TYPE_DOUBLE, &b->width_m, "depth", G_TYPE_DOUBLE, &b->depth_m,
      "fill", G_TYPE_DOUBLE, &b->fill, NULL);
}

static void
set_metrics (GstStructure * s, const GstTreeStereoMetrics * m, const gchar * p)
{
  gchar f[64];
  GValue bands = G_VALUE_INIT;
  guint i;
  const gchar *mode;

  mode = gst_tree_stereo_canopy_mode_to_string ((GstTreeStereoCanopyMode) m->canopy_mode);
  gst_structure_set (s, mfield (f, sizeof f, p, "tree-present"), G_TYPE_BOOLEAN,
      m->tree_present, NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "canopy-mode"), G_TYPE_STRING,
      mode ? mode : "unknown", NULL);
  if (!m->tree_present)
    return;
  gst_structure_set (s, mfield (f, sizeof f, p, "distance"), G_TYPE_DOUBLE, m->distance_m, NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "height"), G_TYPE_DOUBLE, m->height_m, NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "width"), G_TYPE_DOUBLE, m->width_m, NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "thickness"), G_TYPE_DOUBLE, m->thickness_m,
      NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "area"), G_TYPE_DOUBLE, m->area_m2, NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "perimeter"), G_TYPE_DOUBLE, m->perimeter_m,
      NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "complexity"), G_TYPE_DOUBLE, m->complexity,
      NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "centroid-x"), G_TYPE_DOUBLE, m->centroid_m[0],
      NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "centroid-y"), G_TYPE_DOUBLE, m->centroid_m[1],
      NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "centroid-z"), G_TYPE_DOUBLE, m->centroid_m[2],
      NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "clipped"), G_TYPE_UINT, m->clipped, NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "clipped-top"), G_TYPE_BOOLEAN,
      (m->clipped & GST_TREE_STEREO_CLIPPED_TOP) != 0, NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "clipped-bottom"), G_TYPE_BOOLEAN,
      (m->clipped & GST_TREE_STEREO_CLIPPED_BOTTOM) != 0, NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "clipped-left"), G_TYPE_BOOLEAN,
      (m->clipped & GST_TREE_STEREO_CLIPPED_LEFT) != 0, NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "clipped-right"), G_TYPE_BOOLEAN,
      (m->clipped & GST_TREE_STEREO_CLIPPED_RIGHT) != 0, NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "points"), G_TYPE_UINT, m->n_points, NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "matches"), G_TYPE_UINT, m->n_matches, NULL);
  gst_structure_set (s, mfield (f, sizeof f, p, "confidence"), G_TYPE_DOUBLE, m->confidence,
      NULL);

  g_value_init (&bands, GST_TYPE_ARRAY);
  for (i = 0; i < m->n_bands; i++)
    append_band (&bands, &m->bands[i]);
  gst_structure_take_value (s, mfield (f, sizeof f, p, "bands"), &bands);
}

static gboolean
get_metrics (const GstStructure * s, GstTreeStereoMetrics * m, const gchar * p)
{
  gchar f[12][64];
  const GValue *bands;
  guint i, n;

  GstTreeStereoCanopyMode mode;

  gst_tree_stereo_metrics_clear (m);
  if (!gst_structure_get_boolean (s, mfield (f[0], 64, p, "tree-present"), &m->tree_present))
    return FALSE;
  if (!gst_tree_stereo_canopy_mode_from_string (gst_structure_get_string (s, mfield (f[0], 64, p,
                  "canopy-mode")), &mode))
    return FALSE;
  m->canopy_mode = mode;
  if (!m->tree_present)
    return TRUE;
  if (!gst_structure_get (s,
          mfield (f[0], 64, p, "distance"), G_TYPE_DOUBLE, &m->distance_m,
          mfield (f[1], 64, p, "height"), G_TYPE_DOUBLE, &m->height_m,
          mfield (f[2], 64, p, "width"), G_TYPE_DOUBLE, &m->width_m,
          mfield (f[3], 64, p, "thickness"), G_TYPE_DOUBLE, &m->thickness_m,
          mfield (f[4], 64, p, "area"), G_TYPE_DOUBLE, &m->area_m2,
          mfield (f[5], 64, p, "perimeter"), G_TYPE_DOUBLE, &m->perimeter_m,
          mfield (f[6], 64, p, "complexity"), G_TYPE_DOUBLE, &m->complexity,
          mfield (f[7], 64, p, "centroid-x"), G_TYPE_DOUBLE, &m->centroid_m[0],
          mfield (f[8], 64, p, "centroid-y"), G_TYPE_DOUBLE, &m->centroid_m[1],
          mfield (f[9], 64, p, "centroid-z"), G_TYPE_DOUBLE, &m->centroid_m[2],
          mfield (f[10], 64, p, "clipped"), G_TYPE_UINT, &m->clipped, NULL))
    return FALSE;
  if (!gst_structure_get (s,
          mfield (f[0], 64, p, "points"), G_TYPE_UINT, &m->n_points,
          mfield (f[1], 64, p, "matches"), G_TYPE_UINT, &m->n_matches,
          mfield (f[2], 64, p, "confidence"), G_TYPE_DOUBLE, &m->confidence, NULL))
    return FALSE;
  bands = gst_structure_get_value (s, mfield (f[0], 64, p, "bands"));
  if (!bands || !GST_VALUE_HOLDS_ARRAY (bands))
    return FALSE;
  n = gst_value_array_get_size (bands);
  gst_tree_stereo_metrics_set_n_bands (m, n);
  for (i = 0; i < n; i++)
    if (!parse_band (gst_value_array_get_value (bands, i), &m->bands[i]))
      return FALSE;
  return TRUE;
}

/* The travel fields of the treemetrics message into @m. */
static gboolean
get_travel (const GstStructure * s, GstTreeStereoMetrics * m)
{
  GstTreeStereoTravelSource source;

  if (!gst_tree_stereo_travel_source_from_string (gst_structure_get_string (s,
              "travel-source"), &source))
    return FALSE;
  m->travel_source = source;
  if (!gst_structure_get (s, "travel-m", G_TYPE_DOUBLE, &m->travel_m,
          "position-m", G_TYPE_DOUBLE, &m->position_m, NULL))
    return FALSE;
  /* optional: messages recorded before the row's direction was measured */
  if (!gst_structure_get (s, "row-direction-x", G_TYPE_DOUBLE, &m->row_direction[0],
          "row-direction-y", G_TYPE_DOUBLE, &m->row_direction[1],
          "row-direction-z", G_TYPE_DOUBLE, &m->row_direction[2], NULL)) {
    m->row_direction[0] = 1;
    m->row_direction[1] = m->row_direction[2] = 0;
  }
  return TRUE;
}

GstStructure *
gst_tree_stereo_metrics_message_structure (const GstTreeStereoMetrics * metrics,
    const GstTreeStereoMetrics * smoothed, const GstTreeStereoTimes * times)
{
  GstStructure *s;
  const gchar *source;

  g_return_val_if_fail (metrics != NULL, NULL);
  s = gst_structure_new_empty (GST_TREE_STEREO_MESSAGE_TREEMETRICS);
  set_times (s, times);
  source = gst_tree_stereo_travel_source_to_string ((GstTreeStereoTravelSource)
      metrics->travel_source);
  /* the rig's travel is one per frame: not repeated under "smoothed-" */
  gst_structure_set (s, "travel-m", G_TYPE_DOUBLE, metrics->travel_m,
      "position-m", G_TYPE_DOUBLE, metrics->position_m,
      "travel-source", G_TYPE_STRING, source ? source : "none",
      "row-direction-x", G_TYPE_DOUBLE, metrics->row_direction[0],
      "row-direction-y", G_TYPE_DOUBLE, metrics->row_direction[1],
      "row-direction-z", G_TYPE_DOUBLE, metrics->row_direction[2], NULL);
  set_metrics (s, metrics, "");
  if (smoothed)
    set_metrics (s, smoothed, "smoothed-");
  return s;
}

gboolean
gst_tree_stereo_metrics_message_parse (const GstStructure * s, GstTreeStereoMetrics * metrics,
    GstTreeStereoMetrics * smoothed, GstTreeStereoTimes * times)
{
  g_return_val_if_fail (s != NULL && metrics != NULL, FALSE);
  if (!gst_structure_has_name (s, GST_TREE_STEREO_MESSAGE_TREEMETRICS))
    return FALSE;
  if (!get_times (s, times) || !get_metrics (s, metrics, ""))
    return FALSE;
  if (smoothed && !get_metrics (s, smoothed, "smoothed-"))
    return FALSE;
  if (!get_travel (s, metrics))
    return FALSE;
  if (smoothed) {
    smoothed->travel_m = metrics->travel_m;
    smoothed->position_m = metrics->position_m;
    smoothed->travel_source = metrics->travel_source;
    memcpy (smoothed->row_direction, metrics->row_direction, sizeof metrics->row_direction);
  }
  return TRUE;
}

/* ---------------------------------------------------------------------------------------------
 * Tree records
 * --------------------------------------------------------------------------------------------- */

void
gst_tree_stereo_tree_record_clear (GstTreeStereoTreeRecord * record)
{
  g_return_if_fail (record != NULL);
  g_free (record->bands);
  memset (record, 0, sizeof (*record));
}

void
gst_tree_stereo_tree_record_set_n_bands (GstTreeStereoTreeRecord * record, guint n)
{
  g_return_if_fail (record != NULL);
  g_free (record->bands);
  record->bands = n ? g_new0 (GstTreeStereoBand, n) : NULL;
  record->n_bands = n;
}

GstStructure *
gst_tree_stereo_tree_message_structure (const GstTreeStereoTreeRecord * r,
    const GstTreeStereoTimes * times)
{
  GstStructure *s;
  const gchar *mode;

  g_return_val_if_fail (r != NULL, NULL);
  mode = gst_tree_stereo_canopy_mode_to_string (r->mode);
  s = gst_structure_new_empty (GST_TREE_STEREO_MESSAGE_TREE);
  set_times (s, times);
  gst_structure_set (s,
      "id", G_TYPE_UINT, r->id,
      "canopy-mode", G_TYPE_STRING, mode ? mode : "unknown",
      "segment", G_TYPE_BOOLEAN, r->mode == GST_TREE_STEREO_CANOPY_ROW,
      "complete", G_TYPE_BOOLEAN, r->complete,
      "start-seen", G_TYPE_BOOLEAN, r->start_seen,
      "end-seen", G_TYPE_BOOLEAN, r->end_seen,
      "lost", G_TYPE_BOOLEAN, r->lost,
      "position-m", G_TYPE_DOUBLE, r->position_m,
      "start-m", G_TYPE_DOUBLE, r->start_m,
      "end-m", G_TYPE_DOUBLE, r->end_m,
      "frames", G_TYPE_UINT, r->frames,
      "frames-seen", G_TYPE_UINT, r->frames_seen, NULL);
  if (r->has_height)
    gst_structure_set (s, "height-m", G_TYPE_DOUBLE, r->height_m, NULL);
  if (r->has_width)
    gst_structure_set (s, "width-m", G_TYPE_DOUBLE, r->width_m, NULL);
  if (r->has_depth) {
    GValue bands = G_VALUE_INIT;
    guint i;
    gst_structure_set (s, "distance-m", G_TYPE_DOUBLE, r->distance_m,
        "thickness-m", G_TYPE_DOUBLE, r->thickness_m,
        "confidence", G_TYPE_DOUBLE, r->confidence, NULL);
    g_value_init (&bands, GST_TYPE_ARRAY);
    for (i = 0; i < r->n_bands; i++)
      append_band (&bands, &r->bands[i]);
    gst_structure_take_value (s, "bands", &bands);
  }
  if (r->has_spacing)
    gst_structure_set (s, "spacing-m", G_TYPE_DOUBLE, r->spacing_m,
        "gap-m", G_TYPE_DOUBLE, r->gap_m, NULL);
  return s;
}

gboolean
gst_tree_stereo_tree_message_parse (const GstStructure * s, GstTreeStereoTreeRecord * r,
    GstTreeStereoTimes * times)
{
  GstTreeStereoCanopyMode mode;

  g_return_val_if_fail (s != NULL && r != NULL, FALSE);
  gst_tree_stereo_tree_record_clear (r);
  if (!gst_structure_has_name (s, GST_TREE_STEREO_MESSAGE_TREE) || !get_times (s, times))
    return FALSE;
  if (!gst_tree_stereo_canopy_mode_from_string (gst_structure_get_string (s, "canopy-mode"),
          &mode))
    return FALSE;
  r->mode = mode;
  if (!gst_structure_get (s,
          "id", G_TYPE_UINT, &r->id,
          "complete", G_TYPE_BOOLEAN, &r->complete,
          "start-seen", G_TYPE_BOOLEAN, &r->start_seen,
          "end-seen", G_TYPE_BOOLEAN, &r->end_seen,
          "lost", G_TYPE_BOOLEAN, &r->lost,
          "position-m", G_TYPE_DOUBLE, &r->position_m,
          "start-m", G_TYPE_DOUBLE, &r->start_m,
          "end-m", G_TYPE_DOUBLE, &r->end_m,
          "frames", G_TYPE_UINT, &r->frames,
          "frames-seen", G_TYPE_UINT, &r->frames_seen, NULL))
    return FALSE;
  if (gst_structure_has_field (s, "height-m")) {
    if (!gst_structure_get_double (s, "height-m", &r->height_m))
      return FALSE;
    r->has_height = TRUE;
  }
  if (gst_structure_has_field (s, "width-m")) {
    if (!gst_structure_get_double (s, "width-m", &r->width_m))
      return FALSE;
    r->has_width = TRUE;
  }
  if (gst_structure_has_field (s, "distance-m")) {
    const GValue *bands = gst_structure_get_value (s, "bands");
    guint i, n;
    if (!gst_structure_get (s, "distance-m", G_TYPE_DOUBLE, &r->distance_m,
            "thickness-m", G_TYPE_DOUBLE, &r->thickness_m,
            "confidence", G_TYPE_DOUBLE, &r->confidence, NULL))
      return FALSE;
    if (!bands || !GST_VALUE_HOLDS_ARRAY (bands))
      return FALSE;
    n = gst_value_array_get_size (bands);
    gst_tree_stereo_tree_record_set_n_bands (r, n);
    for (i = 0; i < n; i++)
      if (!parse_band (gst_value_array_get_value (bands, i), &r->bands[i]))
        return FALSE;
    r->has_depth = TRUE;
  }
  if (gst_structure_has_field (s, "spacing-m")) {
    if (!gst_structure_get (s, "spacing-m", G_TYPE_DOUBLE, &r->spacing_m,
            "gap-m", G_TYPE_DOUBLE, &r->gap_m, NULL))
      return FALSE;
    r->has_spacing = TRUE;
  }
  return TRUE;
}

void
gst_tree_stereo_canopy_message_add (GstStructure * s, const GstTreeStereoCanopyMeta * meta)
{
  const gchar *mode;

  g_return_if_fail (s != NULL && meta != NULL);
  mode = gst_tree_stereo_canopy_mode_to_string (meta->mode);
  gst_structure_set (s,
      "canopy-present", G_TYPE_BOOLEAN, meta->view.present,
      "canopy-mode", G_TYPE_STRING, mode ? mode : "unknown",
      "canopy-near", G_TYPE_DOUBLE, meta->near_m,
      "canopy-far", G_TYPE_DOUBLE, meta->far_m,
      "ground-found", G_TYPE_BOOLEAN, meta->ground_found,
      "segments", G_TYPE_UINT, meta->n_segments,
      "canopy-points", G_TYPE_UINT, meta->n_canopy_points, NULL);
}

gboolean
gst_tree_stereo_canopy_message_parse (const GstStructure * s, GstTreeStereoCanopyMeta * meta)
{
  GstTreeStereoCanopyMode mode;

  g_return_val_if_fail (s != NULL && meta != NULL, FALSE);
  if (!gst_tree_stereo_canopy_mode_from_string (gst_structure_get_string (s, "canopy-mode"),
          &mode))
    return FALSE;
  gst_tree_stereo_vegetation_view_clear (&meta->view);
  meta->mode = mode;
  return gst_structure_get (s,
      "canopy-present", G_TYPE_BOOLEAN, &meta->view.present,
      "canopy-near", G_TYPE_DOUBLE, &meta->near_m,
      "canopy-far", G_TYPE_DOUBLE, &meta->far_m,
      "ground-found", G_TYPE_BOOLEAN, &meta->ground_found,
      "segments", G_TYPE_UINT, &meta->n_segments,
      "canopy-points", G_TYPE_UINT, &meta->n_canopy_points, NULL);
}

GstStructure *
gst_tree_stereo_section_message_structure (const GstTreeStereoSectionCommand * c)
{
  g_return_val_if_fail (c != NULL, NULL);
  return gst_structure_new (GST_TREE_STEREO_MESSAGE_SECTION,
      "section", G_TYPE_UINT, c->section,
      "on", G_TYPE_BOOLEAN, c->on,
      "rate", G_TYPE_DOUBLE, c->rate,
      "at-ns", G_TYPE_INT64, c->at_ns,
      "position-m", G_TYPE_DOUBLE, c->position_m,
      "fallback", G_TYPE_BOOLEAN, c->fallback, NULL);
}

gboolean
gst_tree_stereo_section_message_parse (const GstStructure * s,
    GstTreeStereoSectionCommand * c)
{
  g_return_val_if_fail (s != NULL && c != NULL, FALSE);
  memset (c, 0, sizeof (*c));
  if (!gst_structure_has_name (s, GST_TREE_STEREO_MESSAGE_SECTION))
    return FALSE;
  return gst_structure_get (s,
      "section", G_TYPE_UINT, &c->section,
      "on", G_TYPE_BOOLEAN, &c->on,
      "rate", G_TYPE_DOUBLE, &c->rate,
      "at-ns", G_TYPE_INT64, &c->at_ns,
      "position-m", G_TYPE_DOUBLE, &c->position_m,
      "fallback", G_TYPE_BOOLEAN, &c->fallback, NULL);
}
