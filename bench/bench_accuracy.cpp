// bench-accuracy: the measuring chain against the synthetic orchard's ground truth, as users run
// it (treetestsrc x2 -> stereorectify -> exgsegment -> siftmatch -> stereodepth -> treemetrics),
// swept over distance, seed, light and frame size. Prints the paper-style distance table and
// the error summary as markdown.
//
//   bench-accuracy [--sizes 1296x972,2592x1944] [--distances 1.5:2.5:0.1] [--seeds 1,2,3]
//                  [--lights 0.7,1.0,1.3] [--frames 1] [--csv FILE]
//                  [--siftmatch "layer-tolerance=-1 ..."] [--exgsegment "unmix-edges=false ..."]
//                  [--stereodepth "edge-band=0 ..."] [--treemetrics "round-limbs=false ..."]
//                  [--scene lab|orchard|hedgerow] [--treetestsrc "row-spacing=4 ..."]
//                  (the elements' properties, gst-launch syntax)
//
// Truth: distance and thickness are the visible canopy surface's median and p95-p05 depth in the
// rectified-left frame (the renderer's truth rotated by the geometry meta's R1), height and width
// the canopy's true 3D extents: the same definitions treemetrics uses.
#include "chain_sweep.hpp"
#include "treestereo/stats.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>
#include <vector>

using namespace treestereo;
using treestereo::bench::ElementProps;
using treestereo::bench::parse_list;
using treestereo::bench::parse_sizes;
using treestereo::bench::RigFile;
using treestereo::bench::SceneConfig;
using treestereo::bench::Sweep;
using treestereo::bench::sweep_option;

namespace {

struct Result {
  SceneConfig c;
  int frame = 0;
  bool present = false;
  double distance = 0, height = 0, width = 0, thickness = 0;
  double t_distance = 0, t_height = 0, t_width = 0, t_thickness = 0;
  unsigned points = 0, clipped = 0;
  double ms_per_frame = 0;
};

std::vector<Result> run_config(const SceneConfig &c, int frames, const std::string &calib,
                               const ElementProps &props)
{
  const std::string tail = "stereodepth " + props.stereodepth + " ! treemetrics post-messages=false " +
                           props.treemetrics + " ! appsink name=out sync=false";
  SceneRenderer renderer(c.params()); // for the truth, in the same frames
  std::vector<Result> out;
  const auto on_frame = [&](int frame, const std::vector<GstBuffer *> &buf) {
    Result r;
    r.c = c;
    r.frame = frame;
    const GstTreeStereoGeometryMeta *g = gst_buffer_get_tree_stereo_geometry_meta(buf[0]);
    const GstTreeStereoMetricsMeta *m = gst_buffer_get_tree_stereo_metrics_meta(buf[0]);
    if (g && m && m->metrics.tree_present) {
      r.present = true;
      r.distance = m->metrics.distance_m;
      r.height = m->metrics.height_m;
      r.width = m->metrics.width_m;
      r.thickness = m->metrics.thickness_m;
      r.points = m->metrics.n_points;
      r.clipped = m->metrics.clipped;
    }
    const GroundTruth tr = bench::rectified_truth(renderer, frame, g);
    r.t_distance = tr.distance_m;
    r.t_thickness = tr.thickness_m;
    r.t_height = tr.canopy_height_m;
    r.t_width = tr.canopy_width_m;
    out.push_back(r);
  };
  const double ms = bench::run_chain(bench::chain_description(c, frames, calib, props, tail),
                                     {"out"}, on_frame, "bench-accuracy");
  for (Result &r : out)
    r.ms_per_frame = ms;
  return out;
}

struct Errors {
  std::vector<double> d, d_rel, h_rel, w_rel, t_rel;
  int frames = 0, present = 0, clipped = 0;
  void add(const Result &r)
  {
    frames++;
    if (!r.present)
      return;
    present++;
    if (r.clipped)
      clipped++;
    d.push_back(r.distance - r.t_distance);
    d_rel.push_back((r.distance - r.t_distance) / r.t_distance);
    if (!r.clipped) {
      h_rel.push_back((r.height - r.t_height) / r.t_height);
      w_rel.push_back((r.width - r.t_width) / r.t_width);
    }
    t_rel.push_back((r.thickness - r.t_thickness) / r.t_thickness);
  }
};

std::string pct(const std::vector<double> &v, bool abs_median = false)
{
  if (v.empty())
    return "-";
  Summary s = summarize(v);
  char b[64];
  if (abs_median) {
    std::vector<double> a;
    for (double x : v)
      a.push_back(std::abs(x));
    std::snprintf(b, sizeof b, "%+.2f / %.2f", 100 * s.mean, 100 * median(a));
  } else {
    std::snprintf(b, sizeof b, "%+.2f ± %.2f", 100 * s.mean, 100 * s.stddev);
  }
  return b;
}

} // namespace

