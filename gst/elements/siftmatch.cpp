/**
 * SECTION:element-siftmatch
 * @title: siftmatch
 *
 * Matches SIFT features between the two rectified views of a side-by-side stereo frame (from
 * stereorectify) under the stereo constraints: an epipolar band around the keypoint's row, a
 * disparity range (by default derived from a depth range and the frame's
 * #GstTreeStereoGeometryMeta), a left-right consistency check, sub-pixel refinement of each
 * disparity by correlation at full resolution and a two-layer test that drops keypoints beside
 * a depth edge (see #siftmatch:layer-tolerance). Adds a #GstTreeStereoMatchesMeta (coordinates in
 * each view's own pixels) and posts a `siftmatch` element message with the keypoint counts,
 * the match count, the keypoints or matches dropped by each constraint and the wall times.
 *
 * With #siftmatch:use-mask and a #GstTreeStereoVegetationMeta from exgsegment on the buffer,
 * each view is searched only inside its canopy (the mask, or the bounding box when the meta
 * carries no mask) and #siftmatch:mask-inset px (of the detection image) away from its edge;
 * without that meta the whole view is searched. Pixels pass through untouched.
 *
 * SIFT's contrast threshold is 0.02 by default, with a mask inset of 4: no keypoint within 4
 * detection px of the canopy's edge, whose descriptor windows straddle the background and whose
 * matches mostly fail the two-layer test. The upright SIFT makes the low threshold affordable: on
 * 36 treetestsrc pairs at 1296x972 it keeps 233 matches per pair in the canopy (163 at 0.035) at
 * the same correct rate (99.55%), and Middlebury Jadeplant reaches 98.2% (97.4%), for about 24%
 * more CPU in the step (docs/results.md, "SIFT contrast threshold 0.02 (2026-12-02, Intel Xeon
 * host)").
 *
 * The two-layer test is on by default (#siftmatch:layer-tolerance 0.5; lib keeps it off): on 9
 * treetestsrc pairs at 1296x972 it takes the correct-match rate from 91.5% to 99.4% (178 of 526
 * matches per pair kept), Middlebury Jadeplant from 87.0% to 96.6%. It was off while stereodepth
 * measured from the matches alone, whose thinning made the canopy thickness read low; since
 * stereodepth densifies (the matches only seed and bound a grid of canopy pixels) the chain's
 * distance, height, width and thickness come out the same with it on or off (45 frames, 1.8-2.2 m:
 * distance std 0.19 cm both, thickness -6.85% against -6.73%; docs/elements/siftmatch.md). Set
 * layer-tolerance=-1 for the most matches.
 *
 * Further tests run with it (all on by default): a 0.9 correlation peak (#siftmatch:min-zncc), a
 * peak that stands out along the row (#siftmatch:min-zncc-drop, against horizontal edges), the
 * 3x3 centre's own tolerance (#siftmatch:layer-centre-tolerance) and a minimum correlation of each
 * part of the window at the refined disparity (#siftmatch:layer-min-zncc,
 * #siftmatch:layer-centre-min-zncc). On 24 treetestsrc pairs at 1.8/2.2 m they take the correct
 * rate from 99.2-99.7% to 99.55-99.91% for 5-6% fewer matches, Jadeplant from 96.7% to 97.9%.
 * The refinement's windows (7x7, #siftmatch:layer-window) are sized for a detection scale of 0.5
 * or more and grow by 0.5 / scale below it (13x13 and 21x21 at 2592x1944).
 *
 * Last, each match is moved by at most #siftmatch:relocate px (default 1) to the pixel its
 * disparity belongs to: a keypoint in a dark gap between two near leaves, where the leaf behind
 * shows, takes the near leaves' disparity from its window and now stands on a near leaf. On 36
 * treetestsrc pairs at 1.6/2.0/2.4 m it takes the correct rate from 99.33% to 99.56% with the
 * same matches (docs/elements/siftmatch.md).
 *
 * Keypoints come from treestereo's own SIFT (#siftmatch:upright, default on): Lowe's detector
 * as OpenCV 4.6 runs it (the same places and scales), but each place described once, at angle 0,
 * since on rectified views the rows are the epipolar lines and no orientation is needed, and only
 * the keypoints that have a candidate in the other view. On the 1296x972 timing pair that is 493
 * against 881 M instructions a step (39.0 against 62.7 ms, medians of three runs) for the same
 * correct rates on treetestsrc pairs; Jadeplant 97.4% against 98.2% (one more wrong match of 114;
 * cosine-norm 100% against 98.0%). upright=false runs OpenCV's SIFT, one descriptor per
 * dominant orientation (docs/elements/siftmatch.md).
 *
 * A buffer without the geometry meta, or a stream that is not side by side, is an error.
 *
 * ## Example launch line
 * |[
 * gst-launch-1.0 -m stereorectify name=r calibration=rig.yml ! exgsegment ! siftmatch ! \
 *   fakesink   treetestsrc view=left ! r.left   treetestsrc view=right ! r.right
 * ]|
 */
