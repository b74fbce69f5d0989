/* treestereo: metas and element messages of the treestereo plugin set
 *
 * One public header, plain C. Every element of the plugin set attaches one of these metas to
 * the buffers it handles and posts an element message with the same figures; applications read
 * either. Pixel coordinates are in rectified-view pixels (each view's own coordinates, the right
 * view's x not offset by the side-by-side layout), 3D values in the rectified-left camera frame
 * (x right, y down, z forward).
 *
 * Link with pkg-config gsttreestereo-1.0.
 */
#ifndef __GST_TREE_STEREO_META_H__
#define __GST_TREE_STEREO_META_H__

#include <gst/gst.h>
#include <gst/video/video.h>

G_BEGIN_DECLS

#define GST_TREE_STEREO_LEFT 0
#define GST_TREE_STEREO_RIGHT 1

/* -------------------------------------------------------------------------------------------
 * Stereo geometry (stereorectify)
 * ------------------------------------------------------------------------------------------- */

/**
 * GstTreeStereoGeometryMeta:
 * @view_width: width of one rectified view (the frame is 2 * view_width wide when side by side)
 * @view_height: height of one rectified view
 * @side_by_side: TRUE when the buffer holds both views side by side, FALSE for one view
 * @rectified: TRUE when the pixels were rectified (FALSE: passed through as already rectified)
 * @fx: rectified focal length in x (px) per view ([0] left, [1] right)
 * @fy: rectified focal length in y (px) per view
 * @cx: principal point x (px) per view
 * @cy: principal point y (px) per view
 * @baseline_mm: distance between the optical centres (mm)
 * @Q: 4x4 disparity-to-depth matrix, row major (cv::stereoRectify's Q), disparity = xl - xr
 * @R1: 3x3 rotation from the (unrectified) left camera frame to the rectified-left frame
 * @pts: the original timestamps of the left and right frames
 * @skew_ns: pts[right] - pts[left] in running time (ns)
 *
 * Added by stereorectify. Depth of a point with disparity d: Z = fx[0] * baseline_mm / (d - doffs)
 * where doffs = cx[0] - cx[1] (0 after OpenCV's rectification with CALIB_ZERO_DISPARITY).
 */
typedef struct {
  GstMeta meta;

  guint view_width;
  guint view_height;
  gboolean side_by_side;
  gboolean rectified;
  gdouble fx[2];
  gdouble fy[2];
  gdouble cx[2];
  gdouble cy[2];
  gdouble baseline_mm;
  gdouble Q[16];
  gdouble R1[9];
  GstClockTime pts[2];
  gint64 skew_ns;
} GstTreeStereoGeometryMeta;

GType gst_tree_stereo_geometry_meta_api_get_type (void);
const GstMetaInfo *gst_tree_stereo_geometry_meta_get_info (void);
#define GST_TREE_STEREO_GEOMETRY_META_API_TYPE (gst_tree_stereo_geometry_meta_api_get_type ())
#define GST_TREE_STEREO_GEOMETRY_META_INFO (gst_tree_stereo_geometry_meta_get_info ())

/* Adds a geometry meta with all fields zero and pts invalid; the caller fills it in. */
GstTreeStereoGeometryMeta *gst_buffer_add_tree_stereo_geometry_meta (GstBuffer *buffer);
#define gst_buffer_get_tree_stereo_geometry_meta(b) \
  ((GstTreeStereoGeometryMeta *) gst_buffer_get_meta ((b), GST_TREE_STEREO_GEOMETRY_META_API_TYPE))

/* Disparity offset cx[0] - cx[1] (px). */
gdouble gst_tree_stereo_geometry_meta_doffs (const GstTreeStereoGeometryMeta *meta);

/* -------------------------------------------------------------------------------------------
 * Vegetation (exgsegment)
 * ------------------------------------------------------------------------------------------- */

typedef enum {
  GST_TREE_STEREO_INDEX_EXG = 0,          /* 2G - R - B */
  GST_TREE_STEREO_INDEX_EXG_EXR = 1,      /* ExG - ExR, ExR = 1.4R - G */
  GST_TREE_STEREO_INDEX_EXG_NORM = 2,     /* 2g - r - b on chromatic coordinates r = R/(R+G+B) */
  GST_TREE_STEREO_INDEX_EXG_EXR_NORM = 3, /* ExG - ExR on chromatic coordinates */
} GstTreeStereoVegetationIndex;

/**
 * GstTreeStereoVegetationView:
 * @present: TRUE when a canopy was found in this view; all other figures are 0 otherwise
 * @threshold: the index threshold used (Otsu's or the fixed one), in the index's own units
 * @area_px: canopy area (px)
 * @perimeter_px: canopy perimeter (px), of the outer contour(s)
 * @complexity: perimeter^2 / (4 pi area), 1 for a disc
 * @centroid_x: centroid x (px)
 * @centroid_y: centroid y (px)
 * @bbox_x: bounding box of the canopy (px)
 * @n_regions: number of connected regions kept
 * @n_contour: number of points in @contour
 * @contour: outer contour of the largest region, @n_contour (x, y) pairs, px
 * @mask: a GRAY8 mask of the whole view (255 canopy, 0 not), @mask_stride bytes per row, or NULL
 */
typedef struct {
  gboolean present;
  gdouble threshold;
  gdouble area_px;
  gdouble perimeter_px;
  gdouble complexity;
  gdouble centroid_x;
  gdouble centroid_y;
  gint bbox_x;
  gint bbox_y;
  gint bbox_width;
  gint bbox_height;
  guint n_regions;
  guint n_contour;
  gint32 *contour;
  GstBuffer *mask;
  guint mask_width;
  guint mask_height;
  guint mask_stride;
} GstTreeStereoVegetationView;

