/* Shared by the treestereo elements: frames as cv::Mat without copies, meta <-> lib/ type
 * conversions, and the error policy (how a missing meta, an exception or a bad setting becomes
 * a GST_ELEMENT_ERROR). */
#pragma once

#include <gst/gst.h>
#include <gst/video/video.h>
#include <gst/treestereo/treestereo-meta.h>

#include <opencv2/core.hpp>

#include "treestereo/canopy.hpp"
#include "treestereo/depth.hpp"
#include "treestereo/errors.hpp"
#include "treestereo/match.hpp"
#include "treestereo/metrics.hpp"
#include "treestereo/rowmap.hpp"
#include "treestereo/rowtrack.hpp"
#include "treestereo/segment.hpp"
#include "treestereo/types.hpp"

#include <exception>
#include <string>
#include <vector>

namespace treestereo::gst {

/* The video formats every analysis element accepts (packed 8-bit, colour or grey). */
#define TREESTEREO_VIDEO_FORMATS "{ RGB, BGR, RGBx, BGRx, xRGB, xBGR, RGBA, BGRA, ARGB, ABGR, GRAY8 }"
/* Colour only: what needs a vegetation index. */
#define TREESTEREO_COLOR_FORMATS "{ RGB, BGR, RGBx, BGRx, xRGB, xBGR, RGBA, BGRA, ARGB, ABGR }"

/* Adds a filter's two pads (always) to @klass: "sink" and "src", both with @caps (e.g.
 * GST_VIDEO_CAPS_MAKE(TREESTEREO_VIDEO_FORMATS)). */
void add_filter_pad_templates(GstElementClass *klass, const char *caps);

/* Where R, G and B sit in a packed pixel, and how many bytes it has. */
struct PixelLayout {
  int channels = 0;
  int r = 0, g = 0, b = 0;
  bool color = false;
  ChannelOrder order() const { return {r, g, b, channels}; }
};
PixelLayout pixel_layout(GstVideoFormat format);

/* Wraps plane 0 of a mapped frame, with its real stride, no copy. */
cv::Mat frame_mat(const GstVideoFrame *frame);

/* One view of a frame: the left or right half of a side-by-side frame, or the whole frame
 * when it holds one view. No copy. */
cv::Mat view_mat(const cv::Mat &frame, int view, int n_views);

/* Maps a buffer as a video frame for the scope. */
class MappedFrame {
public:
  MappedFrame(const GstVideoInfo *info, GstBuffer *buffer, GstMapFlags flags);
  ~MappedFrame();
  MappedFrame(const MappedFrame &) = delete;
  MappedFrame &operator=(const MappedFrame &) = delete;
  bool ok() const { return mapped_; }
  GstVideoFrame *frame() { return &frame_; }
  cv::Mat mat() const { return frame_mat(&frame_); }

private:
  GstVideoFrame frame_{};
  bool mapped_ = false;
};

/* A view as 8-bit grey (Rec. 601 weights from the layout's R, G, B): the view itself for GRAY8,
 * otherwise a converted copy. Padding bytes (x) of 4-byte formats do not count. */
cv::Mat gray_view(const cv::Mat &view, const PixelLayout &layout);

/* How many views a frame of these caps holds: 2 with multiview-mode=side-by-side, else 1. */
int n_views_of(const GstVideoInfo *info);

/* Geometry meta <-> lib/ geometry. */
StereoGeometry geometry_from_meta(const GstTreeStereoGeometryMeta *meta);
void geometry_to_meta(const StereoGeometry &g, GstTreeStereoGeometryMeta *meta);

/* A copy of @m in a new GstBuffer, rows packed (stride = cols * elemSize). */
GstBuffer *buffer_from_mat(const cv::Mat &m);

/* The matches meta's matches as lib's, and lib's matches as the meta's. */
std::vector<StereoMatch> matches_from_meta(const GstTreeStereoMatchesMeta *meta);
std::vector<GstTreeStereoMatch> to_gst_matches(const std::vector<StereoMatch> &matches);
/* lib's points as the points meta's, and the points meta's (all of them, valid or not) as
 * lib's. */
std::vector<GstTreeStereoPoint> to_gst_points(const std::vector<Point3> &points);
std::vector<Point3> points_from_meta(const GstTreeStereoPointsMeta *meta);

/* lib's matching method <-> the meta's. */
GstTreeStereoMatchMethod match_method_to_gst(MatchMethod m);
MatchMethod match_method_from_gst(GstTreeStereoMatchMethod m);
/* lib's match statistics -> the meta/message's, with the method and the whole run's time. */
void match_stats_to_gst(const MatchStats &st, GstTreeStereoMatchMethod method, double total_ms,
                        GstTreeStereoMatchStats *out);
/* lib's depth statistics -> the points meta/message's (n_grid is left as it is). */
void depth_stats_to_gst(const DepthStats &s, GstTreeStereoDepthStats *out);
/* lib's vegetation index -> the vegetation meta's. */
GstTreeStereoVegetationIndex veg_index_to_gst(VegIndex index);

/* Silhouette (lib/) -> vegetation view of the meta. Without @mask_buffer the mask is copied into
 * a new GstBuffer. With it, s.mask must already wrap @mask_buffer's memory (the caller let lib/
 * write into the mapped buffer, row stride s.mask.step): the buffer is attached as it is, no
 * copy. No mask is attached when s.present is false. */
void silhouette_to_view(const Silhouette &s, GstTreeStereoVegetationView *view,
                        GstBuffer *mask_buffer = nullptr);
/* Vegetation view of the meta -> silhouette; the mask is wrapped (valid while @mask_map is). */
Silhouette silhouette_from_view(const GstTreeStereoVegetationView *view, GstMapInfo *mask_map);

/* The silhouette of a vegetation view with its mask mapped for as long as this lives: the
 * mask is unmapped and released in the destructor. A NULL view gives an empty silhouette. */
class MappedSilhouette {
public:
  explicit MappedSilhouette(const GstTreeStereoVegetationView *view);
  ~MappedSilhouette();
  MappedSilhouette(const MappedSilhouette &) = delete;
  MappedSilhouette &operator=(const MappedSilhouette &) = delete;
  const Silhouette &get() const { return silhouette_; }

private:
  GstBuffer *mask_ = nullptr; // a ref, set while mapped
  GstMapInfo map_{};
  Silhouette silhouette_;
};

/* lib/'s tree metrics -> the meta/message figures (@out is cleared first; metres as in lib).
 * @mode: what the measured silhouette was (the canopy meta's mode, or colour without one). */
void metrics_to_gst(const TreeMetrics &m, GstTreeStereoMetrics *out,
                    GstTreeStereoCanopyMode mode = GST_TREE_STEREO_CANOPY_COLOUR);

/* lib/'s canopy mode -> the meta's. */
GstTreeStereoCanopyMode canopy_mode_to_gst(CanopyMode mode);

/* Attaches lib/'s 3D canopy decision as a GstTreeStereoCanopyMeta: the silhouette (its mask
 * copied into a new GstBuffer) as the left view, the zone and the ground in metres, the counts.
 * r.present false gives a view with present FALSE (no canopy in the zone). @row (may be NULL):
 * the near row's silhouette (CanopyDepth::row) as the row view, when present. */
GstTreeStereoCanopyMeta *add_canopy_meta(GstBuffer *buf, const CanopyResult &r, CanopyMode mode,
                                         const Silhouette *row = nullptr);

/* The canopy meta's stored segments (m) as lib's (mm), left to right. */
std::vector<RowSegment> segments_from_meta(const GstTreeStereoCanopyMeta *meta);
/* The canopy meta's ground plane in lib's units (mm); found false without one (or no meta). */
GroundPlane ground_from_meta(const GstTreeStereoCanopyMeta *meta);
/* The points meta's valid points with their rectified-left pixels: a grid or dense point's from
 * its pixel index (y * @view_width + x), a match point's from the matches meta (skipped when
 * @mm is NULL or lacks it). @grid false: the match points alone. @dropped_from_mm <
 * @dropped_to_mm: also the points dropped (valid FALSE) whose depth lies in that range (mm):
 * stereodepth keeps a point off the canopy's zone or mask with its triangulated coordinates,
 * a neighbour's among them. */
std::vector<PixelPoint> pixel_points_of(const GstTreeStereoPointsMeta *pm,
                                        const GstTreeStereoMatchesMeta *mm, guint view_width,
                                        bool grid = true, double dropped_from_mm = 0,
                                        double dropped_to_mm = 0);
/* Adds one frame of @buf to a row map (treemetrics' map, spraycontrol's): the canopy meta's
 * silhouette as the mask (all empty when it has none of the view's size: the view seen without
 * canopy), the points meta's points with their pixels (@pm may be NULL), @ground (must be found),
 * the rig's position along the row (mm) and the row's direction (row_direction_of()). Mode
 * tree: the mask speaks for the tree's part of the row (cut_lo_m to cut_hi_m); the row view,
 * when the meta has one, for the rest of the view. lib's exceptions pass through. */
void feed_row_map(RowMap &map, GstBuffer *buf, const StereoGeometry &geometry,
                  const GstTreeStereoCanopyMeta *canopy, const GstTreeStereoPointsMeta *pm,
                  const GroundPlane &ground, double position_mm, const cv::Vec3d &row_direction);

/* The metrics' row direction (GstTreeStereoMetrics::row_direction) as RowMap and TreeTracker take
 * it: (1, 0, 0) when unset (all 0) or not a unit vector within 60 degrees of x. */
cv::Vec3d row_direction_of(const GstTreeStereoMetrics &metrics);

/* lib's tree record -> the message's (@out is cleared first). */
void record_to_gst(const TreeRecord &r, GstTreeStereoTreeRecord *out);

/* decide_allocation for an element that produces whole video frames of the query's caps: keeps
 * downstream's pool when it takes our config, else a GstVideoBufferPool, sized for a frame. */
bool decide_video_allocation(GstElement *element, GstQuery *query);

/* Metrics of the meta -> lib/ metrics (bands too; depth_measured and extent_depth_m, which the
 * meta does not carry, stay false/0; canopy_mode is the meta's alone). */
TreeMetrics metrics_from_meta(const GstTreeStereoMetrics *m);

/* Posts an element message built by the meta library (call with no lock held). */
void post_element_message(GstElement *element, GstStructure *s);

} // namespace treestereo::gst