#ifdef HAVE_CONFIG_H
#include "config.h"
#endif

#include "common.hpp"
#include "elements.hpp"
#include "properties.hpp"

#include "treestereo/match.hpp"
#include "treestereo/presets.hpp"

#include <chrono>
#include <cmath>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

GST_DEBUG_CATEGORY_STATIC(siftmatch_debug);
#define GST_CAT_DEFAULT siftmatch_debug

using namespace treestereo;
using namespace treestereo::gst;

/* Defaults: lib's SiftmatchPreset (treestereo/presets.hpp), which benches and tools share; see
 * docs/elements/siftmatch.md for the measurements behind them. The element's own: */
#define DEFAULT_MIN_DISPARITY (-1.0) /* from max-depth and the geometry */
#define DEFAULT_MAX_DISPARITY (-1.0) /* from min-depth and the geometry */
#define DEFAULT_SCALE 0.0            /* automatic: SiftmatchPreset::auto_scale */
#define DEFAULT_POST_MESSAGES TRUE
#define MAX_DISPARITY_LIMIT 100000.0

namespace {

/* siftmatch's defaults, from lib (the property defaults and the settings' initial values). */
const MatchParams &preset()
{
  static const MatchParams p = SiftmatchPreset::params();
  return p;
}

struct Settings {
  GstTreeStereoMatchMethod method = treestereo::gst::match_method_to_gst(preset().matcher.method);
  double ratio = preset().matcher.ratio;
  int candidates = preset().matcher.candidates;
  double epipolar_tolerance = preset().matcher.constraints.epipolar_tolerance;
  double min_disparity = DEFAULT_MIN_DISPARITY;
  double max_disparity = DEFAULT_MAX_DISPARITY;
  double min_depth = SiftmatchPreset::kMinDepthMm;
  double max_depth = SiftmatchPreset::kMaxDepthMm;
  bool mutual = preset().matcher.constraints.mutual;
  int nfeatures = preset().detect.nfeatures;
  double contrast_threshold = preset().detect.contrast_threshold;
  double scale = DEFAULT_SCALE;
  bool use_mask = preset().detect.use_mask;
  bool upright = preset().detect.engine == SiftEngine::Upright;
  int mask_inset = preset().detect.mask_inset;
  bool refine = preset().refine;
  double min_zncc = preset().refine_params.min_zncc;
  double min_zncc_drop = preset().refine_params.min_zncc_drop;
  double layer_tolerance = preset().refine_params.layer_tolerance;
  int layer_window = preset().refine_params.layer_half_window;
  int layer_search = preset().refine_params.layer_search;
  double layer_centre_tolerance = preset().refine_params.layer_centre_tolerance;
  double layer_min_zncc = preset().refine_params.layer_min_zncc;
  double layer_centre_min_zncc = preset().refine_params.layer_centre_min_zncc;
  int relocate = preset().refine_params.relocate;
  bool post_messages = DEFAULT_POST_MESSAGES;
  guint64 generation = 0; // bumped by every change that needs a new StereoMatcher
};

/* What a StereoMatcher is built from: the settings' generation and the values derived from the
 * frame (disparity range from the geometry, automatic scale from the view size). */
struct MatcherKey {
  guint64 generation = ~guint64(0);
  double min_disparity = 0, max_disparity = 0, scale = 0;
  bool operator==(const MatcherKey &o) const
  {
    return generation == o.generation && min_disparity == o.min_disparity &&
           max_disparity == o.max_disparity && scale == o.scale;
  }
};

struct State {
  std::mutex lock; // guards settings
  Settings settings;

  // streaming thread only
  std::unique_ptr<StereoMatcher> matcher;
  MatcherKey key;
  bool told_no_vegetation = false;
};

} // namespace