/**
 * GstTreeStereoVegetationMeta:
 * @n_views: 2 for a side-by-side stereo frame, 1 for a mono-view stream
 * @index: the vegetation index used
 * @views: per view figures, [0] left (or the only view), [1] right
 */
typedef struct {
  GstMeta meta;

  guint n_views;
  GstTreeStereoVegetationIndex index;
  GstTreeStereoVegetationView views[2];
} GstTreeStereoVegetationMeta;

GType gst_tree_stereo_vegetation_meta_api_get_type (void);
const GstMetaInfo *gst_tree_stereo_vegetation_meta_get_info (void);
#define GST_TREE_STEREO_VEGETATION_META_API_TYPE (gst_tree_stereo_vegetation_meta_api_get_type ())
#define GST_TREE_STEREO_VEGETATION_META_INFO (gst_tree_stereo_vegetation_meta_get_info ())

GstTreeStereoVegetationMeta *gst_buffer_add_tree_stereo_vegetation_meta (GstBuffer *buffer,
    guint n_views);
#define gst_buffer_get_tree_stereo_vegetation_meta(b) \
  ((GstTreeStereoVegetationMeta *) gst_buffer_get_meta ((b), GST_TREE_STEREO_VEGETATION_META_API_TYPE))

/* Sets the contour of @view (copies @n (x, y) pairs). */
void gst_tree_stereo_vegetation_view_set_contour (GstTreeStereoVegetationView *view,
    const gint32 *xy, guint n);
/* Sets the mask of @view (takes a ref on @mask). */
void gst_tree_stereo_vegetation_view_set_mask (GstTreeStereoVegetationView *view,
    GstBuffer *mask, guint width, guint height, guint stride);
/* Copies all figures, the contour and a ref of the mask of @src into @dest (cleared first). */
void gst_tree_stereo_vegetation_view_copy (GstTreeStereoVegetationView *dest,
    const GstTreeStereoVegetationView *src);
/* Frees the contour, drops the mask and zeroes the view. */
void gst_tree_stereo_vegetation_view_clear (GstTreeStereoVegetationView *view);

/* -------------------------------------------------------------------------------------------
 * Stereo matches (siftmatch)
 * ------------------------------------------------------------------------------------------- */

typedef enum {
  GST_TREE_STEREO_MATCH_EUCLIDEAN = 0,   /* nearest neighbour on L2 distance + ratio test */
  GST_TREE_STEREO_MATCH_COSINE_NORM = 1, /* the paper's: smallest angles, then closest norms */
} GstTreeStereoMatchMethod;

/**
 * GstTreeStereoMatch:
 * @xl: left x (px, rectified left view)
 * @yl: left y
 * @xr: right x (px, rectified right view's own coordinates); disparity = xl - xr
 * @yr: right y
 * @score: the matcher's score (descriptor distance or angle; smaller is better)
 */
typedef struct {
  gfloat xl;
  gfloat yl;
  gfloat xr;
  gfloat yr;
  gfloat score;
} GstTreeStereoMatch;

typedef struct {
  GstMeta meta;

  GstTreeStereoMatchMethod method;
  guint n_keypoints[2];
  guint n_matches;
  GstTreeStereoMatch *matches;
} GstTreeStereoMatchesMeta;

GType gst_tree_stereo_matches_meta_api_get_type (void);
const GstMetaInfo *gst_tree_stereo_matches_meta_get_info (void);
#define GST_TREE_STEREO_MATCHES_META_API_TYPE (gst_tree_stereo_matches_meta_api_get_type ())
#define GST_TREE_STEREO_MATCHES_META_INFO (gst_tree_stereo_matches_meta_get_info ())

/* Adds a matches meta holding a copy of @n_matches @matches (may be NULL when 0). */
GstTreeStereoMatchesMeta *gst_buffer_add_tree_stereo_matches_meta (GstBuffer *buffer,
    GstTreeStereoMatchMethod method, guint n_keypoints_left, guint n_keypoints_right,
    const GstTreeStereoMatch *matches, guint n_matches);
#define gst_buffer_get_tree_stereo_matches_meta(b) \
  ((GstTreeStereoMatchesMeta *) gst_buffer_get_meta ((b), GST_TREE_STEREO_MATCHES_META_API_TYPE))

/* -------------------------------------------------------------------------------------------
 * Stereo points (stereodepth)
 * ------------------------------------------------------------------------------------------- */

/**
 * GstTreeStereoPoint:
 * @x: X (mm), rectified-left camera frame
 * @y: Y (mm)
 * @z: Z, depth (mm)
 * @match_index: index of the match in the matches meta this point comes from; for dense
 *   points and densification grid points (the trailing #GstTreeStereoDepthStats.n_grid ones)
 *   the left-view pixel index y * view width + x
 * @valid: FALSE when the point was dropped (out of range or an outlier)
 */
typedef struct {
  gfloat x;
  gfloat y;
  gfloat z;
  guint32 match_index;
  gboolean valid;
} GstTreeStereoPoint;

