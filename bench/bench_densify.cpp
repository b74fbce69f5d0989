// bench-densify: does an even sample of the canopy (densify_matches: ZNCC on a grid of mask
// pixels, seeded by the SIFT matches) bring the measured distance and thickness to the visible
// surface's truth? lib/ only, the chain as the elements run it (rectify, exgsegment's defaults,
// siftmatch's defaults with the automatic scale, stereodepth's filter), per scene:
//   - the grid points' depth error against the renderer's truth at the same rectified pixel;
//   - distance, thickness, height and width of compute_tree_metrics from (a) the SIFT points
//     alone (the chain before densification), (b) the grid points alone, (c) both (what the
//     chain now does); and, to see where the remaining errors come from (these use the truth,
//     as a diagnosis, never in the chain): (d) both with the true silhouette (the renderer's
//     canopy mask rectified), (e) the true visible surface with the true silhouette, (f) the grid
//     points within 2 cm of the truth at their pixel, (g) the truth at the kept grid pixels;
//   - the truth's median over the segmented mask, over the grid and over the kept grid pixels
//     (what an even sample of each would give);
//   - the time densify_matches takes.
// Prints markdown tables.
//
//   bench-densify [--sizes 1296x972] [--distances 1.8,2.0,2.2] [--seeds 1,2,3] [--lights 1.0]
//                 [--step 0] [--target 4000] [--half-window 3] [--min-zncc 0.8]
//                 [--margin 0.05] [--lr 1] [--tangent-fraction 0.1] [--tangent-min 15] [--round-limbs 1]
//                 [--morph 5] [--reconstruct 1] [--area-weighted 1] [--outlier-k 3.5]
//                 [--edge-band 0.05] [--edge-step 0] [--extreme-points 6] [--threads N]
//
// --threads 1 runs OpenCV's parallel loops in the calling thread, so that callgrind's
// --toggle-collect (e.g. 'treestereo::densify_matches*') counts all of a function's work.
#include "scene_pairs.hpp"
#include "sweep.hpp"
#include "treestereo/densify.hpp"
#include "treestereo/depth.hpp"
#include "treestereo/match.hpp"
#include "treestereo/metrics.hpp"
#include "treestereo/presets.hpp"
#include "treestereo/rectify.hpp"
#include "treestereo/scene.hpp"
#include "treestereo/segment.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

using namespace treestereo;
using treestereo::bench::parse_list;
using treestereo::bench::parse_sizes;
using treestereo::bench::Sweep;
using treestereo::bench::sweep_option;
using treestereo::bench::render_rectified;
using treestereo::bench::RectifiedRender;
using treestereo::bench::truth_depth_rectified;

namespace {

struct Errs {
  std::vector<double> d_cm, d_rel, h, w, t;
};

std::string ms(const std::vector<double> &v)
{
  char b[64];
  const Summary s = summarize(v);
  std::snprintf(b, sizeof b, "%+.2f ± %.2f", s.mean, s.stddev);
  return b;
}

} // namespace