struct GstSiftMatch {
  GstVideoFilter parent;
  State *state;
};

struct GstSiftMatchClass {
  GstVideoFilterClass parent_class;
};

#define GST_TYPE_SIFT_MATCH (gst_sift_match_get_type())
#define GST_SIFT_MATCH(obj) (G_TYPE_CHECK_INSTANCE_CAST((obj), GST_TYPE_SIFT_MATCH, GstSiftMatch))
G_DEFINE_TYPE(GstSiftMatch, gst_sift_match, GST_TYPE_VIDEO_FILTER);
GST_ELEMENT_REGISTER_DEFINE(siftmatch, "siftmatch", GST_RANK_NONE, GST_TYPE_SIFT_MATCH);

#define GST_TYPE_SIFT_MATCH_METHOD (gst_sift_match_method_get_type())
static GType gst_sift_match_method_get_type(void)
{
  static gsize type = 0;
  static const GEnumValue values[] = {
      {GST_TREE_STEREO_MATCH_EUCLIDEAN,
       "Nearest neighbour on Euclidean distance with Lowe's ratio test", "euclidean"},
      {GST_TREE_STEREO_MATCH_COSINE_NORM,
       "The paper's: the smallest descriptor angles, then the closest descriptor norm",
       "cosine-norm"},
      {0, nullptr, nullptr},
  };
  if (g_once_init_enter(&type))
    g_once_init_leave(&type, g_enum_register_static("GstSiftMatchMethod", values));
  return GType(type);
}

#define CAPS GST_VIDEO_CAPS_MAKE(TREESTEREO_VIDEO_FORMATS)

/* scale=0: automatic (SiftmatchPreset::auto_scale of the view's width). */
static double resolve_scale(double scale, int view_width)
{
  return scale > 0 ? scale : SiftmatchPreset::auto_scale(view_width);
}

/* The matcher for these settings and this frame's geometry, rebuilt only when they changed. */
static const StereoMatcher &matcher_for(GstSiftMatch *self, const Settings &s,
                                        const StereoGeometry &g)
{
  State *st = self->state;
  MatcherKey key;
  key.generation = s.generation;
  key.min_disparity = s.min_disparity;
  key.max_disparity = s.max_disparity;
  if (s.min_disparity < 0 || s.max_disparity < 0) {
    if (!g.valid())
      throw BadInput("siftmatch: the stereo geometry meta has no focal length or baseline, so "
                     "no disparity range can be derived from min-depth/max-depth; set "
                     "min-disparity and max-disparity");
    if (!(s.max_depth > s.min_depth))
      throw BadSettings("siftmatch's max-depth must be above its min-depth: raise max-depth or "
                        "lower min-depth.",
                        "siftmatch: max-depth (" + std::to_string(s.max_depth) +
                            " mm) must be above min-depth (" + std::to_string(s.min_depth) +
                            " mm)");
    const DisparityRange r = disparity_range_for_depth(g, s.min_depth, s.max_depth);
    if (s.min_disparity < 0)
      key.min_disparity = r.min;
    if (s.max_disparity < 0)
      key.max_disparity = r.max;
  }
  if (key.min_disparity > key.max_disparity)
    throw BadSettings("siftmatch's disparity range is empty: set min-disparity below "
                      "max-disparity, or min-depth and max-depth that leave a range.",
                      "siftmatch: the disparity range is empty: min " +
                          std::to_string(key.min_disparity) + " px > max " +
                          std::to_string(key.max_disparity) +
                          " px; check min-disparity/max-disparity or min-depth/max-depth");
  key.scale = resolve_scale(s.scale, g.view_size.width);
  if (st->matcher && st->key == key)
    return *st->matcher;

  MatchParams p = SiftmatchPreset::params(); // then every field the properties set
  p.detect.nfeatures = s.nfeatures;
  p.detect.contrast_threshold = s.contrast_threshold;
  p.detect.scale = key.scale;
  p.detect.use_mask = s.use_mask;
  p.detect.engine = s.upright ? SiftEngine::Upright : SiftEngine::OpenCV;
  p.detect.mask_inset = s.mask_inset;
  p.matcher.method = treestereo::gst::match_method_from_gst(s.method);
  p.matcher.ratio = s.ratio;
  p.matcher.candidates = s.candidates;
  p.matcher.constraints.epipolar_tolerance = s.epipolar_tolerance;
  p.matcher.constraints.min_disparity = key.min_disparity;
  p.matcher.constraints.max_disparity = key.max_disparity;
  p.matcher.constraints.mutual = s.mutual;
  p.refine = s.refine;
  p.refine_params.min_zncc = s.min_zncc;
  p.refine_params.min_zncc_drop = s.min_zncc_drop;
  p.refine_params.layer_tolerance = s.layer_tolerance;
  p.refine_params.layer_half_window = s.layer_window;
  p.refine_params.layer_search = s.layer_search;
  p.refine_params.layer_centre_tolerance = s.layer_centre_tolerance;
  p.refine_params.layer_min_zncc = s.layer_min_zncc;
  p.refine_params.layer_centre_min_zncc = s.layer_centre_min_zncc;
  p.refine_params.relocate = s.relocate;
  p.parallel_detect = true;
  st->matcher = std::make_unique<StereoMatcher>(p);
  st->key = key;
  GST_INFO_OBJECT(self, "matcher: %s, disparity %.2f..%.2f px, scale %.3g, band %.2f px",
                  match_method_name(p.matcher.method), key.min_disparity, key.max_disparity,
                  key.scale, s.epipolar_tolerance);
  return *st->matcher;
}

