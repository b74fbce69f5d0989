// Stereo matching of SIFT features between two rectified views: the plain nearest neighbour
// on Euclidean distance and the paper's "improved" cosine-angle + descriptor-norm strategy,
// both under the stereo constraints (epipolar band, disparity range, left-right consistency),
// then sub-pixel refinement of the disparity at full resolution.
#pragma once

#include "treestereo/features.hpp"
#include "treestereo/types.hpp"
#include "treestereo/worker.hpp"

#include <opencv2/core.hpp>

#include <array>
#include <cstddef>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace treestereo {

enum class MatchMethod {
  Euclidean,  // nearest neighbour on L2 distance + Lowe's ratio test
  CosineNorm, // the paper: k smallest descriptor angles, then the smallest norm difference
};

// "euclidean" / "cosine-norm"; anything else throws BadSettings listing the names.
MatchMethod parse_match_method(const std::string &name);
const char *match_method_name(MatchMethod method);

// Constraints of a rectified pair. Candidates are searched only where they hold, so a keypoint
// whose true partner is ambiguous elsewhere in the image is not disturbed by it.
struct StereoConstraints {
  double epipolar_tolerance = 2.0; // |yl - yr| <= this (px); negative = off: every keypoint is a
                                   // candidate, as in the paper
  double min_disparity = -std::numeric_limits<double>::infinity(); // d = xl - xr (px)
  double max_disparity = std::numeric_limits<double>::infinity();
  bool mutual = true;              // keep a match only when matching back from the other view
                                   // picks the same pair (left-right consistency)
};

struct DisparityRange {
  double min = 0, max = 0;
};
// Disparities of points between z_near_mm and z_far_mm (0 < near < far) in front of the rectified
// pair: d = fx * baseline / Z + doffs. Throws BadInput on an invalid geometry, BadSettings on an
// empty range.
DisparityRange disparity_range_for_depth(const StereoGeometry &geometry, double z_near_mm,
                                         double z_far_mm);

struct MatchStats {
  std::array<std::size_t, 2> keypoints{{0, 0}}; // per view (LEFT, RIGHT)
  std::size_t matches = 0;                      // kept at the end
  std::size_t candidates_tested = 0;            // descriptor comparisons, all directions
  // Reference keypoints (or matches) dropped, by the first reason that dropped them.
  std::size_t rejected_ratio = 0;     // ambiguous: best not clearly better than the second
  std::size_t rejected_epipolar = 0;  // no keypoint of the other view within the band
  std::size_t rejected_disparity = 0; // keypoints in the band, none in the disparity range
  std::size_t rejected_mutual = 0;    // the other view's keypoint matched elsewhere
  std::size_t rejected_refine = 0;    // no clear correlation peak near the match, or a failed
                                      // two-layer test (RefineParams)
  double detect_ms = 0, match_ms = 0, refine_ms = 0; // wall times
};

struct MatcherParams {
  // Euclidean by default: with the stereo constraints it is as correct as the paper's cosine-norm
  // or better, with 2-3x the matches (docs/results-matching.md).
  MatchMethod method = MatchMethod::Euclidean;
  // Ratio test: keep a reference keypoint only when its best candidate's distance (euclidean:
  // L2; cosine-norm: angle, as in Lowe's match.m) is below ratio x the second best's.
  // A single candidate passes. >= 1 turns it off (the paper states no such test).
  double ratio = 0.8;
  int candidates = 5; // cosine-norm: how many smallest angles compete on the norm difference
  StereoConstraints constraints;
};

// A descriptor matcher between the two views of a rectified pair.
class Matcher {
public:
  virtual ~Matcher() = default;
  virtual const char *name() const = 0;
  // Matches in left/right view coordinates, sorted by left keypoint (row, then column), each
  // pair once (SIFT repeats a keypoint per dominant orientation). Adds to `stats`
  // (candidates_tested, rejected_*; not keypoints/matches/times).
  virtual std::vector<StereoMatch> match(const Features &left, const Features &right,
                                         MatchStats &stats) const = 0;
};

