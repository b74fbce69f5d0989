// bench-extent: where the canopy height/width error of the measuring chain comes from, with
// lib/ only (no GStreamer). For each scene it renders both views, rectifies them as
// stereorectify does, and compares:
//   - the silhouette: lib's segmentation of the rectified left view against the renderer's
//     ground-truth canopy mask rectified the same way (pixel extents, in rectified pixels);
//   - the extents of compute_tree_metrics for every ExtentDepth model, fed (a) the segmented
//     mask and the matched points (what treemetrics sees), (b) the true mask and the matched
//     points, (c) the true mask and the true visible canopy points (perfect depth), (d) the
//     segmented mask and the true points (what the segmentation alone costs);
// against the canopy's true 3D height and width. Prints markdown tables.
//
//   bench-extent [--sizes 1296x972] [--distances 1.8,2.0,2.2] [--seeds 1,2,3] [--lights 1.0]
#include "scene_pairs.hpp"
#include "sweep.hpp"
#include "treestereo/depth.hpp"
#include "treestereo/match.hpp"
#include "treestereo/presets.hpp"
#include "treestereo/metrics.hpp"
#include "treestereo/rectify.hpp"
#include "treestereo/scene.hpp"
#include "treestereo/segment.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/imgproc.hpp>

#include <cstdio>
#include <map>
#include <sstream>
#include <string>
#include <vector>

using namespace treestereo;
using treestereo::bench::parse_list;
using treestereo::bench::Sweep;
using treestereo::bench::sweep_option;
using treestereo::bench::render_rectified;
using treestereo::bench::RectifiedRender;

namespace {

const char *model_name(ExtentDepth e)
{
  switch (e) {
  case ExtentDepth::kRoundCanopy: return "round-canopy";
  case ExtentDepth::kEdgePoints: return "edge-points";
  case ExtentDepth::kMidDepth: return "mid-depth";
  case ExtentDepth::kFrontFace: return "front-face";
  case ExtentDepth::kTangentPoints: return "tangent-points";
  }
  return "?";
}

const ExtentDepth kModels[] = {ExtentDepth::kRoundCanopy, ExtentDepth::kEdgePoints,
                               ExtentDepth::kMidDepth, ExtentDepth::kFrontFace,
                               ExtentDepth::kTangentPoints};

// Relative errors (%) of height and width per (input, model).
struct Errs {
  std::vector<double> h, w;
};

} // namespace

