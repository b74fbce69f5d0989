// treestereo-measure: the measuring job. Builds the whole pipeline
//   sources -> stereorectify -> exgsegment -> siftmatch -> stereodepth -> treemetrics
//   [-> treeoverlay -> x264enc -> mp4mux (fragmented) -> file]
// from its inputs (the synthetic orchard, image sequences, video files or two Aravis cameras),
// and writes one JSON object (and/or CSV row) per stereo frame, a one-line summary per frame
// on the terminal, and optionally an annotated video. Ctrl-C ends the stream cleanly (EOS): the
// recording gets its duration and seek index. The recording is a fragmented MP4 written
// synchronously, a fragment a second, so after a SIGKILL or a power cut it still plays up to
// its last second or so; JSON and CSV lines go out whole, one write each (docs/reliability.md).
// An output that cannot be written (missing folder, disk full) is an error naming the file:
// at the start before the pipeline runs, later it stops the measuring with exit status 1.
#include "treestereo/calibration_file.hpp"
#include "treestereo/json.hpp"
#include "treestereo/record_json.hpp"
#include "treestereo/rowmap.hpp"
#include "treestereo/rowtrack.hpp"
#include "treestereo/scene.hpp"

#include <gst/gst.h>
#include <gst/treestereo/treestereo-meta.h>
#include "band-meta.hpp"
#include <glib-unix.h>
#include <glib/gstdio.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <stdexcept>
#include <sstream>
#include <string>
#include <sys/stat.h>
#include <unistd.h>

using namespace treestereo;

namespace {

struct Options {
  // inputs
  gboolean synthetic = FALSE;
  gchar *left = nullptr, *right = nullptr;
  gchar *camera_left = nullptr, *camera_right = nullptr;
  gchar *camera_caps = nullptr;
  gchar *calibration = nullptr;
  gint frames = -1;
  gchar *size = nullptr;
  gdouble fps = 0;
  gdouble latency_ms = 100, max_skew_ms = 20;
  gint pair_queue = 8;
  gint camera_timeout_ms = 2000; // a camera is lost after this long without a frame
  gint reconnect_ms = 500;       // first wait before reopening it (0: a lost camera ends the run)
  gint64 seed = 1;
  gdouble distance = 2.0, speed = 0.5, light = 1.0;
  gchar *scene = nullptr; // synthetic: lab, orchard (default) or hedgerow
  // analysis
  gchar *index = nullptr, *method = nullptr, *mode = nullptr;
  gchar *canopy = nullptr; // stereodepth canopy: tree, row or off
  gdouble scale = -1, smoothing = 0, min_depth = 500, max_depth = 10000;
  gint bands = 4;
  gboolean no_rectify = FALSE;
  // outputs
  gchar *json = nullptr, *csv = nullptr, *record = nullptr;
  gchar *trees = nullptr, *row_map = nullptr; // tree records (JSON lines), row map (CSV + PNG)
  gchar *sections = nullptr; // nozzle-section commands (JSON lines)
  gdouble rig_speed = 0;                       // treemetrics speed: the rig's own, m/s (0: stereo)
  gboolean points = FALSE, matches = FALSE, quiet = FALSE;
  gint bitrate = 4000;

  Options() = default;
  Options(const Options &) = delete;
  Options &operator=(const Options &) = delete;
  ~Options()
  {
    // GOption fills these with g_strdup'ed strings
    for (gchar *s : {left, right, camera_left, camera_right, camera_caps, calibration, size,
                     scene, index, method, mode, canopy, json, csv, record, trees, row_map, sections})
      g_free(s);
  }
};

const gchar *kSummary =
    "Measures fruit trees with two cameras: distance to the canopy, its height, width,\n"
    "thickness, area, perimeter and a per-height-band profile, one result per stereo frame.\n"
    "\n"
    "Inputs (one of):\n"
    "  --synthetic (the default with no inputs): the built-in orchard, a sprayer driving by\n"
    "    (--scene orchard|hedgerow|lab)\n"
    "  --left PATTERN --right PATTERN: image sequences (left_%04d.jpg) or video files\n"
    "  --camera-left NAME --camera-right NAME: two Aravis cameras (name, serial or IP)\n"
    "Files and cameras need --calibration (OpenCV YAML/XML, or 'left.yaml;right.yaml' ROS).\n"
    "A camera that drops out is reopened (--camera-timeout, --reconnect); meanwhile the JSON\n"
    "output gets {\"status\":\"camera-lost\",...} lines, one per second.\n"
    "\n"
    "Exit status: 0 when the stream ended normally (or by Ctrl-C), 1 on a pipeline error (also\n"
    "a lost camera with --reconnect 0) or an output that cannot be written (disk full), 2 on a\n"
    "usage error.";

// A usage error unwinds to main (exit status 2), so that what the run made so far, such as the
// synthetic rig's temporary calibration, is removed on the way.
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

[[noreturn]] void usage_error(const std::string &msg)
{
  throw UsageError(msg);
}

bool parse_size(const char *s, int &w, int &h)
{
  return s && std::sscanf(s, "%dx%d", &w, &h) == 2 && w > 0 && h > 0;
}

// gst-launch quoting for a property value.
std::string quoted(const std::string &v)
{
  std::string o = "\"";
  for (char c : v) {
    if (c == '"' || c == '\\')
      o += '\\';
    o += c;
  }
  return o + "\"";
}

bool has_suffix(const std::string &s, const char *suf)
{
  return g_str_has_suffix(s.c_str(), suf);
}

bool is_pattern(const std::string &s)
{
  return s.find('%') != std::string::npos;
}

// Number of files of a printf pattern from index 0.
int count_sequence(const std::string &pattern)
{
  int n = 0;
  for (;; n++) {
    gchar *name = g_strdup_printf(pattern.c_str(), n);
    const bool exists = g_file_test(name, G_FILE_TEST_EXISTS);
    g_free(name);
    if (!exists)
      return n;
  }
}

std::string file_source(const std::string &path, double fps, int frames)
{
  std::ostringstream s;
  if (is_pattern(path)) {
    const char *caps = (has_suffix(path, ".png") || has_suffix(path, ".PNG")) ? "image/png"
                                                                               : "image/jpeg";
    const int rate = fps > 0 ? int(fps + 0.5) : 7;
    s << "multifilesrc location=" << quoted(path) << " index=0"
      << (frames > 0 ? " stop-index=" + std::to_string(frames - 1) : std::string())
      << " caps=\"" << caps << ",framerate=(fraction)" << rate << "/1\" ! decodebin";
  } else {
    s << "filesrc location=" << quoted(path) << " ! decodebin";
  }
  s << " ! videoconvert ! video/x-raw,format=RGB";
  return s.str();
}

// treecamerasrc: aravissrc do-timestamp=true ! caps ! leaky queue ! [bayer2rgb] ! videoconvert,
// reopened when the camera drops out (docs/aravis.md). No num-buffers: --frames counts measured
// pairs, not camera frames. The two cameras start at different times and their first unpaired
// frames are dropped, so the tool itself ends the stream after the N-th pair (on_result).
std::string camera_source(const std::string &name, const char *side, const Options &o)
{
  std::ostringstream s;
  const std::string caps = o.camera_caps ? o.camera_caps : "video/x-raw,format=RGB";
  s << "treecamerasrc name=camera-" << side << " camera=" << quoted(name)
    << " caps=" << quoted(caps) << " timeout=" << o.camera_timeout_ms
    << " reconnect-interval=" << o.reconnect_ms;
  return s.str();
}

// An output of lines (JSON lines, CSV): a file, or stdout for '-'. Each line goes out whole in
// one write(2), so a SIGKILL cuts no line; when a write fails (disk full, I/O error) the file is
// cut back to its last whole line.
class LineOutput {
public:
  LineOutput() = default;
  LineOutput(const LineOutput &) = delete;
  LineOutput &operator=(const LineOutput &) = delete;
  ~LineOutput()
  {
    if (fd_ >= 0)
      close(fd_);
  }

