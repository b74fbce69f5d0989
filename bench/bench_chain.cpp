// bench-chain: throughput, per-element time, CPU use and memory of the measuring chain on
// preloaded frames, side by side with gst-plugins-bad's `disparity` (OpenCV SGBM) and with
// `stereodepth mode=dense`; how the cost grows with keypoints and image size; RSS over a long run.
//
//   bench-chain [--sizes 640x480,1296x972,2592x1944] [--frames 40] [--runs 3] [--distinct 6]
//               [--pipelines full,queued,dense,disparity] [--keypoints 1296x972]
//               [--growth-sizes 320x240,...] [--memory 2000] [--only throughput|keypoints|sizes|memory]
//               [--scene lab|orchard|hedgerow] [--exgsegment PROP=VALUE+...]
//               [--plugin-path [LABEL=]DIR[,[LABEL=]DIR2...]]
//
// Frames: `distinct` stereo pairs of the synthetic scene (SceneRenderer, SceneParams::kind from
// --scene: lab by default, the tree alone on soil; orchard/hedgerow: a row of trees, a row
// behind, grass; the rig driving at 1 m/s, 7 frames/s, so every pair differs) are rendered once
// into GstBuffers before the pipeline starts. --exgsegment adds exgsegment properties to every
// chain (default none; with --scene orchard or hedgerow, keep=all). A pipeline spec's extra
// properties go to siftmatch ("full/scale=0.5"), or to the element named ("full/stereodepth.
// canopy=off"); a plugin without that property skips the variant ("-" in the table).
//
// --plugin-path (throughput only) measures plugin builds side by side on the SAME frames: this
// process renders the frames once into a file, then runs one child bench-chain per plugin build
// and run, interleaved (A B A B ...: GStreamer loads one plugin of a name per process), each with
// GST_PLUGIN_PATH=DIR, its own registry, and LD_LIBRARY_PATH=DIR/../meta (that build's meta
// library, when there); one table gives every plugin's figures and its frame rate against the
// first plugin's same pipeline (or, when the first has no such variant, its same kind). Two appsrc (format=time, is-live=false, block=true) push shallow copies of
// them (gst_buffer_copy shares the memory: no pixel copy, no decoding) with PTS i/7 s, cycling
// through the distinct pairs. The sink is fakesink sync=false, so the chain runs as fast as it can.
//
// Timing: a buffer probe on every element's sink and src pad stamps each frame (by PTS) with the
// monotonic clock; an in-place element's time is src - sink of the same frame. stereorectify is
// an aggregator with its own streaming thread; in the sequential chain that thread runs the whole
// chain, so its time is its src stamp of frame i minus the fakesink stamp of frame i-1 (the
// moment its previous push returned): that includes pairing and buffer allocation. The first
// `warmup` frames (caps, maps, pools, SIFT's first allocations) are left out of every figure.
// Frame rate: frames after the warm-up over the time between their fakesink stamps.
// CPU use: getrusage(RUSAGE_SELF) user+sys over wall time over the same frames (200 % = both
// cores busy). Peak RSS: VmHWM of the process, reset (malloc_trim, then clear_refs 5) before
// each pipeline; it includes the preloaded frames, reported separately.
#include "treestereo/calibration_file.hpp"
#include "treestereo/rectify.hpp"
#include "treestereo/scene.hpp"
#include "treestereo/stats.hpp"

#include <gst/app/gstappsrc.h>
#include <gst/gst.h>
#include <gst/video/video.h>
#include <gst/treestereo/treestereo-meta.h>
#include <glib/gstdio.h>

#include <malloc.h>
#include <sys/resource.h>
#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h> // profile only the pipelines: valgrind --instr-atstart=no
#else
#define CALLGRIND_START_INSTRUMENTATION
#define CALLGRIND_STOP_INSTRUMENTATION
#endif

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

using namespace treestereo;

namespace {

constexpr int FPS_N = 7; // the sprayer's frame rate: only sets the PTS

struct Options {
  std::vector<cv::Size> sizes{{640, 480}, {1296, 972}, {2592, 1944}};
  std::vector<std::string> pipelines{"full", "queued", "dense", "disparity"}; // see variant_of
  std::vector<cv::Size> growth_sizes{{320, 240}, {640, 480}, {960, 720}, {1296, 972},
                                     {1944, 1458}, {2592, 1944}};
  cv::Size keypoint_size{1296, 972};
  int frames = 40, runs = 3, distinct = 6, warmup = 4, memory_frames = 2000;
  bool header = true;
  std::string only;
  SceneKind scene = SceneKind::Lab;
  std::string exg_extra;                 // extra exgsegment properties ("keep=all")
  bool exg_extra_set = false;
  std::vector<std::string> plugin_paths; // [LABEL=]DIR per plugin build: side by side
  std::string pipelines_arg = "full,queued,dense,disparity";
  std::string frames_file; // child: load the frames from this file instead of rendering
};

std::vector<cv::Size> parse_sizes(const std::string &s)
{
  std::vector<cv::Size> v;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    int w, h;
    if (std::sscanf(item.c_str(), "%dx%d", &w, &h) != 2 || w < 64 || h < 48)
      throw std::runtime_error("bench-chain: bad size '" + item + "' (want WxH, at least 64x48)");
    v.emplace_back(w, h);
  }
  return v;
}

std::vector<std::string> parse_words(const std::string &s)
{
  std::vector<std::string> v;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    v.push_back(item);
  return v;
}

long proc_status_kb(const char *key)
{
  std::ifstream f("/proc/self/status");
  std::string line;
  const size_t n = std::strlen(key);
  while (std::getline(f, line))
    if (line.compare(0, n, key) == 0)
      return std::atol(line.c_str() + n + 1);
  return -1;
}

// Returns the heap that earlier pipelines freed to the system, then restarts VmHWM from the
// current RSS, so a pipeline's peak is its own.
void reset_peak_rss()
{
  malloc_trim(0);
  std::ofstream f("/proc/self/clear_refs");
  f << "5";
}