int main(int argc, char **argv)
{
  Sweep sweep{"1296x972", "1.8,2.0,2.2", "1,2,3", "1.0"};
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i], v = argv[i + 1];
    if (sweep_option(a, v, sweep))
      continue;
    std::fprintf(stderr, "bench-extent: unknown option %s\n", a.c_str());
    return 2;
  }
  int w = 0, h = 0;
  if (std::sscanf(sweep.sizes.c_str(), "%dx%d", &w, &h) != 2) {
    std::fprintf(stderr, "bench-extent: --sizes WxH\n");
    return 2;
  }
  const char *inputs[] = {"seg mask + matched pts", "true mask + matched pts",
                          "true mask + true pts", "seg mask + true pts"};
  std::map<std::pair<int, int>, Errs> errs; // (input, model)
  std::vector<double> vis_w, vis_h;         // visible surface's 3D extent vs truth (%)
  std::vector<double> dl, dr, dt, db;       // silhouette edge offsets seg - truth (px, outward +)
  std::printf("| d (m) | seed | light | seg bbox (px) | true bbox (px) | true H x W (m) | "
              "round-canopy H x W (m), seg+matched |\n|---|---|---|---|---|---|---|\n");
  for (double d : parse_list(sweep.distances))
    for (double sd : parse_list(sweep.seeds))
      for (double light : parse_list(sweep.lights)) {
        SceneParams p;
        p.image_size = cv::Size(w, h);
        p.distance_mm = d * 1000;
        p.seed = std::uint64_t(sd);
        p.light = light;
        SceneRenderer r(p);
        const RectifiedRender rr = render_rectified(r, p.image_size);
        const StereoRectification &rect = rr.rect;
        const StereoGeometry &g = rect.geometry;
        const cv::Mat *rv = rr.view;
        const GroundTruth &t = rr.truth_left;
        cv::Mat tmask;
        rectify_view(rect, LEFT, t.canopy_mask, tmask);
        cv::threshold(tmask, tmask, 127, 255, cv::THRESH_BINARY);
        Silhouette seg = segment_vegetation(rv[LEFT]);
        SegmentParams sp;
        Silhouette segr = segment_vegetation(rv[RIGHT], sp);
        Silhouette truth_sil;
        truth_sil.present = true;
        truth_sil.mask = tmask;

        MatchParams mp;
        mp.matcher.method = MatchMethod::Euclidean;
        const DisparityRange dr_ = disparity_range_for_depth(g, 500, 10000);
        mp.matcher.constraints.min_disparity = dr_.min;
        mp.matcher.constraints.max_disparity = dr_.max;
        mp.detect.scale = SiftmatchPreset::auto_scale(w);
        const StereoMatchResult mr = match_stereo(rv[LEFT], rv[RIGHT], seg.mask, segr.mask, mp);
        const DepthResult dres = triangulate_matches(mr.matches, g, DepthParams());

        const GroundTruth tr = truth_in_frame(t, g.R1);
        std::vector<Point3> tpts;
        for (std::size_t i = 0; i < tr.canopy_points_mm.size(); i += 7) {
          const cv::Point3f &q = tr.canopy_points_mm[i];
          Point3 pt;
          pt.x = q.x;
          pt.y = q.y;
          pt.z = q.z;
          tpts.push_back(pt);
        }

        {
          // How much of the true extent the visible canopy surface itself spans.
          float x0 = 1e9f, x1 = -1e9f, y0 = 1e9f, y1 = -1e9f;
          for (const cv::Point3f &q : t.canopy_points_mm) {
            x0 = std::min(x0, q.x);
            x1 = std::max(x1, q.x);
            y0 = std::min(y0, q.y);
            y1 = std::max(y1, q.y);
          }
          vis_w.push_back(100 * ((x1 - x0) / 1000 - t.canopy_width_m) / t.canopy_width_m);
          vis_h.push_back(100 * ((y1 - y0) / 1000 - t.canopy_height_m) / t.canopy_height_m);
        }
        const cv::Rect sb = cv::boundingRect(seg.mask), tb = cv::boundingRect(tmask);
        dl.push_back(tb.x - sb.x);
        dr.push_back(sb.br().x - tb.br().x);
        dt.push_back(tb.y - sb.y);
        db.push_back(sb.br().y - tb.br().y);
        MetricsParams mpar;
        for (int in = 0; in < 4; ++in)
          for (int mi = 0; mi < 5; ++mi) {
            mpar.extent_depth = kModels[mi];
            const Silhouette &sil = in == 0 || in == 3 ? seg : truth_sil;
            const std::vector<Point3> &pts = in >= 2 ? tpts : dres.points;
            const TreeMetrics m = compute_tree_metrics(sil, pts, g, mpar);
            errs[{in, mi}].h.push_back(100 * (m.height_m - t.canopy_height_m) / t.canopy_height_m);
            errs[{in, mi}].w.push_back(100 * (m.width_m - t.canopy_width_m) / t.canopy_width_m);
            if (in == 0 && mi == 0)
              std::printf("| %.1f | %d | %.1f | %dx%d@(%d,%d) | %dx%d@(%d,%d) | %.3f x %.3f | "
                          "%.3f x %.3f |\n",
                          d, int(sd), light, sb.width, sb.height, sb.x, sb.y, tb.width,
                          tb.height, tb.x, tb.y, t.canopy_height_m, t.canopy_width_m, m.height_m,
                          m.width_m);
          }
        std::fflush(stdout);
      }
  auto ms = [](const std::vector<double> &v) {
    char b[64];
    const Summary s = summarize(v);
    std::snprintf(b, sizeof b, "%+.2f ± %.2f", s.mean, s.stddev);
    return std::string(b);
  };
  std::printf("\nSilhouette edges, segmented minus true (px, + = segmented wider): left %s, "
              "right %s, top %s, bottom %s\n\n",
              ms(dl).c_str(), ms(dr).c_str(), ms(dt).c_str(), ms(db).c_str());
  std::printf("Visible canopy surface's own 3D extent vs the true extent (%%): height %s, "
              "width %s\n\n", ms(vis_h).c_str(), ms(vis_w).c_str());
  std::printf("| input | model | height err %% | width err %% |\n|---|---|---|---|\n");
  for (auto &[key, e] : errs)
    std::printf("| %s | %s | %s | %s |\n", inputs[key.first], model_name(kModels[key.second]),
                ms(e.h).c_str(), ms(e.w).c_str());
  return 0;
}