// Left is the reference; the nearest right descriptor in L2, then the ratio test.
class EuclideanMatcher : public Matcher {
public:
  explicit EuclideanMatcher(const MatcherParams &params);
  const char *name() const override { return "euclidean"; }
  std::vector<StereoMatch> match(const Features &left, const Features &right,
                                 MatchStats &stats) const override;

private:
  MatcherParams params_;
};

// The paper's strategy. The view with more keypoints is the reference; for each reference
// descriptor the angle arccos(a.b / |a||b|) to every candidate of the other view is computed,
// the `candidates` smallest are kept and the one with the smallest | |a| - |b| | wins.
// Note: OpenCV normalises SIFT descriptors to a norm of 512 before rounding to integers, so the
// norms only differ by rounding (510.6..513.4 on Jadeplant); the norm criterion then picks
// nearly at random among the smallest angles. Score = the chosen angle (radians).
class CosineNormMatcher : public Matcher {
public:
  explicit CosineNormMatcher(const MatcherParams &params);
  const char *name() const override { return "cosine-norm"; }
  std::vector<StereoMatch> match(const Features &left, const Features &right,
                                 MatchStats &stats) const override;

private:
  MatcherParams params_;
};

std::unique_ptr<Matcher> make_matcher(const MatcherParams &params);

// Sub-pixel disparity at full resolution: ZNCC of a (2*half_window+1)^2 patch around the left
// keypoint (rounded to the pixel) against patches of the right view on the same row, at integer
// offsets within +-search px of the matcher's estimate; a parabola through the best score and its
// two neighbours gives a sub-pixel start, and up to six Gauss-Newton steps on the linearly
// interpolated right patch remove the parabola's pull towards whole pixels (on a smooth texture
// shifted by 23.37 px: every error below 0.1 px, median 0.013 px; the parabola alone: up to 0.34). A match is rejected when the best score is below
// min_zncc, when the best offset is outside +-search (the estimate was off) or when the patch
// leaves the image or has no texture. After refinement yr := yl: on a rectified pair the rows
// agree, and the vertical offset of the detection carries no depth.
//
// Then the two-layer test (layer_tolerance; negative = off) rejects matches whose patch straddles
// a depth edge: a keypoint on the background beside a leaf's or branch's edge is matched at the
// foreground's disparity, because the foreground's texture dominates its patch. The four
// quadrants of a (2*layer_half_window+1)^2 window around the left pixel (each with the centre
// row and column) and its 3x3 centre are each searched on their own within +-layer_search px of
// the refined position; every one must peak within layer_tolerance px of it. A part on the other
// depth layer peaks at its own disparity, or anywhere when it is flat. On 9 treetestsrc pairs
// (layer_tolerance 0.5) it leaves 10 of 403 wrong matches and a third of the matches
// (docs/results.md). Off here, so lib's callers get every match; the siftmatch element turns it
// on (0.5): with stereodepth's densification the chain measures the same with or without it
// (docs/elements/siftmatch.md).
//
// Three refinements of that test, all off here and on in siftmatch (with min_zncc 0.9 and
// min_zncc_drop 0.05, which rejects a patch whose correlation hardly changes along the row, such
// as a horizontal edge: the aperture problem): the 3x3 centre, only 9 pixels, has its own
// tolerance (layer_centre_tolerance), since its peak wanders further than a quadrant's on one
// surface; and each quadrant's, and the centre's, ZNCC at the refined position must reach
// layer_min_zncc and layer_centre_min_zncc: a part of the window that is not where the match puts
// it (another layer, or one hidden in the right view) correlates poorly there even when its peak
// happens to lie close. On treetestsrc pairs they remove a third to a half of the wrong matches
// the quadrant peaks leave, for 5-6% fewer matches; on Jadeplant 2 of 4 (docs/results.md).
//
// Last, relocation (relocate px; 0 = off here, 1 in siftmatch) moves each surviving match to the
// pixel its disparity belongs to: of the pixels within relocate px (Chebyshev) of the keypoint,
// the one whose own 3x3 patch differs least (sum of absolute differences, in grey levels) from
// the right view at the refined disparity, among those whose 3x3 correlates there (ZNCC >= 0.5,
// peak within 0.5 px), when it beats the keypoint's own pixel by more than 2 grey levels (the
// interpolation noise of a sub-pixel disparity); else the match stays. The disparity is kept:
// it is the 7x7 window's, and the window's dominant texture can belong to a neighbour. The wrong matches the two-layer test leaves on treetestsrc pairs
// are nearly all of that kind: a pixel in a dark gap between two near leaves, where the leaf
// behind shows, given the near leaves' disparity (1-4 px nearer than the truth). The move is at
// most relocate px, so the 3D point hardly moves, but it now stands on the surface it measures.
struct RefineParams {
  int half_window = 3;   // 7x7 patches: fewer straddle a depth edge than 11x11
  int search = 2;        // px around the estimate
  double min_zncc = 0.8; // the correlation peak must be at least this
  double min_zncc_drop = 0; // the peak must exceed the lowest score within +-(search + 1) px by
                            // at least this (0 = off; SiftmatchPreset: 0.05)
  double layer_tolerance = -1;  // px; negative = off (SiftmatchPreset: 0.5)
  int layer_half_window = 5;    // quadrants of 6x6 px
  int layer_search = 3;         // px
  double layer_centre_tolerance = -1; // px for the 3x3 centre; negative = layer_tolerance
  double layer_min_zncc = -1;         // quadrants' ZNCC at the refined position; -1 = no minimum
  double layer_centre_min_zncc = -1;  // the centre's; -1 = no minimum
  int relocate = 0; // px (0..3): move a match to the neighbour its disparity belongs to; 0 = off
};