  // Creates (truncates) the file, or takes stdout for "-"; throws naming the file and why.
  void open(const char *path)
  {
    path_ = path;
    if (path_ == "-")
      return;
    fd_ = ::open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd_ < 0)
      throw std::runtime_error("cannot write " + path_ + ": " + g_strerror(errno));
  }
  explicit operator bool() const { return !path_.empty(); }
  bool is_stdout() const { return path_ == "-"; }
  const std::string &path() const { return path_; }

  // Writes a line (with its '\n'). False with errno set when it could not; the file then ends
  // with the last whole line.
  bool put(const std::string &line)
  {
    if (fd_ < 0) { // stdout: through stdio, in order with the summary lines
      if (std::fwrite(line.data(), 1, line.size(), stdout) == line.size() &&
          std::fflush(stdout) == 0)
        return true;
      if (errno == 0)
        errno = EIO;
      return false;
    }
    std::size_t done = 0;
    while (done < line.size()) {
      const ssize_t n = ::write(fd_, line.data() + done, line.size() - done);
      if (n < 0 && errno == EINTR)
        continue;
      if (n <= 0) {
        const int e = n < 0 ? errno : ENOSPC;
        if (done > 0 && ftruncate(fd_, whole_) == 0)
          lseek(fd_, whole_, SEEK_SET);
        errno = e;
        return false;
      }
      done += std::size_t(n);
    }
    whole_ += off_t(line.size());
    return true;
  }

private:
  std::string path_; // empty: no such output
  int fd_ = -1;
  off_t whole_ = 0; // bytes of whole lines in the file
};

// Fails (throws naming the file and why) unless PATH can be written, without changing it: the
// outputs an element writes later (--record, --row-map) are checked before the pipeline starts.
void check_writable(const std::string &path)
{
  int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
  bool created = false;
  if (fd < 0 && errno == ENOENT) {
    fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    created = fd >= 0;
  }
  if (fd < 0)
    throw std::runtime_error("cannot write " + path + ": " + g_strerror(errno));
  close(fd);
  if (created)
    g_unlink(path.c_str());
}

struct Job {
  Job() = default;
  Job(const Job &) = delete;
  Job &operator=(const Job &) = delete;
  ~Job()
  {
    if (!temp_calibration.empty()) {
      g_unlink(temp_calibration.c_str());
      gchar *dir = g_path_get_dirname(temp_calibration.c_str());
      g_rmdir(dir);
      g_free(dir);
    }
  }

  Options o;
  std::string calibration; // path used by stereorectify
  std::string temp_calibration;
  std::string scene = "orchard"; // synthetic: treetestsrc's scene
  int total_frames = -1; // when known
  GstElement *pipeline = nullptr;
  GMainLoop *loop = nullptr;
  LineOutput json; // written from the streaming thread (on_result)
  LineOutput trees;
  guint64 n_trees = 0;
  LineOutput sections; // spraycontrol's commands, one JSON line each
  guint64 n_commands = 0;
  LineOutput csv; // written from the streaming thread (on_result)
  guint64 frames = 0, present = 0;
  guint64 stop_after = 0; // live cameras: pairs to measure before ending the stream (0: all)
  bool error = false, interrupted = false;
  std::atomic<bool> output_failed{false}; // an output could not be written: the job stops
  guint output_timeout = 0;               // ends the main loop should the EOS not get through
  std::chrono::steady_clock::time_point start;
  // live cameras: which one is missing (treecamerasrc's treestereo-camera messages)
  bool camera_lost[2] = {false, false};
  guint64 n_camera_lost = 0, n_camera_back = 0; // JSON status lines written
  guint lost_timer = 0;
};

void write_metrics_json(JsonWriter &w, const GstTreeStereoMetrics &m)
{
  const gchar *mode =
      gst_tree_stereo_canopy_mode_to_string(GstTreeStereoCanopyMode(m.canopy_mode));
  w.field("tree_present", bool(m.tree_present)).field("canopy_mode", mode ? mode : "unknown");
  if (!m.tree_present)
    return;
  w.field("distance_m", m.distance_m)
      .field("height_m", m.height_m)
      .field("width_m", m.width_m)
      .field("thickness_m", m.thickness_m)
      .field("area_m2", m.area_m2)
      .field("perimeter_m", m.perimeter_m)
      .field("complexity", m.complexity)
      .key("centroid_m")
      .array({m.centroid_m[0], m.centroid_m[1], m.centroid_m[2]})
      .key("clipped")
      .begin_array();
  if (m.clipped & GST_TREE_STEREO_CLIPPED_TOP)
    w.value("top");
  if (m.clipped & GST_TREE_STEREO_CLIPPED_BOTTOM)
    w.value("bottom");
  if (m.clipped & GST_TREE_STEREO_CLIPPED_LEFT)
    w.value("left");
  if (m.clipped & GST_TREE_STEREO_CLIPPED_RIGHT)
    w.value("right");
  w.end_array().key("bands").begin_array();
  for (guint i = 0; i < m.n_bands; i++) {
    write_band(w, band_from_meta(m.bands[i]));
  }
  w.end_array()
      .field("n_points", m.n_points)
      .field("n_matches", m.n_matches)
      .field("confidence", m.confidence);
}

