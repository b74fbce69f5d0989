// The paper's Table 1 on treetestsrc (SceneRenderer) pairs: rendered, rectified as stereorectify
// does, matched with siftmatch's settings (scale 0.5 at 1296x972, 2 px band, disparity range of
// 0.5..10 m, mutual, refinement), scored against the per-pixel true disparity (correct: |d - d_true|
// <= 1 px at the left keypoint's pixel). Rows: euclidean / cosine-norm, stereo constraints off /
// on (with the two-layer test off = before: min-zncc 0.8 and no other filter, and on = siftmatch's
// refinement filters), and the paper's
// perturbations of the right view (light -30 % / +30 %, rotation 90 degrees and scale 50 %, the
// last two without the epipolar constraint, with siftmatch's upright SIFT and with OpenCV's,
// which is rotation invariant). Also: a breakdown of the wrong matches by kind,
// Middlebury Jadeplant before/after (--only middlebury: the other four Middlebury scenes too, held
// out), and timing rows.
//
//   bench-match-scene [--seeds 1,2,3] [--distances 1.8,2.2] [--size 1296x972] [--runs 3]
//                     [--only table,errors,row,jadeplant,middlebury,timing,step]
//                     [--set key=value,...]
//                     [--mask] [--data DIR]
//
// --set changes the settings of the "two-layer test on" rows (keys: min-zncc, min-zncc-drop,
// layer-tolerance, layer-half-window, layer-search, layer-centre-tolerance, layer-min-zncc,
// layer-centre-min-zncc, relocate, half-window, search, scale, nfeatures, contrast-threshold,
// mask-inset, upright (1: the project's upright SIFT, 0: OpenCV's), ratio, epipolar-tolerance,
// mutual), to explore other values. --mask: the row and errors modes detect inside each view's
// rendered canopy mask, as siftmatch does behind exgsegment (default: whole views, as Table 1).
// --only step runs just the siftmatch step on the timing pair (1296x972, canopy mask) --runs
// times on one OpenCV thread, for instruction counts under callgrind (bench/callgrind-step.sh).
#include "scene_pairs.hpp"
#include "sweep.hpp"
#include "treestereo/data_dir.hpp"
#include "treestereo/match.hpp"
#include "treestereo/middlebury.hpp"
#include "treestereo/presets.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/imgproc.hpp>

#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

using namespace treestereo;

