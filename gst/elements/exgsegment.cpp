/**
 * SECTION:element-exgsegment
 * @title: exgsegment
 *
 * Finds the canopy by its colour in each view of a side-by-side stereo frame
 * (`multiview-mode=side-by-side`, as stereorectify makes them) or in the single view of a plain
 * stream, and describes its shape: area, centroid, perimeter, complexity, bounding box and outer
 * contour (lib's VegetationSegmenter: a colour vegetation index, Otsu's threshold, morphology,
 * connected components, boundary pixels decided by their leaf coverage; see
 * docs/segmentation.md).
 *
 * The element works in place and does not touch the pixels. It attaches a
 * #GstTreeStereoVegetationMeta with the figures and a GRAY8 canopy mask per view, a
 * #GstVideoRegionOfInterestMeta of type "tree" for the left (or only) view's canopy box when a
 * canopy was found, and posts an `exgsegment` element message with the figures per view
 * (see docs/elements/exgsegment.md for every field).
 *
 * #exgsegment:keep is `all` by default: colour says "plant", and in an orchard the neighbours,
 * the next row and the grass are plants too, so the mask holds every vegetation region and
 * stereodepth's #stereodepth:canopy decides in 3D which of it is the tree in front. `largest`
 * keeps the single largest region (one tree on a clear background, with stereodepth canopy=off).
 *
 * ## Example launch lines
 * |[
 * gst-launch-1.0 -m treetestsrc num-buffers=3 ! exgsegment ! fakesink
 * ]|
 * |[
 * gst-launch-1.0 -m stereorectify name=r calibration=rig.yml ! exgsegment ! fakesink \
 *   treetestsrc view=left ! r.left  treetestsrc view=right ! r.right
 * ]|
 * (rig.yml written beforehand by treetestsrc calibration-out=rig.yml, or a real calibration)
 */
#ifdef HAVE_CONFIG_H
#include "config.h"
#endif

#include "common.hpp"
#include "elements.hpp"
#include "properties.hpp"

#include "treestereo/segment.hpp"

#include <gst/video/gstvideofilter.h>

#include <memory>
#include <mutex>

GST_DEBUG_CATEGORY_STATIC(exgsegment_debug);
#define GST_CAT_DEFAULT exgsegment_debug

using namespace treestereo;
using namespace treestereo::gst;

#define DEFAULT_THRESHOLD (-1.0)
#define DEFAULT_POST_MESSAGES TRUE
/* The largest value any index reaches (ExG-ExR's 765): a fixed threshold above it can never be
 * exceeded, so the property stops there. */
#define MAX_THRESHOLD 765.0

namespace {

struct Settings {
  SegmentParams params; // segmentation settings (the channel order is set per format)
  bool post_messages = DEFAULT_POST_MESSAGES;
  guint64 generation = 0; // bumped when a segmentation parameter changes
};

/* A pool of GRAY8 mask buffers of one view size, so a stream does not allocate (and fault in)
 * a fresh mask per view and frame; buffers come back when downstream drops the meta. */
struct MaskPool {
  GstBufferPool *pool = nullptr;
  cv::Size size;
  guint stride = 0;

  ~MaskPool() { reset(); }
  void reset()
  {
    if (pool) {
      gst_buffer_pool_set_active(pool, FALSE);
      gst_object_unref(pool);
      pool = nullptr;
    }
    size = cv::Size();
  }
  /* Rows padded to 4 bytes as a GRAY8 video frame's are, so the mask can be wrapped as one. */
  void configure(cv::Size view)
  {
    if (pool && view == size)
      return;
    reset();
    stride = guint(GST_ROUND_UP_4(view.width));
    pool = gst_buffer_pool_new();
    GstStructure *config = gst_buffer_pool_get_config(pool);
    gst_buffer_pool_config_set_params(config, nullptr, stride * guint(view.height), 0, 0);
    if (!gst_buffer_pool_set_config(pool, config) || !gst_buffer_pool_set_active(pool, TRUE)) {
      reset();
      throw std::runtime_error("exgsegment: could not set up a pool for the canopy masks");
    }
    size = view;
  }
  GstBuffer *acquire()
  {
    GstBuffer *buf = nullptr;
    if (gst_buffer_pool_acquire_buffer(pool, &buf, nullptr) != GST_FLOW_OK || !buf)
      throw std::runtime_error("exgsegment: could not get a canopy mask buffer");
    return buf;
  }
};

/* A mask buffer mapped for writing for the scope; the segmenter writes into it through mat. */
class MappedMask {
public:
  MappedMask(GstBuffer *buf, cv::Size size, guint stride) : buf_(buf)
  {
    if (!gst_buffer_map(buf_, &map_, GST_MAP_WRITE)) {
      gst_buffer_unref(buf_);
      throw std::runtime_error("exgsegment: could not map a canopy mask buffer");
    }
    mat = cv::Mat(size, CV_8UC1, map_.data, stride);
  }
  ~MappedMask()
  {
    gst_buffer_unmap(buf_, &map_);
    gst_buffer_unref(buf_);
  }
  MappedMask(const MappedMask &) = delete;
  MappedMask &operator=(const MappedMask &) = delete;
  GstBuffer *buffer() const { return buf_; }
  const uchar *data() const { return map_.data; }
  cv::Mat mat;

private:
  GstBuffer *buf_;
  GstMapInfo map_{};
};

struct State {
  std::mutex lock; // guards settings (the object lock is not held around C++ code)
  Settings settings;