// Throws BadSettings when a value is out of range.
void check_refine_params(const RefineParams &params);

// Refines `matches` in place and removes the rejected ones; returns how many were removed.
// `left`, `right`: the full-resolution views (8-bit grey/BGR/BGRA, the same size).
std::size_t refine_matches(const cv::Mat &left, const cv::Mat &right,
                           std::vector<StereoMatch> &matches, const RefineParams &params);

// The refinement windows for detection at `detect_scale`: half_window and layer_half_window as
// given for a scale of 0.5 or more, and 0.5 / detect_scale times as large below it. A keypoint
// found at scale 0.25 (2592x1944 views) stands for twice as many full-resolution pixels as one
// found at 0.5 (1296x972), and a 7x7 patch there holds half the texture: 2592x1944 pairs kept
// 15-29 matches in dim light (light 0.7) with 7x7 and 11x11 windows and 26-42 with 13x13 and
// 21x21, with 3 wrong of 718 (12 pairs, docs/results.md "The canopy's extremes from its points
// (2026-11-22)").
RefineParams refine_params_for_scale(const RefineParams &params, double detect_scale);

struct MatchParams {
  DetectParams detect;
  MatcherParams matcher;
  bool refine = true;
  RefineParams refine_params; // windows for a detection scale >= 0.5 (refine_params_for_scale)
  bool parallel_detect = true; // detect the two views concurrently
};

struct StereoMatchResult {
  std::vector<StereoMatch> matches;
  MatchStats stats;
};

// Detection (both views), matching and refinement with detectors created once.
class StereoMatcher {
public:
  explicit StereoMatcher(const MatchParams &params);
  // Views: rectified, 8-bit grey/BGR/BGRA (ROIs of a side-by-side frame are fine). Masks: empty
  // or CV_8U of the view's size (the vegetation). Throws BadInput on bad input.
  StereoMatchResult run(const cv::Mat &left, const cv::Mat &right, const cv::Mat &mask_left,
                        const cv::Mat &mask_right) const;
  const MatchParams &params() const { return params_; }

private:
  MatchParams params_;
  RefineParams refine_; // params_.refine_params for the detection scale
  FeatureDetector detector_[2];
  std::unique_ptr<Matcher> matcher_;
  std::unique_ptr<Worker> worker_; // detects the right view when parallel_detect
};

// One-shot convenience around StereoMatcher.
StereoMatchResult match_stereo(const cv::Mat &left, const cv::Mat &right, const cv::Mat &mask_left,
                               const cv::Mat &mask_right, const MatchParams &params);

} // namespace treestereo