int main(int argc, char **argv)
{
  bench::init_gstreamer(argc, argv);
  Sweep sweep{"1296x972,2592x1944", "1.5:2.5:0.1", "1,2,3", "0.7,1.0,1.3"};
  std::string csv;
  ElementProps props;
  int frames = 1;
  SceneKind scene = SceneKind::Lab;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i], v = argv[i + 1];
    if (sweep_option(a, v, sweep) || bench::element_option(a, v, props))
      continue;
    if (a == "--frames")
      frames = std::stoi(v);
    else if (a == "--csv")
      csv = v;
    else if (a == "--scene")
      scene = scene_kind_from_name(v);
    else {
      std::fprintf(stderr, "bench-accuracy: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  std::vector<Result> all;
  for (const cv::Size &size : parse_sizes(sweep.sizes)) {
    const RigFile rig(size);
    for (double d : parse_list(sweep.distances))
      for (double s : parse_list(sweep.seeds))
        for (double l : parse_list(sweep.lights)) {
          const SceneConfig c(size, d, std::uint64_t(s), l, scene);
          std::vector<Result> r = run_config(c, frames, rig.path(), props);
          for (const Result &x : r)
            std::fprintf(stderr,
                         "%dx%d d=%.1f seed=%llu light=%.1f: %s distance %.4f (truth %.4f) "
                         "height %.3f (%.3f) width %.3f (%.3f) thickness %.3f (%.3f) %u pts "
                         "%.0f ms\n",
                         size.width, size.height, d, (unsigned long long)c.seed, l,
                         x.present ? "tree" : "NO TREE", x.distance, x.t_distance, x.height,
                         x.t_height, x.width, x.t_width, x.thickness, x.t_thickness, x.points,
                         x.ms_per_frame);
          all.insert(all.end(), r.begin(), r.end());
        }
  }

  if (!csv.empty()) {
    std::ofstream f(csv);
    f << "width,height,distance_set_m,seed,light,frame,present,distance_m,truth_distance_m,"
         "height_m,truth_height_m,width_m,truth_width_m,thickness_m,truth_thickness_m,points,"
         "clipped\n";
    for (const Result &r : all)
      f << r.c.size.width << ',' << r.c.size.height << ',' << r.c.distance_m << ',' << r.c.seed
        << ',' << r.c.light << ',' << r.frame << ',' << r.present << ',' << r.distance << ','
        << r.t_distance << ',' << r.height << ',' << r.t_height << ',' << r.width << ','
        << r.t_width << ',' << r.thickness << ',' << r.t_thickness << ',' << r.points << ','
        << r.clipped << '\n';
  }

  // Paper-style table: per size and set distance, the distance error over seeds and lights.
  std::printf("### Distance error by trunk distance\n\n");
  std::printf("| size | trunk distance (m) | frames | tree found | distance error mean (cm) | "
              "std (cm) | height err %% | width err %% | thickness err %% | clipped |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  std::map<std::pair<int, int>, Errors> by_size_near; // 1.8-2.2 m
  std::map<std::pair<int, long>, Errors> by_row;
  for (const Result &r : all) {
    by_row[{r.c.size.width, std::lround(r.c.distance_m * 10)}].add(r);
    if (r.c.distance_m > 1.75 && r.c.distance_m < 2.25)
      by_size_near[{r.c.size.width, r.c.size.height}].add(r);
  }
  for (auto &[key, e] : by_row) {
    Summary d = summarize(e.d);
    std::printf("| %d wide | %.1f | %d | %d | %+.2f | %.2f | %s | %s | %s | %d |\n", key.first,
                key.second / 10.0, e.frames, e.present, 100 * d.mean, 100 * d.stddev,
                pct(e.h_rel).c_str(), pct(e.w_rel).c_str(), pct(e.t_rel).c_str(), e.clipped);
  }
  std::printf("\n### Summary at 1.8-2.2 m (the paper's range)\n\n");
  std::printf("| size | frames | tree found | distance std (cm) | distance bias %% | height err "
              "%% (mean / median abs) | width err %% (mean / median abs) | thickness err %% "
              "(mean / median abs) |\n|---|---|---|---|---|---|---|---|\n");
  for (auto &[key, e] : by_size_near) {
    Summary d = summarize(e.d), dr = summarize(e.d_rel);
    std::printf("| %dx%d | %d | %d | %.2f | %+.2f | %s | %s | %s |\n", key.first, key.second,
                e.frames, e.present, 100 * d.stddev, 100 * dr.mean, pct(e.h_rel, true).c_str(),
                pct(e.w_rel, true).c_str(), pct(e.t_rel, true).c_str());
  }
  return 0;
}