  // streaming thread only
  std::unique_ptr<VegetationSegmenter> segmenter[2]; // one per view: each keeps its scratch
  guint64 seg_generation = ~guint64(0);
  ChannelOrder order;
  int n_views = 1;
  MaskPool masks;
};

} // namespace

struct GstExgSegment {
  GstVideoFilter parent;
  State *state;
};

struct GstExgSegmentClass {
  GstVideoFilterClass parent_class;
};

#define GST_TYPE_EXG_SEGMENT (gst_exg_segment_get_type())
#define GST_EXG_SEGMENT(obj) (G_TYPE_CHECK_INSTANCE_CAST((obj), GST_TYPE_EXG_SEGMENT, GstExgSegment))
G_DEFINE_TYPE(GstExgSegment, gst_exg_segment, GST_TYPE_VIDEO_FILTER);
GST_ELEMENT_REGISTER_DEFINE(exgsegment, "exgsegment", GST_RANK_NONE, GST_TYPE_EXG_SEGMENT);

#define CAPS GST_VIDEO_CAPS_MAKE(TREESTEREO_COLOR_FORMATS)


/* The values are lib's VegIndex / KeepMode, the nicks lib's names (veg_index_name ...). */
static GType gst_exg_segment_index_get_type(void)
{
  static GType type = 0;
  static const GEnumValue values[] = {
      {int(VegIndex::Exg), "2G-R-B, the paper's super green", "exg"},
      {int(VegIndex::ExgExr), "ExG - ExR: 3G-2.4R-B", "exg-exr"},
      {int(VegIndex::ExgNorm), "2g-r-b on chromatic coordinates (light invariant)", "exg-norm"},
      {int(VegIndex::ExgExrNorm), "3g-2.4r-b on chromatic coordinates (light invariant)",
       "exg-exr-norm"},
      {0, nullptr, nullptr},
  };
  if (g_once_init_enter(&type)) {
    GType t = g_enum_register_static("GstExgSegmentIndex", values);
    g_once_init_leave(&type, t);
  }
  return type;
}

static GType gst_exg_segment_keep_get_type(void)
{
  static GType type = 0;
  static const GEnumValue values[] = {
      {int(KeepMode::Largest), "The largest region (one tree on a clear background)",
       "largest"},
      {int(KeepMode::All),
       "Every region of at least min-area pixels (all the vegetation; depth picks the canopy)",
       "all"},
      {0, nullptr, nullptr},
  };
  if (g_once_init_enter(&type)) {
    GType t = g_enum_register_static("GstExgSegmentKeep", values);
    g_once_init_leave(&type, t);
  }
  return type;
}

/* (Re)builds the per-view segmenters when the settings or the channel order changed. */
static void ensure_segmenters(GstExgSegment *self, const Settings &s)
{
  State *st = self->state;
  if (st->segmenter[0] && st->seg_generation == s.generation)
    return;
  SegmentParams p = s.params;
  p.order = st->order;
  validate(p);
  for (auto &seg : st->segmenter)
    seg = std::make_unique<VegetationSegmenter>(p);
  st->seg_generation = s.generation;
  GST_INFO_OBJECT(self,
                  "segmenting with %s, threshold %g, morph-size %d, reconstruct %d, unmix-edges %d, "
                  "min-area %g, keep %s",
                  veg_index_name(p.index), p.threshold, p.morph_size, int(p.reconstruct),
                  int(p.unmix_edges), p.min_area, keep_mode_name(p.keep));
}