bool write_json(Job &job, GstBuffer *buf, const GstTreeStereoMetricsMeta *mm)
{
  std::ostringstream line;
  JsonWriter w(line);
  w.begin_object().field("frame", static_cast<unsigned long long>(job.frames));
  if (GST_BUFFER_PTS_IS_VALID(buf))
    w.field("pts_ns", static_cast<unsigned long long>(GST_BUFFER_PTS(buf)));
  else
    w.key("pts_ns").null();
  if (mm) {
    // The rig's travel along the row (DESIGN.md "In an orchard"): per frame, not per canopy.
    const gchar *src = gst_tree_stereo_travel_source_to_string(
        GstTreeStereoTravelSource(mm->metrics.travel_source));
    w.field("travel_m", mm->metrics.travel_m)
        .field("position_m", mm->metrics.position_m)
        .field("travel_source", src ? src : "none");
    write_metrics_json(w, mm->metrics);
    if (job.o.smoothing > 0 && mm->smoothed.tree_present) {
      w.key("smoothed").begin_object();
      write_metrics_json(w, mm->smoothed);
      w.end_object();
    }
  } else {
    w.field("tree_present", false);
  }
  if (job.o.points) {
    w.key("points_mm").begin_array();
    if (const GstTreeStereoPointsMeta *pm = gst_buffer_get_tree_stereo_points_meta(buf))
      for (guint i = 0; i < pm->n_points; i++)
        if (pm->points[i].valid)
          w.array({pm->points[i].x, pm->points[i].y, pm->points[i].z});
    w.end_array();
  }
  if (job.o.matches) {
    w.key("matches").begin_array();
    if (const GstTreeStereoMatchesMeta *ma = gst_buffer_get_tree_stereo_matches_meta(buf))
      for (guint i = 0; i < ma->n_matches; i++)
        w.array({ma->matches[i].xl, ma->matches[i].yl, ma->matches[i].xr, ma->matches[i].yr});
    w.end_array();
  }
  if (const GstTreeStereoTruthMeta *t = gst_buffer_get_tree_stereo_truth_meta(buf)) {
    w.key("truth")
        .begin_object()
        .field("distance_m", t->truth.distance_m)
        .field("height_m", t->truth.height_m)
        .field("width_m", t->truth.width_m)
        .field("thickness_m", t->truth.thickness_m)
        .end_object();
  }
  w.end_object();
  line << "\n";
  return job.json.put(line.str());
}

const char *kCsvHeader = "frame,pts_ns,tree_present,distance_m,height_m,width_m,thickness_m,"
                         "area_m2,perimeter_m,complexity,centroid_x_m,centroid_y_m,centroid_z_m,"
                         "clipped,n_points,n_matches,confidence";

bool write_csv(Job &job, GstBuffer *buf, const GstTreeStereoMetricsMeta *mm)
{
  char line[512];
  const GstClockTime pts = GST_BUFFER_PTS(buf);
  if (!mm || !mm->metrics.tree_present) {
    std::snprintf(line, sizeof line, "%" G_GUINT64_FORMAT ",%s,false,,,,,,,,,,,,,,\n", job.frames,
                  GST_CLOCK_TIME_IS_VALID(pts) ? std::to_string(pts).c_str() : "");
  } else {
    const GstTreeStereoMetrics &m = mm->metrics;
    std::snprintf(line, sizeof line,
                  "%" G_GUINT64_FORMAT ",%s,true,%.5f,%.5f,%.5f,%.5f,%.6f,%.5f,%.4f,%.5f,%.5f,"
                  "%.5f,%u,%u,%u,%.4f\n",
                  job.frames, GST_CLOCK_TIME_IS_VALID(pts) ? std::to_string(pts).c_str() : "",
                  m.distance_m, m.height_m, m.width_m, m.thickness_m, m.area_m2, m.perimeter_m,
                  m.complexity, m.centroid_m[0], m.centroid_m[1], m.centroid_m[2], m.clipped,
                  m.n_points, m.n_matches, m.confidence);
  }
  return job.csv.put(line);
}

void print_progress(Job &job, const GstTreeStereoMetricsMeta *mm)
{
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - job.start).count();
  const bool tty = isatty(STDERR_FILENO);
  if (job.total_frames > 0 && tty) {
    const int width = 30;
    const double frac = std::min(1.0, double(job.frames + 1) / job.total_frames);
    const int fill = int(frac * width);
    const double done = double(job.frames + 1);
    const double eta = elapsed / done * std::max(0.0, job.total_frames - done);
    std::fprintf(stderr, "\r[%.*s%*s] %" G_GUINT64_FORMAT "/%d  ETA %.0f s ", fill,
                 "##############################", width - fill, "", job.frames + 1,
                 job.total_frames, eta);
    std::fflush(stderr);
  }
  if (job.o.quiet || job.json.is_stdout())
    return;
  if (tty && job.total_frames > 0)
    std::fprintf(stderr, "\r%*s\r", 60, "");
  if (mm && mm->metrics.tree_present) {
    const GstTreeStereoMetrics &m = mm->metrics;
    std::printf("frame %4" G_GUINT64_FORMAT "  distance %.3f m  height %s%.3f m  width %s%.3f m  "
                "thickness %.3f m  area %.3f m2  points %u  confidence %.2f\n",
                job.frames, m.distance_m,
                (m.clipped & (GST_TREE_STEREO_CLIPPED_TOP | GST_TREE_STEREO_CLIPPED_BOTTOM))
                    ? ">="
                    : "",
                m.height_m,
                (m.clipped & (GST_TREE_STEREO_CLIPPED_LEFT | GST_TREE_STEREO_CLIPPED_RIGHT))
                    ? ">="
                    : "",
                m.width_m, m.thickness_m, m.area_m2, m.n_points, m.confidence);
  } else {
    std::printf("frame %4" G_GUINT64_FORMAT "  no tree\n", job.frames);
  }
  std::fflush(stdout);
}

gboolean send_eos(gpointer data)
{
  Job &job = *static_cast<Job *>(data);
  gst_element_send_event(job.pipeline, gst_event_new_eos());
  return G_SOURCE_REMOVE;
}

gboolean quit_after_output_error(gpointer data)
{
  Job &job = *static_cast<Job *>(data);
  job.output_timeout = 0;
  std::fprintf(stderr, "treestereo-measure: the stream did not end within 10 s, stopping\n");
  g_main_loop_quit(job.loop);
  return G_SOURCE_REMOVE;
}