/* The canopy of one view as a detection mask: the vegetation mask when it has the view's size,
 * else the bounding box; all zero when no canopy was found (nothing to match there). */
class ViewMask {
public:
  ViewMask(const GstTreeStereoVegetationView *v, cv::Size view_size)
  {
    mat_ = cv::Mat::zeros(view_size, CV_8UC1);
    if (!v->present)
      return;
    if (v->mask && int(v->mask_width) == view_size.width &&
        int(v->mask_height) == view_size.height && gst_buffer_map(v->mask, &map_, GST_MAP_READ)) {
      buffer_ = v->mask;
      if (map_.size >= gsize(v->mask_stride) * (v->mask_height - 1) + v->mask_width) {
        mat_ = cv::Mat(view_size, CV_8UC1, map_.data, v->mask_stride);
        return;
      }
    }
    const cv::Rect box = cv::Rect(v->bbox_x, v->bbox_y, v->bbox_width, v->bbox_height) &
                         cv::Rect(cv::Point(0, 0), view_size);
    mat_(box).setTo(255);
  }
  ~ViewMask()
  {
    if (buffer_)
      gst_buffer_unmap(buffer_, &map_);
  }
  ViewMask(const ViewMask &) = delete;
  ViewMask &operator=(const ViewMask &) = delete;
  const cv::Mat &mat() const { return mat_; }

private:
  cv::Mat mat_;
  GstMapInfo map_{};
  GstBuffer *buffer_ = nullptr;
};

/* Runs the matcher on @buf (read only, with its geometry meta @gm) and attaches the matches
 * meta. Throws on bad input. */