/**
 * GstTreeStereoDepthStats:
 * @n_points: points computed
 * @n_valid: points kept
 * @dropped_range: dropped as outside [min-depth, max-depth]
 * @dropped_outlier: dropped as outliers of the depth distribution
 * @median_z_mm: median depth of the kept points (0 when none)
 * @mad_z_mm: median absolute deviation of the kept depths
 * @p05_z_mm: 5th percentile of the kept depths
 * @p95_z_mm: 95th percentile
 * @dropped_disparity: points without a finite depth (disparity - doffs <= 0); not in @n_valid
 * @accept_lo_mm: nearest depth accepted after the range and outlier cuts (0 when none kept)
 * @accept_hi_mm: farthest depth accepted after the range and outlier cuts (0 when none kept)
 * @n_grid: of @n_points, how many are grid points of stereodepth's densification; they are
 *   the last @n_grid points of the points meta (the first @n_points - @n_grid are the matches')
 * @dropped_zone: dropped as off the 3D canopy (another tree, the next row, the ground; see
 *   #GstTreeStereoCanopyMeta), before the range and outlier cuts
 */
typedef struct {
  guint n_points;
  guint n_valid;
  guint dropped_range;
  guint dropped_outlier;
  gdouble median_z_mm;
  gdouble mad_z_mm;
  gdouble p05_z_mm;
  gdouble p95_z_mm;
  guint dropped_disparity;
  gdouble accept_lo_mm;
  gdouble accept_hi_mm;
  guint n_grid;
  guint dropped_zone;
} GstTreeStereoDepthStats;

/**
 * GstTreeStereoPointsMeta:
 * @dense: TRUE when the points come from a dense disparity map
 * @depth_map: optional GRAY16_LE depth map (mm, 0 = unknown) covering the left-view rectangle
 *   (@depth_x, @depth_y, @depth_width, @depth_height), @depth_stride bytes per row
 */
typedef struct {
  GstMeta meta;

  gboolean dense;
  guint n_points;
  GstTreeStereoPoint *points;
  GstTreeStereoDepthStats stats;
  GstBuffer *depth_map;
  gint depth_x;
  gint depth_y;
  guint depth_width;
  guint depth_height;
  guint depth_stride;
} GstTreeStereoPointsMeta;

GType gst_tree_stereo_points_meta_api_get_type (void);
const GstMetaInfo *gst_tree_stereo_points_meta_get_info (void);
#define GST_TREE_STEREO_POINTS_META_API_TYPE (gst_tree_stereo_points_meta_api_get_type ())
#define GST_TREE_STEREO_POINTS_META_INFO (gst_tree_stereo_points_meta_get_info ())

/* Adds a points meta holding a copy of @n_points @points and @stats (may be NULL: zeroes). */
GstTreeStereoPointsMeta *gst_buffer_add_tree_stereo_points_meta (GstBuffer *buffer,
    const GstTreeStereoPoint *points, guint n_points, const GstTreeStereoDepthStats *stats);
#define gst_buffer_get_tree_stereo_points_meta(b) \
  ((GstTreeStereoPointsMeta *) gst_buffer_get_meta ((b), GST_TREE_STEREO_POINTS_META_API_TYPE))
/* Sets the dense depth map (takes a ref on @map). */
void gst_tree_stereo_points_meta_set_depth_map (GstTreeStereoPointsMeta *meta, GstBuffer *map,
    gint x, gint y, guint width, guint height, guint stride);

/* -------------------------------------------------------------------------------------------
 * The 3D canopy (stereodepth)
 * ------------------------------------------------------------------------------------------- */

/**
 * GstTreeStereoCanopyMode:
 * @GST_TREE_STEREO_CANOPY_COLOUR: no 3D canopy upstream: the canopy is the colour silhouette
 *   (exgsegment's vegetation in the left view)
 * @GST_TREE_STEREO_CANOPY_TREE: the tree in front, decided in 3D (near row, above the ground,
 *   separated from its neighbours along the row)
 * @GST_TREE_STEREO_CANOPY_ROW: the near row's vegetation in view, decided in 3D (hedgerows,
 *   fruit walls)
 *
 * What "the canopy" measured is. Names in messages: "colour", "tree", "row".
 */
typedef enum {
  GST_TREE_STEREO_CANOPY_COLOUR = 0,
  GST_TREE_STEREO_CANOPY_TREE = 1,
  GST_TREE_STEREO_CANOPY_ROW = 2,
} GstTreeStereoCanopyMode;

GType gst_tree_stereo_canopy_mode_get_type (void);
#define GST_TYPE_TREE_STEREO_CANOPY_MODE (gst_tree_stereo_canopy_mode_get_type ())

/**
 * GstTreeStereoRowSegment:
 * @lo_m: X of the segment's leftmost point (m, rectified-left frame)
 * @hi_m: X of its rightmost point (m)
 * @near_m: its front depth, the 5th percentile of its points' Z (m)
 * @n_points: 3D points in it
 * @selected: TRUE when it is part of the canopy the meta's @view is (mode tree: the tree in
 *   front; mode row: every segment)
 * @joined_lo: TRUE when it is cut from the segment before it where their crowns touch (no
 *   empty stretch between them: two trees grown into each other, mode tree)
 * @joined_hi: likewise with the segment after it
 * @lo_z_m: Z of its leftmost point (m; 0: unknown)
 * @hi_z_m: Z of its rightmost point (m; 0: unknown)
 * @lo_clear_m: how far inside the stereo view's left edge its points keep: the least distance
 *   along x of any of its points from that edge's ray at the point's own depth (m; NaN: unknown)
 * @hi_clear_m: likewise from the view's right edge
 * @trunk_m: X of its trunk where it shows below the crown (m; NaN: not seen; mode tree, the
 *   selected segment)
 * @lo_y_m: Y (downwards) of its leftmost point (m; 0: unknown). Along the row a point lies at
 *   its projection on the row's direction, which a rolled view gives a Y component
 * @hi_y_m: Y of its rightmost point (m; 0: unknown)
 * @trunk_y_m: Y of the rows @trunk_m was read in (m)
 *
 * One stretch of the near row along x, separated from the next by an empty stretch (mode tree),
 * or one continuous canopy (mode row).
 */