// After an output failed: EOS, so the other outputs and the recording end properly where the
// disk allows; the main loop ends within 10 s should the EOS not get through.
gboolean stop_after_output_error(gpointer data)
{
  Job &job = *static_cast<Job *>(data);
  gst_element_send_event(job.pipeline, gst_event_new_eos());
  job.output_timeout = g_timeout_add_seconds(10, quit_after_output_error, &job);
  return G_SOURCE_REMOVE;
}

// An output could not be written (disk full, I/O error): says which and why, writes nothing
// more and stops the measuring (exit status 1). Any thread.
void output_failed(Job &job, const LineOutput &out, int err)
{
  if (job.output_failed.exchange(true))
    return;
  std::fprintf(stderr, "\ntreestereo-measure: cannot write %s: %s\n",
               out.is_stdout() ? "stdout" : out.path().c_str(), g_strerror(err));
  g_idle_add(stop_after_output_error, &job);
}

GstPadProbeReturn on_result(GstPad *, GstPadProbeInfo *info, gpointer data)
{
  Job &job = *static_cast<Job *>(data);
  // pairs already on their way when the N-th came out are not measured results
  if (job.stop_after > 0 && job.frames >= job.stop_after)
    return GST_PAD_PROBE_DROP;
  // nor are those after an output failed: the outputs end at the same frame
  if (job.output_failed)
    return GST_PAD_PROBE_DROP;
  GstBuffer *buf = GST_PAD_PROBE_INFO_BUFFER(info);
  const GstTreeStereoMetricsMeta *mm = gst_buffer_get_tree_stereo_metrics_meta(buf);
  if (job.json && !write_json(job, buf, mm)) {
    output_failed(job, job.json, errno);
    return GST_PAD_PROBE_DROP;
  }
  if (job.csv && !write_csv(job, buf, mm)) {
    output_failed(job, job.csv, errno);
    return GST_PAD_PROBE_DROP;
  }
  print_progress(job, mm);
  job.frames++;
  if (mm && mm->metrics.tree_present)
    job.present++;
  // reached once: every later buffer is dropped above. This is the streaming thread; the EOS is
  // sent from the main loop.
  if (job.stop_after > 0 && job.frames == job.stop_after)
    g_idle_add(send_eos, &job);
  return GST_PAD_PROBE_OK;
}

// A tree record as lib has it (its JSON line has DESIGN.md's names), from the message.
TreeRecord record_of(const GstTreeStereoTreeRecord &r)
{
  TreeRecord t;
  t.id = int(r.id);
  t.mode = r.mode == GST_TREE_STEREO_CANOPY_ROW ? CanopyMode::Row : CanopyMode::Tree;
  t.complete = r.complete;
  t.start_seen = r.start_seen;
  t.end_seen = r.end_seen;
  t.position_m = r.position_m;
  t.start_m = r.start_m;
  t.end_m = r.end_m;
  t.has_height = r.has_height;
  t.height_m = r.height_m;
  t.has_width = r.has_width;
  t.width_m = r.width_m;
  t.has_depth = r.has_depth;
  t.distance_m = r.distance_m;
  t.thickness_m = r.thickness_m;
  t.confidence = r.confidence;
  for (guint i = 0; i < r.n_bands; i++) {
    t.bands.push_back(band_from_meta(r.bands[i]));
  }
  t.frames = int(r.frames);
  t.frames_seen = int(r.frames_seen);
  t.has_spacing = r.has_spacing;
  t.spacing_m = r.spacing_m;
  t.gap_m = r.gap_m;
  t.lost = r.lost;
  return t;
}

// spraycontrol's valve commands: one JSON line each (--sections), DESIGN.md's section command.
void on_section(Job &job, GstMessage *msg)
{
  const GstStructure *st = gst_message_get_structure(msg);
  if (!st || !gst_structure_has_name(st, GST_TREE_STEREO_MESSAGE_SECTION) || !job.sections ||
      job.output_failed)
    return;
  GstTreeStereoSectionCommand c;
  if (!gst_tree_stereo_section_message_parse(st, &c))
    return;
  job.n_commands++;
  std::ostringstream line;
  JsonWriter w(line);
  w.begin_object()
      .field("section", c.section)
      .field("on", bool(c.on))
      .field("rate", c.rate)
      .field("at_ns", static_cast<long long>(c.at_ns))
      .field("position_m", c.position_m);
  if (c.fallback)
    w.field("fallback", true); // the fail-safe's, after a gap in the frames
  w.end_object();
  line << "\n";
  if (!job.sections.put(line.str()))
    output_failed(job, job.sections, errno);
}

// treemetrics' tree records: one JSON line each (--trees) and a line of the summary.
void on_tree(Job &job, GstMessage *msg)
{
  const GstStructure *st = gst_message_get_structure(msg);
  if (!st || !gst_structure_has_name(st, GST_TREE_STEREO_MESSAGE_TREE))
    return;
  GstTreeStereoTreeRecord r = {};
  if (!gst_tree_stereo_tree_message_parse(st, &r, nullptr))
    return;
  job.n_trees++;
  if (job.trees && !job.output_failed && !job.trees.put(to_json(record_of(r)) + "\n"))
    output_failed(job, job.trees, errno);
  if (!job.o.quiet && !job.json.is_stdout() && !job.trees.is_stdout()) {
    const char *what = r.mode == GST_TREE_STEREO_CANOPY_ROW ? "canopy" : "tree";
    std::printf("%s %u at %.2f m along the row (%.2f-%.2f m)", what, r.id, r.position_m,
                r.start_m, r.end_m);
    if (r.has_height)
      std::printf("  height %.3f m", r.height_m);
    if (r.has_width)
      std::printf("  width %.3f m", r.width_m);
    if (r.has_depth)
      std::printf("  distance %.3f m", r.distance_m);
    std::printf("%s\n", r.complete ? "" : "  (never wholly in view)");
  }
  gst_tree_stereo_tree_record_clear(&r);
}

// The running time of the pipeline now (what a frame arriving now would be stamped).
GstClockTime running_time_now(GstElement *pipeline)
{
  GstClock *clock = gst_element_get_clock(pipeline);
  if (!clock)
    return GST_CLOCK_TIME_NONE;
  const GstClockTime now = gst_clock_get_time(clock);
  gst_object_unref(clock);
  const GstClockTime base = gst_element_get_base_time(pipeline);
  return now >= base ? now - base : 0;
}

const char *kSides[2] = {"left", "right"};

