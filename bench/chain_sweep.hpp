// What the benchmarks that run the measuring chain on treetestsrc share (bench-accuracy,
// bench-orchard): the scene of one sweep point as element properties and as the renderer's
// parameters (the truth must be rendered from the very scene the source drew), the pipeline,
// the loop that pulls its frames, and the truth in the chain's rectified-left frame.
// Needs GStreamer and the meta library; sweep.hpp holds the parts that do not.
#pragma once

#include "sweep.hpp"
#include "treestereo/calibration_file.hpp"
#include "treestereo/scene.hpp"

#include <gst/app/gstappsink.h>
#include <gst/gst.h>
#include <gst/treestereo/treestereo-meta.h>
#include <glib/gstdio.h>

#include <opencv2/core.hpp>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace treestereo::bench {

// Finds the plugin in the build tree unless GST_PLUGIN_PATH(_1_0) says otherwise, then
// initialises GStreamer. TREESTEREO_PLUGIN_BUILD_DIR comes from bench/meson.build.
inline void init_gstreamer(int &argc, char **&argv)
{
  if (!g_getenv("GST_PLUGIN_PATH_1_0") && !g_getenv("GST_PLUGIN_PATH"))
    g_setenv("GST_PLUGIN_PATH_1_0", TREESTEREO_PLUGIN_BUILD_DIR, TRUE);
  gst_init(&argc, &argv);
}

// One point of a sweep: the scene both treetestsrc instances render.
struct SceneConfig {
  cv::Size size;
  double distance_m = 2.0;
  std::uint64_t seed = 1;
  double light = 1.0;
  SceneKind scene = SceneKind::Lab;
  // The rows (m); negative = the scene's default (treetestsrc's -1).
  double row_gap_min_m = -1, row_gap_max_m = -1, row_spacing_m = -1;
  double speed_m_s = 0;   // the rig driving along the row (at 7 frames/s)
  int touching_pair = -1; // treetestsrc's touching-pair: -1 none

  SceneConfig() = default;
  SceneConfig(cv::Size size_, double distance_m_, std::uint64_t seed_, double light_,
              SceneKind scene_)
      : size(size_), distance_m(distance_m_), seed(seed_), light(light_), scene(scene_)
  {
  }

  SceneParams params() const
  {
    SceneParams p;
    p.image_size = size;
    p.distance_mm = distance_m * 1000.0;
    p.seed = seed;
    p.light = light;
    p.kind = scene;
    const auto mm = [](double m) { return m < 0 ? kSceneDefault : m * 1000.0; };
    p.row_gap_min_mm = mm(row_gap_min_m);
    p.row_gap_max_mm = mm(row_gap_max_m);
    p.row_spacing_mm = mm(row_spacing_m);
    p.speed_m_s = speed_m_s;
    if (touching_pair >= 0)
      p.touching_pair = touching_pair;
    return p;
  }

  // treetestsrc's properties for this scene (without view and num-buffers).
  std::string treetestsrc() const
  {
    char b[512];
    std::snprintf(b, sizeof b,
                  "scene=%s seed=%llu distance=%g light=%g row-gap-min=%g row-gap-max=%g "
                  "row-spacing=%g speed=%g touching-pair=%d",
                  scene_kind_name(scene), (unsigned long long)seed, distance_m, light,
                  row_gap_min_m < 0 ? -1.0 : row_gap_min_m,
                  row_gap_max_m < 0 ? -1.0 : row_gap_max_m,
                  row_spacing_m < 0 ? -1.0 : row_spacing_m, speed_m_s, touching_pair);
    return b;
  }
};

// Extra properties per element, gst-launch syntax.
struct ElementProps {
  std::string exgsegment, siftmatch, stereodepth, treemetrics, treetestsrc;
};

// Takes one of the element options ("--exgsegment", "--siftmatch", "--stereodepth",
// "--treemetrics", "--treetestsrc") with its value into `p`; false for any other option.
inline bool element_option(const std::string &option, const std::string &value, ElementProps &p)
{
  return take_option(option, value,
                     {{"--exgsegment", &p.exgsegment},
                      {"--siftmatch", &p.siftmatch},
                      {"--stereodepth", &p.stereodepth},
                      {"--treemetrics", &p.treemetrics},
                      {"--treetestsrc", &p.treetestsrc}});
}

// The rig's calibration at one frame size, saved to a temporary file for stereorectify.
class RigFile
{
public:
  explicit RigFile(cv::Size size) : dir_(g_dir_make_tmp("bench-chain-rig-XXXXXX", nullptr))
  {
    SceneParams p;
    p.image_size = size;
    calibration_ = rig_calibration(p);
    path_ = std::string(dir_) + "/rig.yml";
    save_calibration(calibration_, path_);
  }
  ~RigFile()
  {
    g_unlink(path_.c_str());
    g_rmdir(dir_);
    g_free(dir_);
  }
  RigFile(const RigFile &) = delete;
  RigFile &operator=(const RigFile &) = delete;
  const std::string &path() const { return path_; }
  const StereoCalibration &calibration() const { return calibration_; }

private:
  gchar *dir_;
  std::string path_;
  StereoCalibration calibration_;
};