typedef struct {
  gdouble lo_m;
  gdouble hi_m;
  gdouble near_m;
  guint n_points;
  gboolean selected;
  gboolean joined_lo;
  gboolean joined_hi;
  gdouble lo_z_m;
  gdouble hi_z_m;
  gdouble lo_clear_m;
  gdouble hi_clear_m;
  gdouble trunk_m;
  gdouble lo_y_m;
  gdouble hi_y_m;
  gdouble trunk_y_m;
} GstTreeStereoRowSegment;

/* Segments a canopy meta holds at most (the view of a rig between two rows holds a few). */
#define GST_TREE_STEREO_MAX_SEGMENTS 16

/**
 * GstTreeStereoCanopyMeta:
 * @mode: #GST_TREE_STEREO_CANOPY_TREE or #GST_TREE_STEREO_CANOPY_ROW
 * @view: the 3D canopy's silhouette in the LEFT view, as the vegetation meta's views are (its
 *   mask a GstBuffer shared by reference, contour, area, bbox...); @view.present FALSE: no
 *   canopy in the zone (the tree is absent, whatever colour says)
 * @near_m: the depth zone used, nearest Z (m)
 * @far_m: the depth zone used, farthest Z (m)
 * @zone_from_data: TRUE when the zone is the near row found in the data, FALSE the user's
 *   spray zone
 * @ground_found: TRUE when a ground plane was found (fitted or from the rig)
 * @ground_normal: the ground plane's unit normal (pointing up), rectified-left frame
 * @ground_d_m: the plane's offset: normal . X + d = 0 (X in m)
 * @n_segments: near-row segments along the row
 * @left_m: X of the selected canopy's leftmost point (m)
 * @right_m: X of its rightmost point (m)
 * @n_points: 3D points the decision was made on
 * @n_canopy_points: of them, on the selected canopy
 * @n_seam_pixels: mask pixels decided by the photo-consistency test on a seam
 * @n_stored_segments: how many of the @n_segments segments @segments holds
 *   (MIN (@n_segments, #GST_TREE_STEREO_MAX_SEGMENTS): the leftmost ones)
 * @segments: the near row's segments along the row, left to right (treemetrics follows the
 *   trees along the row with them)
 * @cut_lo_m: mode tree: X (m) where the selected tree's part of the row begins, halfway across
 *   the gap to its left neighbour (or where joined crowns meet); -infinity: no neighbour. @view
 *   holds no canopy left of it, whatever the view shows there (mode row: -infinity)
 * @cut_hi_m: likewise where it ends (+infinity: no neighbour)
 * @row_view: mode tree, on a stream's first frame (the first after the caps are set, or one
 *   flagged DISCONT): the near row's canopy as mode row decides it, the neighbours in view
 *   included. The part of the row behind the first tree in view is no later frame's tree: the
 *   row map takes it from here. Not present on other frames and in mode row (@view is the row)
 *
 * Added by stereodepth when it decides the canopy in 3D. treemetrics measures @view instead of
 * the vegetation meta's left view, treeoverlay outlines it.
 */
typedef struct {
  GstMeta meta;

  GstTreeStereoCanopyMode mode;
  GstTreeStereoVegetationView view;
  gdouble near_m;
  gdouble far_m;
  gboolean zone_from_data;
  gboolean ground_found;
  gdouble ground_normal[3];
  gdouble ground_d_m;
  guint n_segments;
  gdouble left_m;
  gdouble right_m;
  guint n_points;
  guint n_canopy_points;
  guint n_seam_pixels;
  guint n_stored_segments;
  GstTreeStereoRowSegment segments[GST_TREE_STEREO_MAX_SEGMENTS];
  gdouble cut_lo_m;
  gdouble cut_hi_m;
  GstTreeStereoVegetationView row_view;
} GstTreeStereoCanopyMeta;

GType gst_tree_stereo_canopy_meta_api_get_type (void);
const GstMetaInfo *gst_tree_stereo_canopy_meta_get_info (void);
#define GST_TREE_STEREO_CANOPY_META_API_TYPE (gst_tree_stereo_canopy_meta_api_get_type ())
#define GST_TREE_STEREO_CANOPY_META_INFO (gst_tree_stereo_canopy_meta_get_info ())

/* Adds a canopy meta with all figures zero (an empty view; the segments' clearances NaN,
 * unknown; the cuts infinite, none) in @mode; the caller fills it in. */
GstTreeStereoCanopyMeta *gst_buffer_add_tree_stereo_canopy_meta (GstBuffer *buffer,
    GstTreeStereoCanopyMode mode);
#define gst_buffer_get_tree_stereo_canopy_meta(b) \
  ((GstTreeStereoCanopyMeta *) gst_buffer_get_meta ((b), GST_TREE_STEREO_CANOPY_META_API_TYPE))

/* -------------------------------------------------------------------------------------------
 * Tree metrics (treemetrics)
 * ------------------------------------------------------------------------------------------- */