// One status line in the --json output: {"status":"camera-lost"|"camera-back","camera":"right",
// "pts_ns":...}; pts_ns is the running time, comparable with the pairs' pts_ns.
void write_camera_status(Job &job, int side, bool lost, GstClockTime running, double gap_s)
{
  if (lost)
    job.n_camera_lost++;
  else
    job.n_camera_back++;
  if (!job.json)
    return;
  std::ostringstream line;
  JsonWriter w(line);
  w.begin_object()
      .field("status", lost ? "camera-lost" : "camera-back")
      .field("camera", kSides[side]);
  if (GST_CLOCK_TIME_IS_VALID(running))
    w.field("pts_ns", static_cast<unsigned long long>(running));
  else
    w.key("pts_ns").null();
  if (!lost)
    w.field("gap_s", gap_s);
  w.end_object();
  line << "\n";
  if (!job.json.put(line.str()))
    output_failed(job, job.json, errno);
}

// While a camera is missing: one camera-lost line per second for each missing camera.
gboolean on_lost_timer(gpointer data)
{
  Job &job = *static_cast<Job *>(data);
  if (job.interrupted || (!job.camera_lost[0] && !job.camera_lost[1])) {
    job.lost_timer = 0;
    return G_SOURCE_REMOVE;
  }
  const GstClockTime now = running_time_now(job.pipeline);
  for (int side = 0; side < 2; side++)
    if (job.camera_lost[side])
      write_camera_status(job, side, true, now, 0);
  return G_SOURCE_CONTINUE;
}

// treecamerasrc's treestereo-camera messages: lost, retry (still missing), back.
void on_camera(Job &job, GstMessage *msg)
{
  const GstStructure *st = gst_message_get_structure(msg);
  if (!st || !gst_structure_has_name(st, "treestereo-camera"))
    return;
  const char *src = GST_OBJECT_NAME(GST_MESSAGE_SRC(msg));
  const int side = std::strcmp(src, "camera-left") == 0    ? 0
                   : std::strcmp(src, "camera-right") == 0 ? 1
                                                            : -1;
  const char *state = gst_structure_get_string(st, "state");
  if (side < 0 || !state)
    return;
  guint64 running = GST_CLOCK_TIME_NONE;
  gst_structure_get_uint64(st, "running-time", &running);
  if (std::strcmp(state, "lost") == 0 && !job.camera_lost[side]) {
    // the WARNING beside this message says why, on stderr
    job.camera_lost[side] = true;
    if (!job.interrupted)
      write_camera_status(job, side, true, running, 0);
    if (!job.lost_timer)
      job.lost_timer = g_timeout_add(1000, on_lost_timer, &job);
  } else if (std::strcmp(state, "back") == 0 && job.camera_lost[side]) {
    job.camera_lost[side] = false;
    guint64 gap = 0;
    gst_structure_get_uint64(st, "gap", &gap);
    guint attempt = 0;
    gst_structure_get_uint(st, "attempt", &attempt);
    std::fprintf(stderr, "\ntreestereo-measure: %s camera back after %.1f s (attempt %u)\n",
                 kSides[side], gap / 1e9, attempt);
    if (!job.interrupted)
      write_camera_status(job, side, false, running, gap / 1e9);
  }
}

gboolean on_bus(GstBus *, GstMessage *msg, gpointer data)
{
  Job &job = *static_cast<Job *>(data);
  switch (GST_MESSAGE_TYPE(msg)) {
  case GST_MESSAGE_ERROR: {
    GError *err = nullptr;
    gchar *dbg = nullptr;
    gst_message_parse_error(msg, &err, &dbg);
    if (job.o.record && std::strcmp(GST_OBJECT_NAME(msg->src), "recording") == 0) {
      // the recording's filesink: name the file (its disk-full error does not)
      const bool full = g_error_matches(err, GST_RESOURCE_ERROR, GST_RESOURCE_ERROR_NO_SPACE_LEFT);
      std::fprintf(stderr, "\ntreestereo-measure: cannot write %s: %s\n", job.o.record,
                   full ? g_strerror(ENOSPC) : err->message);
    } else {
      std::fprintf(stderr, "\ntreestereo-measure: error from %s: %s\n",
                   GST_OBJECT_NAME(msg->src), err->message);
    }
    if (dbg)
      std::fprintf(stderr, "  (%s)\n", dbg);
    g_error_free(err);
    g_free(dbg);
    job.error = true;
    g_main_loop_quit(job.loop);
    break;
  }
  case GST_MESSAGE_WARNING: {
    GError *err = nullptr;
    gst_message_parse_warning(msg, &err, nullptr);
    std::fprintf(stderr, "\ntreestereo-measure: warning from %s: %s\n",
                 GST_OBJECT_NAME(msg->src), err->message);
    g_error_free(err);
    break;
  }
  case GST_MESSAGE_EOS:
    g_main_loop_quit(job.loop);
    break;
  case GST_MESSAGE_ELEMENT:
    on_tree(job, msg);
    on_section(job, msg);
    on_camera(job, msg);
    break;
  default:
    break;
  }
  return TRUE;
}

gboolean on_sigint(gpointer data)
{
  Job &job = *static_cast<Job *>(data);
  if (job.interrupted) {
    std::fprintf(stderr, "\ntreestereo-measure: interrupted twice, stopping without EOS\n");
    g_main_loop_quit(job.loop);
    return G_SOURCE_REMOVE;
  }
  job.interrupted = true;
  std::fprintf(stderr, "\ntreestereo-measure: interrupted, finishing the files (Ctrl-C again "
                       "to stop at once)\n");
  gst_element_send_event(job.pipeline, gst_event_new_eos());
  return G_SOURCE_CONTINUE;
}

