#include "common.hpp"

#include "band-meta.hpp"

#include "treestereo/calibration.hpp"
#include "treestereo/errors.hpp"
#include "treestereo/features.hpp"

#include <algorithm>
#include <cstring>
#include <limits>

GST_DEBUG_CATEGORY_STATIC(treestereo_common_debug);
#define GST_CAT_DEFAULT treestereo_common_debug

namespace treestereo::gst {

void add_filter_pad_templates(GstElementClass *klass, const char *caps)
{
  GstCaps *c = gst_caps_from_string(caps);
  gst_element_class_add_pad_template(klass,
                                     gst_pad_template_new("sink", GST_PAD_SINK, GST_PAD_ALWAYS, c));
  gst_element_class_add_pad_template(klass,
                                     gst_pad_template_new("src", GST_PAD_SRC, GST_PAD_ALWAYS, c));
  gst_caps_unref(c);
}

static void ensure_debug_category()
{
  static gsize once = 0;
  if (g_once_init_enter(&once)) {
    GST_DEBUG_CATEGORY_INIT(treestereo_common_debug, "treestereo", 0, "treestereo common");
    g_once_init_leave(&once, 1);
  }
}

PixelLayout pixel_layout(GstVideoFormat format)
{
  switch (format) {
  case GST_VIDEO_FORMAT_RGB:
    return {3, 0, 1, 2, true};
  case GST_VIDEO_FORMAT_BGR:
    return {3, 2, 1, 0, true};
  case GST_VIDEO_FORMAT_RGBx:
  case GST_VIDEO_FORMAT_RGBA:
    return {4, 0, 1, 2, true};
  case GST_VIDEO_FORMAT_BGRx:
  case GST_VIDEO_FORMAT_BGRA:
    return {4, 2, 1, 0, true};
  case GST_VIDEO_FORMAT_xRGB:
  case GST_VIDEO_FORMAT_ARGB:
    return {4, 1, 2, 3, true};
  case GST_VIDEO_FORMAT_xBGR:
  case GST_VIDEO_FORMAT_ABGR:
    return {4, 3, 2, 1, true};
  case GST_VIDEO_FORMAT_GRAY8:
    return {1, 0, 0, 0, false};
  default:
    return {};
  }
}

cv::Mat frame_mat(const GstVideoFrame *frame)
{
  const GstVideoInfo *info = &frame->info;
  const int channels = pixel_layout(GST_VIDEO_INFO_FORMAT(info)).channels;
  if (channels == 0)
    throw std::runtime_error(std::string("unsupported video format ") +
                             gst_video_format_to_string(GST_VIDEO_INFO_FORMAT(info)));
  return cv::Mat(GST_VIDEO_INFO_HEIGHT(info), GST_VIDEO_INFO_WIDTH(info), CV_8UC(channels),
                 GST_VIDEO_FRAME_PLANE_DATA(frame, 0),
                 static_cast<size_t>(GST_VIDEO_FRAME_PLANE_STRIDE(frame, 0)));
}

cv::Mat view_mat(const cv::Mat &frame, int view, int n_views)
{
  if (n_views == 1)
    return frame;
  const int w = frame.cols / 2;
  return frame(cv::Rect(view == LEFT ? 0 : w, 0, w, frame.rows));
}

MappedFrame::MappedFrame(const GstVideoInfo *info, GstBuffer *buffer, GstMapFlags flags)
{
  mapped_ = gst_video_frame_map(&frame_, const_cast<GstVideoInfo *>(info), buffer, flags);
}

MappedFrame::~MappedFrame()
{
  if (mapped_)
    gst_video_frame_unmap(&frame_);
}

cv::Mat gray_view(const cv::Mat &view, const PixelLayout &l)
{
  if (l.channels == 1)
    return view;
  if (l.channels != view.channels())
    throw std::runtime_error("gray_view: the pixel layout does not match the frame");
  return to_gray8(view, l.order());
}

int n_views_of(const GstVideoInfo *info)
{
  return GST_VIDEO_INFO_MULTIVIEW_MODE(info) == GST_VIDEO_MULTIVIEW_MODE_SIDE_BY_SIDE ? 2 : 1;
}

StereoGeometry geometry_from_meta(const GstTreeStereoGeometryMeta *m)
{
  StereoGeometry g;
  g.view_size = cv::Size(int(m->view_width), int(m->view_height));
  g.fx = m->fx[0];
  g.fy = m->fy[0];
  g.cx[0] = m->cx[0];
  g.cx[1] = m->cx[1];
  g.cy = m->cy[0];
  g.baseline_mm = m->baseline_mm;
  for (int i = 0; i < 16; i++)
    g.Q.val[i] = m->Q[i];
  for (int i = 0; i < 9; i++)
    g.R1.val[i] = m->R1[i];
  return g;
}

void geometry_to_meta(const StereoGeometry &g, GstTreeStereoGeometryMeta *m)
{
  m->view_width = guint(g.view_size.width);
  m->view_height = guint(g.view_size.height);
  for (int v = 0; v < 2; v++) {
    m->fx[v] = g.fx;
    m->fy[v] = g.fy;
    m->cx[v] = g.cx[v];
    m->cy[v] = g.cy;
  }
  m->baseline_mm = g.baseline_mm;
  for (int i = 0; i < 16; i++)
    m->Q[i] = g.Q.val[i];
  for (int i = 0; i < 9; i++)
    m->R1[i] = g.R1.val[i];
}

/* Copies a cv::Mat into a new GstBuffer (rows packed). */
GstBuffer *buffer_from_mat(const cv::Mat &m)
{
  const gsize row = gsize(m.cols) * m.elemSize();
  GstBuffer *buf = gst_buffer_new_allocate(nullptr, row * gsize(m.rows), nullptr);
  GstMapInfo map;
  gst_buffer_map(buf, &map, GST_MAP_WRITE);
  cv::Mat dst(m.rows, m.cols, m.type(), map.data, row);
  m.copyTo(dst);
  gst_buffer_unmap(buf, &map);
  return buf;
}

void silhouette_to_view(const Silhouette &s, GstTreeStereoVegetationView *v,
                        GstBuffer *mask_buffer)
{
  gst_tree_stereo_vegetation_view_clear(v);
  v->present = s.present;
  v->threshold = s.threshold;
  if (!s.present)
    return;
  v->area_px = s.area_px;
  v->perimeter_px = s.perimeter_px;
  v->complexity = s.complexity;
  v->centroid_x = s.centroid.x;
  v->centroid_y = s.centroid.y;
  v->bbox_x = s.bbox.x;
  v->bbox_y = s.bbox.y;
  v->bbox_width = s.bbox.width;
  v->bbox_height = s.bbox.height;
  v->n_regions = guint(s.n_regions);
  std::vector<gint32> xy;
  xy.reserve(s.contour.size() * 2);
  for (const cv::Point &p : s.contour) {
    xy.push_back(p.x);
    xy.push_back(p.y);
  }
  gst_tree_stereo_vegetation_view_set_contour(v, xy.data(), guint(s.contour.size()));
  if (s.mask.empty())
    return;
  CV_Assert(s.mask.type() == CV_8UC1);
  if (mask_buffer) {
    CV_Assert(gst_buffer_get_size(mask_buffer) >= s.mask.step[0] * gsize(s.mask.rows - 1) +
                                                      gsize(s.mask.cols));
    gst_tree_stereo_vegetation_view_set_mask(v, mask_buffer, guint(s.mask.cols),
                                             guint(s.mask.rows), guint(s.mask.step[0]));
    return;
  }
  GstBuffer *mask = buffer_from_mat(s.mask);
  gst_tree_stereo_vegetation_view_set_mask(v, mask, guint(s.mask.cols), guint(s.mask.rows),
                                           guint(s.mask.cols));
  gst_buffer_unref(mask);
}

Silhouette silhouette_from_view(const GstTreeStereoVegetationView *v, GstMapInfo *mask_map)
{
  Silhouette s;
  s.present = v->present;
  s.threshold = v->threshold;
  if (!v->present)
    return s;
  s.area_px = v->area_px;
  s.perimeter_px = v->perimeter_px;
  s.complexity = v->complexity;
  s.centroid = cv::Point2d(v->centroid_x, v->centroid_y);
  s.bbox = cv::Rect(v->bbox_x, v->bbox_y, v->bbox_width, v->bbox_height);
  s.n_regions = int(v->n_regions);
  s.contour.reserve(v->n_contour);
  for (guint i = 0; i < v->n_contour; i++)
    s.contour.emplace_back(v->contour[2 * i], v->contour[2 * i + 1]);
  if (v->mask && mask_map && gst_buffer_map(v->mask, mask_map, GST_MAP_READ)) {
    if (mask_map->size >= gsize(v->mask_stride) * (v->mask_height - 1) + v->mask_width)
      s.mask = cv::Mat(int(v->mask_height), int(v->mask_width), CV_8UC1, mask_map->data,
                       v->mask_stride);
    else
      gst_buffer_unmap(v->mask, mask_map);
  }
  return s;
}

MappedSilhouette::MappedSilhouette(const GstTreeStereoVegetationView *view)
{
  if (!view)
    return;
  silhouette_ = silhouette_from_view(view, &map_);
  if (!silhouette_.mask.empty()) // silhouette_from_view mapped it
    mask_ = gst_buffer_ref(view->mask);
}

MappedSilhouette::~MappedSilhouette()
{
  silhouette_.mask.release();
  if (mask_) {
    gst_buffer_unmap(mask_, &map_);
    gst_buffer_unref(mask_);
  }
}

void metrics_to_gst(const TreeMetrics &m, GstTreeStereoMetrics *out, GstTreeStereoCanopyMode mode)
{
  gst_tree_stereo_metrics_clear(out);
  out->canopy_mode = guint(mode);
  out->tree_present = m.tree_present;
  if (!m.tree_present)
    return; // all zero: never a value that means nothing
  out->distance_m = m.distance_m;
  out->height_m = m.height_m;
  out->width_m = m.width_m;
  out->thickness_m = m.thickness_m;
  out->area_m2 = m.area_m2;
  out->perimeter_m = m.perimeter_m;
  out->complexity = m.complexity;
  out->centroid_m[0] = m.centroid_m.x;
  out->centroid_m[1] = m.centroid_m.y;
  out->centroid_m[2] = m.centroid_m.z;
  out->clipped = guint((m.clipped.top ? GST_TREE_STEREO_CLIPPED_TOP : 0) |
                       (m.clipped.bottom ? GST_TREE_STEREO_CLIPPED_BOTTOM : 0) |
                       (m.clipped.left ? GST_TREE_STEREO_CLIPPED_LEFT : 0) |
                       (m.clipped.right ? GST_TREE_STEREO_CLIPPED_RIGHT : 0));
  out->n_points = guint(m.points);
  out->n_matches = guint(m.matches);
  out->confidence = m.confidence;
  gst_tree_stereo_metrics_set_n_bands(out, guint(m.bands.size()));
  for (std::size_t i = 0; i < m.bands.size(); i++) {
    band_to_meta(m.bands[i], out->bands[i]);
  }
}

GstTreeStereoCanopyMode canopy_mode_to_gst(CanopyMode mode)
{
  return mode == CanopyMode::Row ? GST_TREE_STEREO_CANOPY_ROW : GST_TREE_STEREO_CANOPY_TREE;
}

GstTreeStereoCanopyMeta *add_canopy_meta(GstBuffer *buf, const CanopyResult &r, CanopyMode mode,
                                         const Silhouette *row)
{
  GstTreeStereoCanopyMeta *meta = gst_buffer_add_tree_stereo_canopy_meta(buf, canopy_mode_to_gst(mode));
  if (!meta)
    return nullptr;
  Silhouette s = r.silhouette;
  s.present = r.present && s.present;
  silhouette_to_view(s, &meta->view);
  if (row && row->present)
    silhouette_to_view(*row, &meta->row_view);
  constexpr double kMmToM = 1e-3;
  meta->near_m = r.near_mm * kMmToM;
  meta->far_m = r.far_mm * kMmToM;
  meta->zone_from_data = r.zone_from_data;
  meta->ground_found = r.ground.found;
  for (int i = 0; i < 3; i++)
    meta->ground_normal[i] = r.ground.normal[i];
  meta->ground_d_m = r.ground.d * kMmToM;
  meta->n_segments = guint(std::max(0, r.n_segments));
  meta->left_m = r.left_mm * kMmToM;
  meta->right_m = r.right_mm * kMmToM;
  meta->n_points = guint(r.classes.size());
  meta->n_canopy_points = guint(r.n_canopy_points);
  meta->n_seam_pixels = guint(r.n_seam_pixels);
  meta->cut_lo_m = r.cut_lo_mm * kMmToM; // infinite stays infinite
  meta->cut_hi_m = r.cut_hi_mm * kMmToM;
  const std::size_t n = std::min<std::size_t>(r.segments.size(), GST_TREE_STEREO_MAX_SEGMENTS);
  meta->n_stored_segments = guint(n);
  for (std::size_t i = 0; i < n; i++) {
    const RowSegment &g = r.segments[i];
    GstTreeStereoRowSegment &o = meta->segments[i];
    o.lo_m = g.lo_mm * kMmToM;
    o.hi_m = g.hi_mm * kMmToM;
    o.near_m = g.near_mm * kMmToM;
    o.n_points = guint(g.n_points);
    o.selected = g.selected;
    o.joined_lo = g.joined_lo;
    o.joined_hi = g.joined_hi;
    o.lo_z_m = g.lo_z_mm * kMmToM;
    o.hi_z_m = g.hi_z_mm * kMmToM;
    o.lo_clear_m = g.lo_clear_mm * kMmToM;
    o.hi_clear_m = g.hi_clear_mm * kMmToM;
    o.trunk_m = g.trunk_mm * kMmToM;
    o.lo_y_m = g.lo_y_mm * kMmToM;
    o.hi_y_m = g.hi_y_mm * kMmToM;
    o.trunk_y_m = g.trunk_y_mm * kMmToM;
  }
  return meta;
}

std::vector<RowSegment> segments_from_meta(const GstTreeStereoCanopyMeta *meta)
{
  std::vector<RowSegment> out;
  const guint n = std::min<guint>(meta->n_stored_segments, GST_TREE_STEREO_MAX_SEGMENTS);
  out.reserve(n);
  for (guint i = 0; i < n; i++) {
    const GstTreeStereoRowSegment &g = meta->segments[i];
    RowSegment o;
    o.lo_mm = g.lo_m * 1e3;
    o.hi_mm = g.hi_m * 1e3;
    o.near_mm = g.near_m * 1e3;
    o.n_points = g.n_points;
    o.selected = g.selected != FALSE;
    o.joined_lo = g.joined_lo != FALSE;
    o.joined_hi = g.joined_hi != FALSE;
    o.lo_z_mm = g.lo_z_m * 1e3;
    o.hi_z_mm = g.hi_z_m * 1e3;
    o.lo_clear_mm = g.lo_clear_m * 1e3;
    o.hi_clear_mm = g.hi_clear_m * 1e3;
    o.trunk_mm = g.trunk_m * 1e3;
    o.lo_y_mm = g.lo_y_m * 1e3;
    o.hi_y_mm = g.hi_y_m * 1e3;
    o.trunk_y_mm = g.trunk_y_m * 1e3;
    out.push_back(o);
  }
  return out;
}

GroundPlane ground_from_meta(const GstTreeStereoCanopyMeta *meta)
{
  GroundPlane g;
  if (!meta || !meta->ground_found)
    return g;
  g.found = true;
  g.normal = cv::Vec3d(meta->ground_normal[0], meta->ground_normal[1], meta->ground_normal[2]);
  g.d = meta->ground_d_m * 1e3;
  return g;
}

std::vector<PixelPoint> pixel_points_of(const GstTreeStereoPointsMeta *pm,
                                        const GstTreeStereoMatchesMeta *mm, guint view_width,
                                        bool grid, double dropped_from_mm, double dropped_to_mm)
{
  std::vector<PixelPoint> out;
  if (!pm || view_width == 0)
    return out;
  out.reserve(pm->n_points);
  const guint n_grid = std::min(pm->stats.n_grid, pm->n_points);
  const guint first_grid = pm->dense ? 0 : pm->n_points - n_grid;
  for (guint i = 0; i < pm->n_points; i++) {
    const GstTreeStereoPoint &p = pm->points[i];
    const bool dropped_in_range =
        dropped_from_mm < dropped_to_mm && p.z >= dropped_from_mm && p.z <= dropped_to_mm;
    if (!p.valid && !dropped_in_range)
      continue;
    PixelPoint q;
    if (i >= first_grid) { // a grid or dense point: match_index is the left pixel's index
      if (!grid)
        break; // the grid points are the last ones
      q.px = cv::Point2f(float(p.match_index % view_width), float(p.match_index / view_width));
    } else if (mm && p.match_index < mm->n_matches) {
      q.px = cv::Point2f(mm->matches[p.match_index].xl, mm->matches[p.match_index].yl);
    } else {
      continue; // a match point whose match is not at hand: no pixel
    }
    q.p.x = p.x;
    q.p.y = p.y;
    q.p.z = p.z;
    q.p.match_index = p.match_index;
    q.p.valid = true;
    out.push_back(q);
  }
  return out;
}

void record_to_gst(const TreeRecord &r, GstTreeStereoTreeRecord *out)
{
  gst_tree_stereo_tree_record_clear(out);
  out->id = guint(std::max(0, r.id));
  out->mode = canopy_mode_to_gst(r.mode);
  out->complete = r.complete;
  out->start_seen = r.start_seen;
  out->end_seen = r.end_seen;
  out->position_m = r.position_m;
  out->start_m = r.start_m;
  out->end_m = r.end_m;
  out->has_height = r.has_height;
  out->height_m = r.has_height ? r.height_m : 0;
  out->has_width = r.has_width;
  out->width_m = r.has_width ? r.width_m : 0;
  out->has_depth = r.has_depth;
  if (r.has_depth) {
    out->distance_m = r.distance_m;
    out->thickness_m = r.thickness_m;
    out->confidence = r.confidence;
    gst_tree_stereo_tree_record_set_n_bands(out, guint(r.bands.size()));
    for (std::size_t i = 0; i < r.bands.size(); i++) {
      band_to_meta(r.bands[i], out->bands[i]);
    }
  }
  out->frames = guint(std::max(0, r.frames));
  out->frames_seen = guint(std::max(0, r.frames_seen));
  out->has_spacing = r.has_spacing;
  out->spacing_m = r.has_spacing ? r.spacing_m : 0;
  out->gap_m = r.has_spacing ? r.gap_m : 0;
  out->lost = r.lost;
}

static GstBufferPool *configured_pool(GstBufferPool *pool, GstCaps *caps, guint size, guint min,
                                      guint max)
{
  GstStructure *config = gst_buffer_pool_get_config(pool);
  gst_buffer_pool_config_set_params(config, caps, size, min, max);
  if (gst_buffer_pool_set_config(pool, config))
    return pool;
  gst_object_unref(pool);
  return nullptr;
}

bool decide_video_allocation(GstElement *element, GstQuery *query)
{
  ensure_debug_category();
  GstCaps *caps;
  gst_query_parse_allocation(query, &caps, nullptr);
  GstVideoInfo info;
  if (!caps || !gst_video_info_from_caps(&info, caps))
    return false;

  GstBufferPool *pool = nullptr;
  guint size = 0, min = 0, max = 0;
  const bool have = gst_query_get_n_allocation_pools(query) > 0;
  if (have)
    gst_query_parse_nth_allocation_pool(query, 0, &pool, &size, &min, &max);
  size = MAX(size, guint(GST_VIDEO_INFO_SIZE(&info)));
  min = MAX(min, 2u);
  if (pool)
    pool = configured_pool(pool, caps, size, min, max);
  if (!pool) /* none offered, or downstream's refused our config */
    pool = configured_pool(gst_video_buffer_pool_new(), caps, size, min, max);
  if (!pool) {
    GST_ERROR_OBJECT(element, "could not configure a buffer pool for %" GST_PTR_FORMAT, caps);
    return false;
  }
  if (have)
    gst_query_set_nth_allocation_pool(query, 0, pool, size, min, max);
  else
    gst_query_add_allocation_pool(query, pool, size, min, max);
  gst_object_unref(pool);
  return true;
}

TreeMetrics metrics_from_meta(const GstTreeStereoMetrics *m)
{
  TreeMetrics t;
  t.tree_present = m->tree_present;
  if (!m->tree_present)
    return t;
  t.distance_m = m->distance_m;
  t.height_m = m->height_m;
  t.width_m = m->width_m;
  t.thickness_m = m->thickness_m;
  t.area_m2 = m->area_m2;
  t.perimeter_m = m->perimeter_m;
  t.complexity = m->complexity;
  t.centroid_m = cv::Point3d(m->centroid_m[0], m->centroid_m[1], m->centroid_m[2]);
  t.clipped.top = (m->clipped & GST_TREE_STEREO_CLIPPED_TOP) != 0;
  t.clipped.bottom = (m->clipped & GST_TREE_STEREO_CLIPPED_BOTTOM) != 0;
  t.clipped.left = (m->clipped & GST_TREE_STEREO_CLIPPED_LEFT) != 0;
  t.clipped.right = (m->clipped & GST_TREE_STEREO_CLIPPED_RIGHT) != 0;
  t.points = m->n_points;
  t.matches = m->n_matches;
  t.confidence = m->confidence;
  for (guint i = 0; m->bands && i < m->n_bands; i++) {
    Band o;
    static_cast<BandExtent &>(o) = band_from_meta(m->bands[i]);
    t.bands.push_back(o);
  }
  return t;
}

void feed_row_map(RowMap &map, GstBuffer *buf, const StereoGeometry &geometry,
                  const GstTreeStereoCanopyMeta *canopy, const GstTreeStereoPointsMeta *pm,
                  const GroundPlane &ground, double position_mm, const cv::Vec3d &row_direction)
{
  const MappedSilhouette sil(canopy ? &canopy->view : nullptr);
  cv::Mat mask = sil.get().mask;
  if (mask.empty() || mask.size() != geometry.view_size)
    mask = cv::Mat::zeros(geometry.view_size, CV_8U); // no canopy in view: all seen empty
  const GstTreeStereoMatchesMeta *mm = gst_buffer_get_tree_stereo_matches_meta(buf);
  const std::vector<PixelPoint> points =
      pixel_points_of(pm, mm, guint(geometry.view_size.width));
  // mode tree: the mask holds the selected tree alone, so the frame speaks for its part of the
  // row only (a neighbour's canopy in view is not in the mask)
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const double lo = canopy ? canopy->cut_lo_m * 1e3 : -kInf;
  const double hi = canopy ? canopy->cut_hi_m * 1e3 : kInf;
  map.add_frame(mask, points, geometry, ground, position_mm, row_direction, lo, hi);
  // The row view (a stream's first frame) speaks for the rest: on each side of the tree's part.
  const MappedSilhouette row(canopy && canopy->row_view.present ? &canopy->row_view : nullptr);
  const cv::Mat &row_mask = row.get().mask;
  if (row_mask.empty() || row_mask.size() != geometry.view_size)
    return;
  // Its depths: the points stereodepth dropped as off the tree, within the near row's zone.
  const std::vector<PixelPoint> row_points = pixel_points_of(
      pm, mm, guint(geometry.view_size.width), true, canopy->near_m * 1e3, canopy->far_m * 1e3);
  if (std::isfinite(lo))
    map.add_frame(row_mask, row_points, geometry, ground, position_mm, row_direction, -kInf, lo);
  if (std::isfinite(hi))
    map.add_frame(row_mask, row_points, geometry, ground, position_mm, row_direction, hi, kInf);
}

cv::Vec3d row_direction_of(const GstTreeStereoMetrics &metrics)
{
  const cv::Vec3d d(metrics.row_direction[0], metrics.row_direction[1], metrics.row_direction[2]);
  return is_row_direction(d) ? d : cv::Vec3d(1, 0, 0);
}

void post_element_message(GstElement *element, GstStructure *s)
{
  gst_element_post_message(element, gst_message_new_element(GST_OBJECT(element), s));
}

const NeededMeta kGeometryMeta{"stereo geometry", "geometry meta", "stereorectify",
                               "GstTreeStereoGeometryMeta"};
const NeededMeta kVegetationMeta{"vegetation mask", "vegetation meta", "exgsegment",
                                 "GstTreeStereoVegetationMeta"};
const NeededMeta kMatchesMeta{"stereo matches", "matches meta", "siftmatch",
                              "GstTreeStereoMatchesMeta"};
const NeededMeta kPointsMeta{"3D points", "points meta", "stereodepth", "GstTreeStereoPointsMeta"};
const NeededMeta kMetricsMeta{"rig position", "metrics meta", "treemetrics",
                              "GstTreeStereoMetricsMeta"};

/* The element's factory name ("siftmatch"), or its object name without a factory. */
static std::string element_kind(GstElement *element)
{
  GstElementFactory *f = gst_element_get_factory(element);
  if (f)
    return GST_OBJECT_NAME(f);
  return GST_OBJECT_NAME(element);
}

static void post(GstElement *element, GstMessageType type, const ErrorCode &c,
                 const std::string &message, const std::string &debug, const char *file,
                 const char *function, int line)
{
  ensure_debug_category();
  gst_element_message_full(element, type, c.domain, c.code, g_strdup(message.c_str()),
                           debug.empty() ? nullptr : g_strdup(debug.c_str()), file, function, line);
}

void post_caps_error(GstElement *element, const std::string &message, const GstCaps *caps,
                     const std::string &detail, const char *file, const char *function, int line)
{
  std::string debug;
  if (caps) {
    gchar *text = gst_caps_to_string(caps);
    debug = std::string("caps ") + text;
    g_free(text);
  }
  if (!detail.empty())
    debug += (debug.empty() ? "" : "; ") + detail;
  post(element, GST_MESSAGE_ERROR, ErrorCode{GST_CORE_ERROR, GST_CORE_ERROR_NEGOTIATION}, message,
       debug, file, function, line);
}

void post_missing_meta(GstElement *element, GstMessageType type, GstBuffer *buf,
                       const NeededMeta &need, const char *who, const char *then, const char *file,
                       const char *function, int line)
{
  const std::string by = who ? who : element_kind(element);
  gchar *debug = gst_info_strdup_printf("buffer %" GST_PTR_FORMAT " has no %s", buf, need.api);
  post(element, type, {GST_STREAM_ERROR, GST_STREAM_ERROR_FAILED},
       std::string("No ") + need.what + " on the buffer: " + by + " needs the " + need.meta +
           " of " + need.upstream + " upstream" + (then ? then : "."),
       debug, file, function, line);
  g_free(debug);
}

static FileAccess access_of(const std::exception &e)
{
  if (const auto *c = dynamic_cast<const CalibrationError *>(&e))
    return c->access();
  if (const auto *f = dynamic_cast<const FileError *>(&e))
    return f->access();
  return FileAccess::None;
}

ErrorCode error_code_of(const std::exception &e)
{
  switch (access_of(e)) {
  case FileAccess::Read:
    return {GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_OPEN_READ};
  case FileAccess::Write:
    return {GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_OPEN_WRITE};
  case FileAccess::None:
    break;
  }
  if (dynamic_cast<const BadSettings *>(&e))
    return {GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_SETTINGS};
  return {GST_STREAM_ERROR, GST_STREAM_ERROR_FAILED}; // BadInput, and faults of our own
}

std::string error_advice(GstElement *element, const std::exception &e)
{
  const std::string name = element_kind(element);
  if (const auto *c = dynamic_cast<const CalibrationError *>(&e)) {
    switch (c->access()) {
    case FileAccess::Read:
      return "Could not read the calibration \"" + c->file() +
             "\": check the path in the calibration property.";
    case FileAccess::Write:
      return "Could not write the calibration to \"" + c->file() +
             "\": check that its folder exists and is writable.";
    case FileAccess::None:
      return "The calibration \"" + c->file() + "\" cannot be used: give " + name +
             " an OpenCV YAML/XML calibration (M1 D1 M2 D2 R T) or a ROS pair "
             "'left.yaml;right.yaml'.";
    }
  }
  if (const auto *f = dynamic_cast<const FileError *>(&e))
    return f->access() == FileAccess::Write
               ? "Could not write \"" + f->path() +
                     "\": check that its folder exists, is writable and has room."
               : "Could not read \"" + f->path() + "\": check that it exists and is readable.";
  if (dynamic_cast<const BadSettings *>(&e))
    return "The settings of " + name +
           " cannot be used: change the property the debug detail names.";
  if (dynamic_cast<const BadInput *>(&e))
    return name + " cannot use what arrived from upstream: check the elements before it.";
  return name + " stopped on an internal error; the debug detail has the cause.";
}

void report_exception(GstElement *element, const std::exception &e, const std::string &message,
                      const char *file, const char *function, int line)
{
  const auto *te = dynamic_cast<const Error *>(&e);
  if (message.empty() && te && !te->detail().empty())
    post(element, GST_MESSAGE_ERROR, error_code_of(e), e.what(), te->detail(), file, function,
         line);
  else
    post(element, GST_MESSAGE_ERROR, error_code_of(e),
         message.empty() ? error_advice(element, e) : message, e.what(), file, function, line);
}

std::vector<StereoMatch> matches_from_meta(const GstTreeStereoMatchesMeta *meta)
{
  std::vector<StereoMatch> out(meta->n_matches);
  for (guint i = 0; i < meta->n_matches; i++) {
    const GstTreeStereoMatch &m = meta->matches[i];
    out[i] = {m.xl, m.yl, m.xr, m.yr, m.score};
  }
  return out;
}

std::vector<GstTreeStereoMatch> to_gst_matches(const std::vector<StereoMatch> &matches)
{
  std::vector<GstTreeStereoMatch> out(matches.size());
  for (std::size_t i = 0; i < matches.size(); i++) {
    const StereoMatch &m = matches[i];
    out[i] = GstTreeStereoMatch{m.xl, m.yl, m.xr, m.yr, m.score};
  }
  return out;
}

std::vector<GstTreeStereoPoint> to_gst_points(const std::vector<Point3> &points)
{
  std::vector<GstTreeStereoPoint> out(points.size());
  for (std::size_t i = 0; i < points.size(); i++)
    out[i] = {points[i].x, points[i].y, points[i].z, points[i].match_index,
              points[i].valid ? TRUE : FALSE};
  return out;
}

std::vector<Point3> points_from_meta(const GstTreeStereoPointsMeta *meta)
{
  std::vector<Point3> pts(meta->n_points);
  for (guint i = 0; i < meta->n_points; i++) {
    const GstTreeStereoPoint &p = meta->points[i];
    pts[i].x = p.x;
    pts[i].y = p.y;
    pts[i].z = p.z;
    pts[i].match_index = p.match_index;
    pts[i].valid = p.valid != FALSE;
  }
  return pts;
}

GstTreeStereoMatchMethod match_method_to_gst(MatchMethod m)
{
  return m == MatchMethod::CosineNorm ? GST_TREE_STEREO_MATCH_COSINE_NORM
                                      : GST_TREE_STEREO_MATCH_EUCLIDEAN;
}

MatchMethod match_method_from_gst(GstTreeStereoMatchMethod m)
{
  return m == GST_TREE_STEREO_MATCH_COSINE_NORM ? MatchMethod::CosineNorm : MatchMethod::Euclidean;
}

void match_stats_to_gst(const MatchStats &st, GstTreeStereoMatchMethod method, double total_ms,
                        GstTreeStereoMatchStats *out)
{
  out->method = method;
  out->keypoints_left = guint(st.keypoints[LEFT]);
  out->keypoints_right = guint(st.keypoints[RIGHT]);
  out->matches = guint(st.matches);
  out->candidates_tested = guint(st.candidates_tested);
  out->rejected_ratio = guint(st.rejected_ratio);
  out->rejected_epipolar = guint(st.rejected_epipolar);
  out->rejected_disparity = guint(st.rejected_disparity);
  out->rejected_mutual = guint(st.rejected_mutual);
  out->rejected_refine = guint(st.rejected_refine);
  out->detect_ms = st.detect_ms;
  out->match_ms = st.match_ms;
  out->refine_ms = st.refine_ms;
  out->total_ms = total_ms;
}

void depth_stats_to_gst(const DepthStats &s, GstTreeStereoDepthStats *out)
{
  out->n_points = guint(s.n_points);
  out->n_valid = guint(s.n_valid);
  out->dropped_disparity = guint(s.dropped_disparity);
  out->dropped_range = guint(s.dropped_range);
  out->dropped_outlier = guint(s.dropped_outlier);
  out->median_z_mm = s.median_mm;
  out->mad_z_mm = s.mad_mm;
  out->p05_z_mm = s.p05_mm;
  out->p95_z_mm = s.p95_mm;
  out->accept_lo_mm = s.accept_lo_mm;
  out->accept_hi_mm = s.accept_hi_mm;
  out->dropped_zone = guint(s.dropped_zone);
}

GstTreeStereoVegetationIndex veg_index_to_gst(VegIndex index)
{
  switch (index) {
  case VegIndex::Exg:
    return GST_TREE_STEREO_INDEX_EXG;
  case VegIndex::ExgExr:
    return GST_TREE_STEREO_INDEX_EXG_EXR;
  case VegIndex::ExgNorm:
    return GST_TREE_STEREO_INDEX_EXG_NORM;
  case VegIndex::ExgExrNorm:
    return GST_TREE_STEREO_INDEX_EXG_EXR_NORM;
  }
  throw std::logic_error("unknown vegetation index");
}

} // namespace treestereo::gst