static gboolean gst_exg_segment_set_info(GstVideoFilter *filter, GstCaps *incaps,
                                         GstVideoInfo *in_info, GstCaps *, GstVideoInfo *)
{
  GstExgSegment *self = GST_EXG_SEGMENT(filter);
  State *st = self->state;
  const PixelLayout layout = pixel_layout(GST_VIDEO_INFO_FORMAT(in_info));
  if (!layout.color) {
    post_caps_error(GST_ELEMENT(self),
                    std::string("exgsegment needs colour frames, got ") +
                        gst_video_format_to_string(GST_VIDEO_INFO_FORMAT(in_info)) +
                        ": put videoconvert before it.",
                    incaps);
    return FALSE;
  }
  st->order = layout.order();
  st->n_views = n_views_of(in_info);
  st->seg_generation = ~guint64(0); // the channel order may have changed
  const cv::Size view(GST_VIDEO_INFO_WIDTH(in_info) / st->n_views, GST_VIDEO_INFO_HEIGHT(in_info));
  if (view.width < 1) {
    post_caps_error(GST_ELEMENT(self),
                    "A side-by-side frame " + std::to_string(GST_VIDEO_INFO_WIDTH(in_info)) +
                        " px wide has no room for two views: check the caps upstream.",
                    incaps);
    return FALSE;
  }
  return guarded(GST_ELEMENT(self), FALSE, [&] {
    st->masks.configure(view);
    GST_DEBUG_OBJECT(self, "%d view(s) of %dx%d", st->n_views, view.width, view.height);
    return TRUE;
  });
}

static gboolean gst_exg_segment_stop(GstBaseTransform *trans)
{
  State *st = GST_EXG_SEGMENT(trans)->state;
  st->masks.reset();
  for (auto &seg : st->segmenter)
    seg.reset();
  return TRUE;
}

/* Segments view @v of @frame into @out, the mask written straight into a pooled buffer. */
static void segment_view(State *st, const cv::Mat &frame, int v, GstTreeStereoVegetationView *out)
{
  const cv::Mat view = view_mat(frame, v, st->n_views);
  MappedMask mask(st->masks.acquire(), view.size(), st->masks.stride);
  Silhouette sil;
  sil.mask = mask.mat;
  st->segmenter[v]->run(view, sil);
  /* lib reuses a mask of the right size and type, so this holds; if it ever reallocated,
   * silhouette_to_view copies instead of attaching a buffer lib did not write */
  const bool in_place = sil.mask.data == mask.data();
  silhouette_to_view(sil, out, in_place ? mask.buffer() : nullptr);
}

static GstFlowReturn process(GstExgSegment *self, GstBuffer *buf)
{
  State *st = self->state;
  GstVideoFilter *filter = GST_VIDEO_FILTER(self);
  const Settings s = settings_snapshot(self);
  ensure_segmenters(self, s);

  /* before mapping: a mapped frame holds a ref, and a buffer with two refs takes no meta */
  GstTreeStereoVegetationMeta *meta =
      gst_buffer_add_tree_stereo_vegetation_meta(buf, guint(st->n_views));
  meta->index = veg_index_to_gst(s.params.index);
  {
    /* read only: mapping for writing would copy pixels a tee still shares */
    MappedFrame frame(&filter->in_info, buf, GST_MAP_READ);
    if (!frame.ok()) {
      GST_ELEMENT_ERROR(self, STREAM, FAILED,
                        ("exgsegment could not read the frame: the buffer is smaller than its "
                         "caps say; check the elements before it."),
                        ("buffer of %" G_GSIZE_FORMAT " bytes for %dx%d %s",
                         gst_buffer_get_size(buf), GST_VIDEO_INFO_WIDTH(&filter->in_info),
                         GST_VIDEO_INFO_HEIGHT(&filter->in_info),
                         gst_video_format_to_string(GST_VIDEO_INFO_FORMAT(&filter->in_info))));
      return GST_FLOW_ERROR;
    }
    const cv::Mat mat = frame.mat();
    const gint64 t0 = g_get_monotonic_time();
    for (int v = 0; v < st->n_views; ++v)
      segment_view(st, mat, v, &meta->views[v]);
    GST_LOG_OBJECT(self, "segmented %d view(s) in %.2f ms", st->n_views,
                   double(g_get_monotonic_time() - t0) / 1000.0);
  }

  const GstTreeStereoVegetationView &left = meta->views[LEFT];
  if (left.present)
    gst_buffer_add_video_region_of_interest_meta(buf, "tree", guint(left.bbox_x),
                                                 guint(left.bbox_y), guint(left.bbox_width),
                                                 guint(left.bbox_height));
  if (s.post_messages) {
    GstTreeStereoTimes times;
    gst_tree_stereo_times_from_buffer(&times, buf, &GST_BASE_TRANSFORM(self)->segment);
    post_element_message(GST_ELEMENT(self),
                         gst_tree_stereo_vegetation_message_structure(meta, &times));
  }
  return GST_FLOW_OK;
}

/* GstVideoFilter's own transform_ip maps the frame for writing when not in passthrough, and
 * writing a buffer whose memory is shared (a tee upstream) copies the pixels. This element
 * only reads them, so it maps the frame read-only itself; base transform still makes the
 * buffer's metadata writable (a shallow copy at most) so the metas can be added. */