namespace {

struct Options {
  std::vector<double> seeds{1, 2, 3};
  std::vector<double> distances{1.8, 2.2};
  cv::Size size{1296, 972};
  int runs = 3;
  std::string only = "table,errors,jadeplant,timing";
  std::string set;
  bool mask = false; // row/errors: detect inside the rendered canopy masks
  std::string data = data_dir();
};

// A perturbation of the right view and the map from its pixels back to the original right view
// (as bench-match does on Middlebury).
struct Perturbation {
  const char *name;
  std::function<cv::Mat(const cv::Mat &)> apply;
  std::function<cv::Point2f(cv::Point2f, cv::Size)> to_original; // (point, original size)
  double tolerance; // px in the original view: 1 px of the perturbed view
  bool rectified;   // still row-aligned: the stereo constraints and refinement apply
};

std::vector<Perturbation> perturbations()
{
  auto same = [](cv::Point2f p, cv::Size) { return p; };
  auto gain = [](double g) {
    return [g](const cv::Mat &m) {
      cv::Mat o;
      m.convertTo(o, -1, g);
      return o;
    };
  };
  return {
      {"control", [](const cv::Mat &m) { return m; }, same, 1.0, true},
      {"light -30%", gain(0.7), same, 1.0, true},
      {"light +30%", gain(1.3), same, 1.0, true},
      // Clockwise: dst(x', y') = src(x = y', y = H - 1 - x').
      {"rotate 90",
       [](const cv::Mat &m) {
         cv::Mat o;
         cv::rotate(m, o, cv::ROTATE_90_CLOCKWISE);
         return o;
       },
       [](cv::Point2f p, cv::Size s) { return cv::Point2f(p.y, float(s.height - 1) - p.x); }, 1.0,
       false},
      {"scale 50%",
       [](const cv::Mat &m) {
         cv::Mat o;
         cv::resize(m, o, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
         return o;
       },
       [](cv::Point2f p, cv::Size) { return cv::Point2f(p.x * 2 + 0.5f, p.y * 2 + 0.5f); }, 2.0,
       false},
  };
}

// siftmatch's detection defaults (SiftmatchPreset): every row detects with them. The inset only
// acts with a mask.
void detection_defaults(MatchParams &p)
{
  p.detect = SiftmatchPreset::params().detect;
}
// The same in words, for the table's heading.
std::string detection_text()
{
  const DetectParams d = SiftmatchPreset::params().detect;
  char buf[160];
  std::snprintf(buf, sizeof buf, "contrast-threshold=%g, mask-inset=%d (with a mask)%s",
                d.contrast_threshold, d.mask_inset,
                d.engine == SiftEngine::Upright ? ", upright" : "");
  return buf;
}

// The "two-layer test on" rows: siftmatch's defaults for the refinement and its filters.
void filters_on(MatchParams &p)
{
  p.refine_params = SiftmatchPreset::params().refine_params;
}
// The same in words, for the table's heading.
std::string filters_on_text()
{
  const RefineParams r = SiftmatchPreset::params().refine_params;
  char buf[240];
  std::snprintf(buf, sizeof buf,
                "min-zncc=%g, min-zncc-drop=%g, layer-tolerance=%g, layer-centre-tolerance=%g, "
                "layer-min-zncc=%g, layer-centre-min-zncc=%g, relocate=%d",
                r.min_zncc, r.min_zncc_drop, r.layer_tolerance, r.layer_centre_tolerance,
                r.layer_min_zncc, r.layer_centre_min_zncc, r.relocate);
  return buf;
}

// The two-layer test switched off: the matcher as it was before it.
void filters_off(MatchParams &p)
{
  p.refine_params.layer_tolerance = -1;
  p.refine_params.min_zncc = 0.8;
  p.refine_params.min_zncc_drop = 0;
}

void apply_set(MatchParams &p, const std::string &set)
{
  std::stringstream ss(set);
  std::string item;
  while (std::getline(ss, item, ',')) {
    const auto eq = item.find('=');
    if (eq == std::string::npos)
      throw std::runtime_error("--set: expected key=value, got '" + item + "'");
    const std::string k = item.substr(0, eq);
    const double v = std::stod(item.substr(eq + 1));
    if (k == "min-zncc") p.refine_params.min_zncc = v;
    else if (k == "half-window") p.refine_params.half_window = int(v);
    else if (k == "search") p.refine_params.search = int(v);
    else if (k == "layer-tolerance") p.refine_params.layer_tolerance = v;
    else if (k == "layer-search") p.refine_params.layer_search = int(v);
    else if (k == "layer-half-window") p.refine_params.layer_half_window = int(v);
    else if (k == "layer-centre-tolerance") p.refine_params.layer_centre_tolerance = v;
    else if (k == "layer-min-zncc") p.refine_params.layer_min_zncc = v;
    else if (k == "layer-centre-min-zncc") p.refine_params.layer_centre_min_zncc = v;
    else if (k == "relocate") p.refine_params.relocate = int(v);
    else if (k == "min-zncc-drop") p.refine_params.min_zncc_drop = v;
    else if (k == "scale") p.detect.scale = v;
    else if (k == "nfeatures") p.detect.nfeatures = int(v);
    else if (k == "contrast-threshold") p.detect.contrast_threshold = v;
    else if (k == "mask-inset") p.detect.mask_inset = int(v);
    else if (k == "upright") p.detect.engine = v != 0 ? SiftEngine::Upright : SiftEngine::OpenCV;
    else if (k == "ratio") p.matcher.ratio = v;
    else if (k == "epipolar-tolerance") p.matcher.constraints.epipolar_tolerance = v;
    else if (k == "mutual") p.matcher.constraints.mutual = v != 0;
    else throw std::runtime_error("--set: unknown key '" + k + "'");
  }
}

// siftmatch's settings for a view of this width: automatic scale, 2 px band, 0.5..10 m.
MatchParams element_params(const StereoGeometry &g, int width, MatchMethod method, bool filters,
                           const std::string &set)
{
  MatchParams p;
  p.matcher = SiftmatchPreset::params().matcher;
  detection_defaults(p);
  p.detect.scale = SiftmatchPreset::auto_scale(width);
  p.matcher.method = method;
  const DisparityRange range =
      disparity_range_for_depth(g, SiftmatchPreset::kMinDepthMm, SiftmatchPreset::kMaxDepthMm);
  p.matcher.constraints.min_disparity = range.min;
  p.matcher.constraints.max_disparity = range.max;
  filters_off(p);
  if (filters) {
    filters_on(p);
    apply_set(p, set);
  }
  return p;
}

void unconstrained(MatchParams &p)
{
  p.matcher.constraints.epipolar_tolerance = -1;
  p.matcher.constraints.min_disparity = -std::numeric_limits<double>::infinity();
  p.matcher.constraints.max_disparity = std::numeric_limits<double>::infinity();
  p.matcher.constraints.mutual = false;
  p.refine = false;
  filters_off(p);
}

struct Pair {
  double distance;
  int seed;
  bench::ScenePair scene;
  cv::Mat nocc, disp_gt; // evaluate_matches' inputs: known truth, NaN replaced by 0
};

std::vector<Pair> render_pairs(const Options &o)
{
  std::vector<Pair> pairs;
  for (double dist : o.distances)
    for (double seed : o.seeds) {
      SceneParams sp;
      sp.seed = std::uint64_t(seed);
      sp.image_size = o.size;
      sp.distance_mm = dist * 1000.0;
      Pair p{dist, int(seed), bench::render_pair(sp), {}, {}};
      p.nocc = p.scene.d_true == p.scene.d_true; // false on NaN
      p.disp_gt = p.scene.d_true.clone();
      p.disp_gt.setTo(0, ~p.nocc);
      pairs.push_back(std::move(p));
    }
  return pairs;
}

struct Row {
  std::size_t kp_l = 0, kp_r = 0, matches = 0, min_matches = ~std::size_t(0), evaluated = 0,
              wrong = 0;
  std::vector<double> ms;
};

Row run_row(const std::vector<Pair> &pairs, const Perturbation &pert, const MatchParams &p,
            int runs, bool masked = false)
{
  Row row;
  const StereoMatcher matcher(p);
  for (const Pair &pair : pairs) {
    const cv::Mat right = pert.apply(pair.scene.view[RIGHT]);
    StereoMatchResult r;
    for (int i = 0; i < runs; ++i) {
      r = matcher.run(pair.scene.view[LEFT], right, masked ? pair.scene.mask[LEFT] : cv::Mat(),
                      masked ? pair.scene.mask[RIGHT] : cv::Mat());
      row.ms.push_back(r.stats.detect_ms + r.stats.match_ms + r.stats.refine_ms);
    }
    for (StereoMatch &m : r.matches) {
      const cv::Point2f q = pert.to_original({m.xr, m.yr}, pair.scene.view[RIGHT].size());
      m.xr = q.x;
      m.yr = q.y;
    }
    const MatchAccuracy acc = evaluate_matches(r.matches, pair.disp_gt, pair.nocc, pert.tolerance);
    row.kp_l += r.stats.keypoints[0];
    row.kp_r += r.stats.keypoints[1];
    row.matches += r.matches.size();
    row.min_matches = std::min(row.min_matches, r.matches.size());
    row.evaluated += acc.evaluated;
    row.wrong += acc.wrong();
  }
  return row;
}

void table(const std::vector<Pair> &pairs, const Options &o)
{
  std::printf("\n## Table 1 on treetestsrc pairs (%dx%d)\n\n", o.size.width, o.size.height);
  std::printf("%zu pairs (seeds ", pairs.size());
  for (double s : o.seeds)
    std::printf("%g ", s);
  std::printf("x distances ");
  for (double d : o.distances)
    std::printf("%g ", d);
  std::printf("m), frame 0, whole views (no mask). Keypoints and matches: mean per pair; "
              "min: the pair with the fewest. ms: median of %d run(s) per pair of the whole "
              "step (detection of both views, matching, refinement, two-layer test). Detection: "
              "%s. Two-layer test on: %s%s%s.\n\n",
              o.runs, detection_text().c_str(), filters_on_text().c_str(),
              o.set.empty() ? "" : ", then --set ", o.set.c_str());
  std::printf("| condition | method | constraints | two-layer test | keypoints L | keypoints R "
              "| matches | min matches | evaluated | wrong | correct %% | ms |\n"
              "|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  const double n = double(pairs.size());
  for (const Perturbation &pert : perturbations())
    for (MatchMethod method : {MatchMethod::Euclidean, MatchMethod::CosineNorm})
      for (int variant = 0; variant < 4; ++variant) {
        // 0: constraints off; 1: on, two-layer test off (the default); 2: on, test on. The
        // views that are not rectified (rotated, scaled): 0, then 3: constraints off with
        // OpenCV's SIFT, whose descriptors follow each keypoint's orientation (the upright
        // ones cannot match a rotated view).
        if (pert.rectified ? variant == 3 : variant == 1 || variant == 2)
          continue;
        MatchParams p = element_params(pairs[0].scene.geometry, o.size.width, method,
                                       variant == 2, o.set);
        if (variant == 0 || variant == 3)
          unconstrained(p);
        if (variant == 3)
          p.detect.engine = SiftEngine::OpenCV;
        Row r = run_row(pairs, pert, p, o.runs);
        const std::string name = std::string(pert.name) + (variant == 3 ? ", OpenCV's SIFT" : "");
        std::printf("| %s | %s | %s | %s | %.0f | %.0f | %.0f | %zu | %zu | %zu | %.2f | %.1f |\n",
                    name.c_str(), match_method_name(method), variant == 0 || variant == 3 ? "off" : "on",
                    variant == 2 ? "on" : "off", double(r.kp_l) / n, double(r.kp_r) / n,
                    double(r.matches) / n, r.min_matches, r.evaluated, r.wrong,
                    r.evaluated ? 100.0 * double(r.evaluated - r.wrong) / double(r.evaluated) : 0.0,
                    median(r.ms));
        std::fflush(stdout);
      }
}

// CPU time of the process (all threads), ms: unlike wall time, not inflated by other load.
double cpu_ms()
{
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return (double(u.ru_utime.tv_sec) + double(u.ru_stime.tv_sec)) * 1e3 +
         (double(u.ru_utime.tv_usec) + double(u.ru_stime.tv_usec)) * 1e-3;
}

// One row of Table 1 (control, euclidean, constraints and two-layer test on, then --set): for
// comparing settings quickly, e.g. on two seed sets.
void one_row(const std::vector<Pair> &pairs, const Options &o)
{
  const MatchParams p =
      element_params(pairs[0].scene.geometry, o.size.width, MatchMethod::Euclidean, true, o.set);
  const double c0 = cpu_ms();
  Row r = run_row(pairs, perturbations()[0], p, o.runs, o.mask);
  const double n = double(pairs.size()), cpu = (cpu_ms() - c0) / n / o.runs;
  std::printf("| %s | %.0f/%.0f | %.0f | %zu | %zu | %zu | %.2f | %.1f | %.0f |\n",
              o.set.empty() ? "(siftmatch's defaults)" : o.set.c_str(), double(r.kp_l) / n,
              double(r.kp_r) / n, double(r.matches) / n, r.min_matches, r.evaluated, r.wrong,
              r.evaluated ? 100.0 * double(r.evaluated - r.wrong) / double(r.evaluated) : 0.0,
              median(r.ms), cpu);
  std::fflush(stdout);
}

// Whether the left pixel (x, y) with true disparity t is hidden in the right view: a left pixel
// further right on the row lands on the same right pixel with a larger disparity.
bool occluded(const cv::Mat &d_true, int x, int y, float t)
{
  const float *row = d_true.ptr<float>(y);
  for (int x2 = x + 1; x2 < d_true.cols && x2 - x < 400; ++x2) {
    const float t2 = row[x2];
    if (!std::isnan(t2) && t2 - t > 0.5f && std::abs((float(x2) - t2) - (float(x) - t)) <= 0.5f)
      return true;
  }
  return false;
}

// Chebyshev distance (1..3) from (x, y) to the nearest pixel whose true disparity is within
// 1 px of d; 0 when there is none. Non-finite truth is unknown.
int edge_ring(const cv::Mat &dt, int x, int y, float d)
{
  for (int rr = 1; rr <= 3; ++rr)
    for (int dy = -rr; dy <= rr; ++dy)
      for (int dx = -rr; dx <= rr; ++dx) {
        const int xx = x + dx, yy = y + dy;
        if (xx < 0 || yy < 0 || xx >= dt.cols || yy >= dt.rows)
          continue;
        const float tn = dt.at<float>(yy, xx);
        if (std::isfinite(tn) && std::abs(d - tn) <= 1.0f)
          return rr;
      }
  return 0;
}

// The wrong matches of the constrained rows, by kind.
void errors(const std::vector<Pair> &pairs, const Options &o)
{
  std::printf("\n## Wrong matches by kind (control, constraints on)\n\n"
              "edge: the matched disparity is the true one (within 1 px) of a pixel within 3 px "
              "(Chebyshev distance 1, 2 or 3) of the keypoint (the 7x7 refinement window), i.e. the match took a neighbouring "
              "depth layer's disparity; nearer: the match is nearer than the truth at the "
              "keypoint's pixel (a background pixel given the foreground's disparity); occluded: "
              "the keypoint's pixel is hidden in the right view; near miss: 1-2 px off; other: "
              "the rest.\n\n");
  std::printf("| method | two-layer test | evaluated | wrong | edge, nearer | edge, farther | "
              "of which occluded | edge at 1 / 2 / 3 px | near miss | other |\n"
              "|---|---|---|---|---|---|---|---|---|---|\n");
  for (MatchMethod method : {MatchMethod::Euclidean, MatchMethod::CosineNorm})
    for (bool filters : {false, true}) {
      std::size_t evaluated = 0, wrong = 0, edge_near = 0, edge_far = 0, occ = 0, near_miss = 0,
                  other = 0, at_ring[3] = {0, 0, 0};
      for (const Pair &pair : pairs) {
        const MatchParams p =
            element_params(pair.scene.geometry, o.size.width, method, filters, o.set);
        const StereoMatchResult r =
            StereoMatcher(p).run(pair.scene.view[LEFT], pair.scene.view[RIGHT],
                                 o.mask ? pair.scene.mask[LEFT] : cv::Mat(),
                                 o.mask ? pair.scene.mask[RIGHT] : cv::Mat());
        const cv::Mat &dt = pair.scene.d_true;
        for (const StereoMatch &m : r.matches) {
          const int x = int(std::lround(m.xl)), y = int(std::lround(m.yl));
          const float t = dt.at<float>(y, x);
          if (std::isnan(t))
            continue;
          ++evaluated;
          const float d = m.disparity();
          if (std::abs(d - t) <= 1.0f)
            continue;
          ++wrong;
          const int ring = edge_ring(dt, x, y, d);
          if (ring > 0) {
            (d > t ? edge_near : edge_far) += 1;
            ++at_ring[ring - 1];
            occ += occluded(dt, x, y, t) ? 1 : 0;
          } else if (std::abs(d - t) <= 2.0f) {
            ++near_miss;
          } else {
            ++other;
          }
        }
      }
      std::printf("| %s | %s | %zu | %zu | %zu | %zu | %zu | %zu / %zu / %zu | %zu | %zu |\n",
                  match_method_name(method), filters ? "on" : "off", evaluated, wrong, edge_near,
                  edge_far, occ, at_ring[0], at_ring[1], at_ring[2], near_miss, other);
      std::fflush(stdout);
    }
}

// The Middlebury 2014 scenes (quarter size) as lib's test and siftmatch's element test run
// Jadeplant: scale 1, 1 px band, 0..ndisp, mutual, refinement; without and with the two-layer
// test (and siftmatch's other refinement filters). Jadeplant is the target; the other
// scenes are held out, to see whether a setting chosen on treetestsrc and Jadeplant carries over.
void middlebury(const Options &o, bool jadeplant_only)
{
  std::printf("\n## Middlebury 2014 (quarter size, scale 1, 1 px band, 0..ndisp, mutual, "
              "refinement). Wrong by kind: edge = the matched disparity is the truth of a pixel "
              "within 3 px (nearer: the match is nearer than the keypoint's own truth); other: the "
              "rest.\n\n| scene | method | two-layer test | keypoints L/R | matches | evaluated "
              "| wrong | correct %% | edge, nearer | edge, farther | other |\n"
              "|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::vector<std::string> scenes{"Jadeplant"};
  if (!jadeplant_only)
    scenes = {"Adirondack", "Jadeplant", "Pipes", "Plants", "Teddy"};
  for (const std::string &name : scenes) {
    const std::string dir = o.data + "/middlebury2014-quarter/" + name;
    if (!std::ifstream(dir + "/disp0GT.pfm").good()) {
      std::printf("| %s | (skipped: no ground truth, %s/disp0GT.pfm) |\n", name.c_str(),
                  dir.c_str());
      continue;
    }
    const MiddleburyScene s = load_middlebury_scene(dir);
    for (MatchMethod method : {MatchMethod::Euclidean, MatchMethod::CosineNorm})
      for (bool filters : {false, true}) {
        MatchParams p;
        detection_defaults(p);
        p.matcher.method = method;
        p.matcher.constraints.epipolar_tolerance = 1.0;
        p.matcher.constraints.min_disparity = 0;
        p.matcher.constraints.max_disparity = s.calib.ndisp;
        filters_off(p);
        if (filters) {
          filters_on(p);
          apply_set(p, o.set);
        }
        const StereoMatchResult r = match_stereo(s.left, s.right, cv::Mat(), cv::Mat(), p);
        const MatchAccuracy acc = evaluate_matches(r.matches, s.disp_gt, s.mask_nocc, 1.0);
        std::size_t nearer = 0, farther = 0, other = 0;
        for (const StereoMatch &m : r.matches) {
          const int x = int(std::lround(m.xl)), y = int(std::lround(m.yl));
          if (x < 0 || y < 0 || x >= s.disp_gt.cols || y >= s.disp_gt.rows ||
              (!s.mask_nocc.empty() && s.mask_nocc.at<std::uint8_t>(y, x) != 255))
            continue;
          const float t = s.disp_gt.at<float>(y, x), d = m.disparity();
          if (!std::isfinite(t) || (std::abs(d - t) <= 1.0f && std::abs(m.yr - m.yl) <= 1.0f))
            continue;
          if (edge_ring(s.disp_gt, x, y, d) > 0)
            (d > t ? nearer : farther) += 1;
          else
            ++other;
        }
        std::printf("| %s | %s | %s | %zu/%zu | %zu | %zu | %zu | %.2f | %zu | %zu | %zu |\n",
                    name.c_str(), match_method_name(method), filters ? "on" : "off",
                    r.stats.keypoints[0], r.stats.keypoints[1], r.matches.size(), acc.evaluated,
                    acc.wrong(), 100.0 * acc.correct_rate(), nearer, farther, other);
        std::fflush(stdout);
      }
  }
}

// The whole siftmatch step (both views detected concurrently, matching, refinement, filters),
// on treetestsrc pairs with the true canopy mask (as exgsegment's would give) and without.
void timing(const Options &o)
{
  std::printf("\n## Timing of the siftmatch step (euclidean, constraints and two-layer test on)\n\n"
              "Seed 1 at 2.0 m; median of %d runs after one warm-up; canopy = the rendered "
              "canopy mask, rectified (stands in for exgsegment's); CPU ms = user + system time "
              "of the process during the run (both threads; independent of other load).\n\n"
              "| size | scale | nfeatures | contrast | mask | keypoints L/R | matches | correct %% "
              "| detect ms | match ms | refine ms | total ms | CPU ms |\n"
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
              o.runs);
  struct Setting {
    cv::Size size;
    double scale;
    int nfeatures;
    double contrast;
    int inset; // mask-inset (acts on the canopy rows only)
  };
  // The first three rows of each size: OpenCV's contrast threshold without the inset (0.04, no
  // inset), 0.035 with inset 4, and siftmatch's defaults (0.02, inset 4).
  const Setting settings[] = {
      {{1296, 972}, 0.5, 0, 0.04, 0},    {{1296, 972}, 0.5, 0, 0.035, 4},
      {{1296, 972}, 0.5, 0, 0.02, 4},    {{1296, 972}, 0.5, 0, 0.035, 0},
      {{1296, 972}, 0.5, 0, 0.02, 0},    {{1296, 972}, 0.4, 0, 0.02, 0},
      {{1296, 972}, 0.5, 1500, 0.02, 0}, {{1296, 972}, 0.25, 0, 0.02, 0},
      {{2592, 1944}, 0.25, 0, 0.04, 0},  {{2592, 1944}, 0.25, 0, 0.035, 4},
      {{2592, 1944}, 0.25, 0, 0.02, 4},  {{2592, 1944}, 0.25, 0, 0.035, 0},
      {{2592, 1944}, 0.25, 0, 0.02, 0},
  };
  cv::Size rendered;
  bench::ScenePair pair;
  cv::Mat nocc, gt;
  for (const Setting &st : settings) {
    if (st.size != rendered) {
      SceneParams sp;
      sp.image_size = st.size;
      pair = bench::render_pair(sp);
      nocc = pair.d_true == pair.d_true;
      gt = pair.d_true.clone();
      gt.setTo(0, ~nocc);
      rendered = st.size;
    }
    for (bool masked : {false, true}) {
      MatchParams p = element_params(pair.geometry, st.size.width, MatchMethod::Euclidean, true, o.set);
      p.detect.scale = st.scale;
      p.detect.nfeatures = st.nfeatures;
      p.detect.contrast_threshold = st.contrast;
      p.detect.mask_inset = st.inset;
      if (!masked && st.inset > 0)
        continue; // the same as the row without the inset
      const StereoMatcher m(p);
      const cv::Mat ml = masked ? pair.mask[LEFT] : cv::Mat(), mr = masked ? pair.mask[RIGHT] : cv::Mat();
      StereoMatchResult r = m.run(pair.view[LEFT], pair.view[RIGHT], ml, mr); // warm-up
      std::vector<double> det, mat, ref, tot, cpu;
      for (int i = 0; i < o.runs; ++i) {
        const double c0 = cpu_ms();
        r = m.run(pair.view[LEFT], pair.view[RIGHT], ml, mr);
        cpu.push_back(cpu_ms() - c0);
        det.push_back(r.stats.detect_ms);
        mat.push_back(r.stats.match_ms);
        ref.push_back(r.stats.refine_ms);
        tot.push_back(r.stats.detect_ms + r.stats.match_ms + r.stats.refine_ms);
      }
      const MatchAccuracy acc = evaluate_matches(r.matches, gt, nocc, 1.0);
      const std::string mask_name =
          !masked ? "no" : st.inset > 0 ? "canopy, inset " + std::to_string(st.inset) : "canopy";
      std::printf("| %dx%d | %.2g | %d | %.2g | %s | %zu/%zu | %zu | %.2f | %.1f | %.1f | %.1f | "
                  "%.1f | %.0f |\n",
                  st.size.width, st.size.height, st.scale, st.nfeatures, st.contrast,
                  mask_name.c_str(),
                  r.stats.keypoints[0], r.stats.keypoints[1],
                  r.matches.size(), 100.0 * acc.correct_rate(), median(det), median(mat),
                  median(ref), median(tot), median(cpu));
      std::fflush(stdout);
    }
  }
}

// The siftmatch step alone on the timing pair (1296x972, seed 1 at 2.0 m, canopy mask), with
// siftmatch's defaults then --set, --runs times on one OpenCV thread (the right view still in its
// own thread, as siftmatch does): under callgrind the instructions of --runs N minus those of
// --runs 0, over N, are the step's, repeatable whatever the load (bench/callgrind-step.sh).
void step(const Options &o)
{
  cv::setNumThreads(1); // no pool threads spinning: the count is the work
  SceneParams sp;
  sp.image_size = o.size;
  const bench::ScenePair pair = bench::render_pair(sp);
  const MatchParams p =
      element_params(pair.geometry, o.size.width, MatchMethod::Euclidean, true, o.set);
  const StereoMatcher m(p);
  StereoMatchResult r;
  for (int i = 0; i < o.runs; ++i)
    r = m.run(pair.view[LEFT], pair.view[RIGHT], pair.mask[LEFT], pair.mask[RIGHT]);
  std::printf("step %s: %d run(s), keypoints %zu/%zu, matches %zu\n",
              o.set.empty() ? "(siftmatch's defaults)" : o.set.c_str(), o.runs,
              r.stats.keypoints[0], r.stats.keypoints[1], r.matches.size());
}

} // namespace

int main(int argc, char **argv)
{
  Options o;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto next = [&]() -> std::string {
        if (i + 1 >= argc)
          throw std::runtime_error(a + " needs a value");
        return argv[++i];
      };
      if (a == "--seeds") o.seeds = bench::parse_list(next());
      else if (a == "--distances") o.distances = bench::parse_list(next());
      else if (a == "--size") {
        const auto s = bench::parse_sizes(next());
        if (s.empty())
          throw std::runtime_error("--size: expected WxH");
        o.size = s[0];
      } else if (a == "--runs") o.runs = std::max(0, std::atoi(next().c_str()));
      else if (a == "--only") o.only = next();
      else if (a == "--set") o.set = next();
      else if (a == "--data") o.data = next();
      else if (a == "--mask") o.mask = true;
      else throw std::runtime_error("unknown option " + a);
    }
    auto want = [&](const char *what) { return o.only.find(what) != std::string::npos; };
    if (o.runs == 0 && o.only != "step")
      throw std::runtime_error("--runs 0 is only for --only step");
    if (want("table") || want("errors") || want("row")) {
      const std::vector<Pair> pairs = render_pairs(o);
      if (want("table"))
        table(pairs, o);
      if (want("row"))
        one_row(pairs, o);
      if (want("errors"))
        errors(pairs, o);
    }
    if (want("jadeplant") || want("middlebury"))
      middlebury(o, !want("middlebury"));
    if (want("timing"))
      timing(o);
    if (want("step"))
      step(o);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "bench-match-scene: %s\n", e.what());
    return 1;
  }
  return 0;
}
