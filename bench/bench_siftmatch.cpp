// The siftmatch element's work per frame (StereoMatcher::run with the element's defaults, lib's
// SiftmatchPreset) at the camera sizes of the design: Middlebury Jadeplant resized to 1296x972 and 2592x1944 (ground
// truth disparities scaled alike), whole views and a canopy mask, at several detection scales.
//
//   ./build/bench/bench-siftmatch [data dir] [runs]
#include "scene_pairs.hpp"
#include "treestereo/data_dir.hpp"
#include "treestereo/match.hpp"
#include "treestereo/middlebury.hpp"
#include "treestereo/presets.hpp"
#include "treestereo/rectify.hpp"
#include "treestereo/scene.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

using namespace treestereo;

namespace {

struct Scene {
  cv::Mat left, right, disp_gt, nocc;
  StereoGeometry geometry;
  double max_disparity = 0;
};

Scene resized(const MiddleburyScene &s, cv::Size size)
{
  Scene r;
  const double k = double(size.width) / s.left.cols;
  cv::resize(s.left, r.left, size, 0, 0, cv::INTER_CUBIC);
  cv::resize(s.right, r.right, size, 0, 0, cv::INTER_CUBIC);
  cv::resize(s.disp_gt, r.disp_gt, size, 0, 0, cv::INTER_NEAREST);
  r.disp_gt *= k;
  cv::resize(s.mask_nocc, r.nocc, size, 0, 0, cv::INTER_NEAREST);
  r.max_disparity = s.calib.ndisp * k;
  return r;
}

// The canopy stand-in: the central 50% x 70% of the left view; the right one widened leftwards
// by the largest disparity so the same scene part is searched.
void masks(const Scene &s, cv::Mat &ml, cv::Mat &mr)
{
  const cv::Size sz = s.left.size();
  const cv::Rect box(sz.width / 4, sz.height * 15 / 100, sz.width / 2, sz.height * 70 / 100);
  ml = cv::Mat::zeros(sz, CV_8U);
  mr = cv::Mat::zeros(sz, CV_8U);
  ml(box).setTo(255);
  const int x0 = std::max(0, box.x - int(s.max_disparity));
  mr(cv::Rect(x0, box.y, box.x + box.width - x0, box.height)).setTo(255);
}

// Table 1 on SceneRenderer pairs: five trees at `size`, rectified as stereorectify does.
void scene_table(cv::Size size, int runs)
{
  std::printf("\n| size | method | mask | matches (mean) | evaluated | correct %% | total ms "
              "(median) |\n|---|---|---|---|---|---|---|\n");
  for (MatchMethod method : {MatchMethod::Euclidean, MatchMethod::CosineNorm})
    for (bool masked : {false, true}) {
      std::size_t matches = 0, evaluated = 0, correct = 0;
      std::vector<double> ms;
      const int seeds = 5;
      for (int seed = 1; seed <= seeds; ++seed) {
        SceneParams sp;
        sp.seed = std::uint64_t(seed);
        sp.image_size = size;
        const bench::ScenePair pair = bench::render_pair(sp);
        const cv::Mat *view = pair.view, *mask = pair.mask;
        const cv::Mat &d_true = pair.d_true;
        // the element's defaults at this size: automatic scale, disparities of 0.5..10 m
        MatchParams p = SiftmatchPreset::for_view(pair.geometry, size.width);
        p.matcher.method = method;
        const StereoMatcher matcher(p);
        StereoMatchResult r;
        for (int i = 0; i < runs; ++i) {
          r = matcher.run(view[LEFT], view[RIGHT], masked ? mask[LEFT] : cv::Mat(),
                          masked ? mask[RIGHT] : cv::Mat());
          ms.push_back(r.stats.detect_ms + r.stats.match_ms + r.stats.refine_ms);
        }
        matches += r.matches.size();
        for (const StereoMatch &m : r.matches) {
          const float t = d_true.at<float>(cvRound(m.yl), cvRound(m.xl));
          if (std::isnan(t))
            continue;
          ++evaluated;
          correct += std::abs(m.disparity() - t) <= 1.0f ? 1 : 0;
        }
      }
      std::printf("| %dx%d | %s | %s | %.0f | %zu | %.2f | %.1f |\n", size.width, size.height,
                  match_method_name(method), masked ? "canopy" : "no", double(matches) / seeds,
                  evaluated, evaluated ? 100.0 * double(correct) / double(evaluated) : 0.0,
                  median(ms));
      std::fflush(stdout);
    }
}

} // namespace

int main(int argc, char **argv)
{
  std::string root = data_dir();
  if (argc > 1 && argv[1][0] != '\0')
    root = argv[1];
  const int runs = argc > 2 ? std::max(1, std::atoi(argv[2])) : 3;
  const MiddleburyScene jade = load_middlebury_scene(root + "/middlebury2014-quarter/Jadeplant");

  std::printf("| size | scale | mask | keypoints L/R | matches | evaluated | correct %% | detect ms "
              "| match ms | refine ms | total ms |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
  const cv::Size sizes[] = {{1296, 972}, {2592, 1944}};
  for (const cv::Size &size : sizes) {
    const Scene s = resized(jade, size);
    cv::Mat ml, mr;
    masks(s, ml, mr);
    const double scales[] = {0.5, 0.25, 0.125};
    for (double scale : scales) {
      for (bool masked : {false, true}) {
        // The element's defaults at this scale; the disparity range from the scene's ndisp as
        // a depth range would give.
        MatchParams p = SiftmatchPreset::params();
        p.detect.scale = scale;
        p.matcher.constraints.min_disparity = 0;
        p.matcher.constraints.max_disparity = s.max_disparity;
        const StereoMatcher matcher(p);
        std::vector<double> total, det, mat, ref;
        StereoMatchResult r;
        for (int i = 0; i < runs; ++i) {
          r = matcher.run(s.left, s.right, masked ? ml : cv::Mat(), masked ? mr : cv::Mat());
          det.push_back(r.stats.detect_ms);
          mat.push_back(r.stats.match_ms);
          ref.push_back(r.stats.refine_ms);
          total.push_back(r.stats.detect_ms + r.stats.match_ms + r.stats.refine_ms);
        }
        // 1 px of Jadeplant's quarter-size ground truth, in the resized frame.
        const double tol = double(size.width) / jade.left.cols;
        const MatchAccuracy acc = evaluate_matches(r.matches, s.disp_gt, s.nocc, tol);
        std::printf("| %dx%d | %.3g | %s | %zu/%zu | %zu | %zu | %.2f | %.1f | %.1f | %.1f | %.1f |\n",
                    size.width, size.height, scale, masked ? "50%x70%" : "no",
                    r.stats.keypoints[0], r.stats.keypoints[1], r.matches.size(), acc.evaluated,
                    100.0 * acc.correct_rate(), median(det), median(mat), median(ref),
                    median(total));
        std::fflush(stdout);
      }
    }
  }
  scene_table({1296, 972}, runs);
  return 0;
}
