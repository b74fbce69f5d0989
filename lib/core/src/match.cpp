#include "treestereo/match.hpp"

#include "treestereo/errors.hpp"

#include <opencv2/core/hal/hal.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <future>
#include <stdexcept>

namespace treestereo {

MatchMethod parse_match_method(const std::string &name)
{
  if (name == "euclidean")
    return MatchMethod::Euclidean;
  if (name == "cosine-norm")
    return MatchMethod::CosineNorm;
  throw BadSettings("Unknown match method '" + name + "': use euclidean or cosine-norm.",
                    "parse_match_method(\"" + name + "\")");
}

const char *match_method_name(MatchMethod method)
{
  return method == MatchMethod::Euclidean ? "euclidean" : "cosine-norm";
}

DisparityRange disparity_range_for_depth(const StereoGeometry &g, double z_near_mm,
                                         double z_far_mm)
{
  if (!(g.fx > 0 && g.baseline_mm > 0))
    throw BadInput("The stereo geometry has no focal length or baseline: the disparity range "
                   "needs a calibrated pair (fx and baseline above 0).",
                   "disparity_range_for_depth: fx=" + std::to_string(g.fx) +
                       " baseline_mm=" + std::to_string(g.baseline_mm));
  if (!(z_near_mm > 0 && z_far_mm > z_near_mm))
    throw BadSettings("The depth range for matching is empty: set the near depth above 0 and "
                      "the far depth above it.",
                      "disparity_range_for_depth: near " + std::to_string(z_near_mm) +
                          " mm, far " + std::to_string(z_far_mm) + " mm");
  const double k = g.fx * g.baseline_mm;
  return {k / z_far_mm + g.doffs(), k / z_near_mm + g.doffs()};
}

namespace {

constexpr int kDescriptorSize = 128;

enum class Outcome : std::uint8_t { Matched, NoEpipolar, NoDisparity, Ambiguous };

struct Choice {
  int j = -1;       // index in the target view
  float score = 0;  // smaller is better
  Outcome outcome = Outcome::Matched;
};

void check_features(const Features &f, const char *which)
{
  if (f.descriptors.rows != int(f.keypoints.size()) ||
      (f.descriptors.rows > 0 &&
       (f.descriptors.type() != CV_32F || f.descriptors.cols != kDescriptorSize)))
    throw BadInput(std::string("The ") + which +
                       " features cannot be matched: give one float descriptor of 128 values per "
                       "keypoint.",
                   std::string("match: ") + which + " descriptors " +
                       std::to_string(f.descriptors.rows) + "x" +
                       std::to_string(f.descriptors.cols) + " of type " +
                       std::to_string(f.descriptors.type()) + " for " +
                       std::to_string(f.keypoints.size()) + " keypoints");
}

std::vector<float> descriptor_norms(const cv::Mat &d)
{
  std::vector<float> n(std::size_t(d.rows));
  for (int i = 0; i < d.rows; ++i)
    n[std::size_t(i)] = float(cv::norm(d.row(i), cv::NORM_L2));
  return n;
}

// The target keypoints bucketed by pixel row, so a query only looks at rows within the band.
class RowIndex {
public:
  explicit RowIndex(const std::vector<cv::KeyPoint> &kps)
  {
    int rows = 0;
    for (const cv::KeyPoint &k : kps)
      rows = std::max(rows, int(std::floor(k.pt.y)) + 1);
    rows_.resize(std::size_t(std::max(rows, 0)));
    for (std::size_t j = 0; j < kps.size(); ++j) {
      const int r = int(std::floor(kps[j].pt.y));
      if (r >= 0)
        rows_[std::size_t(r)].push_back(int(j));
    }
  }
  // f(j) for the keypoints of the rows within tol of y, until f returns false.
  template <class F> void for_each_near(float y, double tol, F &&f) const
  {
    const int r0 = std::max(0, int(std::floor(double(y) - tol)));
    const int r1 = std::min(int(rows_.size()) - 1, int(std::floor(double(y) + tol)));
    for (int r = r0; r <= r1; ++r)
      for (int j : rows_[std::size_t(r)])
        if (!f(j))
          return;
  }

private:
  std::vector<std::vector<int>> rows_;
};

// One view's side of a matching direction.
struct Side {
  const Features *f;
  std::vector<float> norms;
  bool is_left;
};

enum class Pairing : std::uint8_t { OutOfBand, OutOfRange, Candidate };

// Whether target keypoint `t` may be the match of query keypoint `q` under the constraints.
Pairing pairing(const cv::Point2f &q, const cv::Point2f &t, bool query_is_left,
                const StereoConstraints &c)
{
  if (c.epipolar_tolerance >= 0 && std::abs(double(t.y) - double(q.y)) > c.epipolar_tolerance)
    return Pairing::OutOfBand;
  const double d = query_is_left ? double(q.x) - t.x : double(t.x) - q.x;
  return d >= c.min_disparity && d <= c.max_disparity ? Pairing::Candidate : Pairing::OutOfRange;
}

// Calls f(j) for the target keypoints that can pass the epipolar band of `q` (all of them when
// the band is off), until f returns false.
template <class F>
void for_each_in_band(const cv::KeyPoint &q, const std::vector<cv::KeyPoint> &tk,
                      const RowIndex &index, const StereoConstraints &c, F &&f)
{
  if (c.epipolar_tolerance >= 0) {
    index.for_each_near(q.pt.y, c.epipolar_tolerance, f);
  } else {
    for (int j = 0; j < int(tk.size()); ++j)
      if (!f(j))
        return;
  }
}

// Indices of target keypoints that satisfy the stereo constraints for query keypoint `q`.
Outcome gather_candidates(const cv::KeyPoint &q, const Side &query, const Side &target,
                          const RowIndex &index, const StereoConstraints &c, std::vector<int> &out)
{
  out.clear();
  const auto &tk = target.f->keypoints;
  bool any_in_band = false;
  for_each_in_band(q, tk, index, c, [&](int j) {
    const Pairing p = pairing(q.pt, tk[std::size_t(j)].pt, query.is_left, c);
    any_in_band |= p != Pairing::OutOfBand;
    if (p == Pairing::Candidate)
      out.push_back(j);
    return true;
  });
  if (!any_in_band)
    return Outcome::NoEpipolar;
  return out.empty() ? Outcome::NoDisparity : Outcome::Matched;
}

float l2sqr(const cv::Mat &a, int i, const cv::Mat &b, int j)
{
  return cv::hal::normL2Sqr_(a.ptr<float>(i), b.ptr<float>(j), kDescriptorSize);
}

struct EuclideanChooser {
  double ratio;
  Choice operator()(const Side &q, int i, const Side &t, const std::vector<int> &cands) const
  {
    float d1 = std::numeric_limits<float>::max(), d2 = d1;
    int best = -1;
    for (int j : cands) {
      const float d = l2sqr(q.f->descriptors, i, t.f->descriptors, j);
      if (d < d1) {
        d2 = d1;
        d1 = d;
        best = j;
      } else if (d < d2) {
        d2 = d;
      }
    }
    Choice c{best, std::sqrt(d1), Outcome::Matched};
    if (ratio < 1.0 && cands.size() > 1 && !(double(d1) < ratio * ratio * double(d2)))
      c.outcome = Outcome::Ambiguous;
    return c;
  }
};

struct CosineNormChooser {
  double ratio;
  int k;
  Choice operator()(const Side &q, int i, const Side &t, const std::vector<int> &cands) const
  {
    const double qn = q.norms[std::size_t(i)];
    thread_local std::vector<std::pair<float, int>> angles;
    angles.clear();
    for (int j : cands) {
      const double tn = t.norms[std::size_t(j)];
      double cosv = 0.0;
      if (qn > 0 && tn > 0) {
        // a.b from |a-b|^2 = |a|^2 + |b|^2 - 2 a.b: one SIMD kernel serves both matchers.
        const double d2 = l2sqr(q.f->descriptors, i, t.f->descriptors, j);
        cosv = std::clamp((qn * qn + tn * tn - d2) / (2.0 * qn * tn), -1.0, 1.0);
      }
      angles.emplace_back(float(std::acos(cosv)), j);
    }
    const std::size_t keep = std::min(angles.size(), std::size_t(k));
    // Sort at least two: the ratio test needs the second smallest angle.
    const std::size_t sorted = std::min(angles.size(), std::max<std::size_t>(keep, 2));
    std::partial_sort(angles.begin(), angles.begin() + std::ptrdiff_t(sorted), angles.end());
    Choice c;
    double best_delta = std::numeric_limits<double>::max();
    for (std::size_t m = 0; m < keep; ++m) { // in angle order: a tie keeps the smaller angle
      const double delta = std::abs(qn - double(t.norms[std::size_t(angles[m].second)]));
      if (delta < best_delta) {
        best_delta = delta;
        c.j = angles[m].second;
        c.score = angles[m].first;
      }
    }
    if (ratio < 1.0 && angles.size() > 1 && !(angles[0].first < ratio * angles[1].first))
      c.outcome = Outcome::Ambiguous;
    return c;
  }
};

// Matches every query keypoint into the target view under the constraints.
template <class Chooser>
std::vector<Choice> one_way(const Side &query, const Side &target, const StereoConstraints &c,
                            const Chooser &choose, std::size_t &tested)
{
  const auto &qk = query.f->keypoints;
  const RowIndex index(target.f->keypoints);
  std::vector<Choice> out(qk.size());
  std::vector<std::size_t> counts(qk.size(), 0);
  cv::parallel_for_(cv::Range(0, int(qk.size())), [&](const cv::Range &r) {
    std::vector<int> cands;
    for (int i = r.start; i < r.end; ++i) {
      const Outcome o = gather_candidates(qk[std::size_t(i)], query, target, index, c, cands);
      counts[std::size_t(i)] = cands.size();
      if (o != Outcome::Matched) {
        out[std::size_t(i)].outcome = o;
        continue;
      }
      out[std::size_t(i)] = choose(query, i, target, cands);
    }
  });
  for (std::size_t n : counts)
    tested += n;
  return out;
}

template <class Chooser>
std::vector<StereoMatch> match_with(const Features &left, const Features &right, bool left_is_ref,
                                    const StereoConstraints &c, const Chooser &choose,
                                    MatchStats &stats)
{
  check_features(left, "left");
  check_features(right, "right");
  Side l{&left, descriptor_norms(left.descriptors), true};
  Side r{&right, descriptor_norms(right.descriptors), false};
  const Side &ref = left_is_ref ? l : r;
  const Side &other = left_is_ref ? r : l;

  const std::vector<Choice> fwd = one_way(ref, other, c, choose, stats.candidates_tested);
  std::vector<Choice> back;
  if (c.mutual)
    back = one_way(other, ref, c, choose, stats.candidates_tested);

  std::vector<StereoMatch> matches;
  for (std::size_t i = 0; i < fwd.size(); ++i) {
    const Choice &ch = fwd[i];
    switch (ch.outcome) {
    case Outcome::NoEpipolar: ++stats.rejected_epipolar; continue;
    case Outcome::NoDisparity: ++stats.rejected_disparity; continue;
    case Outcome::Ambiguous: ++stats.rejected_ratio; continue;
    case Outcome::Matched: break;
    }
    if (c.mutual) {
      const Choice &b = back[std::size_t(ch.j)];
      if (b.outcome != Outcome::Matched || b.j != int(i)) {
        ++stats.rejected_mutual;
        continue;
      }
    }
    const cv::Point2f &pl = left_is_ref ? left.keypoints[i].pt : left.keypoints[std::size_t(ch.j)].pt;
    const cv::Point2f &pr = left_is_ref ? right.keypoints[std::size_t(ch.j)].pt : right.keypoints[i].pt;
    matches.push_back(StereoMatch{pl.x, pl.y, pr.x, pr.y, ch.score});
  }
  std::sort(matches.begin(), matches.end(), [](const StereoMatch &a, const StereoMatch &b) {
    return a.yl != b.yl ? a.yl < b.yl : a.xl != b.xl ? a.xl < b.xl : a.xr < b.xr;
  });
  // SIFT gives one keypoint per dominant orientation at the same place: report the pair once.
  matches.erase(std::unique(matches.begin(), matches.end(),
                            [](const StereoMatch &a, const StereoMatch &b) {
                              return a.xl == b.xl && a.yl == b.yl && a.xr == b.xr && a.yr == b.yr;
                            }),
                matches.end());
  return matches;
}

// For each keypoint of `query`: does any keypoint of `target` pass the constraints with it? The
// relation is symmetric, so a keypoint without one is nobody's candidate either: the matchers
// never read its descriptor.
std::vector<char> has_candidate(const std::vector<cv::KeyPoint> &query, bool query_is_left,
                                const std::vector<cv::KeyPoint> &target,
                                const StereoConstraints &c)
{
  const RowIndex index(target);
  std::vector<char> out(query.size(), 0);
  for (std::size_t i = 0; i < query.size(); ++i)
    for_each_in_band(query[i], target, index, c, [&](int j) {
      out[i] = pairing(query[i].pt, target[std::size_t(j)].pt, query_is_left, c) ==
               Pairing::Candidate;
      return !out[i];
    });
  return out;
}

void check_matcher_params(const MatcherParams &p)
{
  if (!(p.ratio > 0))
    throw BadSettings("The matching ratio is out of range: set it above 0 (1 or more turns the "
                      "ratio test off).",
                      "MatcherParams.ratio = " + std::to_string(p.ratio));
  if (p.candidates < 1)
    throw BadSettings("The matching setting candidates is out of range: set it to 1 or more.",
                      "MatcherParams.candidates = " + std::to_string(p.candidates));
  if (p.constraints.min_disparity > p.constraints.max_disparity)
    throw BadSettings("The matching disparity range is empty: set min_disparity at most "
                      "max_disparity.",
                      "StereoConstraints: min_disparity " +
                          std::to_string(p.constraints.min_disparity) + " > max_disparity " +
                          std::to_string(p.constraints.max_disparity));
}

} // namespace

EuclideanMatcher::EuclideanMatcher(const MatcherParams &params) : params_(params)
{
  check_matcher_params(params_);
}

std::vector<StereoMatch> EuclideanMatcher::match(const Features &left, const Features &right,
                                                 MatchStats &stats) const
{
  return match_with(left, right, true, params_.constraints, EuclideanChooser{params_.ratio}, stats);
}

CosineNormMatcher::CosineNormMatcher(const MatcherParams &params) : params_(params)
{
  check_matcher_params(params_);
}

std::vector<StereoMatch> CosineNormMatcher::match(const Features &left, const Features &right,
                                                  MatchStats &stats) const
{
  // The paper: the view with more keypoints is the reference (left on a tie).
  const bool left_is_ref = left.size() >= right.size();
  return match_with(left, right, left_is_ref, params_.constraints,
                    CosineNormChooser{params_.ratio, params_.candidates}, stats);
}

std::unique_ptr<Matcher> make_matcher(const MatcherParams &params)
{
  if (params.method == MatchMethod::Euclidean)
    return std::make_unique<EuclideanMatcher>(params);
  return std::make_unique<CosineNormMatcher>(params);
}

namespace {
double ms_since(std::chrono::steady_clock::time_point t0)
{
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}
} // namespace

RefineParams refine_params_for_scale(const RefineParams &params, double detect_scale)
{
  RefineParams p = params;
  if (detect_scale > 0 && detect_scale < 0.5) {
    const double k = 0.5 / detect_scale;
    p.half_window = int(std::lround(params.half_window * k));
    p.layer_half_window = int(std::lround(params.layer_half_window * k));
  }
  return p;
}

StereoMatcher::StereoMatcher(const MatchParams &params)
    : params_(params), refine_(refine_params_for_scale(params.refine_params, params.detect.scale)),
      detector_{FeatureDetector(params.detect), FeatureDetector(params.detect)},
      matcher_(make_matcher(params.matcher)),
      worker_(params.parallel_detect ? std::make_unique<Worker>() : nullptr)
{
  check_refine_params(refine_);
}

StereoMatchResult StereoMatcher::run(const cv::Mat &left, const cv::Mat &right,
                                     const cv::Mat &mask_left, const cv::Mat &mask_right) const
{
  if (left.empty() || right.empty())
    throw BadInput("A view is empty: stereo matching needs a left and a right image.",
                   "StereoMatcher::run: left " + std::to_string(left.cols) + "x" +
                       std::to_string(left.rows) + ", right " + std::to_string(right.cols) + "x" +
                       std::to_string(right.rows));
  if (params_.refine && left.size() != right.size())
    throw BadInput("The views differ in size: stereo matching with refinement needs a left and "
                   "a right view of the same size.",
                   "StereoMatcher::run: left " + std::to_string(left.cols) + "x" +
                       std::to_string(left.rows) + ", right " + std::to_string(right.cols) + "x" +
                       std::to_string(right.rows));
  StereoMatchResult res;
  auto t0 = std::chrono::steady_clock::now();
  // Grey once per view, for detection and for refinement, in the view's own thread. Then, with
  // the upright engine, descriptors only for keypoints with a candidate in the other view.
  const bool prune = params_.detect.engine == SiftEngine::Upright;
  const StereoConstraints &c = params_.matcher.constraints;
  auto needed = [&](const LocatedFeatures &a, const LocatedFeatures &b, bool a_is_left) {
    return prune ? has_candidate(a.features.keypoints, a_is_left, b.features.keypoints, c)
                 : std::vector<char>();
  };
  Features fl, fr;
  cv::Mat gl, gr;
  if (params_.parallel_detect) {
    auto right_job = worker_->run([&] {
      gr = to_gray8(right);
      return detector_[RIGHT].locate(gr, mask_right);
    });
    LocatedFeatures ll, lr;
    {
      const WaitFor waited(right_job); // it reads the caller's views and writes gr
      gl = to_gray8(left);
      ll = detector_[LEFT].locate(gl, mask_left);
      lr = right_job.get();
    }
    const std::vector<char> need_l = needed(ll, lr, true), need_r = needed(lr, ll, false);
    auto describe_right = worker_->run(
        [&] { return detector_[RIGHT].describe(std::move(lr), need_r); });
    {
      const WaitFor waited(describe_right);
      fl = detector_[LEFT].describe(std::move(ll), need_l);
      fr = describe_right.get();
    }
  } else {
    gl = to_gray8(left);
    gr = to_gray8(right);
    LocatedFeatures ll = detector_[LEFT].locate(gl, mask_left);
    LocatedFeatures lr = detector_[RIGHT].locate(gr, mask_right);
    const std::vector<char> need_l = needed(ll, lr, true), need_r = needed(lr, ll, false);
    fl = detector_[LEFT].describe(std::move(ll), need_l);
    fr = detector_[RIGHT].describe(std::move(lr), need_r);
  }
  res.stats.detect_ms = ms_since(t0);
  res.stats.keypoints = {{fl.size(), fr.size()}};

  t0 = std::chrono::steady_clock::now();
  res.matches = matcher_->match(fl, fr, res.stats);
  res.stats.match_ms = ms_since(t0);

  if (params_.refine) {
    t0 = std::chrono::steady_clock::now();
    res.stats.rejected_refine = refine_matches(gl, gr, res.matches, refine_);
    res.stats.refine_ms = ms_since(t0);
  }
  res.stats.matches = res.matches.size();
  return res;
}

StereoMatchResult match_stereo(const cv::Mat &left, const cv::Mat &right, const cv::Mat &mask_left,
                               const cv::Mat &mask_right, const MatchParams &params)
{
  return StereoMatcher(params).run(left, right, mask_left, mask_right);
}

} // namespace treestereo