static GstFlowReturn gst_exg_segment_transform_ip(GstBaseTransform *trans, GstBuffer *buf)
{
  GstExgSegment *self = GST_EXG_SEGMENT(trans);
  if (!GST_VIDEO_FILTER(trans)->negotiated) {
    post_caps_error(GST_ELEMENT(self),
                    "exgsegment got a frame before any caps it accepts: check the caps of the "
                    "elements before it.",
                    nullptr, "a buffer arrived before caps");
    return GST_FLOW_NOT_NEGOTIATED;
  }
  return guarded(GST_ELEMENT(self), GST_FLOW_ERROR, [&] { return process(self, buf); });
}

static void gst_exg_segment_class_init(GstExgSegmentClass *klass)
{
  GObjectClass *gobject_class = G_OBJECT_CLASS(klass);
  GstElementClass *element_class = GST_ELEMENT_CLASS(klass);
  GstBaseTransformClass *trans_class = GST_BASE_TRANSFORM_CLASS(klass);
  GstVideoFilterClass *filter_class = GST_VIDEO_FILTER_CLASS(klass);
  const SegmentParams d;

  GST_DEBUG_CATEGORY_INIT(exgsegment_debug, "exgsegment", 0, "treestereo exgsegment");

  gobject_class->finalize = finalize_state<GstExgSegment, &gst_exg_segment_parent_class>;

  auto props = PropertyTable<Settings>::in_state<GstExgSegment>(gobject_class);
  props.after_set([](Settings &s) { s.generation++; }); // the segmenters are made again
  props.enumeration("index", "Index",
                    "Colour vegetation index (see docs/segmentation.md for their units)",
                    gst_exg_segment_index_get_type(), int(d.index), TS_FIELD(params.index));
  props.real("threshold", "Threshold",
             "Index threshold in the index's units (exg -510..510, exg-exr -867..765, exg-norm "
             "-1..2, exg-exr-norm -2.4..3); a pixel is canopy above it. -1 = Otsu's threshold per "
             "view (fixed thresholds are >= 0)",
             -1.0, MAX_THRESHOLD, DEFAULT_THRESHOLD, TS_FIELD(params.threshold));
  props.real("min-area", "Minimum area", "Regions smaller than this (px) are not canopy", 0.0,
             G_MAXDOUBLE, d.min_area, TS_FIELD(params.min_area));
  props.integer("morph-size", "Morphology size",
                "Diameter (px, made odd) of the open-then-close element that removes specks and "
                "fills narrow gaps; 0 = off",
                0, 255, d.morph_size, TS_FIELD(params.morph_size));
  props.boolean("reconstruct", "Reconstruct",
                "Opening by reconstruction: a region the opening keeps gets its whole "
                "thresholded shape back (leaf tips), specks stay removed; false = the plain "
                "opening, which shaves details narrower than morph-size",
                d.reconstruct, TS_FIELD(params.reconstruct));
  props.boolean("unmix-edges", "Unmix edges",
                "Decide the pixels on the canopy's boundary by how much of each is leaf (linear "
                "unmixing between the canopy and background colours around it, canopy from half "
                "up) instead of by the threshold, which drops edge pixels mixed with bright sky; "
                "false = thresholded edges",
                d.unmix_edges, TS_FIELD(params.unmix_edges));
  props.enumeration("keep", "Keep",
                    "Which connected regions make the vegetation mask: all (default; "
                    "stereodepth's canopy picks the tree in 3D) or the largest",
                    gst_exg_segment_keep_get_type(), int(d.keep), TS_FIELD(params.keep));
  props.after_set(nullptr);
  props.boolean("post-messages", "Post messages", "Post an exgsegment element message per frame",
                DEFAULT_POST_MESSAGES, TS_FIELD(post_messages));

  add_filter_pad_templates(element_class, CAPS);
  gst_element_class_set_static_metadata(
      element_class, "Vegetation segmentation", "Filter/Analyzer/Video",
      "Finds the canopy by its colour in each view and describes its shape (area, centroid, "
      "perimeter, complexity, box) in a vegetation meta and an element message",
      "treestereo developers");

  trans_class->stop = gst_exg_segment_stop;
  trans_class->transform_ip = gst_exg_segment_transform_ip;
  filter_class->set_info = gst_exg_segment_set_info;

  gst_type_mark_as_plugin_api(gst_exg_segment_index_get_type(), GstPluginAPIFlags(0));
  gst_type_mark_as_plugin_api(gst_exg_segment_keep_get_type(), GstPluginAPIFlags(0));
}

static void gst_exg_segment_init(GstExgSegment *self)
{
  self->state = new State();
  gst_base_transform_set_in_place(GST_BASE_TRANSFORM(self), TRUE);
  gst_base_transform_set_passthrough(GST_BASE_TRANSFORM(self), FALSE);
}