typedef enum {
  GST_TREE_STEREO_CLIPPED_NONE = 0,
  GST_TREE_STEREO_CLIPPED_TOP = (1 << 0),
  GST_TREE_STEREO_CLIPPED_BOTTOM = (1 << 1),
  GST_TREE_STEREO_CLIPPED_LEFT = (1 << 2),
  GST_TREE_STEREO_CLIPPED_RIGHT = (1 << 3),
} GstTreeStereoClipped;

/**
 * GstTreeStereoBand:
 * @present: FALSE when the band holds no canopy; the other values are then 0
 * @top_m: Y of the band's top (m)
 * @bottom_m: Y of the band's bottom (m)
 * @left_m: X of the canopy's left edge in the band (m)
 * @right_m: X of the right edge (m)
 * @width_m: right_m - left_m
 * @depth_m: nearest-face depth of the canopy in the band (m)
 * @fill: share (0..1) of the band's left-right extent covered by canopy: of the image columns
 *   between the band's leftmost and rightmost canopy pixel, those with canopy in at least one
 *   of the band's rows
 */
typedef struct {
  gboolean present;
  gdouble top_m;
  gdouble bottom_m;
  gdouble left_m;
  gdouble right_m;
  gdouble width_m;
  gdouble depth_m;
  gdouble fill;
} GstTreeStereoBand;

/**
 * GstTreeStereoTravelSource:
 * @GST_TREE_STEREO_TRAVEL_NONE: no travel this frame (the first frame, the estimate failed or
 *   is off): travel 0, the position kept
 * @GST_TREE_STEREO_TRAVEL_STEREO: measured from the stereo views of this frame and the previous
 * @GST_TREE_STEREO_TRAVEL_SPEED: the speed the application set times the time between frames
 * @GST_TREE_STEREO_TRAVEL_PREDICTED: the stereo estimate failed on this frame; the speed of
 *   the last frames it measured, times the time between frames (a rig does not stop between
 *   two frames; after a second without a measurement the travel is "none")
 *
 * Where a frame's travel comes from. Names in messages: "none", "stereo", "speed",
 * "predicted".
 */
typedef enum {
  GST_TREE_STEREO_TRAVEL_NONE = 0,
  GST_TREE_STEREO_TRAVEL_STEREO = 1,
  GST_TREE_STEREO_TRAVEL_SPEED = 2,
  GST_TREE_STEREO_TRAVEL_PREDICTED = 3,
} GstTreeStereoTravelSource;

/**
 * GstTreeStereoMetrics:
 *
 * Every figure of the treemetrics message (see docs/elements/treemetrics.md). When
 * @tree_present is FALSE all other values but @canopy_mode are 0 and carry no meaning.
 * @confidence: how much of the measured silhouette has depth support (0..1): the share of its
 *   pixels near a 3D point the figures rest on
 * @canopy_mode: #GstTreeStereoCanopyMode of the silhouette measured (set with or without a tree)
 * @travel_m: the rig's motion along the row since the previous frame (m, positive towards the
 *   camera's +x); 0 when @travel_source is #GST_TREE_STEREO_TRAVEL_NONE. Set whether or not a
 *   tree is present.
 * @position_m: the rig's position along the row since the start of the stream (m): the sum of
 *   the travels
 * @travel_source: #GstTreeStereoTravelSource of @travel_m
 * @row_direction: the direction the rig drives in, in the rectified-left camera frame (unit, x
 *   component positive): the mean of its measured motions. A point's place along the row is
 *   @position_m plus its projection on it (m). The camera's x axis in the ground plane before
 *   the motion is known, and when the travel comes from the speed property; all 0 in a meta made
 *   without it (read as (1, 0, 0)).
 */
typedef struct {
  gboolean tree_present;
  gdouble distance_m;
  gdouble height_m;
  gdouble width_m;
  gdouble thickness_m;
  gdouble area_m2;
  gdouble perimeter_m;
  gdouble complexity;
  gdouble centroid_m[3];
  guint clipped; /* GstTreeStereoClipped flags */
  guint n_points;
  guint n_matches;
  guint n_bands;
  GstTreeStereoBand *bands;
  gdouble confidence;
  guint canopy_mode; /* GstTreeStereoCanopyMode */
  gdouble travel_m;
  gdouble position_m;
  guint travel_source; /* GstTreeStereoTravelSource */
  gdouble row_direction[3];
} GstTreeStereoMetrics;

/* Deep copy (bands too) of @src into @dest; @dest is cleared first. */
void gst_tree_stereo_metrics_copy (GstTreeStereoMetrics *dest, const GstTreeStereoMetrics *src);
/* Frees the bands and zeroes everything. */
void gst_tree_stereo_metrics_clear (GstTreeStereoMetrics *m);
/* Allocates @n zeroed bands (frees the previous ones). */
void gst_tree_stereo_metrics_set_n_bands (GstTreeStereoMetrics *m, guint n);

/**
 * GstTreeStereoMetricsMeta:
 * @metrics: the raw figures of this frame
 * @smoothed: the temporally smoothed figures (equal to @metrics when smoothing is off)
 */
typedef struct {
  GstMeta meta;

  GstTreeStereoMetrics metrics;
  GstTreeStereoMetrics smoothed;
} GstTreeStereoMetricsMeta;

GType gst_tree_stereo_metrics_meta_api_get_type (void);
const GstMetaInfo *gst_tree_stereo_metrics_meta_get_info (void);
#define GST_TREE_STEREO_METRICS_META_API_TYPE (gst_tree_stereo_metrics_meta_api_get_type ())
#define GST_TREE_STEREO_METRICS_META_INFO (gst_tree_stereo_metrics_meta_get_info ())

