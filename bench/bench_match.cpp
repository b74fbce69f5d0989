// Reproduces the paper's Table 1 (feature matching statistics) on the Middlebury 2014 scenes with
// ground truth, plus its perturbations (light -30%/+30%, rotation 90 degrees, scale 50% of the
// right view), and measures the speed of the stereo pipeline (scale, ROI, parallel detection).
// Usage: bench-match [data_dir] [runs]   (data_dir: default $TREESTEREO_DATA_DIR or ../shared/data)
#include "treestereo/data_dir.hpp"
#include "treestereo/match.hpp"
#include "treestereo/middlebury.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

using namespace treestereo;

namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0)
{
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double median_of(std::vector<double> v) { return median(v); }

// A perturbation of the right view and the map from its pixels back to the original right view.
struct Perturbation {
  const char *name;
  std::function<cv::Mat(const cv::Mat &)> apply;
  std::function<cv::Point2f(cv::Point2f, cv::Size)> to_original; // (point, original size)
  double tolerance;     // px in the original view: 1 px of the perturbed view
  bool rectified;       // the pair is still row-aligned: stereo constraints and refinement apply
};

std::vector<Perturbation> perturbations()
{
  auto same = [](cv::Point2f p, cv::Size) { return p; };
  return {
      {"control", [](const cv::Mat &m) { return m; }, same, 1.0, true},
      {"light -30%", [](const cv::Mat &m) { cv::Mat o; m.convertTo(o, -1, 0.7); return o; }, same,
       1.0, true},
      {"light +30%", [](const cv::Mat &m) { cv::Mat o; m.convertTo(o, -1, 1.3); return o; }, same,
       1.0, true},
      // Clockwise: dst(x', y') = src(x = y', y = H - 1 - x').
      {"rotate 90", [](const cv::Mat &m) { cv::Mat o; cv::rotate(m, o, cv::ROTATE_90_CLOCKWISE); return o; },
       [](cv::Point2f p, cv::Size s) { return cv::Point2f(p.y, float(s.height - 1) - p.x); }, 1.0,
       false},
      {"scale 50%", [](const cv::Mat &m) { cv::Mat o; cv::resize(m, o, cv::Size(), 0.5, 0.5, cv::INTER_AREA); return o; },
       [](cv::Point2f p, cv::Size) { return cv::Point2f(p.x * 2 + 0.5f, p.y * 2 + 0.5f); }, 2.0,
       false},
  };
}

struct Method {
  const char *name;
  MatchMethod method;
  double ratio;
};

const std::vector<Method> kMethods = {
    {"euclidean", MatchMethod::Euclidean, 0.8},
    {"cosine-norm", MatchMethod::CosineNorm, 0.8},
    {"cosine-norm, no ratio test (paper as written)", MatchMethod::CosineNorm, 1.0},
};

MatcherParams matcher_params(const Method &m, bool constrained, const MiddleburyCalib &calib)
{
  MatcherParams p;
  p.method = m.method;
  p.ratio = m.ratio;
  if (constrained) {
    p.constraints.epipolar_tolerance = 1.0;
    p.constraints.min_disparity = 0;
    p.constraints.max_disparity = calib.ndisp > 0 ? calib.ndisp : calib.width;
    p.constraints.mutual = true;
  } else {
    p.constraints.epipolar_tolerance = -1;
    p.constraints.mutual = false;
  }
  return p;
}

void table1(const std::string &root, int runs)
{
  std::printf("## Table 1 on Middlebury 2014 (quarter size)\n\n");
  std::printf("Correct: |d - d_gt| <= 1 px and |yr - yl| <= 1 px at the left keypoint's pixel, on "
              "pixels with known, non-occluded ground truth (scale 50%%: 1 px of the reduced view "
              "= 2 px). Constraints: epipolar band 1 px, disparity 0..ndisp, mutual check, "
              "ZNCC refinement. Times: median of %d runs, both views; detection is shared by the "
              "methods.\n\n",
              runs);
  std::printf("| scene | condition | method | constraints | keypoints L | keypoints R | matches | "
              "evaluated | wrong | correct %% | detect ms | match ms |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  const char *scenes[] = {"Jadeplant", "Pipes", "Adirondack", "Teddy"};
  const FeatureDetector det{DetectParams{}};
  for (const char *scene : scenes) {
    const std::string dir = root + "/middlebury2014-quarter/" + scene;
    if (!std::ifstream(dir + "/disp0GT.pfm").good()) {
      std::printf("| %s | (not found in %s) | | | | | | | | | | |\n", scene, dir.c_str());
      continue;
    }
    const MiddleburyScene s = load_middlebury_scene(dir);
    for (const Perturbation &pert : perturbations()) {
      const cv::Mat right = pert.apply(s.right);
      Features fl, fr;
      std::vector<double> det_ms;
      for (int r = 0; r < runs; ++r) {
        const auto t0 = Clock::now();
        fl = det.detect(s.left);
        fr = det.detect(right);
        det_ms.push_back(ms_since(t0));
      }
      for (const Method &method : kMethods)
        for (bool constrained : {false, true}) {
          if (constrained && !pert.rectified)
            continue; // the paper's perturbations run without the epipolar constraint
          const auto matcher = make_matcher(matcher_params(method, constrained, s.calib));
          std::vector<StereoMatch> m;
          std::vector<double> match_ms;
          for (int r = 0; r < runs; ++r) {
            MatchStats st;
            const auto t0 = Clock::now();
            m = matcher->match(fl, fr, st);
            if (constrained)
              refine_matches(s.left, right, m, RefineParams{});
            match_ms.push_back(ms_since(t0));
          }
          for (StereoMatch &x : m) {
            const cv::Point2f p = pert.to_original({x.xr, x.yr}, s.right.size());
            x.xr = p.x;
            x.yr = p.y;
          }
          const MatchAccuracy acc = evaluate_matches(m, s.disp_gt, s.mask_nocc, pert.tolerance);
          std::printf("| %s | %s | %s | %s | %zu | %zu | %zu | %zu | %zu | %.2f | %.1f | %.1f |\n",
                      scene, pert.name, method.name, constrained ? "on" : "off", fl.size(),
                      fr.size(), m.size(), acc.evaluated, acc.wrong(), 100.0 * acc.correct_rate(),
                      median_of(det_ms), median_of(match_ms));
        }
    }
  }
}

void speed(const std::string &root, int runs)
{
  const std::string dir = root + "/middlebury2014-quarter/Jadeplant";
  if (!std::ifstream(dir + "/disp0GT.pfm").good()) {
    std::printf("\n(speed table skipped: %s not found)\n", dir.c_str());
    return;
  }
  const MiddleburyScene s = load_middlebury_scene(dir);
  std::printf("\n## Speed of the stereo pipeline (Jadeplant; euclidean with constraints and refinement)\n\n"
              "2x = the quarter images upsampled to 1318x994 (ground truth disparities x2). ROI = "
              "a mask covering the central 50%% x 70%% of the left view (the right's widened leftwards by ndisp). Median of %d runs on this "
              "machine.\n\n",
              runs);
  std::printf("| size | scale | ROI | parallel | keypoints L/R | matches | correct %% | detect ms | "
              "match ms | refine ms | total ms |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (int up : {1, 2}) {
    cv::Mat l = s.left, r = s.right, gt = s.disp_gt, nocc = s.mask_nocc;
    if (up == 2) {
      cv::resize(s.left, l, cv::Size(), 2, 2, cv::INTER_CUBIC);
      cv::resize(s.right, r, cv::Size(), 2, 2, cv::INTER_CUBIC);
      cv::resize(s.disp_gt, gt, cv::Size(), 2, 2, cv::INTER_NEAREST);
      gt *= 2.0;
      cv::resize(s.mask_nocc, nocc, cv::Size(), 2, 2, cv::INTER_NEAREST);
    }
    // The right view's object sits up to ndisp px further left: its mask is the left box
    // widened leftwards, as a segmentation of the right view would give.
    const cv::Rect box(l.cols / 4, l.rows * 15 / 100, l.cols / 2, l.rows * 70 / 100);
    const int reach = std::min(box.x, s.calib.ndisp * up);
    cv::Mat mask = cv::Mat::zeros(l.size(), CV_8U), mask_r = mask.clone();
    mask(box).setTo(255);
    mask_r(cv::Rect(box.x - reach, box.y, box.width + reach, box.height)).setTo(255);
    for (double scale : {1.0, 0.5})
      for (bool roi : {false, true})
        for (bool parallel : {false, true}) {
          MatchParams p;
          p.detect.scale = scale;
          p.matcher = matcher_params(kMethods[0], true, s.calib);
          p.matcher.constraints.max_disparity *= up;
          p.parallel_detect = parallel;
          const StereoMatcher sm(p);
          std::vector<double> d, m, f, t;
          StereoMatchResult res;
          for (int i = 0; i < runs; ++i) {
            res = roi ? sm.run(l, r, mask, mask_r) : sm.run(l, r, cv::Mat(), cv::Mat());
            d.push_back(res.stats.detect_ms);
            m.push_back(res.stats.match_ms);
            f.push_back(res.stats.refine_ms);
            t.push_back(res.stats.detect_ms + res.stats.match_ms + res.stats.refine_ms);
          }
          const MatchAccuracy acc = evaluate_matches(res.matches, gt, nocc, 1.0);
          std::printf("| %dx%d | %.1f | %s | %s | %zu/%zu | %zu | %.2f | %.1f | %.1f | %.1f | %.1f |\n",
                      l.cols, l.rows, scale, roi ? "yes" : "no", parallel ? "yes" : "no",
                      res.stats.keypoints[0], res.stats.keypoints[1], res.matches.size(),
                      100.0 * acc.correct_rate(), median_of(d), median_of(m), median_of(f),
                      median_of(t));
        }
  }
}

} // namespace

int main(int argc, char **argv)
{
  std::string root = data_dir();
  if (argc > 1 && argv[1][0] != '\0')
    root = argv[1];
  const int runs = argc > 2 ? std::max(1, std::atoi(argv[2])) : 3;
  try {
    table1(root, runs);
    speed(root, runs);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "bench-match: %s\n", e.what());
    return 1;
  }
  return 0;
}