double cpu_seconds()
{
  struct rusage u;
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// The preloaded stereo pairs of one size: raw views (for the chains) and rectified views (for
// `disparity`, which expects rectified input and has no rectifier of its own).
struct Frames {
  cv::Size size;
  std::string calib_path;
  std::vector<GstBuffer *> raw[2], rectified[2]; // rectified: only while `disparity` runs
  std::vector<double> truth_distance_m; // per distinct pair, in the rectified-left frame
  bool owns_calib = true;                // a child reads its parent's file: leaves it
  ~Frames()
  {
    drop(rectified);
    drop(raw);
    if (owns_calib && !calib_path.empty())
      g_unlink(calib_path.c_str());
  }
  static void drop(std::vector<GstBuffer *> (&views)[2])
  {
    for (std::vector<GstBuffer *> &v : views) {
      for (GstBuffer *b : v)
        gst_buffer_unref(b);
      v.clear();
    }
  }
  double megabytes() const
  {
    return 2.0 * raw[0].size() * size.area() * 3 / (1024.0 * 1024.0);
  }
};

GstBuffer *mat_buffer(const cv::Mat &m)
{
  GstBuffer *b = gst_buffer_new_allocate(nullptr, m.total() * m.elemSize(), nullptr);
  gst_buffer_fill(b, 0, m.data, m.total() * m.elemSize());
  return b;
}

std::unique_ptr<Frames> preload(cv::Size size, int distinct, const std::string &dir,
                                SceneKind scene = SceneKind::Lab)
{
  auto f = std::make_unique<Frames>();
  f->size = size;
  SceneParams p;
  p.kind = scene;
  p.image_size = size;
  p.speed_m_s = 1.0;
  p.framerate = FPS_N;
  SceneRenderer renderer(p);
  f->calib_path = dir + "/rig-" + std::to_string(size.width) + ".yml";
  save_calibration(renderer.calibration(), f->calib_path);
  const cv::Matx33d R1 = compute_rectification(renderer.calibration(), size).geometry.R1;
  for (int i = 0; i < distinct; i++)
    for (int v = 0; v < 2; v++) {
      cv::Mat rgb;
      GroundTruth t;
      renderer.render(v, std::uint64_t(i), rgb, v == 0 ? &t : nullptr);
      if (v == 0)
        f->truth_distance_m.push_back(truth_in_frame(t, R1).distance_m);
      f->raw[v].push_back(mat_buffer(rgb));
    }
  return f;
}

// The preloaded frames in a file, for the children of --plugin-path: the size, the calibration
// file's path, the truth, then each view's raw RGB pixels.
void save_frames(const Frames &f, const std::string &path)
{
  std::ofstream o(path, std::ios::binary);
  const int head[3] = {f.size.width, f.size.height, int(f.raw[0].size())};
  o.write(reinterpret_cast<const char *>(head), sizeof head);
  const std::size_t n = f.calib_path.size();
  o.write(reinterpret_cast<const char *>(&n), sizeof n);
  o.write(f.calib_path.data(), std::streamsize(n));
  o.write(reinterpret_cast<const char *>(f.truth_distance_m.data()),
          std::streamsize(f.truth_distance_m.size() * sizeof(double)));
  for (int v = 0; v < 2; v++)
    for (GstBuffer *b : f.raw[v]) {
      GstMapInfo map;
      gst_buffer_map(b, &map, GST_MAP_READ);
      o.write(reinterpret_cast<const char *>(map.data), std::streamsize(map.size));
      gst_buffer_unmap(b, &map);
    }
  if (!o)
    throw std::runtime_error("bench-chain: could not write " + path);
}

std::unique_ptr<Frames> load_frames(const std::string &path)
{
  std::ifstream in(path, std::ios::binary);
  auto f = std::make_unique<Frames>();
  f->owns_calib = false;
  int head[3] = {0, 0, 0};
  std::size_t n = 0;
  in.read(reinterpret_cast<char *>(head), sizeof head);
  in.read(reinterpret_cast<char *>(&n), sizeof n);
  if (!in || head[0] < 64 || head[1] < 48 || head[2] < 1 || n > 4096)
    throw std::runtime_error("bench-chain: bad frames file " + path);
  f->size = cv::Size(head[0], head[1]);
  f->calib_path.resize(n);
  in.read(f->calib_path.data(), std::streamsize(n));
  f->truth_distance_m.resize(std::size_t(head[2]));
  in.read(reinterpret_cast<char *>(f->truth_distance_m.data()),
          std::streamsize(f->truth_distance_m.size() * sizeof(double)));
  const std::size_t bytes = std::size_t(f->size.area()) * 3;
  std::vector<char> px(bytes);
  for (int v = 0; v < 2; v++)
    for (int i = 0; i < head[2]; i++) {
      in.read(px.data(), std::streamsize(bytes));
      GstBuffer *b = gst_buffer_new_allocate(nullptr, bytes, nullptr);
      gst_buffer_fill(b, 0, px.data(), bytes);
      f->raw[v].push_back(b);
    }
  if (!in)
    throw std::runtime_error("bench-chain: short frames file " + path);
  return f;
}

// The same pairs rectified once, for `disparity`, which expects rectified views and has no
// rectifier of its own (so its figures leave rectification out: in its favour).
void add_rectified(Frames &f)
{
  const StereoRectification rect =
      compute_rectification(load_calibration(f.calib_path), f.size);
  for (int v = 0; v < 2; v++)
    for (GstBuffer *b : f.raw[v]) {
      GstMapInfo map;
      gst_buffer_map(b, &map, GST_MAP_READ);
      cv::Mat rectified;
      rectify_view(rect, v, cv::Mat(f.size, CV_8UC3, map.data), rectified);
      gst_buffer_unmap(b, &map);
      f.rectified[v].push_back(mat_buffer(rectified));
    }
}

// One pipeline description; the bench finds its elements by these names.
struct Chain {
  std::string description;
  std::vector<std::string> timed; // in-place elements timed sink -> src
  bool has_rectify = true;
};

// Extra properties of the chains' elements: siftmatch's (a pipeline spec's plain ones), the
// element-qualified ones of the spec ("stereodepth.canopy=off") and --exgsegment's.
struct Extras {
  std::string siftmatch, stereodepth, exgsegment;
};

Chain chain_of(const std::string &kind, const Frames &f, const Extras &x)
{
  const std::string &sift_extra = x.siftmatch;
  const std::string exg = " ! exgsegment name=exgsegment " + x.exgsegment;
  const std::string sd = " " + x.stereodepth;
  const std::string src = "appsrc name=src0 ! r.left appsrc name=src1 ! r.right "
                          "stereorectify name=r calibration=" + f.calib_path;
  const std::string sink = " ! fakesink name=sink sync=false";
  Chain c;
  if (kind == "full" || kind == "sparse") {
    // sparse: stereodepth without densification (the matches' points alone)
    c.description = src + exg + " ! siftmatch name=siftmatch " +
                    sift_extra + " ! stereodepth name=stereodepth" + sd +
                    (kind == "sparse" ? " densify=false" : "") +
                    " ! treemetrics name=treemetrics" + sink;
    c.timed = {"exgsegment", "siftmatch", "stereodepth", "treemetrics"};
  } else if (kind == "queued") {
    // Two stages: rectify+segment on the aggregator's thread, match+depth+metrics on the
    // queue's, so they overlap on the two cores.
    c.description = src + exg + " ! queue max-size-buffers=2 ! siftmatch "
                          "name=siftmatch " + sift_extra + " ! stereodepth name=stereodepth" +
                    sd + " ! treemetrics name=treemetrics" + sink;
    c.timed = {"exgsegment", "siftmatch", "stereodepth", "treemetrics"};
  } else if (kind == "dense") {
    c.description = src + exg + " ! stereodepth name=stereodepth "
                          "mode=dense" + sd + " ! treemetrics name=treemetrics" + sink;
    c.timed = {"exgsegment", "stereodepth", "treemetrics"};
  } else if (kind == "disparity") {
    c.description = "disparity name=disparity method=sgbm" + sink +
                    " appsrc name=src0 ! disparity.sink_left appsrc name=src1 ! "
                    "disparity.sink_right";
    c.has_rectify = false;
  } else {
    throw std::runtime_error("bench-chain: unknown pipeline '" + kind + "'");
  }
  return c;
}

// Per-frame stamps (µs, monotonic) written by the probes: one writer per slot, read after EOS.
struct Stamps {
  int n = 0;
  std::map<std::string, std::vector<gint64>> in, out;
  std::vector<gint64> sink;
  std::vector<double> cpu_at_sink; // process CPU seconds when the frame reached the sink
  std::vector<long> rss_kb;        // VmRSS every 100 frames (at frames 50, 150, ...)
  long last_rss_kb = 0;            // VmRSS at the last frame
  std::vector<unsigned> keypoints; // left + right, from the matches meta
  std::vector<char> tree;          // the metrics meta said tree_present
  std::vector<double> distance_m;  // its distance
  // The first GstMemory of each frame as stereorectify pushed it and as it reached the sink:
  // a difference means an element copied the frame.
  std::vector<const void *> mem_out, mem_sink;
};

struct ProbeCtx {
  Stamps *stamps;
  std::vector<gint64> *slot;
  bool is_sink = false;
  std::vector<const void *> *mem = nullptr;
};

int frame_index(GstBuffer *b, int n)
{
  if (!GST_BUFFER_PTS_IS_VALID(b))
    return -1;
  const long i = std::lround(double(GST_BUFFER_PTS(b)) * FPS_N / GST_SECOND);
  return i >= 0 && i < n ? int(i) : -1;
}

GstPadProbeReturn stamp_probe(GstPad *, GstPadProbeInfo *info, gpointer data)
{
  const gint64 now = g_get_monotonic_time();
  auto *ctx = static_cast<ProbeCtx *>(data);
  GstBuffer *b = GST_PAD_PROBE_INFO_BUFFER(info);
  const int i = frame_index(b, ctx->stamps->n);
  if (i < 0)
    return GST_PAD_PROBE_OK;
  (*ctx->slot)[i] = now;
  if (ctx->mem && gst_buffer_n_memory(b) > 0)
    (*ctx->mem)[i] = gst_buffer_peek_memory(b, 0);
  if (ctx->is_sink) {
    Stamps &s = *ctx->stamps;
    s.cpu_at_sink[i] = cpu_seconds();
    if (i % 100 == 49)
      s.rss_kb.push_back(proc_status_kb("VmRSS:"));
    if (i == s.n - 1)
      s.last_rss_kb = proc_status_kb("VmRSS:");
    if (const GstTreeStereoMatchesMeta *m = gst_buffer_get_tree_stereo_matches_meta(b))
      s.keypoints[i] = m->n_keypoints[0] + m->n_keypoints[1];
    if (const GstTreeStereoMetricsMeta *m = gst_buffer_get_tree_stereo_metrics_meta(b))
    {
      s.tree[i] = m->metrics.tree_present ? 1 : 0;
      s.distance_m[i] = m->metrics.distance_m;
    }
  }
  return GST_PAD_PROBE_OK;
}

void add_probe(GstElement *pipe, const char *element, const char *pad, ProbeCtx *ctx)
{
  GstElement *e = gst_bin_get_by_name(GST_BIN(pipe), element);
  if (!e)
    throw std::runtime_error(std::string("bench-chain: no element ") + element);
  GstPad *p = gst_element_get_static_pad(e, pad);
  gst_pad_add_probe(p, GST_PAD_PROBE_TYPE_BUFFER, stamp_probe, ctx, nullptr);
  gst_object_unref(p);
  gst_object_unref(e);
}

void feed(GstElement *appsrc, const std::vector<GstBuffer *> &frames, int n)
{
  const GstClockTime dur = gst_util_uint64_scale_int(GST_SECOND, 1, FPS_N);
  for (int i = 0; i < n; i++) {
    // A new buffer header on the same memory: the pixels are never copied.
    GstBuffer *b = gst_buffer_copy(frames[size_t(i) % frames.size()]);
    GST_BUFFER_PTS(b) = gst_util_uint64_scale_int(GST_SECOND, i, FPS_N);
    GST_BUFFER_DURATION(b) = dur;
    if (gst_app_src_push_buffer(GST_APP_SRC(appsrc), b) != GST_FLOW_OK)
      return;
  }
  gst_app_src_end_of_stream(GST_APP_SRC(appsrc));
}

struct RunResult {
  double fps = 0, cpu_pct = 0, peak_rss_mb = 0;
  std::map<std::string, std::vector<double>> ms; // per element, per frame after warm-up
  std::vector<double> distance_err_cm;           // |measured - true| trunk-canopy distance
  double cpu_ms_per_frame = 0;
  std::vector<unsigned> keypoints;
  std::vector<long> rss_kb;
  long last_rss_kb = 0;
  int frames = 0, trees = 0, counted = 0, copies = 0;
};

RunResult run_chain(const Chain &c, const Frames &f, int n, int warmup)
{
  if (n <= warmup + 1)
    throw std::runtime_error("bench-chain: --frames must exceed the warm-up");
  GError *err = nullptr;
  GstElement *pipe = gst_parse_launch(c.description.c_str(), &err);
  if (!pipe || err)
    throw std::runtime_error("bench-chain: pipeline: " + std::string(err ? err->message : "?"));
  const bool rectified_input = !c.has_rectify;
  for (int v = 0; v < 2; v++) {
    GstElement *src = gst_bin_get_by_name(GST_BIN(pipe), v ? "src1" : "src0");
    // Fully fixed caps, as gst_video_info_to_caps() writes them: `disparity` refuses a second
    // pad's caps unless they equal those it derived from the first pad's.
    GstVideoInfo info;
    gst_video_info_set_format(&info, GST_VIDEO_FORMAT_RGB, guint(f.size.width),
                              guint(f.size.height));
    GST_VIDEO_INFO_FPS_N(&info) = FPS_N;
    GST_VIDEO_INFO_FPS_D(&info) = 1;
    GstCaps *caps = gst_video_info_to_caps(&info);
    g_object_set(src, "caps", caps, "format", GST_FORMAT_TIME, "is-live", FALSE, "block", TRUE,
                 "max-bytes", guint64(3) * f.size.area() * 3, nullptr);
    gst_caps_unref(caps);
    gst_object_unref(src);
  }
  Stamps s;
  s.n = n;
  s.sink.assign(n, 0);
  s.cpu_at_sink.assign(n, 0);
  s.keypoints.assign(n, 0);
  s.tree.assign(n, 0);
  s.distance_m.assign(n, 0);
  std::vector<std::unique_ptr<ProbeCtx>> ctxs;
  s.mem_out.assign(n, nullptr);
  s.mem_sink.assign(n, nullptr);
  auto probe = [&](const std::string &el, const char *pad, std::vector<gint64> *slot, bool sink,
                   std::vector<const void *> *mem = nullptr) {
    ctxs.push_back(std::make_unique<ProbeCtx>(ProbeCtx{&s, slot, sink, mem}));
    add_probe(pipe, el.c_str(), pad, ctxs.back().get());
  };
  std::vector<std::string> timed = c.timed;
  if (!c.has_rectify)
    timed = {"disparity"};
  for (const std::string &el : timed) {
    s.in[el].assign(n, 0);
    s.out[el].assign(n, 0);
    // disparity computes in its right pad's chain function and pushes from it.
    probe(el, el == "disparity" ? "sink_right" : "sink", &s.in[el], false);
    probe(el, "src", &s.out[el], false);
  }
  if (c.has_rectify) {
    s.out["stereorectify"].assign(n, 0);
    probe("r", "src", &s.out["stereorectify"], false, &s.mem_out);
  }
  probe("sink", "sink", &s.sink, true, &s.mem_sink);

  reset_peak_rss();
  GstElement *src0 = gst_bin_get_by_name(GST_BIN(pipe), "src0");
  GstElement *src1 = gst_bin_get_by_name(GST_BIN(pipe), "src1");
  CALLGRIND_START_INSTRUMENTATION;
  gst_element_set_state(pipe, GST_STATE_PLAYING);
  std::thread l(feed, src0, std::cref(rectified_input ? f.rectified[0] : f.raw[0]), n);
  std::thread r(feed, src1, std::cref(rectified_input ? f.rectified[1] : f.raw[1]), n);
  GstBus *bus = gst_element_get_bus(pipe);
  std::string error;
  for (;;) {
    GstMessage *m = gst_bus_timed_pop_filtered(
        bus, 600 * GST_SECOND, GstMessageType(GST_MESSAGE_EOS | GST_MESSAGE_ERROR));
    if (!m) {
      error = "timeout";
      break;
    }
    if (GST_MESSAGE_TYPE(m) == GST_MESSAGE_ERROR) {
      GError *e = nullptr;
      gst_message_parse_error(m, &e, nullptr);
      error = e->message;
      g_error_free(e);
    }
    gst_message_unref(m);
    break;
  }
  CALLGRIND_STOP_INSTRUMENTATION;
  gst_element_set_state(pipe, GST_STATE_NULL);
  l.join();
  r.join();
  gst_object_unref(bus);
  gst_object_unref(src0);
  gst_object_unref(src1);
  gst_object_unref(pipe);
  if (!error.empty())
    throw std::runtime_error("bench-chain: " + error);

  RunResult res;
  res.peak_rss_mb = proc_status_kb("VmHWM:") / 1024.0;
  res.rss_kb = s.rss_kb;
  res.last_rss_kb = s.last_rss_kb;
  // `disparity` forwards the left pad's EOS at once and may drop the last pair: count the frames
  // that arrived.
  int last = n - 1;
  while (last > 0 && s.sink[last] == 0)
    last--;
  const int first = warmup - 1;
  if (last <= first || s.sink[first] == 0)
    throw std::runtime_error("bench-chain: too few frames reached the sink");
  res.frames = last - first;
  const double secs = (s.sink[last] - s.sink[first]) * 1e-6;
  res.fps = res.frames / secs;
  res.cpu_pct = 100.0 * (s.cpu_at_sink[last] - s.cpu_at_sink[first]) / secs;
  res.cpu_ms_per_frame = 1000.0 * (s.cpu_at_sink[last] - s.cpu_at_sink[first]) / res.frames;
  for (int i = warmup; i <= last; i++) {
    if (s.sink[i] == 0 || s.sink[i - 1] == 0)
      continue;
    res.counted++;
    res.keypoints.push_back(s.keypoints[i]);
    res.trees += s.tree[i];
    if (c.has_rectify && s.mem_out[i] != s.mem_sink[i])
      res.copies++;
    if (s.tree[i])
      res.distance_err_cm.push_back(
          100 * std::abs(s.distance_m[i] - f.truth_distance_m[size_t(i) % f.truth_distance_m.size()]));
    for (const std::string &el : timed)
      res.ms[el].push_back((s.out[el][i] - s.in[el][i]) / 1000.0);
    if (c.has_rectify && c.timed.size() && c.description.find("queue") == std::string::npos)
      res.ms["stereorectify"].push_back((s.out["stereorectify"][i] - s.sink[i - 1]) / 1000.0);
  }
  return res;
}

// All runs of one pipeline on one size, pooled.
struct Pooled {
  std::vector<double> fps, cpu, rss, cpu_ms, distance_err_cm;
  std::map<std::string, std::vector<double>> ms;
  std::vector<double> keypoints;
  int frames = 0, trees = 0, copies = 0;
  void add(const RunResult &r)
  {
    fps.push_back(r.fps);
    cpu.push_back(r.cpu_pct);
    cpu_ms.push_back(r.cpu_ms_per_frame);
    distance_err_cm.insert(distance_err_cm.end(), r.distance_err_cm.begin(),
                           r.distance_err_cm.end());
    rss.push_back(r.peak_rss_mb);
    for (const auto &[el, v] : r.ms)
      ms[el].insert(ms[el].end(), v.begin(), v.end());
    for (unsigned k : r.keypoints)
      keypoints.push_back(k);
    frames += r.counted;
    trees += r.trees;
    copies += r.copies;
  }
};

std::string ms_cell(const Pooled &p, const std::string &el)
{
  auto it = p.ms.find(el);
  if (it == p.ms.end() || it->second.empty())
    return "-";
  const Summary s = summarize(it->second);
  return cv::format("%.1f / %.1f", s.median, s.p95);
}

std::string size_str(cv::Size s)
{
  return std::to_string(s.width) + "x" + std::to_string(s.height);
}

// A pipeline variant: its kind (chain_of) and extra element properties.
struct Variant {
  std::string label, kind;
  Extras x;
  // The same kind with the same siftmatch settings: the plugins' rows compared when the
  // reference plugin lacks an element-qualified property.
  std::string base() const { return kind + "/" + x.siftmatch; }
};

Extras with_options(Extras x, const Options &o)
{
  x.exgsegment = o.exg_extra;
  return x;
}

// Runs every variant `runs` times, interleaved (A B C A B C ...) so that a change in the
// machine's load hits them alike.
std::vector<Pooled> run_many(const std::vector<Variant> &variants, Frames &f, const Options &o)
{
  std::vector<Pooled> out(variants.size());
  for (const Variant &v : variants)
    if (v.kind == "disparity" && f.rectified[0].empty())
      add_rectified(f);
  for (int r = 0; r < o.runs; r++)
    for (size_t k = 0; k < variants.size(); k++) {
      const Variant &v = variants[k];
      RunResult res = run_chain(chain_of(v.kind, f, with_options(v.x, o)), f, o.frames, o.warmup);
      std::fprintf(stderr, "  %s %s run %d: %.2f frames/s, CPU %.0f %% (%.0f ms/frame), peak "
                   "RSS %.0f MB\n", v.label.c_str(), size_str(f.size).c_str(), r + 1, res.fps,
                   res.cpu_pct, res.cpu_ms_per_frame, res.peak_rss_mb);
      out[k].add(res);
    }
  Frames::drop(f.rectified);
  return out;
}

std::string err_cell(const Pooled &p)
{
  if (p.distance_err_cm.empty())
    return "-";
  const Summary s = summarize(p.distance_err_cm);
  return cv::format("%.1f / %.1f", s.median, s.p95);
}

// "kind" or "kind/prop=value+prop=value": extra siftmatch properties, or, as
// "element.prop=value", stereodepth's.
Variant variant_of(const std::string &spec)
{
  Variant v;
  v.label = spec;
  const size_t slash = spec.find('/');
  v.kind = spec.substr(0, slash);
  if (slash != std::string::npos) {
    for (const std::string &kv : parse_words([&] {
           std::string t = spec.substr(slash + 1);
           std::replace(t.begin(), t.end(), '+', ',');
           return t;
         }())) {
      const size_t eq = kv.find('='), dot = kv.find('.');
      if (dot != std::string::npos && dot < eq) {
        const std::string el = kv.substr(0, dot);
        if (el != "stereodepth" && el != "siftmatch")
          throw std::runtime_error("bench-chain: '" + kv + "': only siftmatch.* and "
                                   "stereodepth.* in a pipeline spec (--exgsegment for it)");
        std::string &to = el == "stereodepth" ? v.x.stereodepth : v.x.siftmatch;
        to += (to.empty() ? "" : " ") + kv.substr(dot + 1);
      } else {
        v.x.siftmatch += (v.x.siftmatch.empty() ? "" : " ") + kv;
      }
    }
    v.label = v.kind;
    if (!v.x.siftmatch.empty())
      v.label += " (siftmatch " + v.x.siftmatch + ")";
    if (!v.x.stereodepth.empty())
      v.label += " (stereodepth " + v.x.stereodepth + ")";
  }
  return v;
}

// Whether this process's plugin has every property the variant sets (an older build may lack
// one: its row is then "-").
bool plugin_supports(const Variant &v)
{
  for (const auto &[element, props] :
       {std::pair{"siftmatch", v.x.siftmatch}, std::pair{"stereodepth", v.x.stereodepth}}) {
    if (props.empty())
      continue;
    GstElement *e = gst_element_factory_make(element, nullptr);
    if (!e)
      return false;
    std::stringstream ss(props);
    std::string kv;
    bool ok = true;
    while (ss >> kv)
      ok = ok && g_object_class_find_property(G_OBJECT_GET_CLASS(e),
                                              kv.substr(0, kv.find('=')).c_str()) != nullptr;
    gst_object_unref(e);
    if (!ok)
      return false;
  }
  return true;
}

void throughput(const Options &o, const std::string &dir)
{
  if (o.header) {
    std::printf("### Throughput on preloaded frames\n\n");
    std::printf("frames/s: median of %d runs of %d frames (the first %d of each left out), the "
                "pipelines interleaved; CPU ms/frame: user+sys of the process per frame (the "
                "load-independent cost); CPU %%: of one core (200 %% = both); element ms: median "
                "/ p95 over all frames (peak RSS: see the size table; here the pipelines "
                "share one process); distance error: |measured - true| distance to the canopy (cm, median / "
                "p95) on frames with a tree found; frames copied: frames whose pixel memory at "
                "the sink is not the one stereorectify wrote (0 = no element copied a frame)."
                "\n\n",
                o.runs, o.frames, o.warmup);
    std::printf("| size | pipeline | frames/s | vs disparity | CPU ms/frame | CPU %% | "
                "stereorectify ms | exgsegment ms | siftmatch ms | stereodepth ms | treemetrics "
                "ms | disparity ms | trees found | distance error cm | keypoints L+R | frames copied "
                "|\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  }
  std::vector<Variant> variants;
  for (const std::string &spec : o.pipelines)
    variants.push_back(variant_of(spec));
  for (const cv::Size &size : o.sizes) {
    std::fprintf(stderr, "bench-chain: rendering %d pairs at %s\n", o.distinct,
                 size_str(size).c_str());
    std::unique_ptr<Frames> f = preload(size, o.distinct, dir, o.scene);
    std::vector<Pooled> by = run_many(variants, *f, o);
    double ref = 0;
    for (size_t k = 0; k < variants.size(); k++)
      if (variants[k].kind == "disparity")
        ref = median(by[k].fps);
    for (size_t k = 0; k < variants.size(); k++) {
      Pooled &p = by[k];
      const std::string &kind = variants[k].kind;
      const double fps = median(p.fps);
      const bool measures = kind != "disparity";
      std::printf("| %s | %s | %.2f | %s | %.0f | %.0f | %s | %s | %s | %s | %s | %s | %s | "
                  "%s | %s | %s |\n",
                  size_str(size).c_str(), variants[k].label.c_str(), fps,
                  ref > 0 ? cv::format("%.2fx", fps / ref).c_str() : "-", median(p.cpu_ms),
                  median(p.cpu), ms_cell(p, "stereorectify").c_str(),
                  ms_cell(p, "exgsegment").c_str(), ms_cell(p, "siftmatch").c_str(),
                  ms_cell(p, "stereodepth").c_str(), ms_cell(p, "treemetrics").c_str(),
                  ms_cell(p, "disparity").c_str(),
                  measures ? cv::format("%d/%d", p.trees, p.frames).c_str() : "-",
                  measures ? err_cell(p).c_str() : "-",
                  measures && kind != "dense" ? cv::format("%.0f", median(p.keypoints)).c_str()
                                              : "-",
                  measures ? std::to_string(p.copies).c_str() : "-");
      std::fflush(stdout);
    }
  }
}

// --plugin-path's child: one run of each variant on the parent's frames, its figures as lines on
// stdout (P plugin file; S k: variant k unsupported; R k fps cpu% cpu-ms rss frames trees counted
// copies; M k element ms,...; D k distance errors; K k keypoints).
void child_runs(const Options &o)
{
  std::unique_ptr<Frames> f = load_frames(o.frames_file);
  GstPlugin *plugin = gst_registry_find_plugin(gst_registry_get(), "treestereo");
  std::string meta = "?"; // the meta library this process loaded
  {
    std::ifstream maps("/proc/self/maps");
    std::string line;
    while (std::getline(maps, line))
      if (line.find("libgsttreestereo-1.0.so") != std::string::npos) {
        meta = line.substr(line.find('/'));
        break;
      }
  }
  std::printf("P %s, meta %s\n", plugin ? gst_plugin_get_filename(plugin) : "?", meta.c_str());
  if (plugin)
    gst_object_unref(plugin);
  std::vector<Variant> variants;
  for (const std::string &spec : o.pipelines)
    variants.push_back(variant_of(spec));
  for (const Variant &v : variants)
    if (v.kind == "disparity" && f->rectified[0].empty())
      add_rectified(*f);
  auto list = [](const auto &values) {
    std::string t;
    for (const auto &x : values)
      t += (t.empty() ? "" : ",") + cv::format("%.4f", double(x));
    return t;
  };
  for (size_t k = 0; k < variants.size(); k++) {
    if (!plugin_supports(variants[k])) {
      std::printf("S %zu\n", k);
      continue;
    }
    const RunResult r =
        run_chain(chain_of(variants[k].kind, *f, with_options(variants[k].x, o)), *f, o.frames,
                  o.warmup);
    std::printf("R %zu %.6f %.6f %.6f %.3f %d %d %d %d\n", k, r.fps, r.cpu_pct,
                r.cpu_ms_per_frame, r.peak_rss_mb, r.frames, r.trees, r.counted, r.copies);
    for (const auto &[el, ms] : r.ms)
      std::printf("M %zu %s %s\n", k, el.c_str(), list(ms).c_str());
    std::printf("D %zu %s\n", k, list(r.distance_err_cm).c_str());
    std::printf("K %zu %s\n", k, list(r.keypoints).c_str());
  }
  std::fflush(stdout);
}

std::vector<double> parse_list(const std::string &s)
{
  std::vector<double> v;
  for (const std::string &x : parse_words(s))
    if (!x.empty())
      v.push_back(std::stod(x));
  return v;
}

// --plugin-path: every plugin build on the same frames, one child process per plugin and run,
// interleaved; one table.
void compare_plugins(const Options &o, const std::string &dir)
{
  struct Plugin {
    std::string label, dir, loaded;
  };
  std::vector<Plugin> plugins;
  for (const std::string &spec : o.plugin_paths) {
    const size_t eq = spec.find('=');
    Plugin p;
    p.dir = eq == std::string::npos ? spec : spec.substr(eq + 1);
    p.label = eq == std::string::npos ? spec : spec.substr(0, eq);
    plugins.push_back(p);
  }
  std::vector<Variant> variants;
  for (const std::string &spec : o.pipelines)
    variants.push_back(variant_of(spec));
  gchar *self = g_file_read_link("/proc/self/exe", nullptr);
  if (!self)
    throw std::runtime_error("bench-chain: cannot find its own executable");
  const std::string exe = self;
  g_free(self);
  if (o.header) {
    std::printf("### Plugin builds side by side (%s scene)\n\n", scene_kind_name(o.scene));
    std::printf("The same preloaded frames (rendered once, read from one file) through each "
                "plugin build, one process per build and run, interleaved (");
    for (const Plugin &p : plugins)
      std::printf("%s ", p.label.c_str());
    std::printf("...) %d times; frames/s: median of the %d runs of %d frames (the first %d of "
                "each left out), each run's in order; vs: against the first build's same "
                "pipeline; exgsegment %s; element ms: median / p95 over all frames.\n\n",
                o.runs, o.runs, o.frames, o.warmup,
                o.exg_extra.empty() ? "defaults" : o.exg_extra.c_str());
    std::printf("| size | build | pipeline | frames/s | runs | vs %s | CPU ms/frame | CPU %% | "
                "exgsegment ms | siftmatch ms | stereodepth ms | treemetrics ms | trees found | "
                "distance error cm | keypoints L+R |\n",
                plugins[0].label.c_str());
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  }
  const size_t np = plugins.size(), nv = variants.size();
  for (const cv::Size &size : o.sizes) {
    std::fprintf(stderr, "bench-chain: rendering %d pairs at %s (%s)\n", o.distinct,
                 size_str(size).c_str(), scene_kind_name(o.scene));
    std::unique_ptr<Frames> f = preload(size, o.distinct, dir, o.scene);
    const std::string path = dir + "/frames-" + size_str(size) + ".bin";
    save_frames(*f, path);
    std::vector<std::vector<Pooled>> by(np, std::vector<Pooled>(nv));
    std::vector<std::vector<char>> skipped(np, std::vector<char>(nv, 0));
    for (int r = 0; r < o.runs; r++)
      for (size_t i = 0; i < np; i++) {
        const std::string frames = std::to_string(o.frames), warmup = std::to_string(o.warmup);
        std::vector<const char *> argv = {exe.c_str(),         "--only",
                                          "throughput",        "--frames-file",
                                          path.c_str(),        "--pipelines",
                                          o.pipelines_arg.c_str(), "--frames",
                                          frames.c_str(),      "--warmup",
                                          warmup.c_str(),      "--exgsegment",
                                          o.exg_extra.c_str(), nullptr};
        gchar **env = g_get_environ();
        env = g_environ_setenv(env, "GST_PLUGIN_PATH_1_0", plugins[i].dir.c_str(), TRUE);
        env = g_environ_setenv(env, "GST_PLUGIN_PATH", plugins[i].dir.c_str(), TRUE);
        const std::string registry = dir + "/registry-" + std::to_string(i) + ".bin";
        env = g_environ_setenv(env, "GST_REGISTRY_1_0", registry.c_str(), TRUE);
        const std::string meta = plugins[i].dir + "/../meta";
        if (g_file_test(meta.c_str(), G_FILE_TEST_IS_DIR)) {
          const char *old = g_environ_getenv(env, "LD_LIBRARY_PATH");
          const std::string ld = meta + (old && *old ? ":" + std::string(old) : "");
          env = g_environ_setenv(env, "LD_LIBRARY_PATH", ld.c_str(), TRUE);
        }
        std::fprintf(stderr, "  run %d, %s:\n", r + 1, plugins[i].label.c_str());
        gchar *out = nullptr;
        gint status = 0;
        GError *err = nullptr;
        const gboolean spawned =
            g_spawn_sync(nullptr, const_cast<gchar **>(argv.data()), env, G_SPAWN_DEFAULT,
                         nullptr, nullptr, &out, nullptr, &status, &err);
        g_strfreev(env);
        if (!spawned || !g_spawn_check_wait_status(status, &err)) {
          const std::string why = err ? err->message : "?";
          g_clear_error(&err);
          g_free(out);
          throw std::runtime_error("bench-chain: " + plugins[i].label + ": " + why);
        }
        std::stringstream lines(out);
        g_free(out);
        std::string line;
        std::vector<RunResult> res(nv);
        std::vector<char> got(nv, 0);
        while (std::getline(lines, line)) {
          std::stringstream ls(line);
          std::string tag, rest;
          size_t k = 0;
          ls >> tag;
          if (tag == "P") {
            std::getline(ls >> std::ws, plugins[i].loaded);
            continue;
          }
          if (!(ls >> k) || k >= nv)
            continue;
          RunResult &x = res[k];
          if (tag == "S") {
            skipped[i][k] = 1;
          } else if (tag == "R") {
            ls >> x.fps >> x.cpu_pct >> x.cpu_ms_per_frame >> x.peak_rss_mb >> x.frames >>
                x.trees >> x.counted >> x.copies;
            got[k] = 1;
          } else if (tag == "M") {
            std::string el;
            ls >> el >> rest;
            x.ms[el] = parse_list(rest);
          } else if (tag == "D") {
            ls >> rest;
            x.distance_err_cm = parse_list(rest);
          } else if (tag == "K") {
            ls >> rest;
            for (double v : parse_list(rest))
              x.keypoints.push_back(unsigned(v));
          }
        }
        for (size_t k = 0; k < nv; k++)
          if (got[k]) {
            by[i][k].add(res[k]);
            std::fprintf(stderr, "  %s %s %s run %d: %.2f frames/s, CPU %.0f ms/frame\n",
                         plugins[i].label.c_str(), variants[k].label.c_str(),
                         size_str(size).c_str(), r + 1, res[k].fps, res[k].cpu_ms_per_frame);
          } else if (!skipped[i][k]) {
            throw std::runtime_error("bench-chain: " + plugins[i].label + " gave no figures for " +
                                     variants[k].label);
          }
      }
    g_unlink(path.c_str());
    for (size_t i = 0; i < np; i++)
      for (size_t k = 0; k < nv; k++) {
        Pooled &p = by[i][k];
        if (skipped[i][k] || p.fps.empty()) {
          std::printf("| %s | %s | %s | - (no such property) | | | | | | | | | | | |\n",
                      size_str(size).c_str(), plugins[i].label.c_str(),
                      variants[k].label.c_str());
          continue;
        }
        std::string runs;
        for (double x : p.fps)
          runs += (runs.empty() ? "" : " ") + cv::format("%.2f", x);
        const double fps = median(p.fps);
        double ref = 0;
        if (!by[0][k].fps.empty())
          ref = median(by[0][k].fps);
        else
          for (size_t j = 0; j < nv && ref == 0; j++)
            if (variants[j].base() == variants[k].base() && !by[0][j].fps.empty())
              ref = median(by[0][j].fps);
        const std::string &kind = variants[k].kind;
        const bool measures = kind != "disparity";
        std::printf("| %s | %s | %s | %.2f | %s | %s | %.0f | %.0f | %s | %s | %s | %s | %s | %s "
                    "| %s |\n",
                    size_str(size).c_str(), plugins[i].label.c_str(), variants[k].label.c_str(),
                    fps, runs.c_str(),
                    ref > 0 ? cv::format("%.3f (%+.1f %%)", fps / ref, 100 * (fps / ref - 1)).c_str()
                            : "-",
                    median(p.cpu_ms), median(p.cpu), ms_cell(p, "exgsegment").c_str(),
                    ms_cell(p, "siftmatch").c_str(), ms_cell(p, "stereodepth").c_str(),
                    ms_cell(p, "treemetrics").c_str(),
                    measures ? cv::format("%d/%d", p.trees, p.frames).c_str() : "-",
                    measures ? err_cell(p).c_str() : "-",
                    measures && kind != "dense" && !p.keypoints.empty()
                        ? cv::format("%.0f", median(p.keypoints)).c_str()
                        : "-");
      }
    std::fflush(stdout);
  }
  std::printf("\nBuilds: ");
  for (size_t i = 0; i < np; i++)
    std::printf("%s%s = %s", i ? "; " : "", plugins[i].label.c_str(), plugins[i].loaded.c_str());
  std::printf(".\n");
  for (size_t i = 0; i < np; i++)
    g_unlink((dir + "/registry-" + std::to_string(i) + ".bin").c_str());
}

void keypoint_growth(const Options &o, const std::string &dir)
{
  std::printf("\n### Cost against the number of keypoints (%s, full chain, sequential)\n\n",
              size_str(o.keypoint_size).c_str());
  std::printf("Swept with siftmatch's detection scale and contrast-threshold (fewer keypoints as "
              "it rises); %d runs of %d frames each, interleaved.\n\n", o.runs, o.frames);
  std::printf("| siftmatch settings | keypoints L+R (median) | siftmatch ms (median / p95) | "
              "CPU ms/frame | frames/s | distance error cm (median / p95) |\n"
              "|---|---|---|---|---|---|\n");
  std::unique_ptr<Frames> f = preload(o.keypoint_size, o.distinct, dir, o.scene);
  const std::vector<std::string> settings = {
      "scale=0.25", "contrast-threshold=0.08", "contrast-threshold=0.04",
      "contrast-threshold=0.02", "contrast-threshold=0.01", "scale=1"};
  std::vector<Variant> variants;
  for (const std::string &x : settings)
    variants.push_back(Variant{x, "full", Extras{x, "", ""}});
  std::vector<Pooled> by = run_many(variants, *f, o);
  for (size_t k = 0; k < variants.size(); k++) {
    Pooled &p = by[k];
    const double fps = median(p.fps);
    std::printf("| %s | %.0f | %s | %.0f | %.2f | %s |\n", settings[k].c_str(),
                median(p.keypoints), ms_cell(p, "siftmatch").c_str(), median(p.cpu_ms), fps,
                err_cell(p).c_str());
  }
}

void size_growth(const Options &o, const std::string &dir)
{
  std::printf("\n### Cost against image size (full chain, sequential, default settings)\n\n");
  std::printf("One process runs only this chain, one size after the other; peak RSS is the "
              "largest of the %d runs at that size and includes the preloaded frames (%d raw "
              "stereo pairs, last column).\n\n", o.runs, o.distinct);
  std::printf("| size | megapixels | keypoints L+R | stereorectify ms | exgsegment ms | "
              "siftmatch ms | stereodepth ms | treemetrics ms | CPU ms/frame | frames/s | peak "
              "RSS MB | preloaded MB |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const cv::Size &size : o.growth_sizes) {
    std::unique_ptr<Frames> f = preload(size, o.distinct, dir, o.scene);
    Pooled p = run_many({Variant{"full", "full", Extras{}}}, *f, o)[0];
    const double fps = median(p.fps);
    std::printf("| %s | %.2f | %.0f | %s | %s | %s | %s | %s | %.0f | %.2f | %.0f | %.0f |\n",
                size_str(size).c_str(), size.area() / 1e6, median(p.keypoints),
                ms_cell(p, "stereorectify").c_str(), ms_cell(p, "exgsegment").c_str(),
                ms_cell(p, "siftmatch").c_str(), ms_cell(p, "stereodepth").c_str(),
                ms_cell(p, "treemetrics").c_str(), median(p.cpu_ms), fps,
                *std::max_element(p.rss.begin(), p.rss.end()), f->megabytes());
    std::fflush(stdout);
  }
}

void memory_run(const Options &o, const std::string &dir)
{
  const cv::Size size{640, 480};
  std::unique_ptr<Frames> f = preload(size, o.distinct, dir, o.scene);
  RunResult r = run_chain(chain_of("full", *f, with_options(Extras{}, o)), *f, o.memory_frames,
                          o.warmup);
  std::printf("\n### Memory over a long run (%s, full chain, %d frames)\n\n",
              size_str(size).c_str(), o.memory_frames);
  if (r.rss_kb.size() < 4) {
    std::printf("Too few samples (run at least 400 frames).\n");
    return;
  }
  std::printf("VmRSS (MB) at the sink at frames 50, 150, 250, ...:");
  std::vector<double> x, y;
  for (size_t i = 0; i < r.rss_kb.size(); i++) {
    std::printf(" %.0f", r.rss_kb[i] / 1024.0);
    x.push_back(double(i) * 100 + 50);
    y.push_back(r.rss_kb[i] / 1024.0);
  }
  // Least-squares slope over the second half: a leak grows steadily, allocator noise does not.
  const size_t h = x.size() / 2;
  double mx = 0, my = 0, sxy = 0, sxx = 0;
  for (size_t i = h; i < x.size(); i++) {
    mx += x[i];
    my += y[i];
  }
  mx /= double(x.size() - h);
  my /= double(x.size() - h);
  for (size_t i = h; i < x.size(); i++) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
  }
  std::vector<double> first_half(y.begin(), y.begin() + long(h)), second_half(y.begin() + long(h),
                                                                                y.end());
  std::printf(".\n\nMedian RSS of the first half %.1f MB, of the second half %.1f MB; slope over "
              "the second half %+.2f MB per 1000 frames; at the last frame %.1f MB; peak RSS %.0f "
              "MB; %.1f frames/s; trees found in %d/%d frames.\n",
              median(first_half), median(second_half), 1000.0 * sxy / sxx,
              r.last_rss_kb / 1024.0, r.peak_rss_mb, r.fps, r.trees, r.frames);
}

} // namespace

int main(int argc, char **argv)
{
  if (!g_getenv("GST_PLUGIN_PATH_1_0") && !g_getenv("GST_PLUGIN_PATH"))
    g_setenv("GST_PLUGIN_PATH_1_0", TREESTEREO_PLUGIN_BUILD_DIR, TRUE);
  gst_init(&argc, &argv);
  Options o;
  try {
    for (int i = 1; i + 1 < argc; i += 2) {
      const std::string a = argv[i], v = argv[i + 1];
      if (a == "--sizes")
        o.sizes = parse_sizes(v);
      else if (a == "--growth-sizes")
        o.growth_sizes = parse_sizes(v);
      else if (a == "--keypoints")
        o.keypoint_size = parse_sizes(v).at(0);
      else if (a == "--pipelines")
        o.pipelines = parse_words(o.pipelines_arg = v);
      else if (a == "--frames")
        o.frames = std::stoi(v);
      else if (a == "--runs")
        o.runs = std::max(1, std::stoi(v));
      else if (a == "--distinct")
        o.distinct = std::max(1, std::stoi(v));
      else if (a == "--warmup")
        o.warmup = std::max(1, std::stoi(v));
      else if (a == "--memory")
        o.memory_frames = std::stoi(v);
      else if (a == "--header")
        o.header = v != "0";
      else if (a == "--only")
        o.only = v;
      else if (a == "--scene")
        o.scene = scene_kind_from_name(v);
      else if (a == "--exgsegment") {
        o.exg_extra = v;
        o.exg_extra_set = true;
      } else if (a == "--plugin-path")
        o.plugin_paths = parse_words(v);
      else if (a == "--frames-file") // a child of --plugin-path
        o.frames_file = v;
      else
        throw std::runtime_error("bench-chain: unknown option " + a);
    }
    if (!o.exg_extra_set && o.scene != SceneKind::Lab)
      o.exg_extra = "keep=all"; // every tree of the row to the canopy step, not the largest
    std::replace(o.exg_extra.begin(), o.exg_extra.end(), '+', ' ');
    if (!o.frames_file.empty()) {
      child_runs(o);
      return 0;
    }
    if (!o.plugin_paths.empty() && o.only != "throughput")
      throw std::runtime_error("bench-chain: --plugin-path needs --only throughput");
    gchar *dir = g_dir_make_tmp("bench-chain-XXXXXX", nullptr);
    const std::string d = dir;
    if (!o.plugin_paths.empty())
      compare_plugins(o, d);
    else if (o.only.empty() || o.only == "throughput")
      throughput(o, d);
    if (o.only.empty() || o.only == "keypoints")
      keypoint_growth(o, d);
    if (o.only.empty() || o.only == "sizes")
      size_growth(o, d);
    if ((o.only.empty() || o.only == "memory") && o.memory_frames > 0)
      memory_run(o, d);
    g_rmdir(dir);
    g_free(dir);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}
