// bench-orchard: the chain with the canopy decided in 3D (stereodepth canopy=tree|row) against
// the synthetic orchard's exact truth, on tree seeds split into tuning and held-out sets.
// Prints markdown tables.
//
//   bench-orchard [--only orchard|hedgerow|driveby] [--size 1296x972]
//                 [--tuning-seeds 1,3,5,7] [--held-out-seeds 2,4,6,8]
//                 [--distances 1.6:2.4:0.2] [--lights 0.7,1.0,1.3]      (orchard sweep)
//                 [--layouts 0,1,2,3] (of the row layouts below)
//                 [--hedgerow-distances 1.6:2.4:0.4] [--hedgerow-lights 1.0]
//                 [--speeds 0.5,1.0,2.0] [--driveby-distance 2.0]          (drive-by sweep)
//                 [--exgsegment "keep=all"] [--siftmatch ...] [--stereodepth ...]
//                 [--treemetrics ...] [--masks DIR] (overlays of the frames that fail badly;
//                 each drive-by frame's, and each drive-by run's row map, CSV and picture)
//
// Orchard sweep (scene orchard, stereodepth canopy=tree): each seed, distance and light in four
// row layouts (the default gaps of 0.2-0.6 m, tight gaps of 0.2-0.3 m, the next row 3.0 m and
// 4.5 m behind). The same frames go through a second stereodepth with canopy=off (the colour
// silhouette alone, the baseline): one pipeline, teed after siftmatch. Truth as bench-accuracy
// has it: distance = the median Z of the visible canopy of the tree in front in the
// rectified-left frame (truth_in_frame with the geometry meta's R1), height and width its true
// extents. A tree is in view when the truth's canopy_mask has pixels. Height errors count on
// frames whose top and bottom are not clipped, width errors on frames whose left and right are
// not (the chain's clipped flags): a clipped extent is a lower bound, not a measurement.
//
// Hedgerow sweep (scene hedgerow, stereodepth canopy=row): per band the chain's near-face depth
// and fill against the truth over the SAME image rows (band_rows() of the chain's silhouette's
// bounding box): the truth's near-row mask rectified (nearest neighbour, the rig's calibration
// and the geometry meta's rectification) gives fill = band_fill() over those rows; the truth's
// visible near-row points (row_points_mm in the rectified-left frame), projected to rectified
// pixels, give the near-face depth = the 5th percentile of Z of those whose pixel row is in the
// band (treemetrics' band-depth-percentile). A second column takes it over the points the
// right view sees too (stereo measures nothing that one camera alone sees), to tell the two
// apart.
#include "chain_sweep.hpp"
#include "treestereo/metrics.hpp"
#include "treestereo/rectify.hpp"
#include "treestereo/rowmap.hpp"
#include "treestereo/spray.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <map>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <string>
#include <vector>

using namespace treestereo;
using treestereo::bench::AbsErrors;
using treestereo::bench::ElementProps;
using treestereo::bench::parse_list;
using treestereo::bench::parse_sizes;
using treestereo::bench::RigFile;
using treestereo::bench::SceneConfig;