/* Adds a metrics meta with deep copies of @metrics and @smoothed (NULL: same as @metrics). */
GstTreeStereoMetricsMeta *gst_buffer_add_tree_stereo_metrics_meta (GstBuffer *buffer,
    const GstTreeStereoMetrics *metrics, const GstTreeStereoMetrics *smoothed);
#define gst_buffer_get_tree_stereo_metrics_meta(b) \
  ((GstTreeStereoMetricsMeta *) gst_buffer_get_meta ((b), GST_TREE_STEREO_METRICS_META_API_TYPE))

/* -------------------------------------------------------------------------------------------
 * Ground truth (treetestsrc)
 * ------------------------------------------------------------------------------------------- */

/**
 * GstTreeStereoTruth:
 *
 * The true values of the synthetic scene, defined as the treemetrics fields are, in the
 * rendered view's own (unrectified) camera frame for the left view.
 * @view: GST_TREE_STEREO_LEFT or GST_TREE_STEREO_RIGHT
 * @frame: frame number
 * @seed: the scene's seed
 * @distance_m: median depth of the canopy's visible surface in the left view (m)
 * @depth_p05_m: 5th percentile of that depth
 * @depth_p95_m: 95th percentile of that depth
 * @thickness_m: depth_p95_m - depth_p05_m
 * @height_m: the canopy's true vertical extent (m)
 * @width_m: the canopy's true horizontal extent (m)
 * @trunk_distance_m: depth of the trunk's axis (m)
 * @centroid_m: the canopy's 3D centroid (m), left camera frame
 * @offset_x_m: X of the trunk axis of the tree in front, left camera frame (m): the scene's
 *   lateral offset at this frame (the sprayer's travel)
 * @baseline_mm: the rig's baseline
 */
typedef struct {
  guint view;
  guint64 frame;
  guint seed;
  gdouble distance_m;
  gdouble depth_p05_m;
  gdouble depth_p95_m;
  gdouble thickness_m;
  gdouble height_m;
  gdouble width_m;
  gdouble trunk_distance_m;
  gdouble centroid_m[3];
  gdouble offset_x_m;
  gdouble baseline_mm;
} GstTreeStereoTruth;

/**
 * GstTreeStereoTruthMeta:
 * @truth: the scene values
 * @depth: optional per-pixel depth of this view, GRAY32F-like: @width x @height gfloat (mm,
 *   0 = nothing hit), rows of @width floats
 * @mask: optional GRAY8 canopy mask of this view (255 canopy), rows of @width bytes
 */
typedef struct {
  GstMeta meta;

  GstTreeStereoTruth truth;
  GstBuffer *depth;
  GstBuffer *mask;
  guint width;
  guint height;
} GstTreeStereoTruthMeta;

GType gst_tree_stereo_truth_meta_api_get_type (void);
const GstMetaInfo *gst_tree_stereo_truth_meta_get_info (void);
#define GST_TREE_STEREO_TRUTH_META_API_TYPE (gst_tree_stereo_truth_meta_api_get_type ())
#define GST_TREE_STEREO_TRUTH_META_INFO (gst_tree_stereo_truth_meta_get_info ())

/* Adds a truth meta; takes refs on @depth and @mask (either may be NULL). */
GstTreeStereoTruthMeta *gst_buffer_add_tree_stereo_truth_meta (GstBuffer *buffer,
    const GstTreeStereoTruth *truth, GstBuffer *depth, GstBuffer *mask, guint width,
    guint height);
#define gst_buffer_get_tree_stereo_truth_meta(b) \
  ((GstTreeStereoTruthMeta *) gst_buffer_get_meta ((b), GST_TREE_STEREO_TRUTH_META_API_TYPE))

/* -------------------------------------------------------------------------------------------
 * Element messages: the one place that builds and parses them
 *
 * Every analysis element posts an element message whose structure is built here, and tools and
 * tests parse them here. Each structure carries "timestamp", "stream-time", "running-time"
 * (guint64 ns, GST_CLOCK_TIME_NONE when unknown) as gst-plugins-good's level does.
 * ------------------------------------------------------------------------------------------- */

#define GST_TREE_STEREO_MESSAGE_EXGSEGMENT "exgsegment"
#define GST_TREE_STEREO_MESSAGE_SIFTMATCH "siftmatch"
#define GST_TREE_STEREO_MESSAGE_STEREODEPTH "stereodepth"
#define GST_TREE_STEREO_MESSAGE_TREEMETRICS "treemetrics"

typedef struct {
  GstClockTime timestamp;
  GstClockTime stream_time;
  GstClockTime running_time;
} GstTreeStereoTimes;

/* Fills @times from @buffer's PTS and @segment (which may be NULL: only the timestamp is set). */
void gst_tree_stereo_times_from_buffer (GstTreeStereoTimes *times, GstBuffer *buffer,
    const GstSegment *segment);

/* exgsegment: fields "n-views", "index" (string), and per view "left-" / "right-" prefixed
 * (or no prefix with one view): "present", "threshold", "area", "perimeter", "complexity",
 * "centroid-x", "centroid-y", "bbox-x", "bbox-y", "bbox-width", "bbox-height", "regions". */
GstStructure *gst_tree_stereo_vegetation_message_structure (const GstTreeStereoVegetationMeta *meta,
    const GstTreeStereoTimes *times);
/* Parses into @meta's figures (no mask, no contour). @meta must be zero-initialised or hold
 * views from an earlier parse: they are cleared first. Returns FALSE on a malformed structure. */