std::string build_description(Job &job)
{
  const Options &o = job.o;
  std::ostringstream d;
  std::string left, right;
  int w = 1296, h = 972;
  if (o.size && !parse_size(o.size, w, h))
    usage_error(std::string("--size expects WxH, got '") + o.size + "'");

  if (o.synthetic) {
    const int frames = o.frames > 0 ? o.frames : 30;
    const int fps = o.fps > 0 ? int(o.fps + 0.5) : 7;
    job.total_frames = frames;
    for (int v = 0; v < 2; v++) {
      std::ostringstream s;
      s << "treetestsrc view=" << (v == 0 ? "left" : "right") << " scene=" << job.scene
        << " seed=" << o.seed
        << " distance=" << o.distance << " speed=" << o.speed << " light=" << o.light
        << " num-buffers=" << frames << " ! video/x-raw,format=RGB,width=" << w
        << ",height=" << h << ",framerate=" << fps << "/1";
      (v == 0 ? left : right) = s.str();
    }
  } else if (o.camera_left || o.camera_right) {
    if (!o.camera_left || !o.camera_right)
      usage_error("--camera-left and --camera-right go together");
    left = camera_source(o.camera_left, "left", o);
    right = camera_source(o.camera_right, "right", o);
    job.total_frames = o.frames;
    if (o.frames > 0)
      job.stop_after = guint64(o.frames);
  } else {
    if (!o.left || !o.right)
      usage_error("--left and --right go together");
    left = file_source(o.left, o.fps, o.frames);
    right = file_source(o.right, o.fps, o.frames);
    if (is_pattern(o.left)) {
      job.total_frames = count_sequence(o.left);
      if (job.total_frames == 0)
        usage_error(std::string("no file matches ") + o.left + " (index 0)");
      if (o.frames > 0)
        job.total_frames = std::min(job.total_frames, o.frames);
    } else if (!g_file_test(o.left, G_FILE_TEST_EXISTS)) {
      usage_error(std::string("no such file: ") + o.left);
    }
  }

  d << "stereorectify name=rect calibration=" << quoted(job.calibration)
    << (o.no_rectify ? " rectify=false" : "");
  if (o.camera_left) // live: a frame waits this long for its partner; pairs may be this far apart
    d << " latency=" << gint64(o.latency_ms * GST_MSECOND)
      << " max-skew=" << gint64(o.max_skew_ms * GST_MSECOND);
  if (o.camera_left) // live: when the analysis falls behind, the oldest pairs go, not the cameras'
    d << " ! queue max-size-buffers=" << o.pair_queue
      << " max-size-bytes=0 max-size-time=0 leaky=downstream";
  d << " ! exgsegment name=seg" << (o.index ? std::string(" index=") + o.index : "");
  // a queue: segmentation and rectification of the next pair overlap with SIFT (bench-chain:
  // +15 % frames/s at 1296x972 on 2 cores)
  d << " ! queue max-size-buffers=2 max-size-bytes=0 max-size-time=0 ! siftmatch name=match" << (o.method ? std::string(" method=") + o.method : "")
    << (o.scale > 0 ? " scale=" + std::to_string(o.scale) : "") << " min-depth=" << o.min_depth
    << " max-depth=" << o.max_depth;
  d << " ! stereodepth name=depth" << (o.mode ? std::string(" mode=") + o.mode : "")
    << (o.canopy ? std::string(" canopy=") + o.canopy : "")
    << " min-depth=" << o.min_depth << " max-depth=" << o.max_depth;
  d << " ! treemetrics name=metrics bands=" << o.bands << " smoothing=" << o.smoothing;
  if (o.rig_speed > 0)
    d << " speed=" << o.rig_speed;
  if (o.row_map)
    d << " row-map-location=" << quoted(o.row_map);
  if (o.sections) {
    d << " ! spraycontrol name=spray";
    // A file of commands gets its picture beside it: the row map with the valve timeline.
    if (std::string(o.sections) != "-")
      d << " timeline-location=" << quoted(with_extension(o.sections, ".png"));
  }
  if (o.record) {
    d << " ! tee name=t t. ! queue ! fakesink name=results sync=false async=false"
      << " t. ! queue ! treeoverlay draw-map=true ! videoconvert ! video/x-raw,format=I420 ! x264enc bitrate="
      << o.bitrate
      << " speed-preset=veryfast tune=zerolatency ! h264parse"
      // fragmented, a fragment a second, each write synchronous: after a SIGKILL or a power cut
      // the file plays up to its last second or so; at EOS mp4mux adds the duration and the
      // seek index (docs/reliability.md)
      << " ! mp4mux fragment-duration=1000 ! filesink name=recording buffer-mode=unbuffered"
      << " o-sync=true location=" << quoted(o.record);
  } else {
    d << " ! fakesink name=results sync=false";
  }
  d << "  " << left << " ! rect.left  " << right << " ! rect.right";
  return d.str();
}

// Finds the treestereo plugin where this tool was installed, or in the build tree it was built
// in, when GST_PLUGIN_PATH does not already lead to it.
void ensure_plugin()
{
  if (GstPluginFeature *f = gst_registry_lookup_feature(gst_registry_get(), "stereorectify")) {
    gst_object_unref(f);
    return;
  }
  for (const char *dir : {TREESTEREO_PLUGIN_INSTALL_DIR, TREESTEREO_PLUGIN_BUILD_DIR})
    if (g_file_test(dir, G_FILE_TEST_IS_DIR) && gst_registry_scan_path(gst_registry_get(), dir))
      return;
}