int main(int argc, char **argv)
{
  Sweep sweep{"1296x972", "1.8,2.0,2.2", "1,2,3", "1.0"};
  DensifyParams dp;
  MetricsParams mpar;
  SegmentParams segp;
  DepthParams depth_params;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i], v = argv[i + 1];
    if (sweep_option(a, v, sweep))
      continue;
    if (a == "--step")
      dp.step = std::stoi(v);
    else if (a == "--target")
      dp.target_points = std::stoi(v);
    else if (a == "--half-window")
      dp.half_window = std::stoi(v);
    else if (a == "--min-zncc")
      dp.min_zncc = std::stod(v);
    else if (a == "--margin")
      dp.min_margin = std::stod(v);
    else if (a == "--tangent-fraction")
      mpar.tangent_fraction = std::stod(v);
    else if (a == "--tangent-min")
      mpar.tangent_min_points = std::stoi(v);
    else if (a == "--round-limbs")
      mpar.round_limbs = std::stoi(v) != 0;
    else if (a == "--area-weighted")
      mpar.area_weighted = std::stoi(v) != 0;
    else if (a == "--outlier-k")
      depth_params.outlier_k = std::stod(v);
    else if (a == "--morph")
      segp.morph_size = std::stoi(v);
    else if (a == "--reconstruct")
      segp.reconstruct = std::stoi(v) != 0;
    else if (a == "--extreme-points")
      mpar.extreme_points = std::stoi(v);
    else if (a == "--edge-band")
      dp.edge_band = std::stod(v);
    else if (a == "--edge-step")
      dp.edge_step = std::stoi(v);
    else if (a == "--lr")
      dp.left_right_check = std::stoi(v) != 0;
    else if (a == "--threads")
      cv::setNumThreads(std::stoi(v));
    else {
      std::fprintf(stderr, "bench-densify: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  const char *variants[] = {"SIFT points", "grid points", "SIFT + grid",
                            "SIFT + grid, true mask", "true points, true mask",
                            "grid points within 2 cm of truth (oracle), true mask",
                            "truth at the kept grid pixels, true mask"};
  std::map<int, Errs> errs;
  std::vector<double> point_err_med, point_err_bad, densify_ms, kept_frac;
  std::printf("| size | d (m) | seed | light | SIFT pts | grid | kept | flat | weak | ambiguous | "
              "inconsistent | step | disp window | grid pt err median (mm) | p05..p95 (mm) | "
              "|err| > 2 cm | densify ms | truth dist (m) | SIFT dist err (cm) | grid dist err "
              "(cm) |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const cv::Size &size : parse_sizes(sweep.sizes))
    for (double d : parse_list(sweep.distances))
      for (double sd : parse_list(sweep.seeds))
        for (double light : parse_list(sweep.lights)) {
          SceneParams p;
          p.image_size = size;
          p.distance_mm = d * 1000;
          p.seed = std::uint64_t(sd);
          p.light = light;
          SceneRenderer r(p);
          const RectifiedRender rr = render_rectified(r, p.image_size);
          const StereoRectification &rect = rr.rect;
          const StereoGeometry &g = rect.geometry;
          const cv::Mat *rv = rr.view;
          const GroundTruth &t = rr.truth_left;
          const Silhouette segl = segment_vegetation(rv[LEFT], segp);
          const Silhouette segr = segment_vegetation(rv[RIGHT], segp);
          MatchParams mp;
          const DisparityRange dr = disparity_range_for_depth(g, 500, 10000);
          mp.matcher.constraints.min_disparity = dr.min;
          mp.matcher.constraints.max_disparity = dr.max;
          mp.detect.scale = SiftmatchPreset::auto_scale(size.width);
          const StereoMatchResult mr = match_stereo(rv[LEFT], rv[RIGHT], segl.mask, segr.mask, mp);

          const auto t0 = std::chrono::steady_clock::now();
          DensifyStats ds;
          const std::vector<StereoMatch> grid =
              densify_matches(rv[LEFT], rv[RIGHT], segl.mask, mr.matches, dp, &ds);
          const double t_ms =
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
          densify_ms.push_back(t_ms);

          std::vector<StereoMatch> both = mr.matches;
          both.insert(both.end(), grid.begin(), grid.end());
          const DepthResult sift = triangulate_matches(mr.matches, g, depth_params);
          const DepthResult dense = triangulate_matches(grid, g, depth_params);
          const DepthResult all = triangulate_matches(both, g, depth_params);

          const cv::Mat zt = truth_depth_rectified(r, t, g);
          std::vector<double> pe, pe_abs;
          for (const Point3 &q : dense.points) {
            if (!q.valid)
              continue;
            const StereoMatch &m = grid[q.match_index];
            const float z = zt.at<float>(int(m.yl), int(m.xl));
            if (z > 0) {
              pe.push_back(q.z - z);
              pe_abs.push_back(std::abs(q.z - z) > 20.0 ? 1.0 : 0.0);
            }
          }
          // Sampling limits: the truth's median over the segmented mask (a perfect even sample
          // of it), over every grid pixel, and over the kept grid pixels (selection by the tests).
          std::vector<double> z_mask, z_grid, z_kept;
          for (int y = 0; y < zt.rows; ++y)
            for (int x = 0; x < zt.cols; ++x) {
              const float z = zt.at<float>(y, x);
              if (z > 0 && segl.mask.at<uchar>(y, x)) {
                z_mask.push_back(z);
                if (ds.step > 0 && (y - ds.step / 2) % ds.step == 0 &&
                    (x - ds.step / 2) % ds.step == 0)
                  z_grid.push_back(z);
              }
            }
          for (const StereoMatch &m : grid) {
            const float z = zt.at<float>(int(m.yl), int(m.xl));
            if (z > 0)
              z_kept.push_back(z);
          }
          const Summary pes = summarize(pe);
          const Summary bad = summarize(pe_abs);
          point_err_med.push_back(pes.median);
          point_err_bad.push_back(100 * bad.mean);
          kept_frac.push_back(ds.grid ? 100.0 * double(ds.kept) / double(ds.grid) : 0.0);

          const GroundTruth tr = truth_in_frame(t, g.R1);
          // Where the extents' error comes from: the silhouette (the renderer's canopy mask
          // rectified as the views are) or the points (the visible surface's true points).
          Silhouette tsil;
          tsil.present = true;
          rectify_view(rect, LEFT, t.canopy_mask, tsil.mask);
          cv::threshold(tsil.mask, tsil.mask, 127, 255, cv::THRESH_BINARY);
          std::vector<Point3> tpts;
          for (std::size_t i = 0; i < tr.canopy_points_mm.size(); i += 7) {
            Point3 q;
            q.x = tr.canopy_points_mm[i].x;
            q.y = tr.canopy_points_mm[i].y;
            q.z = tr.canopy_points_mm[i].z;
            tpts.push_back(q);
          }
          // Diagnosis only (uses the truth): the grid points whose depth is within 2 cm of the
          // truth at their pixel, to see what the wrong ones cost.
          std::vector<Point3> good;
          for (const Point3 &q : dense.points) {
            const StereoMatch &m = grid[q.match_index];
            const float z = zt.at<float>(int(m.yl), int(m.xl));
            if (q.valid && z > 0 && std::abs(q.z - z) <= 20.0)
              good.push_back(q);
          }
          std::vector<Point3> at_grid;
          for (const StereoMatch &m : grid) {
            const float z = zt.at<float>(int(m.yl), int(m.xl));
            if (z <= 0)
              continue;
            Point3 q;
            q.z = z;
            q.x = float((m.xl - g.cx[LEFT]) * z / g.fx);
            q.y = float((m.yl - g.cy) * z / g.fy);
            at_grid.push_back(q);
          }
          double dist_err[7] = {0, 0, 0, 0, 0, 0, 0};
          const std::vector<Point3> *pts[7] = {&sift.points, &dense.points, &all.points,
                                               &all.points, &tpts, &good, &at_grid};
          for (int k = 0; k < 7; ++k) {
            const TreeMetrics m = compute_tree_metrics(k < 3 ? segl : tsil, *pts[k], g, mpar);
            Errs &e = errs[k];
            dist_err[k] = 100 * (m.distance_m - tr.distance_m);
            e.d_cm.push_back(dist_err[k]);
            e.d_rel.push_back(100 * (m.distance_m - tr.distance_m) / tr.distance_m);
            e.t.push_back(100 * (m.thickness_m - tr.thickness_m) / tr.thickness_m);
            if (!m.clipped.any()) {
              e.h.push_back(100 * (m.height_m - tr.canopy_height_m) / tr.canopy_height_m);
              e.w.push_back(100 * (m.width_m - tr.canopy_width_m) / tr.canopy_width_m);
            }
          }
          std::printf("| %dx%d | %.1f | %d | %.1f | %zu | %zu | %zu | %zu | %zu | %zu | %zu | %d | "
                      "%d..%d | %+.2f | %+.1f..%+.1f | %.1f %% | %.1f | %.4f | %+.2f | %+.2f |\n",
                      size.width, size.height, d, int(sd), light, mr.matches.size(), ds.grid,
                      ds.kept, ds.flat, ds.weak, ds.ambiguous, ds.inconsistent, ds.step,
                      ds.min_disparity, ds.max_disparity, pes.median, pes.p05, pes.p95,
                      100 * bad.mean, t_ms, tr.distance_m, dist_err[0], dist_err[1]);
          std::printf("truth median: canopy %.1f mm, seg mask %.1f, grid px %.1f, kept grid px %.1f\n",
                      tr.distance_m * 1000, median(z_mask), median(z_grid), median(z_kept));
          std::fflush(stdout);
        }
  std::printf("\n| points | scenes | distance err mean (cm) | std (cm) | bias %% | height err %% | "
              "width err %% | thickness err %% |\n|---|---|---|---|---|---|---|---|\n");
  for (auto &[k, e] : errs) {
    const Summary s = summarize(e.d_cm), r = summarize(e.d_rel);
    std::printf("| %s | %zu | %+.2f | %.2f | %+.2f | %s | %s | %s |\n", variants[k], s.n, s.mean,
                s.stddev, r.mean, ms(e.h).c_str(), ms(e.w).c_str(), ms(e.t).c_str());
  }
  std::printf("\nGrid points: kept %.0f %% of the grid; depth error median %s mm; |err| > 2 cm "
              "%s %%; densify %.1f ms median (p95 %.1f)\n",
              summarize(kept_frac).mean, ms(point_err_med).c_str(), ms(point_err_bad).c_str(),
              summarize(densify_ms).median, summarize(densify_ms).p95);
  return 0;
}