namespace treestereo::gst {

/* The error policy of the elements. A post carries a sentence a person can act on as its message
 * and the technical detail (an exception's text, a buffer, the values at odds) as its debug
 * string. Domain and code say who can fix it:
 *   missing upstream meta, bad data from upstream   STREAM/FAILED
 *   a setting (property value, calibration) that cannot be used   RESOURCE/SETTINGS
 *   a file that cannot be read or written   RESOURCE/OPEN_READ, RESOURCE/OPEN_WRITE
 *   caps that do not fit   CORE/NEGOTIATION (post_caps_error(), where the caps are checked)
 *   anything else (an internal fault)   STREAM/FAILED */

/* A meta an element needs from upstream: what a person misses, the meta, the element that adds
 * it, and its API type (for the debug string). */
struct NeededMeta {
  const char *what;
  const char *meta;
  const char *upstream;
  const char *api;
};
extern const NeededMeta kGeometryMeta;   /* stereorectify's */
extern const NeededMeta kVegetationMeta; /* exgsegment's */
extern const NeededMeta kMatchesMeta;    /* siftmatch's */
extern const NeededMeta kPointsMeta;     /* stereodepth's */
extern const NeededMeta kMetricsMeta;    /* treemetrics' */

/* Posts that @buf lacks @need as STREAM/FAILED, an error (the element stops) or a warning
 * (@type GST_MESSAGE_WARNING: it goes on without), with the message "No <what> on the buffer:
 * <who> needs the <meta> of <upstream> upstream<then>". @who defaults to the element's factory
 * name, @then to ".". */
void post_missing_meta(GstElement *element, GstMessageType type, GstBuffer *buf,
                       const NeededMeta &need, const char *who = nullptr, const char *then = ".",
                       const char *file = __builtin_FILE(),
                       const char *function = __builtin_FUNCTION(), int line = __builtin_LINE());

/* Posts that caps do not fit as CORE/NEGOTIATION, an error: @message is the sentence a person
 * acts on (what the element needs, what to change); the debug string holds @caps (may be NULL)
 * and @detail. Every caps check of the elements posts through this. */
void post_caps_error(GstElement *element, const std::string &message, const GstCaps *caps,
                     const std::string &detail = std::string(), const char *file = __builtin_FILE(),
                     const char *function = __builtin_FUNCTION(), int line = __builtin_LINE());

/* The domain and code an exception maps to (see the table above). */
struct ErrorCode {
  GQuark domain;
  gint code;
};
ErrorCode error_code_of(const std::exception &e);

/* The sentence a person reads for @e when the caller has no better one: it names the element
 * (or the file) and what to change. */
std::string error_advice(GstElement *element, const std::exception &e);

/* Posts @e as a GST_ELEMENT_ERROR with the domain and code of its type. The message is @message,
 * else a treestereo::Error's what() when it carries a detail (then the debug string), else
 * error_advice(); the debug string is the exception's text. @file, @function and @line (the
 * caller's by default) place the post in the debug string, as GST_ELEMENT_ERROR does. */
void report_exception(GstElement *element, const std::exception &e,
                      const std::string &message = std::string(),
                      const char *file = __builtin_FILE(),
                      const char *function = __builtin_FUNCTION(), int line = __builtin_LINE());

/* Runs @f; an exception becomes a GST_ELEMENT_ERROR (report_exception) and @on_error is
 * returned. Every vfunc that calls lib/ goes through this, so no exception crosses into
 * GStreamer. */
template <typename R, typename F>
R guarded(GstElement *element, R on_error, F &&f, const char *file = __builtin_FILE(),
          const char *function = __builtin_FUNCTION(), int line = __builtin_LINE())
{
  try {
    return f();
  } catch (const std::exception &e) {
    report_exception(element, e, std::string(), file, function, line);
    return on_error;
  }
}

} // namespace treestereo::gst
