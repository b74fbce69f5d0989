// bench-sampling: is the chain's distance bias a depth error or a sampling effect? For a few
// scenes (lib chain as the elements run it: rectify, segment, SIFT at scale 0.5, refine,
// triangulate) compares each matched point's depth with the renderer's truth at the same
// rectified pixel, and the truth at the matched pixels with the truth over the whole canopy.
//   bench-sampling [seeds (3)]
#include "scene_pairs.hpp"
#include "treestereo/scene.hpp"
#include "treestereo/rectify.hpp"
#include "treestereo/segment.hpp"
#include "treestereo/match.hpp"
#include "treestereo/depth.hpp"
#include "treestereo/stats.hpp"
#include <opencv2/imgproc.hpp>
#include <cstdio>
#include <cstdlib>
using namespace treestereo;
int main(int argc, char **argv)
{
  const int seeds = argc > 1 ? std::atoi(argv[1]) : 3;
  for (int seed = 1; seed <= seeds; seed++) {
    SceneParams p;
    p.seed = seed;
    p.image_size = cv::Size(1296, 972);
    SceneRenderer R(p);
    cv::Mat l, r;
    GroundTruth t;
    R.render(0, 0, l, &t);
    R.render(1, 0, r, nullptr);
    StereoRectification rect = compute_rectification(R.calibration(), p.image_size);
    cv::Mat rl, rr;
    rectify_view(rect, 0, l, rl);
    rectify_view(rect, 1, r, rr);
    const StereoGeometry &g = rect.geometry;
    // the visible canopy surface's depth: rectified into the left view, and every point of it
    const cv::Mat zt = bench::truth_depth_rectified(R, t, g);
    std::vector<double> all;
    for (const cv::Point3f &q : truth_in_frame(t, g.R1).canopy_points_mm)
      all.push_back(q.z);
    SegmentParams sp;
    sp.order = ChannelOrder{0, 1, 2};
    Silhouette s = segment_vegetation(rl, sp);
    MatchParams mp;
    mp.detect.scale = 0.5;
    auto dr = disparity_range_for_depth(g, 500, 10000);
    mp.matcher.constraints.min_disparity = dr.min;
    mp.matcher.constraints.max_disparity = dr.max;
    Silhouette sr = segment_vegetation(rr, sp);
    auto res = StereoMatcher(mp).run(rl, rr, s.mask, sr.mask);
    DepthResult d = triangulate_matches(res.matches, g, DepthParams{});
    std::vector<double> meas, tru, diff;
    for (auto &pt : d.points) {
      if (!pt.valid)
        continue;
      auto &m = res.matches[pt.match_index];
      int u = int(std::lround(m.xl)), v = int(std::lround(m.yl));
      if (!s.mask.at<uchar>(v, u))
        continue;
      meas.push_back(pt.z);
      float z = zt.at<float>(v, u);
      if (z > 0) {
        tru.push_back(z);
        diff.push_back(pt.z - z);
      }
    }
    std::printf("seed %d: truth median (all canopy) %.1f mm; measured median %.1f (n=%zu); truth "
                "at matched px median %.1f (n=%zu); median(meas-truth) %.2f mm\n",
                seed, median(all), median(meas), meas.size(), median(tru), tru.size(),
                median(diff));
  }
}