static void match_buffer(GstSiftMatch *self, GstBuffer *buf, const GstTreeStereoGeometryMeta *gm,
                         const Settings &s, GstTreeStereoMatchStats *out)
{
  const auto t0 = std::chrono::steady_clock::now();
  GstVideoFilter *filter = GST_VIDEO_FILTER(self);
  const int frame_w = GST_VIDEO_INFO_WIDTH(&filter->in_info);
  const int frame_h = GST_VIDEO_INFO_HEIGHT(&filter->in_info);
  if (int(gm->view_width) * 2 != frame_w || int(gm->view_height) != frame_h)
    throw BadInput("siftmatch: the stereo geometry meta is for two " +
                   std::to_string(gm->view_width) + "x" + std::to_string(gm->view_height) +
                   " views but the frame is " + std::to_string(frame_w) + "x" +
                   std::to_string(frame_h));
  const StereoGeometry geometry = treestereo::gst::geometry_from_meta(gm);
  const StereoMatcher &matcher = matcher_for(self, s, geometry);

  StereoMatchResult r;
  {
    /* the mapped frame holds a ref on @buf: the meta is added after it is unmapped */
    treestereo::gst::MappedFrame frame(&filter->in_info, buf, GST_MAP_READ);
    if (!frame.ok())
      throw std::runtime_error("siftmatch: could not map the frame");
    const cv::Mat mat = frame.mat();
    const cv::Mat left = treestereo::gst::view_mat(mat, LEFT, 2);
    const cv::Mat right = treestereo::gst::view_mat(mat, RIGHT, 2);

    const GstTreeStereoVegetationMeta *veg =
        s.use_mask ? gst_buffer_get_tree_stereo_vegetation_meta(buf) : nullptr;
    if (s.use_mask && !veg && !self->state->told_no_vegetation) {
      self->state->told_no_vegetation = true;
      GST_DEBUG_OBJECT(self, "no vegetation meta on the buffers: searching the whole views");
    }
    if (veg && veg->n_views != 2)
      throw BadInput("siftmatch: the vegetation meta holds " + std::to_string(veg->n_views) +
                     " view(s); a side-by-side stereo frame needs 2");
    std::unique_ptr<ViewMask> masks[2];
    if (veg)
      for (int v = 0; v < 2; v++)
        masks[v] = std::make_unique<ViewMask>(&veg->views[v], left.size());
    r = matcher.run(left, right, veg ? masks[LEFT]->mat() : cv::Mat(),
                    veg ? masks[RIGHT]->mat() : cv::Mat());
  }

  const std::vector<GstTreeStereoMatch> matches = treestereo::gst::to_gst_matches(r.matches);
  gst_buffer_add_tree_stereo_matches_meta(buf, s.method, guint(r.stats.keypoints[LEFT]),
                                          guint(r.stats.keypoints[RIGHT]), matches.data(),
                                          guint(matches.size()));
  const double total_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  treestereo::gst::match_stats_to_gst(r.stats, s.method, total_ms, out);
  GST_LOG_OBJECT(self, "%u/%u keypoints, %u matches, %.1f ms", out->keypoints_left,
                 out->keypoints_right, out->matches, total_ms);
}

static GstFlowReturn gst_sift_match_transform_ip(GstBaseTransform *trans, GstBuffer *buf)
{
  GstSiftMatch *self = GST_SIFT_MATCH(trans);
  const Settings s = settings_snapshot(self);
  const GstTreeStereoGeometryMeta *gm = gst_buffer_get_tree_stereo_geometry_meta(buf);
  if (!gm) {
    treestereo::gst::post_missing_meta(GST_ELEMENT(self), GST_MESSAGE_ERROR, buf,
                                       treestereo::gst::kGeometryMeta);
    return GST_FLOW_ERROR;
  }
  GstTreeStereoMatchStats stats{};
  const bool ok = treestereo::gst::guarded(GST_ELEMENT(self), false, [&] {
    match_buffer(self, buf, gm, s, &stats);
    return true;
  });
  if (!ok)
    return GST_FLOW_ERROR;
  if (s.post_messages) {
    GstTreeStereoTimes times;
    gst_tree_stereo_times_from_buffer(&times, buf, &trans->segment);
    treestereo::gst::post_element_message(GST_ELEMENT(self),
                                          gst_tree_stereo_match_message_structure(&stats, &times));
  }
  return GST_FLOW_OK;
}

static gboolean gst_sift_match_set_info(GstVideoFilter *filter, GstCaps *incaps,
                                        GstVideoInfo *in_info, GstCaps *outcaps,
                                        GstVideoInfo *out_info)
{
  if (treestereo::gst::n_views_of(in_info) != 2) {
    post_caps_error(GST_ELEMENT(filter),
                    "siftmatch needs side-by-side stereo frames (multiview-mode=side-by-side) "
                    "from stereorectify",
                    incaps);
    return FALSE;
  }
  return TRUE;
}

static gboolean gst_sift_match_start(GstBaseTransform *trans)
{
  State *st = GST_SIFT_MATCH(trans)->state;
  st->matcher.reset();
  st->key = MatcherKey();
  st->told_no_vegetation = false;
  return TRUE;
}

static gboolean gst_sift_match_stop(GstBaseTransform *trans)
{
  GST_SIFT_MATCH(trans)->state->matcher.reset();
  return TRUE;
}