gboolean gst_tree_stereo_vegetation_message_parse (const GstStructure *s,
    GstTreeStereoVegetationMeta *meta, GstTreeStereoTimes *times);

/* siftmatch: "method" (string), "keypoints-left", "keypoints-right", "matches", and the
 * per-constraint rejection counts and timing below. */
typedef struct {
  GstTreeStereoMatchMethod method;
  guint keypoints_left;
  guint keypoints_right;
  guint matches;
  guint candidates_tested;
  guint rejected_ratio;
  guint rejected_epipolar;
  guint rejected_disparity;
  guint rejected_mutual;
  guint rejected_refine;
  gdouble detect_ms;
  gdouble match_ms;
  gdouble refine_ms;
  gdouble total_ms;
} GstTreeStereoMatchStats;
GstStructure *gst_tree_stereo_match_message_structure (const GstTreeStereoMatchStats *stats,
    const GstTreeStereoTimes *times);
gboolean gst_tree_stereo_match_message_parse (const GstStructure *s,
    GstTreeStereoMatchStats *stats, GstTreeStereoTimes *times);

/* stereodepth: "mode" ("sparse"/"dense"), "points", "valid", "dropped-disparity",
 * "dropped-range", "dropped-outlier", "dropped-zone", "median-depth", "mad-depth", "p05-depth", "p95-depth",
 * "accept-min-depth", "accept-max-depth" (mm), "grid-points". */
GstStructure *gst_tree_stereo_depth_message_structure (gboolean dense,
    const GstTreeStereoDepthStats *stats, const GstTreeStereoTimes *times);
gboolean gst_tree_stereo_depth_message_parse (const GstStructure *s, gboolean *dense,
    GstTreeStereoDepthStats *stats, GstTreeStereoTimes *times);

/* The 3D canopy's figures, added to another element's message (stereodepth's): "canopy-present"
 * (gboolean), "canopy-mode" (string), "canopy-near", "canopy-far" (gdouble, m, the zone used),
 * "ground-found" (gboolean), "segments", "canopy-points" (guint). */
void gst_tree_stereo_canopy_message_add (GstStructure *s, const GstTreeStereoCanopyMeta *meta);
/* Reads those fields back into @meta's figures (view.present, mode, near_m, far_m, ground_found,
 * n_segments, n_canopy_points; no mask, no contour). Returns FALSE when one is missing or
 * malformed (a message without a 3D canopy). */
gboolean gst_tree_stereo_canopy_message_parse (const GstStructure *s,
    GstTreeStereoCanopyMeta *meta);

/* treemetrics: "travel-m", "position-m" (gdouble, m) and "travel-source" (string) of
 * @metrics, in every message (not repeated under "smoothed-"); "tree-present"; when present also "distance", "height", "width", "thickness"
 * (m), "area" (m2), "perimeter" (m), "complexity", "centroid-x/-y/-z" (m), "clipped" (flags)
 * and "clipped-top/-bottom/-left/-right" (booleans), "points", "matches", "bands" (a
 * GstValueArray of GstStructures "band" with "top", "bottom", "left", "right", "width",
 * "depth", "fill", "present"), "confidence"; always "canopy-mode" (string); and the same figures
 * smoothed under "smoothed-" names when @smoothed is not NULL. */
GstStructure *gst_tree_stereo_metrics_message_structure (const GstTreeStereoMetrics *metrics,
    const GstTreeStereoMetrics *smoothed, const GstTreeStereoTimes *times);
/* Parses the raw figures into @metrics, the smoothed ones into @smoothed when not NULL (the
 * travel fields go into both). Both
 * must be zero-initialised or from an earlier parse (they are cleared first); free with
 * gst_tree_stereo_metrics_clear. Returns FALSE on a malformed structure. */
gboolean gst_tree_stereo_metrics_message_parse (const GstStructure *s,
    GstTreeStereoMetrics *metrics, GstTreeStereoMetrics *smoothed, GstTreeStereoTimes *times);

/* treemetrics, one message per tree record (DESIGN.md's tree record), named
 * "treestereo-tree": a tree (mode tree) or a canopy segment (mode row) that left the view, or
 * every one still open at EOS. */
#define GST_TREE_STEREO_MESSAGE_TREE "treestereo-tree"

/**
 * GstTreeStereoTreeRecord:
 * @id: 1, 2, ... in the order the trees entered the view
 * @mode: #GST_TREE_STEREO_CANOPY_TREE (a tree) or #GST_TREE_STEREO_CANOPY_ROW (a canopy segment
 *   of a hedgerow / fruit wall)
 * @complete: both ends seen off the image edge and a frame with the canopy fully in view
 * @start_seen: @start_m was seen off the image edge (else it is the farthest seen)
 * @end_seen: likewise @end_m
 * @position_m: canopy centre along the row, (@start_m + @end_m) / 2 (m, world: the rig's
 *   position plus camera X)
 * @start_m: the canopy's start along the row (m, world), < @end_m
 * @end_m: its end
 * @has_height: @height_m is a measurement (a frame with neither top nor bottom clipped)
 * @height_m: fused height (m)
 * @has_width: @width_m is a measurement
 * @width_m: fused width (m); mode row: @end_m - @start_m
 * @has_depth: @distance_m, @thickness_m, @bands and @confidence are measurements (frames fully
 *   in view)
 * @distance_m: fused distance (m)
 * @thickness_m: fused thickness (m)
 * @n_bands: bands in @bands
 * @bands: fused bands (left_m / right_m world positions along the row), top to bottom
 * @confidence: fused confidence (0..1)
 * @frames: frames fused (fully in view; mode row: seen)
 * @frames_seen: frames its segment was seen in
 * @has_spacing: FALSE on the first record
 * @spacing_m: |position_m - the previous record's position_m| (m)
 * @gap_m: the empty stretch to the previous record's canopy (m; negative: overlap)
 * @lost: emitted because it was not seen while still in view, not because it left
 *
 * Values the record lacks (has_* FALSE) are 0 and absent from the message.
 */