// The chain as users run it, from the two sources to siftmatch's output, followed by `tail`
// (gst-launch syntax, starting with an element, ending in appsinks named as run_chain() is told).
inline std::string chain_description(const SceneConfig &c, int frames, const std::string &calib,
                                     const ElementProps &props, const std::string &tail)
{
  const std::string src = c.treetestsrc() + " " + props.treetestsrc;
  const std::string caps = "video/x-raw,format=RGB,width=" + std::to_string(c.size.width) +
                           ",height=" + std::to_string(c.size.height);
  const std::string n = std::to_string(frames);
  return "stereorectify name=r calibration=" + calib + " ! exgsegment " + props.exgsegment +
         " ! siftmatch " + props.siftmatch + " ! " + tail +
         " treetestsrc view=left num-buffers=" + n + " " + src + " truth-maps=false ! " + caps +
         " ! r.left treetestsrc view=right num-buffers=" + n + " " + src + " truth-maps=false ! " +
         caps + " ! r.right";
}

// Runs a pipeline to its end: for every frame, on_frame(frame, buffers) with one buffer per
// appsink in `sinks` (in that order). Errors on the bus are printed with `who` in front; at the
// end, every element message posted goes to on_element, in order.
// Returns the wall time per frame (ms).
inline double run_chain(const std::string &description, const std::vector<std::string> &sinks,
                        const std::function<void(int, const std::vector<GstBuffer *> &)> &on_frame,
                        const char *who,
                        const std::function<void(GstMessage *)> &on_element = {})
{
  GError *err = nullptr;
  GstElement *p = gst_parse_launch(description.c_str(), &err);
  if (!p || err)
    throw std::runtime_error(std::string("pipeline: ") + (err ? err->message : "?"));
  std::vector<GstElement *> out;
  for (const std::string &name : sinks)
    out.push_back(gst_bin_get_by_name(GST_BIN(p), name.c_str()));
  const gint64 t0 = g_get_monotonic_time();
  gst_element_set_state(p, GST_STATE_PLAYING);
  int frame = 0;
  for (bool more = true; more;) {
    std::vector<GstSample *> samples;
    for (GstElement *sink : out)
      if (GstSample *s = gst_app_sink_try_pull_sample(GST_APP_SINK(sink), 300 * GST_SECOND))
        samples.push_back(s);
    more = samples.size() == out.size(); // else the end of the stream (or a stall)
    if (more) {
      std::vector<GstBuffer *> buffers;
      for (GstSample *s : samples)
        buffers.push_back(gst_sample_get_buffer(s));
      on_frame(frame++, buffers);
    }
    for (GstSample *s : samples)
      gst_sample_unref(s);
  }
  // The bus in order: the first error is printed; element messages go to on_element.
  GstBus *bus = gst_element_get_bus(p);
  bool error_seen = false;
  while (GstMessage *msg = gst_bus_pop(bus)) {
    if (GST_MESSAGE_TYPE(msg) == GST_MESSAGE_ERROR && !error_seen) {
      GError *e = nullptr;
      gst_message_parse_error(msg, &e, nullptr);
      std::fprintf(stderr, "%s: %s\n", who, e->message);
      g_error_free(e);
      error_seen = true;
    } else if (GST_MESSAGE_TYPE(msg) == GST_MESSAGE_ELEMENT && on_element) {
      on_element(msg);
    }
    gst_message_unref(msg);
  }
  gst_object_unref(bus);
  const double ms = (g_get_monotonic_time() - t0) / 1000.0;
  gst_element_set_state(p, GST_STATE_NULL);
  for (GstElement *sink : out)
    gst_object_unref(sink);
  gst_object_unref(p);
  return ms / std::max(1, frame);
}

// The geometry meta's rotation into the rectified-left frame (identity without the meta).
inline cv::Matx33d rectified_rotation(const GstTreeStereoGeometryMeta *g)
{
  cv::Matx33d R1 = cv::Matx33d::eye();
  if (g)
    for (int i = 0; i < 9; i++)
      R1.val[i] = g->R1[i];
  return R1;
}

// The truth of `frame`'s left view, raw (the renderer's left camera frame, per-pixel maps of the
// unrectified view) into *raw when not null, and returned in the chain's rectified-left frame.
inline GroundTruth rectified_truth(const SceneRenderer &renderer, int frame,
                                   const GstTreeStereoGeometryMeta *g, GroundTruth *raw = nullptr)
{
  cv::Mat rgb;
  GroundTruth t;
  renderer.render(0, std::uint64_t(frame), rgb, &t);
  GroundTruth tr = truth_in_frame(t, rectified_rotation(g));
  if (raw)
    *raw = std::move(t);
  return tr;
}

} // namespace treestereo::bench