static void gst_sift_match_class_init(GstSiftMatchClass *klass)
{
  GObjectClass *gobject_class = G_OBJECT_CLASS(klass);
  GstElementClass *element_class = GST_ELEMENT_CLASS(klass);
  GstBaseTransformClass *trans_class = GST_BASE_TRANSFORM_CLASS(klass);
  GstVideoFilterClass *filter_class = GST_VIDEO_FILTER_CLASS(klass);
  const MatchParams &d = preset();

  GST_DEBUG_CATEGORY_INIT(siftmatch_debug, "siftmatch", 0, "treestereo siftmatch");

  gobject_class->finalize = finalize_state<GstSiftMatch, &gst_sift_match_parent_class>;

  auto props = PropertyTable<Settings>::in_state<GstSiftMatch>(gobject_class);
  props.after_set([](Settings &s) { s.generation++; }); // a new matcher is made
  props.enumeration("method", "Method",
                    "How a keypoint's partner is chosen among the "
                    "candidates that satisfy the stereo constraints",
                    GST_TYPE_SIFT_MATCH_METHOD,
                    treestereo::gst::match_method_to_gst(d.matcher.method), TS_FIELD(method));
  props.real("ratio", "Ratio",
             "Ratio test: keep a match only when its distance (euclidean) or angle "
             "(cosine-norm) is below ratio x the second best's; 1 turns the test off",
             0.01, 1.0, d.matcher.ratio, TS_FIELD(ratio));
  props.integer("candidates", "Candidates",
                "cosine-norm: how many smallest angles compete on the norm difference", 1, 128,
                d.matcher.candidates, TS_FIELD(candidates));
  props.real("epipolar-tolerance", "Epipolar tolerance",
             "Largest row difference |yl - yr| (px) of a candidate; negative = no epipolar "
             "constraint (every keypoint of the other view is a candidate)",
             -1.0, 1000.0, d.matcher.constraints.epipolar_tolerance, TS_FIELD(epipolar_tolerance));
  props.real("min-disparity", "Minimum disparity",
             "Smallest disparity xl - xr (px); -1 = from max-depth and the stereo geometry", -1.0,
             MAX_DISPARITY_LIMIT, DEFAULT_MIN_DISPARITY, TS_FIELD(min_disparity));
  props.real("max-disparity", "Maximum disparity",
             "Largest disparity xl - xr (px); -1 = from min-depth and the stereo geometry", -1.0,
             MAX_DISPARITY_LIMIT, DEFAULT_MAX_DISPARITY, TS_FIELD(max_disparity));
  props.real("min-depth", "Minimum depth", "Nearest depth (mm) searched when max-disparity is -1",
             1.0, 1e6, SiftmatchPreset::kMinDepthMm, TS_FIELD(min_depth));
  props.real("max-depth", "Maximum depth", "Farthest depth (mm) searched when min-disparity is -1",
             1.0, 1e7, SiftmatchPreset::kMaxDepthMm, TS_FIELD(max_depth));
  props.boolean("mutual", "Mutual",
                "Keep a match only when matching back from the other view picks the same pair",
                d.matcher.constraints.mutual, TS_FIELD(mutual));
  props.integer("nfeatures", "Features", "Keep the N strongest keypoints per view; 0 = all", 0,
                G_MAXINT, d.detect.nfeatures, TS_FIELD(nfeatures));
  props.real("contrast-threshold", "Contrast threshold",
             "SIFT's contrast threshold (larger: fewer, stronger "
             "keypoints)",
             0.001, 1.0, d.detect.contrast_threshold, TS_FIELD(contrast_threshold));
  props.real("scale", "Scale",
             "Detect on the views resized by this factor (keypoints are reported and "
             "refined at full resolution); 0 = automatic: 1, 1/2, 1/4... whichever first "
             "brings a view to 648 px wide or less",
             0.0, 1.0, DEFAULT_SCALE, TS_FIELD(scale));
  props.boolean("use-mask", "Use mask",
                "Detect only inside the canopy of the vegetation meta (when there is one)",
                d.detect.use_mask, TS_FIELD(use_mask));
  props.boolean("upright", "Upright",
                "Describe each keypoint once, at angle 0, with treestereo's own SIFT (on "
                "rectified views the rows are the epipolar lines: no orientation is needed), "
                "and only those with a candidate in the other view; false: OpenCV's SIFT, one "
                "descriptor per dominant orientation",
                d.detect.engine == SiftEngine::Upright, TS_FIELD(upright));
  props.integer(
      "mask-inset", "Mask inset",
      "With use-mask: keep no keypoint within this many px (of the detection image, see "
      "scale) of the canopy's edge, where the descriptor window straddles the background; "
      "0 = the whole canopy",
      0, 64, d.detect.mask_inset, TS_FIELD(mask_inset));
  props.boolean("refine", "Refine",
                "Refine each disparity to sub-pixel by correlation at full resolution and "
                "drop matches without a clear correlation peak",
                d.refine, TS_FIELD(refine));
  props.real("min-zncc", "Minimum ZNCC",
             "Refinement: drop a match whose 7x7 correlation peak is below this", -1.0, 1.0,
             d.refine_params.min_zncc, TS_FIELD(min_zncc));
  props.real("min-zncc-drop", "Minimum ZNCC drop",
             "Refinement: drop a match whose 7x7 correlation stays within this of its peak "
             "over the whole search (+-3 px): a horizontal edge or a patch without horizontal "
             "structure correlates about as well at every position; 0 = off",
             0.0, 2.0, d.refine_params.min_zncc_drop, TS_FIELD(min_zncc_drop));
  props.real("layer-tolerance", "Layer tolerance",
             "Two-layer test after refinement: the four quadrants of the layer window and "
             "its 3x3 centre, each correlated on its own, must all peak within this many px "
             "of the refined disparity (rejects keypoints beside a depth edge that took the "
             "foreground's disparity); negative = off (needs refine)",
             -1.0, 100.0, d.refine_params.layer_tolerance, TS_FIELD(layer_tolerance));
  props.integer("layer-window", "Layer window",
                "Two-layer test: half size of its window (px at full resolution for a "
                "detection scale >= 0.5, times 0.5 / scale below it; 5 = 11x11, "
                "quadrants of 6x6)",
                1, 32, d.refine_params.layer_half_window, TS_FIELD(layer_window));
  props.integer("layer-search", "Layer search",
                "Two-layer test: how far (px) each part is searched around the refined "
                "disparity",
                1, 32, d.refine_params.layer_search, TS_FIELD(layer_search));
  props.real("layer-centre-tolerance", "Layer centre tolerance",
             "Two-layer test: the tolerance (px) of the 3x3 centre's peak, whose 9 pixels "
             "place it less precisely than a quadrant's; negative = layer-tolerance",
             -1.0, 100.0, d.refine_params.layer_centre_tolerance, TS_FIELD(layer_centre_tolerance));
  props.real("layer-min-zncc", "Layer minimum ZNCC",
             "Two-layer test: each quadrant's correlation at the refined disparity must reach "
             "this (a part of the window on another depth layer, or hidden in the right "
             "view, correlates poorly there); -1 = no minimum",
             -1.0, 1.0, d.refine_params.layer_min_zncc, TS_FIELD(layer_min_zncc));
  props.real("layer-centre-min-zncc", "Layer centre minimum ZNCC",
             "Two-layer test: the 3x3 centre's correlation at the refined disparity must "
             "reach this; -1 = no minimum",
             -1.0, 1.0, d.refine_params.layer_centre_min_zncc, TS_FIELD(layer_centre_min_zncc));
  props.integer("relocate", "Relocate",
                "Refinement: move each match, by at most this many px, to the pixel its "
                "disparity belongs to (the one whose 3x3 patch agrees best with the right "
                "view at that disparity), e.g. off a dark gap between two near leaves "
                "onto a leaf; 0 = off (needs refine)",
                0, 3, d.refine_params.relocate, TS_FIELD(relocate));
  props.after_set(nullptr);
  props.boolean("post-messages", "Post messages", "Post a siftmatch element message per frame",
                DEFAULT_POST_MESSAGES, TS_FIELD(post_messages));

  add_filter_pad_templates(element_class, CAPS);
  gst_element_class_set_static_metadata(
      element_class, "SIFT stereo matcher", "Filter/Analyzer/Video",
      "Matches SIFT features between the rectified views of a side-by-side stereo frame under "
      "the stereo constraints and attaches the matches as a meta",
      "treestereo developers");

  /* Our own transform_ip maps the frame read-only: the pixels are never written. */
  trans_class->transform_ip = gst_sift_match_transform_ip;
  trans_class->transform_ip_on_passthrough = FALSE;
  trans_class->start = gst_sift_match_start;
  trans_class->stop = gst_sift_match_stop;
  filter_class->set_info = gst_sift_match_set_info;

  gst_type_mark_as_plugin_api(GST_TYPE_SIFT_MATCH_METHOD, GstPluginAPIFlags(0));
}

static void gst_sift_match_init(GstSiftMatch *self)
{
  self->state = new State();
  gst_base_transform_set_in_place(GST_BASE_TRANSFORM(self), TRUE);
  gst_base_transform_set_passthrough(GST_BASE_TRANSFORM(self), FALSE);
}