typedef struct {
  guint id;
  GstTreeStereoCanopyMode mode;
  gboolean complete;
  gboolean start_seen;
  gboolean end_seen;
  gdouble position_m;
  gdouble start_m;
  gdouble end_m;
  gboolean has_height;
  gdouble height_m;
  gboolean has_width;
  gdouble width_m;
  gboolean has_depth;
  gdouble distance_m;
  gdouble thickness_m;
  guint n_bands;
  GstTreeStereoBand *bands;
  gdouble confidence;
  guint frames;
  guint frames_seen;
  gboolean has_spacing;
  gdouble spacing_m;
  gdouble gap_m;
  gboolean lost;
} GstTreeStereoTreeRecord;

/* Frees the bands and zeroes everything. */
void gst_tree_stereo_tree_record_clear (GstTreeStereoTreeRecord *record);
/* Allocates @n zeroed bands (frees the previous ones). */
void gst_tree_stereo_tree_record_set_n_bands (GstTreeStereoTreeRecord *record, guint n);

/* "treestereo-tree": the times (of the buffer that made the tree leave the view, or the last
 * buffer at EOS), "id" (guint), "canopy-mode" ("tree"/"row"), "segment" (gboolean, TRUE in mode
 * row: the record is a canopy segment, not a tree), "complete", "start-seen", "end-seen",
 * "lost" (gboolean), "position-m", "start-m", "end-m" (gdouble, m), "frames", "frames-seen"
 * (guint); when measured "height-m", "width-m" (gdouble, m), "distance-m", "thickness-m"
 * (gdouble, m), "confidence" (gdouble), "bands" (GstValueArray of "band" structures as in the
 * treemetrics message); from the second record on "spacing-m", "gap-m" (gdouble, m). */
GstStructure *gst_tree_stereo_tree_message_structure (const GstTreeStereoTreeRecord *record,
    const GstTreeStereoTimes *times);
/* Parses into @record (zero-initialised or from an earlier parse: cleared first; free with
 * gst_tree_stereo_tree_record_clear); the has_* flags say which optional fields were there.
 * @times may be NULL. Returns FALSE on a malformed structure or another message. */
gboolean gst_tree_stereo_tree_message_parse (const GstStructure *s,
    GstTreeStereoTreeRecord *record, GstTreeStereoTimes *times);

/* spraycontrol, one message per valve command of a nozzle section (DESIGN.md's section command),
 * named "treestereo-section". */
#define GST_TREE_STEREO_MESSAGE_SECTION "treestereo-section"

/**
 * GstTreeStereoSectionCommand:
 * @section: the nozzle section, 0 = the lowest
 * @on: open (TRUE) or close the valve
 * @rate: the spray rate (0..1; the on/off model: 1 or 0)
 * @at_ns: the running time (ns) at which the valve must switch (the valve's latency already
 *   taken off); may lie before the message when the command is late
 * @position_m: world position along the row (m) of the canopy slice the command is for
 * @fallback: the command is the fail-safe's (no data for hold-time), not the canopy's
 */
typedef struct {
  guint section;
  gboolean on;
  gdouble rate;
  gint64 at_ns;
  gdouble position_m;
  gboolean fallback;
} GstTreeStereoSectionCommand;

/* "treestereo-section": "section" (guint), "on" (gboolean), "rate" (gdouble), "at-ns"
 * (gint64, running time), "position-m" (gdouble, m), "fallback" (gboolean). */
GstStructure *gst_tree_stereo_section_message_structure (const GstTreeStereoSectionCommand *cmd);
/* Parses into @cmd. Returns FALSE on a malformed structure or another message. */
gboolean gst_tree_stereo_section_message_parse (const GstStructure *s,
    GstTreeStereoSectionCommand *cmd);

/* Enum <-> string names used in messages and properties. */
const gchar *gst_tree_stereo_vegetation_index_to_string (GstTreeStereoVegetationIndex index);
gboolean gst_tree_stereo_vegetation_index_from_string (const gchar *s,
    GstTreeStereoVegetationIndex *index);
const gchar *gst_tree_stereo_match_method_to_string (GstTreeStereoMatchMethod method);
gboolean gst_tree_stereo_match_method_from_string (const gchar *s,
    GstTreeStereoMatchMethod *method);
/* "colour", "tree", "row"; NULL for an unknown mode. */
const gchar *gst_tree_stereo_canopy_mode_to_string (GstTreeStereoCanopyMode mode);
gboolean gst_tree_stereo_canopy_mode_from_string (const gchar *s, GstTreeStereoCanopyMode *mode);
/* "none", "stereo", "speed"; NULL for an unknown source. */
const gchar *gst_tree_stereo_travel_source_to_string (GstTreeStereoTravelSource source);
gboolean gst_tree_stereo_travel_source_from_string (const gchar *s,
    GstTreeStereoTravelSource *source);

G_END_DECLS

#endif /* __GST_TREE_STEREO_META_H__ */