int run(int argc, char **argv)
{
  Job job;
  Options &o = job.o;
  GOptionEntry entries[] = {
      {"synthetic", 0, 0, G_OPTION_ARG_NONE, &o.synthetic,
       "The built-in synthetic orchard (default with no inputs)", nullptr},
      {"left", 0, 0, G_OPTION_ARG_FILENAME, &o.left,
       "Left images (printf pattern, e.g. left_%04d.jpg) or a video file", "PATTERN"},
      {"right", 0, 0, G_OPTION_ARG_FILENAME, &o.right, "Right images or video", "PATTERN"},
      {"camera-left", 0, 0, G_OPTION_ARG_STRING, &o.camera_left, "Left Aravis camera", "NAME"},
      {"camera-right", 0, 0, G_OPTION_ARG_STRING, &o.camera_right, "Right Aravis camera",
       "NAME"},
      {"camera-caps", 0, 0, G_OPTION_ARG_STRING, &o.camera_caps,
       "Caps for the cameras (default video/x-raw,format=RGB; video/x-bayer,... adds "
       "bayer2rgb)",
       "CAPS"},
      {"latency", 0, 0, G_OPTION_ARG_DOUBLE, &o.latency_ms,
       "Cameras: how long a frame waits for its partner, ms (100; at least a frame period)",
       "MS"},
      {"max-skew", 0, 0, G_OPTION_ARG_DOUBLE, &o.max_skew_ms,
       "Cameras: largest time between paired frames, ms (20)", "MS"},
      {"pair-queue", 0, 0, G_OPTION_ARG_INT, &o.pair_queue,
       "Cameras: pairs waiting for the analysis; older ones are dropped when it falls behind "
       "(8)",
       "N"},
      {"camera-timeout", 0, 0, G_OPTION_ARG_INT, &o.camera_timeout_ms,
       "Cameras: a camera that sent no frame for this long is lost and reopened, ms (2000)",
       "MS"},
      {"reconnect", 0, 0, G_OPTION_ARG_INT, &o.reconnect_ms,
       "Cameras: first wait before reopening a lost camera, doubled per failed attempt up to "
       "8 s, ms; 0 = a lost camera ends the run with its error (500)",
       "MS"},
      {"calibration", 'c', 0, G_OPTION_ARG_FILENAME, &o.calibration,
       "Stereo calibration (OpenCV YAML/XML or 'left.yaml;right.yaml')", "FILE"},
      {"no-rectify", 0, 0, G_OPTION_ARG_NONE, &o.no_rectify,
       "The input is already rectified (geometry still from --calibration)", nullptr},
      {"frames", 'n', 0, G_OPTION_ARG_INT, &o.frames,
       "Frames to process (synthetic default 30; all for files; for cameras: pairs to measure, "
       "until Ctrl-C by default)",
       "N"},
      {"size", 0, 0, G_OPTION_ARG_STRING, &o.size, "Synthetic frame size (1296x972)", "WxH"},
      {"fps", 0, 0, G_OPTION_ARG_DOUBLE, &o.fps, "Frame rate of image sequences/synthetic (7)",
       "FPS"},
      {"seed", 0, 0, G_OPTION_ARG_INT64, &o.seed, "Synthetic scene seed (1)", "N"},
      {"distance", 0, 0, G_OPTION_ARG_DOUBLE, &o.distance, "Synthetic trunk distance, m (2.0)",
       "M"},
      {"speed", 0, 0, G_OPTION_ARG_DOUBLE, &o.speed, "Synthetic sprayer speed, m/s (0.5)", "M/S"},
      {"light", 0, 0, G_OPTION_ARG_DOUBLE, &o.light, "Synthetic light level (1.0)", "L"},
      {"scene", 0, 0, G_OPTION_ARG_STRING, &o.scene,
       "Synthetic scene: orchard (a row of trees on grass, a row behind; default), hedgerow or "
       "lab (the tree alone on soil)",
       "KIND"},
      {"index", 0, 0, G_OPTION_ARG_STRING, &o.index, "exgsegment index", "NAME"},
      {"method", 0, 0, G_OPTION_ARG_STRING, &o.method, "siftmatch method", "NAME"},
      {"scale", 0, 0, G_OPTION_ARG_DOUBLE, &o.scale, "siftmatch detection scale", "S"},
      {"mode", 0, 0, G_OPTION_ARG_STRING, &o.mode, "stereodepth mode (sparse|dense)", "MODE"},
      {"canopy", 0, 0, G_OPTION_ARG_STRING, &o.canopy,
       "What the canopy is, decided in 3D by stereodepth: tree (the tree in front; default), "
       "row (the near row in view) or off (the colour mask)",
       "tree|row|off"},
      {"min-depth", 0, 0, G_OPTION_ARG_DOUBLE, &o.min_depth, "Nearest canopy depth, mm (500)",
       "MM"},
      {"max-depth", 0, 0, G_OPTION_ARG_DOUBLE, &o.max_depth, "Farthest canopy depth, mm (10000)",
       "MM"},
      {"bands", 0, 0, G_OPTION_ARG_INT, &o.bands, "Height bands of the profile (4)", "N"},
      {"smoothing", 0, 0, G_OPTION_ARG_DOUBLE, &o.smoothing,
       "Temporal smoothing 0..1 (0 = off)", "A"},
      {"json", 'j', 0, G_OPTION_ARG_FILENAME, &o.json, "JSON lines, one per frame ('-' = stdout)",
       "FILE"},
      {"csv", 0, 0, G_OPTION_ARG_FILENAME, &o.csv, "CSV, one row per frame", "FILE"},
      {"trees", 0, 0, G_OPTION_ARG_FILENAME, &o.trees,
       "Tree records, one JSON line per tree as it leaves the view ('-' = stdout)", "FILE"},
      {"row-map", 0, 0, G_OPTION_ARG_FILENAME, &o.row_map,
       "Row canopy map: CSV here, PNG beside it (FILE with .png), written at the end", "FILE.csv"},
      {"sections", 0, 0, G_OPTION_ARG_FILENAME, &o.sections,
       "Nozzle-section valve commands (spraycontrol, defaults of docs/spraying.md), one JSON "
       "line each ('-' = stdout); a file gets the row map with the valve timeline under it "
       "beside it (FILE with .png)",
       "FILE"},
      {"rig-speed", 0, 0, G_OPTION_ARG_DOUBLE, &o.rig_speed,
       "The rig's speed from outside (wheel odometry, GNSS), m/s; 0 = measured by stereo (0)",
       "M/S"},
      {"points", 0, 0, G_OPTION_ARG_NONE, &o.points, "Add the 3D points to the JSON", nullptr},
      {"matches", 0, 0, G_OPTION_ARG_NONE, &o.matches, "Add the matches to the JSON", nullptr},
      {"record", 'r', 0, G_OPTION_ARG_FILENAME, &o.record,
       "Annotated video (fragmented MP4, H.264: plays up to its last second after a crash or "
       "power cut)",
       "FILE"},
      {"bitrate", 0, 0, G_OPTION_ARG_INT, &o.bitrate, "Recording bitrate, kbit/s (4000)", "KBPS"},
      {"quiet", 'q', 0, G_OPTION_ARG_NONE, &o.quiet, "No per-frame summary", nullptr},
      {nullptr}};
  GOptionContext *ctx = g_option_context_new("- measure fruit trees with two cameras");
  g_option_context_set_summary(ctx, kSummary);
  g_option_context_add_main_entries(ctx, entries, nullptr);
  g_option_context_add_group(ctx, gst_init_get_option_group());
  GError *err = nullptr;
  if (!g_option_context_parse(ctx, &argc, &argv, &err)) {
    std::string m = err->message;
    g_error_free(err);
    g_option_context_free(ctx);
    usage_error(m);
  }
  g_option_context_free(ctx);
  if (argc > 1)
    usage_error(std::string("unexpected argument '") + argv[1] + "'");

  const bool files = o.left || o.right, cameras = o.camera_left || o.camera_right;
  if (!files && !cameras)
    o.synthetic = TRUE;
  if (int(o.synthetic) + int(files) + int(cameras) > 1)
    usage_error("choose one input: --synthetic, --left/--right or --camera-left/--camera-right");
  if (o.pair_queue < 1)
    usage_error("--pair-queue must be at least 1");
  if (o.camera_timeout_ms < 100 || o.camera_timeout_ms > 600000)
    usage_error("--camera-timeout must be 100..600000 ms");
  if (o.reconnect_ms < 0 || o.reconnect_ms > 600000)
    usage_error("--reconnect must be 0 (no reconnecting) or up to 600000 ms");
  if (o.bands < 1 || o.bands > 64)
    usage_error("--bands must be 1..64");
  if (o.smoothing < 0 || o.smoothing >= 1)
    usage_error("--smoothing must be in [0, 1)");
  if (o.canopy && std::strcmp(o.canopy, "tree") != 0 && std::strcmp(o.canopy, "row") != 0 &&
      std::strcmp(o.canopy, "off") != 0)
    usage_error(std::string("--canopy expects tree, row or off, got '") + o.canopy + "'");
  if (o.scene && !o.synthetic)
    usage_error("--scene is for --synthetic (the built-in scene)");
  SceneKind kind = SceneKind::Orchard;
  if (o.scene) {
    try {
      kind = scene_kind_from_name(o.scene);
    } catch (const std::exception &e) {
      usage_error(std::string("--scene: ") + e.what());
    }
  }
  job.scene = scene_kind_name(kind);

  if (o.synthetic) {
    // the rig's true calibration, written before the pipeline starts
    SceneParams p;
    int w = 1296, h = 972;
    if (o.size && !parse_size(o.size, w, h))
      usage_error(std::string("--size expects WxH, got '") + o.size + "'");
    p.image_size = cv::Size(w, h);
    p.seed = std::uint64_t(o.seed);
    p.distance_mm = o.distance * 1000.0;
    p.speed_m_s = o.speed;
    p.light = o.light;
    p.kind = kind;
    gchar *dir = g_dir_make_tmp("treestereo-measure-XXXXXX", nullptr);
    job.temp_calibration = std::string(dir) + "/rig.yml";
    g_free(dir);
    validate_scene_params(p);
    save_calibration(rig_calibration(p), job.temp_calibration);
    job.calibration = o.calibration ? o.calibration : job.temp_calibration;
  } else {
    if (!o.calibration)
      usage_error("--calibration FILE is needed for files and cameras");
    job.calibration = o.calibration;
  }

  if (o.rig_speed < 0 || !std::isfinite(o.rig_speed))
    usage_error("--rig-speed must be 0 (measured) or a speed in m/s");
  // every output is checked before the pipeline starts: a missing folder or a read-only disk
  // is an error naming the file, not a run whose results go nowhere
  if (o.json)
    job.json.open(o.json);
  if (o.trees)
    job.trees.open(o.trees);
  if (o.sections)
    job.sections.open(o.sections);
  if (o.csv) {
    job.csv.open(o.csv);
    if (!job.csv.put(std::string(kCsvHeader) + "\n"))
      throw std::runtime_error(std::string("cannot write ") + o.csv + ": " + g_strerror(errno));
  }
  if (o.record)
    check_writable(o.record);
  if (o.row_map)
    check_writable(o.row_map);

  ensure_plugin();
  const std::string desc = build_description(job);
  if (g_getenv("TREESTEREO_MEASURE_DEBUG"))
    std::fprintf(stderr, "pipeline: %s\n", desc.c_str());
  err = nullptr;
  job.pipeline = gst_parse_launch(desc.c_str(), &err);
  if (!job.pipeline || err) {
    std::fprintf(stderr, "treestereo-measure: cannot build the pipeline: %s\n",
                 err ? err->message : "unknown error");
    if (err)
      g_error_free(err);
    if (job.pipeline)
      gst_object_unref(job.pipeline);
    return 1;
  }

  GstElement *metrics = gst_bin_get_by_name(GST_BIN(job.pipeline), "metrics");
  GstPad *pad = gst_element_get_static_pad(metrics, "src");
  gst_pad_add_probe(pad, GST_PAD_PROBE_TYPE_BUFFER, on_result, &job, nullptr);
  gst_object_unref(pad);
  gst_object_unref(metrics);

  job.loop = g_main_loop_new(nullptr, FALSE);
  GstBus *bus = gst_element_get_bus(job.pipeline);
  gst_bus_add_watch(bus, on_bus, &job);
  gst_object_unref(bus);
  const guint sig = g_unix_signal_add(SIGINT, on_sigint, &job);

  job.start = std::chrono::steady_clock::now();
  if (gst_element_set_state(job.pipeline, GST_STATE_PLAYING) == GST_STATE_CHANGE_FAILURE) {
    // the error message on the bus says why
    GstMessage *m = gst_bus_pop_filtered(gst_element_get_bus(job.pipeline), GST_MESSAGE_ERROR);
    if (m) {
      on_bus(nullptr, m, &job);
      gst_message_unref(m);
    } else {
      std::fprintf(stderr, "treestereo-measure: the pipeline would not start\n");
    }
    job.error = true;
  } else {
    g_main_loop_run(job.loop);
  }
  g_source_remove(sig);
  if (job.lost_timer)
    g_source_remove(job.lost_timer);
  gst_element_set_state(job.pipeline, GST_STATE_NULL);
  gst_object_unref(job.pipeline);
  g_main_loop_unref(job.loop);

  if (job.output_timeout)
    g_source_remove(job.output_timeout);

  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - job.start).count();
  if (isatty(STDERR_FILENO) && job.total_frames > 0)
    std::fprintf(stderr, "\n");
  std::fprintf(stderr,
               "treestereo-measure: %" G_GUINT64_FORMAT " frames (%" G_GUINT64_FORMAT
               " with a tree, %" G_GUINT64_FORMAT " tree records) in %.1f s (%.2f frames/s)%s%s\n",
               job.frames, job.present, job.n_trees, elapsed,
               elapsed > 0 ? job.frames / elapsed : 0.0,
               o.record ? ", video: " : "", o.record ? o.record : "");
  if (job.n_camera_lost > 0)
    std::fprintf(stderr,
                 "treestereo-measure: cameras missing: %" G_GUINT64_FORMAT
                 " camera-lost lines, %" G_GUINT64_FORMAT " returns\n",
                 job.n_camera_lost, job.n_camera_back);
  return job.error || job.output_failed ? 1 : 0;
}

} // namespace

int main(int argc, char **argv)
{
  int status = 1;
  try {
    status = run(argc, argv);
  } catch (const UsageError &e) {
    std::fprintf(stderr, "treestereo-measure: %s (see --help)\n", e.what());
    status = 2;
  } catch (const std::exception &e) {
    std::fprintf(stderr, "treestereo-measure: %s\n", e.what());
  }
  // Joins GStreamer's streaming threads before exit: one of its pooled threads could otherwise
  // still be ending while the process exits, and LeakSanitizer's exit-time check, which stops
  // every thread, then crashes ("Tracer caught signal 11", seen once in the ASan suite).
  if (gst_is_initialized())
    gst_deinit();
  return status;
}