namespace {

struct Layout {
  const char *name;
  double gap_min_m, gap_max_m, spacing_m; // -1: the scene's default
};
// The neighbours of the tree in front: default gaps, tight gaps, the next row near and far.
const Layout kLayouts[] = {{"default gaps 0.2-0.6 m, next row 3.5 m", -1, -1, -1},
                           {"tight gaps 0.2-0.3 m", 0.2, 0.3, -1},
                           {"next row 3.0 m", -1, -1, 3.0},
                           {"next row 4.5 m", -1, -1, 4.5}};

std::string seeds_text(const std::vector<double> &seeds)
{
  std::string s;
  for (double x : seeds)
    s += (s.empty() ? "" : ",") + std::to_string(std::lround(x));
  return s;
}

// A view's mask of a vegetation view (canopy meta), wrapped (valid while `map` is mapped).
struct MappedMask {
  GstBuffer *buf = nullptr;
  GstMapInfo map{};
  cv::Mat mat;
  explicit MappedMask(const GstTreeStereoVegetationView &v)
  {
    if (v.present && v.mask && gst_buffer_map(v.mask, &map, GST_MAP_READ)) {
      buf = v.mask;
      mat = cv::Mat(int(v.mask_height), int(v.mask_width), CV_8UC1, map.data, v.mask_stride);
    }
  }
  ~MappedMask()
  {
    if (buf)
      gst_buffer_unmap(buf, &map);
  }
  MappedMask(const MappedMask &) = delete;
  MappedMask &operator=(const MappedMask &) = delete;
};

// Truth maps of the left view resampled into the chain's rectified left view: nearest neighbour
// through the rig's calibration (the distortion and camera matrix of the rendered view) and the
// rectification stereorectify used (R1, fx, fy, cx, cy of the geometry meta).
class TruthRectifier
{
public:
  TruthRectifier(const StereoCalibration &calib, const GstTreeStereoGeometryMeta &g)
  {
    const cv::Matx33d R1 = bench::rectified_rotation(&g);
    const cv::Matx33d P(g.fx[0], 0, g.cx[0], 0, g.fy[0], g.cy[0], 0, 0, 1);
    cv::initUndistortRectifyMap(calib.M1, calib.D1, cv::Mat(R1), cv::Mat(P),
                                cv::Size(int(g.view_width), int(g.view_height)), CV_32FC1, mx_,
                                my_);
  }
  cv::Mat operator()(const cv::Mat &mask) const
  {
    cv::Mat out;
    cv::remap(mask, out, mx_, my_, cv::INTER_NEAREST, cv::BORDER_CONSTANT, 0);
    return out;
  }

private:
  cv::Mat mx_, my_;
};

// The left rectified view of a side-by-side frame with the chain's canopy outlined in red and
// the truth's in blue, where they disagree tinted in the same colours, written to `path`.
void save_overlay(GstBuffer *buf, const GstTreeStereoGeometryMeta &g, const cv::Mat &chain,
                  const cv::Mat &truth, const std::string &path)
{
  GstMapInfo map;
  if (!gst_buffer_map(buf, &map, GST_MAP_READ))
    return;
  const int w = int(g.view_width), h = int(g.view_height);
  const cv::Mat frame(h, 2 * w, CV_8UC3, map.data, map.size / std::size_t(h));
  cv::Mat bgr;
  cv::cvtColor(frame(cv::Rect(0, 0, w, h)), bgr, cv::COLOR_RGB2BGR);
  gst_buffer_unmap(buf, &map);
  // Where they disagree, tinted: the chain's canopy alone red, the truth's alone blue.
  if (!chain.empty() && !truth.empty()) {
    const cv::Mat only_chain = chain & ~truth, only_truth = truth & ~chain;
    cv::Mat tint = bgr.clone();
    tint.setTo(cv::Scalar(0, 0, 255), only_chain);
    tint.setTo(cv::Scalar(255, 64, 0), only_truth);
    cv::addWeighted(bgr, 0.5, tint, 0.5, 0, bgr);
  }
  for (const auto &[mask, colour] : {std::make_pair(truth, cv::Scalar(255, 64, 0)),
                                     std::make_pair(chain, cv::Scalar(0, 0, 255))}) {
    if (mask.empty())
      continue;
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(mask.clone(), contours, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
    cv::drawContours(bgr, contours, -1, colour, 2);
  }
  cv::imwrite(path, bgr);
}

// ---- Orchard sweep (canopy=tree) ----

struct TreeFrame {
  SceneConfig c;
  int layout = 0;
  bool held_out = false;
  bool in_view = false, present = false;
  double distance = 0, height = 0, width = 0, confidence = 0;
  double t_distance = 0, t_height = 0, t_width = 0;
  unsigned clipped = 0;
};

TreeFrame tree_frame(const TreeFrame &base, const GstTreeStereoMetricsMeta *m)
{
  TreeFrame f = base;
  if (m && m->metrics.tree_present) {
    f.present = true;
    f.distance = m->metrics.distance_m;
    f.height = m->metrics.height_m;
    f.width = m->metrics.width_m;
    f.clipped = m->metrics.clipped;
    f.confidence = m->metrics.confidence;
  }
  return f;
}

bool height_clipped(unsigned c)
{
  return c & (GST_TREE_STEREO_CLIPPED_TOP | GST_TREE_STEREO_CLIPPED_BOTTOM);
}
bool width_clipped(unsigned c)
{
  return c & (GST_TREE_STEREO_CLIPPED_LEFT | GST_TREE_STEREO_CLIPPED_RIGHT);
}

struct TreeErrors {
  int frames = 0, in_view = 0, answered_in_view = 0, answered_empty = 0;
  int h_clipped = 0, w_clipped = 0;
  AbsErrors h, w, d;
  void add(const TreeFrame &f)
  {
    frames++;
    in_view += f.in_view;
    if (!f.present)
      return;
    if (!f.in_view) {
      answered_empty++; // a tree reported where none is in view
      return;
    }
    answered_in_view++;
    d.add((f.distance - f.t_distance) / f.t_distance);
    if (height_clipped(f.clipped))
      h_clipped++;
    else
      h.add((f.height - f.t_height) / f.t_height);
    if (width_clipped(f.clipped))
      w_clipped++;
    else
      w.add((f.width - f.t_width) / f.t_width);
  }
};

void print_tree_row(const std::string &set, const std::string &what, const TreeErrors &e)
{
  std::printf("| %s | %s | %d | %d / %d | %d | %s | %s | %s | %d / %d |\n", set.c_str(),
              what.c_str(), e.frames, e.answered_in_view, e.in_view, e.answered_empty,
              e.h.cell().c_str(), e.w.cell().c_str(), e.d.cell().c_str(), e.h_clipped, e.w_clipped);
}

// ---- Hedgerow sweep (canopy=row) ----

struct BandRecord {
  SceneConfig c;
  bool held_out = false;
  int band = 0;
  bool present = false;
  double depth = 0, fill = 0;
  double t_depth = 0, t_fill = 0;
  std::size_t t_points = 0; // truth near-row points in the band's rows
  // The same near-face depth over the points the right view sees too: stereo cannot measure
  // what one camera alone sees (beside the image's border, the near row's nearest parts).
  double t_depth_stereo = 0;
  std::size_t t_points_stereo = 0;
};

struct HedgeFrame {
  SceneConfig c;
  bool held_out = false, in_view = false, present = false;
};

// The truth of the chain's bands: fill over the same rows of the rectified truth row mask, and
// the 5th percentile of Z of the truth's near-row points whose rectified pixel row is in them.
std::vector<BandRecord> band_truth(const BandRecord &base, const GstTreeStereoMetrics &m,
                                   const cv::Mat &chain_mask, const cv::Mat &truth_row_mask,
                                   const GroundTruth &tr, const GstTreeStereoGeometryMeta &g)
{
  std::vector<BandRecord> out;
  const cv::Rect bbox = cv::boundingRect(chain_mask);
  const int n = int(m.n_bands);
  std::vector<std::vector<double>> z(std::size_t(std::max(n, 0))), zs = z;
  std::vector<cv::Range> rows;
  for (int i = 0; i < n; i++)
    rows.push_back(band_rows(bbox, n, i));
  for (const cv::Point3f &p : tr.row_points_mm) {
    if (!(p.z > 0))
      continue;
    const int row = int(std::floor(g.fy[0] * p.y / p.z + g.cy[0] + 0.5));
    // the right camera sits at (baseline, 0, 0) in the rectified-left frame
    const double xr = g.fx[1] * (p.x - g.baseline_mm) / p.z + g.cx[1];
    const bool stereo = xr >= -0.5 && xr < g.view_width - 0.5;
    for (int i = 0; i < n; i++)
      if (row >= rows[std::size_t(i)].start && row < rows[std::size_t(i)].end) {
        z[std::size_t(i)].push_back(p.z);
        if (stereo)
          zs[std::size_t(i)].push_back(p.z);
      }
  }
  for (int i = 0; i < n; i++) {
    const GstTreeStereoBand &b = m.bands[i];
    BandRecord r = base;
    r.band = i;
    r.present = b.present;
    r.depth = b.depth_m;
    r.fill = b.fill;
    r.t_fill = band_fill(truth_row_mask, rows[std::size_t(i)].start, rows[std::size_t(i)].end);
    r.t_points = z[std::size_t(i)].size();
    if (r.t_points > 0)
      r.t_depth = percentile(z[std::size_t(i)], 5.0) / 1000.0;
    r.t_points_stereo = zs[std::size_t(i)].size();
    if (r.t_points_stereo > 0)
      r.t_depth_stereo = percentile(zs[std::size_t(i)], 5.0) / 1000.0;
    out.push_back(r);
  }
  return out;
}

struct BandErrors {
  int bands = 0, no_truth = 0;
  AbsErrors depth, depth_stereo, fill;
  void add(const BandRecord &r)
  {
    if (r.present && r.t_points_stereo > 0)
      depth_stereo.add((r.depth - r.t_depth_stereo) / r.t_depth_stereo);
    if (!r.present)
      return;
    bands++;
    fill.add(r.fill - r.t_fill);
    if (r.t_points == 0)
      no_truth++;
    else
      depth.add((r.depth - r.t_depth) / r.t_depth);
  }
};

struct Options {
  cv::Size size{1296, 972};
  std::vector<double> tuning{1, 3, 5, 7}, held_out{2, 4, 6, 8};
  std::string distances = "1.6:2.4:0.2", lights = "0.7,1.0,1.3";
  std::string hedge_distances = "1.6:2.4:0.4", hedge_lights = "1.0";
  std::string only, masks;
  std::vector<double> layouts{0, 1, 2, 3}; // indices into kLayouts
  std::string speeds = "0.5,1.0,2.0";       // drive-by sweep (m/s)
  double driveby_distance = 2.0;
  ElementProps props;
};

std::vector<std::pair<double, bool>> all_seeds(const Options &o)
{
  std::vector<std::pair<double, bool>> s;
  for (double x : o.tuning)
    s.emplace_back(x, false);
  for (double x : o.held_out)
    s.emplace_back(x, true);
  return s;
}

std::string common_props(const Options &o)
{
  return "exgsegment \"" + o.props.exgsegment + "\", siftmatch \"" + o.props.siftmatch +
         "\", stereodepth \"" + o.props.stereodepth + "\", treemetrics \"" + o.props.treemetrics +
         "\"";
}

int saved_masks = 0;
constexpr int kMaxSavedMasks = 8;

void orchard_sweep(const Options &o)
{
  const RigFile rig(o.size);
  const ElementProps &p = o.props;
  const std::string branch =
      "treemetrics post-messages=false " + p.treemetrics + " ! appsink sync=false name=";
  const std::string tail = "tee name=t ! queue max-size-buffers=2 ! stereodepth canopy=tree " +
                           p.stereodepth + " ! " + branch + "tree t. ! queue max-size-buffers=2 " +
                           "! stereodepth canopy=off " + p.stereodepth + " ! " + branch + "off";
  std::vector<TreeFrame> tree, off;
  std::vector<int> layouts;
  for (double x : o.layouts)
    if (x >= 0 && x < double(std::size(kLayouts)))
      layouts.push_back(int(x));
  for (int li : layouts)
    for (double d : parse_list(o.distances))
      for (const auto &[seed, held] : all_seeds(o))
        for (double l : parse_list(o.lights)) {
          TreeFrame base;
          base.c = SceneConfig(o.size, d, std::uint64_t(seed), l, SceneKind::Orchard);
          base.c.row_gap_min_m = kLayouts[li].gap_min_m;
          base.c.row_gap_max_m = kLayouts[li].gap_max_m;
          base.c.row_spacing_m = kLayouts[li].spacing_m;
          base.layout = li;
          base.held_out = held;
          const SceneRenderer renderer(base.c.params());
          const auto on_frame = [&](int frame, const std::vector<GstBuffer *> &buf) {
            const GstTreeStereoGeometryMeta *g = gst_buffer_get_tree_stereo_geometry_meta(buf[0]);
            GroundTruth raw;
            const GroundTruth tr = bench::rectified_truth(renderer, frame, g, &raw);
            TreeFrame t = base;
            t.in_view = cv::countNonZero(raw.canopy_mask) > 0;
            t.t_distance = tr.distance_m;
            t.t_height = tr.canopy_height_m;
            t.t_width = tr.canopy_width_m;
            const TreeFrame a = tree_frame(t, gst_buffer_get_tree_stereo_metrics_meta(buf[0]));
            const TreeFrame b = tree_frame(t, gst_buffer_get_tree_stereo_metrics_meta(buf[1]));
            tree.push_back(a);
            off.push_back(b);
            const double eh = a.present ? (a.height - a.t_height) / a.t_height : 0;
            const double ew = a.present ? (a.width - a.t_width) / a.t_width : 0;
            const double ed = a.present ? (a.distance - a.t_distance) / a.t_distance : 0;
            std::fprintf(
                stderr,
                "orchard [%s] seed=%llu%s d=%.1f light=%.1f: %s distance %.4f (truth "
                "%.4f) height %.3f (%.3f) width %.3f (%.3f) clipped %u conf %.2f | "
                "canopy=off: %s height %.3f width %.3f\n",
                kLayouts[li].name, (unsigned long long)a.c.seed, a.held_out ? "h" : "", d, l,
                a.present   ? "tree"
                : a.in_view ? "NO TREE"
                            : "none in view",
                a.distance, a.t_distance, a.height, a.t_height, a.width, a.t_width, a.clipped,
                a.confidence, b.present ? "tree" : "NO TREE", b.height, b.width);
            const bool bad = (a.in_view && !a.present) || std::abs(ed) > 0.05 ||
                             (!height_clipped(a.clipped) && std::abs(eh) > 0.10) ||
                             (!width_clipped(a.clipped) && std::abs(ew) > 0.10);
            if (bad && g && !o.masks.empty() && saved_masks < kMaxSavedMasks) {
              const GstTreeStereoCanopyMeta *cm = gst_buffer_get_tree_stereo_canopy_meta(buf[0]);
              const TruthRectifier rect(rig.calibration(), *g);
              const MappedMask chain(cm ? cm->view : GstTreeStereoVegetationView{});
              char path[512];
              std::snprintf(path, sizeof path, "%s/orchard-l%d-seed%llu-d%.1f-light%.1f.png",
                            o.masks.c_str(), li, (unsigned long long)a.c.seed, d, l);
              save_overlay(buf[0], *g, chain.mat, rect(raw.canopy_mask), path);
              std::fprintf(stderr, "  saved %s (red: chain canopy, blue: truth)\n", path);
              saved_masks++;
            }
          };
          bench::run_chain(bench::chain_description(base.c, 1, rig.path(), p, tail),
                           {"tree", "off"}, on_frame, "bench-orchard");
        }

  std::printf("### Orchard: the tree in front (stereodepth canopy=tree)\n\n");
  std::printf("scene orchard, %dx%d, distances %s m, lights %s, tuning seeds %s, held-out seeds "
              "%s; row layouts: ",
              o.size.width, o.size.height, o.distances.c_str(), o.lights.c_str(),
              seeds_text(o.tuning).c_str(), seeds_text(o.held_out).c_str());
  for (int li : layouts)
    std::printf("%s%s", kLayouts[li].name, li == layouts.back() ? "" : "; ");
  std::printf(". Element properties: %s. Baseline: the same frames through stereodepth "
              "canopy=off (the colour silhouette).\n\n",
              common_props(o).c_str());
  std::printf("| seeds | row layout / canopy | frames | answered / tree in view | answered "
              "without a tree | height \\|err\\| %% mean / worst | width \\|err\\| %% mean / worst "
              "| distance \\|err\\| %% mean / worst | clipped height / width |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|\n");
  const char *sets[] = {"tuning", "held-out", "all"};
  for (int s = 0; s < 3; s++) {
    const auto in_set = [&](const TreeFrame &f) { return s == 2 || f.held_out == (s == 1); };
    for (int k = -1; k < int(layouts.size()); k++) {
      const int li = k < 0 ? -1 : layouts[std::size_t(k)];
      TreeErrors e;
      for (const TreeFrame &f : tree)
        if (in_set(f) && (li < 0 || f.layout == li))
          e.add(f);
      print_tree_row(sets[s], li < 0 ? "all layouts, canopy=tree" : kLayouts[li].name, e);
    }
    TreeErrors e;
    for (const TreeFrame &f : off)
      if (in_set(f))
        e.add(f);
    print_tree_row(sets[s], "all layouts, **canopy=off** (colour only)", e);
  }

  // The worst frames, to look at.
  std::vector<const TreeFrame *> worst;
  for (const TreeFrame &f : tree)
    worst.push_back(&f);
  const auto badness = [](const TreeFrame *f) {
    if (!f->present)
      return f->in_view ? 1e9 : 0.0;
    double b = std::abs(f->distance - f->t_distance) / f->t_distance;
    if (!height_clipped(f->clipped))
      b = std::max(b, std::abs(f->height - f->t_height) / f->t_height);
    if (!width_clipped(f->clipped))
      b = std::max(b, std::abs(f->width - f->t_width) / f->t_width);
    return b;
  };
  std::sort(worst.begin(), worst.end(),
            [&](const TreeFrame *a, const TreeFrame *b) { return badness(a) > badness(b); });
  std::printf("\nThe worst frames (canopy=tree; errors of clipped extents in brackets):\n\n");
  std::printf("| row layout | seed | distance (m) | light | answered | height err %% | width "
              "err %% | distance err %% | clipped |\n|---|---|---|---|---|---|---|---|---|\n");
  for (std::size_t i = 0; i < std::min<std::size_t>(8, worst.size()); i++) {
    const TreeFrame &f = *worst[i];
    const auto err = [](double v, double t, bool clipped) {
      char b[32];
      std::snprintf(b, sizeof b, clipped ? "(%+.1f)" : "%+.1f", 100 * (v - t) / t);
      return std::string(b);
    };
    std::printf("| %s | %llu | %.1f | %.1f | %s | %s | %s | %s | %u |\n", kLayouts[f.layout].name,
                (unsigned long long)f.c.seed, f.c.distance_m, f.c.light,
                f.present   ? "yes"
                : f.in_view ? "**no**"
                            : "no (none in view)",
                f.present ? err(f.height, f.t_height, height_clipped(f.clipped)).c_str() : "-",
                f.present ? err(f.width, f.t_width, width_clipped(f.clipped)).c_str() : "-",
                f.present ? err(f.distance, f.t_distance, false).c_str() : "-", f.clipped);
  }
  std::printf("\n");
}

void hedgerow_sweep(const Options &o)
{
  const RigFile rig(o.size);
  const ElementProps &p = o.props;
  const std::string tail = "stereodepth canopy=row " + p.stereodepth +
                           " ! treemetrics post-messages=false " + p.treemetrics +
                           " ! appsink sync=false name=out";
  std::vector<BandRecord> bands;
  std::vector<HedgeFrame> frames;
  int n_bands = 0;
  for (double d : parse_list(o.hedge_distances))
    for (const auto &[seed, held] : all_seeds(o))
      for (double l : parse_list(o.hedge_lights)) {
        BandRecord base;
        base.c = SceneConfig(o.size, d, std::uint64_t(seed), l, SceneKind::Hedgerow);
        base.held_out = held;
        const SceneRenderer renderer(base.c.params());
        const auto on_frame = [&](int frame, const std::vector<GstBuffer *> &buf) {
          const GstTreeStereoGeometryMeta *g = gst_buffer_get_tree_stereo_geometry_meta(buf[0]);
          const GstTreeStereoMetricsMeta *m = gst_buffer_get_tree_stereo_metrics_meta(buf[0]);
          const GstTreeStereoCanopyMeta *cm = gst_buffer_get_tree_stereo_canopy_meta(buf[0]);
          GroundTruth raw;
          const GroundTruth tr = bench::rectified_truth(renderer, frame, g, &raw);
          HedgeFrame hf{base.c, base.held_out, cv::countNonZero(raw.row_mask) > 0, false};
          if (g && m && cm && m->metrics.tree_present) {
            hf.present = true;
            const TruthRectifier rect(rig.calibration(), *g);
            const MappedMask chain(cm->view);
            const cv::Mat truth_rows = rect(raw.row_mask);
            const std::vector<BandRecord> r =
                band_truth(base, m->metrics, chain.mat, truth_rows, tr, *g);
            n_bands = std::max(n_bands, int(r.size()));
            bool bad = false;
            for (const BandRecord &b : r) {
              std::fprintf(stderr,
                           "hedgerow seed=%llu%s d=%.1f band %d: %s depth %.4f (truth %.4f, %zu "
                           "pts; seen by both views %.4f) fill %.3f (truth %.3f)\n",
                           (unsigned long long)b.c.seed, b.held_out ? "h" : "", d, b.band,
                           b.present ? "" : "absent", b.depth, b.t_depth, b.t_points,
                           b.t_depth_stereo, b.fill, b.t_fill);
              bad = bad ||
                    (b.present && b.t_points > 0 &&
                     std::abs(b.depth - b.t_depth) / b.t_depth > 0.02) ||
                    (b.present && std::abs(b.fill - b.t_fill) > 0.1);
            }
            bands.insert(bands.end(), r.begin(), r.end());
            if (bad && !o.masks.empty() && saved_masks < kMaxSavedMasks) {
              char path[512];
              std::snprintf(path, sizeof path, "%s/hedgerow-seed%llu-d%.1f.png", o.masks.c_str(),
                            (unsigned long long)base.c.seed, d);
              save_overlay(buf[0], *g, chain.mat, truth_rows, path);
              std::fprintf(stderr, "  saved %s (red: chain canopy, blue: truth near row)\n", path);
              saved_masks++;
            }
          } else {
            std::fprintf(stderr, "hedgerow seed=%llu d=%.1f: NO CANOPY\n",
                         (unsigned long long)base.c.seed, d);
          }
          frames.push_back(hf);
        };
        bench::run_chain(bench::chain_description(base.c, 1, rig.path(), p, tail), {"out"},
                         on_frame, "bench-orchard");
      }

  std::printf("### Hedgerow: the near row per band (stereodepth canopy=row)\n\n");
  std::printf("scene hedgerow, %dx%d, distances %s m, lights %s, tuning seeds %s, held-out seeds "
              "%s. Element properties: %s. Truth over the chain's own band rows: fill = "
              "band_fill() of the rectified truth near-row mask, near-face depth = p05 of Z of "
              "the truth's visible near-row points in those rows. Targets: depth within 2 %%, "
              "fill within 0.1.\n\n",
              o.size.width, o.size.height, o.hedge_distances.c_str(), o.hedge_lights.c_str(),
              seeds_text(o.tuning).c_str(), seeds_text(o.held_out).c_str(),
              common_props(o).c_str());
  std::printf("| seeds | band | frames answered / row in view | bands | near-face depth "
              "\\|err\\| %% mean / worst | the same, truth seen by both views | fill \\|err\\| "
              "mean / worst |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  const char *sets[] = {"tuning", "held-out", "all"};
  for (int s = 0; s < 3; s++) {
    int answered = 0, in_view = 0;
    for (const HedgeFrame &f : frames)
      if (s == 2 || f.held_out == (s == 1)) {
        answered += f.present && f.in_view;
        in_view += f.in_view;
      }
    for (int band = -1; band < n_bands; band++) {
      BandErrors e;
      for (const BandRecord &r : bands)
        if ((s == 2 || r.held_out == (s == 1)) && (band < 0 || r.band == band))
          e.add(r);
      std::printf(
          "| %s | %s | %d / %d | %d%s | %s | %s | %s |\n", sets[s],
          band < 0 ? "all" : std::to_string(band + 1).c_str(), answered, in_view, e.bands,
          e.no_truth ? (" (" + std::to_string(e.no_truth) + " no truth depth)").c_str() : "",
          e.depth.cell().c_str(), e.depth_stereo.cell().c_str(), e.fill.cell(1.0, 3).c_str());
    }
  }
  std::printf("\n");
}

} // namespace

// ---- Drive-by sweep (travel, tree records, row map) ----

// A tree record as the chain posted it (the treestereo-tree message).
struct ChainTree {
  double position = 0, start = 0, end = 0, height = 0, width = 0;
  bool complete = false;
};

struct DrivebyRun {
  SceneConfig c;
  bool held_out = false;
  int frames = 0;
  double true_position = 0, position = 0;   // since the start, at the last frame (m)
  int true_trees = 0, chain_trees = 0;      // trees fully in view at some frame; complete records
  std::vector<double> pos_err_cm, height_err, width_err; // matched trees
  int gaps = 0, gaps_seen = 0;              // true gaps of 10 cm and more; of them, in the map
  // spraycontrol (defaults: one section per band of the map), against the renderer's canopy
  // per band: switch errors along the row (mm), the sprayed length's error per section (%),
  // true switches without a command of the chain and commands without a true switch, gaps of
  // 10 cm and more the valve closed in.
  std::vector<double> switch_err_mm, length_err;
  int switches_missed = 0, switches_extra = 0, spray_gaps = 0, spray_gaps_closed = 0;
};

// The truth of spraycontrol's commands: per band of the row map (heights above the ground), the
// near row's canopy along the row as the left camera sees it within the rectified left view
// (GroundTruth::row_points_mm of every frame whose rectified pixel lies in the view: the
// rendered view is wider, and canopy only its margin shows is no stereo chain's to see), gaps
// shorter than min_gap closed, canopy shorter than min_canopy dropped (SprayParams' defaults, as
// spraycontrol's). The points are gathered in 10 mm bins along the row, and each bin
// keeps its lowest and highest x: a stretch of canopy runs from its first bin's lowest point to
// its last bin's highest, not to the bins' edges (which would lengthen every stretch by one bin,
// 10 mm, on average).
struct SprayTruth {
  static constexpr double kBinMm = 10;
  double lo_mm = 0;
  std::vector<double> band_edges_mm;
  std::vector<std::vector<bool>> present;     // [band][bin]
  std::vector<std::vector<double>> lo_x, hi_x; // [band][bin]: the bin's extreme points' x (mm)

  SprayTruth(double lo_mm_, double hi_mm, const RowMapParams &map)
      : lo_mm(lo_mm_), band_edges_mm(RowMap(map).band_edges_mm())
  {
    const std::size_t bins = std::size_t((hi_mm - lo_mm) / kBinMm) + 1;
    present.assign(band_edges_mm.size() - 1, std::vector<bool>(bins));
    lo_x.assign(present.size(), std::vector<double>(bins, 0));
    hi_x = lo_x;
  }
  // `view`: the chain's rectified geometry (R1, fx, fy, cx, cy, view size).
  void add(const GroundTruth &t, double travel_mm, double camera_height_mm,
           const StereoGeometry &view)
  {
    const double fy = view.fy > 0 ? view.fy : view.fx;
    for (const cv::Point3f &q : t.row_points_mm) {
      const cv::Vec3d r = view.R1 * cv::Vec3d(q.x, q.y, q.z);
      const double u = view.fx * r[0] / r[2] + view.cx[0], v = fy * r[1] / r[2] + view.cy;
      if (!(r[2] > 0) || u < -0.5 || v < -0.5 || u >= view.view_size.width - 0.5 ||
          v >= view.view_size.height - 0.5)
        continue;
      const double h = camera_height_mm - q.y, x = travel_mm + q.x;
      const long bin = std::lround(std::floor((x - lo_mm) / kBinMm));
      if (bin < 0 || bin >= long(present[0].size()))
        continue;
      const std::size_t i = std::size_t(bin);
      for (std::size_t b = 0; b + 1 < band_edges_mm.size(); ++b) {
        if (h < band_edges_mm[b] || h >= band_edges_mm[b + 1])
          continue;
        if (!present[b][i]) {
          present[b][i] = true;
          lo_x[b][i] = hi_x[b][i] = x;
        } else {
          lo_x[b][i] = std::min(lo_x[b][i], x);
          hi_x[b][i] = std::max(hi_x[b][i], x);
        }
      }
    }
  }
  // The sprayed intervals of band b (world x, mm).
  std::vector<std::pair<double, double>> intervals(std::size_t b, const SprayParams &sp) const
  {
    std::vector<std::pair<double, double>> runs;
    const auto &v = present[b];
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (!v[i])
        continue;
      const double a = lo_x[b][i], e = hi_x[b][i];
      if (!runs.empty() && a - runs.back().second < sp.min_gap_m * 1000)
        runs.back().second = e;
      else
        runs.emplace_back(a, e);
    }
    std::vector<std::pair<double, double>> out;
    for (const auto &r : runs)
      if (r.second - r.first >= sp.min_canopy_m * 1000)
        out.push_back(r);
    return out;
  }
};

// spraycontrol's commands of a run against SprayTruth over world x in [w_lo, w_hi] (mm). A
// command's switch along the row is where the nozzle is when the valve has switched: the rig's
// true position at at_ns + the valve latency, minus the nozzle offset.
void score_spray(DrivebyRun &run, const SprayTruth &truth,
                 const std::vector<GstTreeStereoSectionCommand> &cmds, double speed_mm_s,
                 double w_lo, double w_hi)
{
  const SprayParams sp;
  const double latency_s = double(sp.valve_latency_ns) * 1e-9;
  const double match_mm = 300;
  for (std::size_t b = 0; b < truth.present.size(); ++b) {
    // The chain's switches of this section, in order, as world x.
    std::vector<std::pair<double, bool>> sw;
    for (const auto &c : cmds)
      if (c.section == b && !c.fallback)
        sw.emplace_back((double(c.at_ns) * 1e-9 + latency_s) * speed_mm_s -
                            sp.nozzle_offset_m * 1000,
                        c.on != FALSE);
    std::stable_sort(sw.begin(), sw.end());
    const auto iv = truth.intervals(b, sp);
    std::vector<std::pair<double, bool>> edges;
    for (const auto &r : iv) {
      if (r.first > w_lo && r.first < w_hi)
        edges.emplace_back(r.first, true);
      if (r.second > w_lo && r.second < w_hi)
        edges.emplace_back(r.second, false);
    }
    std::vector<bool> used(sw.size(), false);
    for (const auto &[x, on] : edges) {
      std::size_t best = sw.size();
      for (std::size_t i = 0; i < sw.size(); ++i)
        if (!used[i] && sw[i].second == on && std::abs(sw[i].first - x) <= match_mm &&
            (best == sw.size() || std::abs(sw[i].first - x) < std::abs(sw[best].first - x)))
          best = i;
      if (best == sw.size()) {
        ++run.switches_missed;
        continue;
      }
      used[best] = true;
      run.switch_err_mm.push_back(sw[best].first - x);
    }
    for (std::size_t i = 0; i < sw.size(); ++i)
      if (!used[i] && sw[i].first > w_lo + match_mm && sw[i].first < w_hi - match_mm)
        ++run.switches_extra;
    // Sprayed length within the window: the chain's open stretches against the truth's.
    auto clip = [&](double a, double e) { return std::max(0.0, std::min(e, w_hi) - std::max(a, w_lo)); };
    double chain_len = 0, true_len = 0;
    bool open = false;
    double from = 0;
    for (const auto &[x, on] : sw) {
      if (on && !open)
        from = x;
      else if (!on && open)
        chain_len += clip(from, x);
      open = on;
    }
    if (open)
      chain_len += clip(from, w_hi);
    std::string chain_runs, true_runs;
    char buf[64];
    for (std::size_t i = 0; i < sw.size(); ++i)
      if (sw[i].second && (i == 0 || !sw[i - 1].second)) {
        std::size_t j = i + 1;
        while (j < sw.size() && sw[j].second)
          ++j;
        std::snprintf(buf, sizeof buf, " %.3f..%.3f", sw[i].first * 1e-3,
                      (j < sw.size() ? sw[j].first : w_hi) * 1e-3);
        chain_runs += buf;
      }
    for (const auto &r : iv) {
      true_len += clip(r.first, r.second);
      std::snprintf(buf, sizeof buf, " %.3f..%.3f", r.first * 1e-3, r.second * 1e-3);
      true_runs += buf;
    }
    std::fprintf(stderr, "driveby seed=%llu: section %zu stretches (m), chain:%s; truth:%s\n",
                 (unsigned long long)run.c.seed, b, chain_runs.c_str(), true_runs.c_str());
    if (true_len > 0)
      run.length_err.push_back(100 * (chain_len - true_len) / true_len);
    std::fprintf(stderr, "driveby seed=%llu: section %zu sprayed %.0f mm (truth %.0f mm, %+.1f %%) "
                 "in %zu switches (truth %zu stretches)\n",
                 (unsigned long long)run.c.seed, b, chain_len, true_len,
                 true_len > 0 ? 100 * (chain_len - true_len) / true_len : 0.0, sw.size(),
                 iv.size());
    // Gaps of 10 cm and more between sprayed stretches: the valve is closed at the gap's middle.
    for (std::size_t i = 0; i + 1 < iv.size(); ++i) {
      const double g0 = iv[i].second, g1 = iv[i + 1].first, mid = 0.5 * (g0 + g1);
      if (g1 - g0 < 100 || mid < w_lo || mid > w_hi)
        continue;
      ++run.spray_gaps;
      bool state = false;
      for (const auto &[x, on] : sw)
        if (x <= mid)
          state = on;
      run.spray_gaps_closed += !state;
    }
  }
}

void driveby_sweep(const Options &o)
{
  const RigFile rig(o.size);
  const double fx = rig.calibration().M1.at<double>(0, 0);
  const double cx = rig.calibration().M1.at<double>(0, 2);
  const ElementProps &p = o.props;
  std::vector<DrivebyRun> runs;
  gchar *dir = g_dir_make_tmp("bench-orchard-map-XXXXXX", nullptr);
  const std::string map_csv = std::string(dir) + "/map.csv";
  for (double speed : parse_list(o.speeds))
    for (const auto &[seed, held] : all_seeds(o)) {
      DrivebyRun run;
      run.c = SceneConfig(o.size, o.driveby_distance, std::uint64_t(seed), 1.0,
                          SceneKind::Orchard);
      run.c.row_gap_min_m = 0.15;
      run.c.row_gap_max_m = 0.8;
      run.c.speed_m_s = speed;
      run.c.touching_pair = 2;
      run.held_out = held;
      const SceneRenderer renderer(run.c.params());
      // Enough frames for trees 0..5 to pass through the view.
      const auto ahead = renderer.row_trees(-1000, 12000);
      double end6 = 0;
      for (const RowTree &t : ahead)
        if (t.index == 5)
          end6 = t.end_m;
      const double half_view = 0.5 * o.size.width / fx * o.driveby_distance;
      const double step = renderer.travel_mm(1) / 1000.0;
      run.frames = int(std::ceil((end6 + half_view + 0.1) / step)) + 1;
      // Trees fully in view at some frame (view edges at each tree's own near-face distance).
      const double last = renderer.travel_mm(std::uint64_t(run.frames - 1)) / 1000.0;
      std::vector<RowTree> truth;
      for (const RowTree &t : renderer.row_trees(-3000, 1000 * (last + 3))) {
        const double l = (0 - cx) / fx * t.distance_m, r = (o.size.width - cx) / fx * t.distance_m;
        // visible in full at frame k when start >= travel_k + l and end <= travel_k + r
        const double k_lo = (t.end_m - r) / step, k_hi = (t.start_m - l) / step;
        if (std::ceil(std::max(0.0, k_lo)) <= std::floor(std::min(double(run.frames - 1), k_hi)))
          truth.push_back(t);
      }
      run.true_trees = int(truth.size());
      run.true_position = last;
      std::vector<ChainTree> chain;
      const std::string tail = "stereodepth canopy=tree " + p.stereodepth +
                               " ! treemetrics row-map-location=" + map_csv + " " +
                               p.treemetrics + " ! spraycontrol ! appsink sync=false name=out";
      std::vector<GstTreeStereoSectionCommand> commands;
      const RowMapParams map_params;
      SprayTruth spray_truth(-3000, 1000 * (last + 3), map_params);
      const StereoGeometry view = compute_rectification(rig.calibration(), o.size).geometry;
      std::vector<int> front(std::size_t(run.frames), 0); // each frame's tree in front
      for (int k = 0; k < run.frames; ++k) {
        cv::Mat rgb;
        GroundTruth gt;
        renderer.render(LEFT, std::uint64_t(k), rgb, &gt);
        spray_truth.add(gt, renderer.travel_mm(std::uint64_t(k)), run.c.params().camera_height_mm,
                        view);
        front[std::size_t(k)] = gt.front_tree;
      }
      const auto on_frame = [&](int frame, const std::vector<GstBuffer *> &buf) {
        // With --masks: every frame's 3D canopy (red) against the true near row (blue).
        const auto *g = gst_buffer_get_tree_stereo_geometry_meta(buf[0]);
        if (!o.masks.empty() && g) {
          cv::Mat rgb;
          GroundTruth gt;
          renderer.render(LEFT, std::uint64_t(frame), rgb, &gt);
          const GstTreeStereoCanopyMeta *cm = gst_buffer_get_tree_stereo_canopy_meta(buf[0]);
          const MappedMask chain_mask(cm ? cm->view : GstTreeStereoVegetationView{});
          char path[512];
          std::snprintf(path, sizeof path, "%s/driveby-seed%llu-%.1fms-frame%03d.png",
                        o.masks.c_str(), (unsigned long long)run.c.seed, speed, frame);
          save_overlay(buf[0], *g, chain_mask.mat, TruthRectifier(rig.calibration(), *g)(gt.row_mask),
                       path);
        }
        if (const auto *m = gst_buffer_get_tree_stereo_metrics_meta(buf[0])) {
          run.position = m->metrics.position_m;
          // The near row's segments along the row (world x: the frame's position + X).
          if (const auto *cm = gst_buffer_get_tree_stereo_canopy_meta(buf[0])) {
            std::string segs;
            char b[96];
            for (guint i = 0; i < std::min<guint>(cm->n_stored_segments, GST_TREE_STEREO_MAX_SEGMENTS); ++i) {
              const GstTreeStereoRowSegment &g = cm->segments[i];
              std::snprintf(b, sizeof b, " %s%.3f..%.3f%s%s", g.joined_lo ? "~" : "[",
                            g.lo_m + m->metrics.position_m, g.hi_m + m->metrics.position_m,
                            g.joined_hi ? "~" : "]", g.selected ? "*" : "");
              segs += b;
            }
            std::fprintf(stderr, "driveby seed=%llu speed=%.1f frame %d: segments%s\n",
                         (unsigned long long)run.c.seed, speed, frame, segs.c_str());
          }
          if (m->metrics.tree_present)
            std::fprintf(stderr, "driveby seed=%llu speed=%.1f frame %d: tree in front height "
                         "%.3f width %.3f clipped %u\n",
                         (unsigned long long)run.c.seed, speed, frame, m->metrics.height_m,
                         m->metrics.width_m, m->metrics.clipped);
          // The canopy's top and bottom edges (the bands', camera Y, m) against the tree in
          // front's true ones.
          if (m->metrics.tree_present && m->metrics.n_bands > 0)
            for (const RowTree &t : truth)
              if (t.index == front[std::size_t(frame)])
                std::fprintf(stderr, "driveby seed=%llu speed=%.1f frame %d: tree %d edges top "
                             "%.3f (%.3f) bottom %.3f (%.3f)\n",
                             (unsigned long long)run.c.seed, speed, frame, t.index,
                             m->metrics.bands[0].top_m, t.top_m,
                             m->metrics.bands[m->metrics.n_bands - 1].bottom_m, t.bottom_m);
          std::fprintf(stderr, "driveby seed=%llu speed=%.1f frame %d: travel %.4f m (%s, truth "
                       "%.4f), position %.3f m (truth %.3f)\n",
                       (unsigned long long)run.c.seed, speed, frame, m->metrics.travel_m,
                       gst_tree_stereo_travel_source_to_string(
                           GstTreeStereoTravelSource(m->metrics.travel_source)),
                       frame > 0 ? step : 0.0, m->metrics.position_m,
                       renderer.travel_mm(std::uint64_t(frame)) / 1000.0);
        }
      };
      const auto on_element = [&](GstMessage *msg) {
        const GstStructure *st = gst_message_get_structure(msg);
        GstTreeStereoSectionCommand cmd;
        if (st && gst_tree_stereo_section_message_parse(st, &cmd)) {
          commands.push_back(cmd);
          return;
        }
        GstTreeStereoTreeRecord rec = {};
        if (!st || !gst_structure_has_name(st, GST_TREE_STEREO_MESSAGE_TREE) ||
            !gst_tree_stereo_tree_message_parse(st, &rec, nullptr))
          return;
        ChainTree t;
        t.position = rec.position_m;
        t.start = rec.start_m;
        t.end = rec.end_m;
        t.height = rec.has_height ? rec.height_m : 0;
        t.width = rec.has_width ? rec.width_m : 0;
        t.complete = rec.complete && rec.has_height && rec.has_width;
        chain.push_back(t);
        std::fprintf(stderr,
                     "driveby seed=%llu speed=%.1f: record %u at %.3f m (%.3f..%.3f) complete %d "
                     "height %s width %s frames %u of %u%s\n",
                     (unsigned long long)run.c.seed, speed, rec.id, rec.position_m, rec.start_m,
                     rec.end_m, rec.complete, rec.has_height ? "yes" : "no",
                     rec.has_width ? "yes" : "no", rec.frames, rec.frames_seen,
                     rec.lost ? " lost" : "");
        gst_tree_stereo_tree_record_clear(&rec);
      };
      bench::run_chain(bench::chain_description(run.c, run.frames, rig.path(), p, tail),
                       {"out"}, on_frame, "bench-orchard", on_element);
      for (const ChainTree &t : chain)
        run.chain_trees += t.complete;
      // The sprayer over the stretch whose map is final: from the view's left edge at the start
      // (as far as the nozzles still lie ahead of it) to the rig's last position.
      score_spray(run, spray_truth, commands, speed * 1000, -1000, 1000 * last - 50);
      for (const RowTree &t : truth) {
        const ChainTree *best = nullptr;
        for (const ChainTree &c : chain)
          if (c.complete && (!best || std::abs(c.position - 0.5 * (t.start_m + t.end_m)) <
                                          std::abs(best->position - 0.5 * (t.start_m + t.end_m))))
            best = &c;
        if (!best)
          continue;
        run.pos_err_cm.push_back(100 * (best->position - 0.5 * (t.start_m + t.end_m)));
        run.height_err.push_back(100 * (best->height - t.height_m) / t.height_m);
        run.width_err.push_back(100 * (best->width - t.width_m) / t.width_m);
        std::fprintf(stderr,
                     "driveby seed=%llu%s speed=%.1f: tree %d at %.3f m (chain %.3f) height "
                     "%.3f (%.3f) width %.3f (%.3f)\n",
                     (unsigned long long)run.c.seed, held ? "h" : "", speed, t.index,
                     0.5 * (t.start_m + t.end_m), best->position, best->height, t.height_m,
                     best->width, t.width_m);
      }
      // With --masks: the run's row map (CSV and picture) kept there.
      if (!o.masks.empty()) {
        char name[128];
        std::snprintf(name, sizeof name, "/driveby-seed%llu-%.1fms-map", (unsigned long long)seed,
                      speed);
        for (const char *ext : {".csv", ".png"}) {
          gchar *data = nullptr;
          gsize len = 0;
          const std::string from = std::string(dir) + "/map" + ext, to = o.masks + name + ext;
          if (g_file_get_contents(from.c_str(), &data, &len, nullptr) &&
              g_file_set_contents(to.c_str(), data, gssize(len), nullptr))
            std::fprintf(stderr, "  saved %s\n", to.c_str());
          g_free(data);
        }
      }
      // Gaps of 10 cm and more between consecutive true trees: a 5 cm bin wholly inside the
      // gap is empty in every band of the map.
      std::map<long, bool> bin_present; // bin start (mm) -> any band present
      if (FILE *f = std::fopen(map_csv.c_str(), "r")) {
        char line[256];
        double bin_m = 0.05;
        std::vector<double> starts;
        while (std::fgets(line, sizeof line, f)) {
          double pos = 0, dist = 0, fill = 0;
          int band = 0, present = 0;
          if (std::sscanf(line, "%lf,%d,%d,%lf,%lf", &pos, &band, &present, &dist, &fill) >= 3) {
            auto &v = bin_present[std::lround(pos * 1000)];
            v = v || present;
          }
        }
        std::fclose(f);
        for (std::size_t i = 0; i + 1 < truth.size(); ++i) {
          const double g0 = truth[i].end_m, g1 = truth[i + 1].start_m;
          if (g1 - g0 < 0.10)
            continue;
          ++run.gaps;
          bool seen = false;
          for (const auto &[mm, present] : bin_present) {
            // bin_present's key: the bin's position_m (its centre) in mm
            const double lo = mm / 1000.0 - 0.5 * bin_m, hi = mm / 1000.0 + 0.5 * bin_m;
            if (lo >= g0 && hi <= g1 && !present)
              seen = true;
          }
          run.gaps_seen += seen;
        }
      }
      std::fprintf(stderr,
                   "driveby seed=%llu%s speed=%.1f: %d frames, position %.3f m (truth %.3f), "
                   "trees %d (truth %d), gaps seen %d of %d\n",
                   (unsigned long long)run.c.seed, held ? "h" : "", speed, run.frames,
                   run.position, run.true_position, run.chain_trees, run.true_trees,
                   run.gaps_seen, run.gaps);
      runs.push_back(run);
    }
  g_unlink(map_csv.c_str());
  g_unlink((std::string(dir) + "/map.png").c_str());
  g_rmdir(dir);
  g_free(dir);

  std::printf("### Drive-by: travel, tree records and the row map (stereodepth canopy=tree)\n\n");
  std::printf("scene orchard, %dx%d at 7 frames/s, trunks at %.1f m, gaps 0.15-0.8 m with trees 2 "
              "and 3 touching, speeds %s m/s, tuning seeds %s, held-out seeds %s. Element "
              "properties: %s. Truth: SceneRenderer::row_trees() (trees fully in view at some "
              "frame), travel_mm(). Targets: count exact, positions within 5 cm, height and width "
              "within 2 %%, position since the start within 2 %%, gaps of 10 cm and more in the "
              "map.\n\n",
              o.size.width, o.size.height, o.driveby_distance, o.speeds.c_str(),
              seeds_text(o.tuning).c_str(), seeds_text(o.held_out).c_str(),
              common_props(o).c_str());
  std::printf("| seeds | speed (m/s) | runs | frames | trees chain / truth | position err %% (end) "
              "mean / worst | tree position \\|err\\| cm mean / worst | height \\|err\\| %% "
              "mean / worst | width \\|err\\| %% mean / worst | gaps >= 10 cm in the map |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  auto row = [&](const char *set, int which, double speed) {
    int n = 0, frames = 0, ct = 0, tt = 0, gaps = 0, seen = 0;
    double pe_sum = 0, pe_max = 0;
    std::vector<double> pos, h, w;
    for (const DrivebyRun &r : runs) {
      if ((which == 0 && r.held_out) || (which == 1 && !r.held_out) ||
          (speed > 0 && std::abs(r.c.speed_m_s - speed) > 1e-9))
        continue;
      ++n;
      frames += r.frames;
      ct += r.chain_trees;
      tt += r.true_trees;
      gaps += r.gaps;
      seen += r.gaps_seen;
      const double pe = std::abs(r.position - r.true_position) / r.true_position * 100;
      pe_sum += pe;
      pe_max = std::max(pe_max, pe);
      for (double x : r.pos_err_cm)
        pos.push_back(std::abs(x));
      for (double x : r.height_err)
        h.push_back(std::abs(x));
      for (double x : r.width_err)
        w.push_back(std::abs(x));
    }
    if (!n)
      return;
    auto mw = [](const std::vector<double> &v) {
      char b[64];
      if (v.empty())
        return std::string("-");
      double sum = 0, mx = 0;
      for (double x : v) {
        sum += x;
        mx = std::max(mx, x);
      }
      std::snprintf(b, sizeof b, "%.2f / %.2f", sum / double(v.size()), mx);
      return std::string(b);
    };
    char sp[32];
    std::snprintf(sp, sizeof sp, speed > 0 ? "%.1f" : "all", speed);
    std::printf("| %s | %s | %d | %d | %d / %d | %.2f / %.2f | %s | %s | %s | %d / %d |\n", set, sp,
                n, frames, ct, tt, pe_sum / n, pe_max, mw(pos).c_str(), mw(h).c_str(),
                mw(w).c_str(), seen, gaps);
  };
  for (int which : {0, 1, 2})
    for (double speed : parse_list(o.speeds)) {
      row(which == 0 ? "tuning" : which == 1 ? "held-out" : "all", which, speed);
    }
  row("all", 2, 0);
  std::printf("\n");

  std::printf("### Drive-by: spraycontrol's valve commands (defaults: a section per band of the "
              "map, nozzles 1.5 m behind, 160 ms valves)\n\n");
  std::printf("Truth per band: the near row's visible canopy (GroundTruth::row_points_mm of every "
              "frame, those in the rectified left view) between the band's heights, gaps under 75 "
              "mm closed, canopy under 100 mm dropped, over the stretch from -1 m to the rig's "
              "last position. A switch's place "
              "is where the nozzle is when the valve has switched (the true rig position at at-ns "
              "+ latency, minus the offset). Targets: every switch within one frame's travel, "
              "gaps of 10 cm and more closed, sprayed length within 5 %% per section.\n\n");
  std::printf("| seeds | speed (m/s) | one frame's travel (mm) | switches within it / matched | "
              "switch \\|err\\| mm mean / worst | missed / extra | sprayed length \\|err\\| %% "
              "mean / worst | gaps >= 10 cm closed |\n");
  std::printf("|---|---|---|---|---|---|---|---|\n");
  auto spray_row = [&](const char *set, int which, double speed) {
    std::vector<double> err, len;
    int within = 0, missed = 0, extra = 0, gaps = 0, closed = 0, n = 0;
    for (const DrivebyRun &r : runs) {
      if ((which == 0 && r.held_out) || (which == 1 && !r.held_out) ||
          std::abs(r.c.speed_m_s - speed) > 1e-9)
        continue;
      ++n;
      const double frame_mm = speed * 1000 / 7.0;
      for (double e : r.switch_err_mm) {
        err.push_back(std::abs(e));
        within += std::abs(e) <= frame_mm;
      }
      for (double e : r.length_err)
        len.push_back(std::abs(e));
      missed += r.switches_missed;
      extra += r.switches_extra;
      gaps += r.spray_gaps;
      closed += r.spray_gaps_closed;
    }
    if (!n)
      return;
    auto mw = [](const std::vector<double> &v, const char *fmt) {
      if (v.empty())
        return std::string("-");
      double sum = 0, mx = 0;
      for (double x : v) {
        sum += x;
        mx = std::max(mx, x);
      }
      char b[64];
      std::snprintf(b, sizeof b, fmt, sum / double(v.size()), mx);
      return std::string(b);
    };
    std::printf("| %s | %.1f | %.0f | %d / %zu | %s | %d / %d | %s | %d / %d |\n", set, speed,
                speed * 1000 / 7.0, within, err.size(), mw(err, "%.0f / %.0f").c_str(), missed,
                extra, mw(len, "%.2f / %.2f").c_str(), closed, gaps);
  };
  for (int which : {0, 1})
    for (double speed : parse_list(o.speeds))
      spray_row(which == 0 ? "tuning" : "held-out", which, speed);
  std::printf("\n");
}

int main(int argc, char **argv)
{
  bench::init_gstreamer(argc, argv);
  Options o;
  // exgsegment must keep every vegetation region: the 3D canopy decides which are the tree.
  o.props.exgsegment = "keep=all";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i], v = argv[i + 1];
    if (a == "--only")
      o.only = v;
    else if (a == "--size" && !parse_sizes(v).empty())
      o.size = parse_sizes(v)[0];
    else if (a == "--tuning-seeds")
      o.tuning = parse_list(v);
    else if (a == "--held-out-seeds")
      o.held_out = parse_list(v);
    else if (a == "--distances")
      o.distances = v;
    else if (a == "--lights")
      o.lights = v;
    else if (a == "--hedgerow-distances")
      o.hedge_distances = v;
    else if (a == "--hedgerow-lights")
      o.hedge_lights = v;
    else if (a == "--layouts")
      o.layouts = parse_list(v);
    else if (a == "--masks")
      o.masks = v;
    else if (a == "--speeds")
      o.speeds = v;
    else if (a == "--driveby-distance")
      o.driveby_distance = std::atof(v.c_str());
    else if (!bench::element_option(a, v, o.props) || a == "--treetestsrc") {
      // (--treetestsrc: the scene is the sweep's; free properties would not reach the truth)
      std::fprintf(stderr, "bench-orchard: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  if (!o.masks.empty())
    g_mkdir_with_parents(o.masks.c_str(), 0755);
  std::printf("Command:");
  for (int i = 0; i < argc; i++)
    std::printf(" %s", argv[i]);
  std::printf("\n\n");
  if (o.only.empty() || o.only == "orchard")
    orchard_sweep(o);
  if (o.only.empty() || o.only == "hedgerow")
    hedgerow_sweep(o);
  if (o.only.empty() || o.only == "driveby")
    driveby_sweep(o);
  return 0;
}
