// The elements' defaults as lib parameters, one place each: the element's property defaults
// come from here, and so do the benches, tools and tests that stand for the element.
#pragma once

#include "treestereo/match.hpp"
#include "treestereo/types.hpp"

namespace treestereo {

// siftmatch's defaults. Where they differ from lib's (which keeps every filter off, so that
// lib's callers get every match) and why:
// - detect: the upright SIFT engine (44 % fewer instructions for the same keypoints on
//   rectified views), contrast threshold 0.02 and a mask inset of 4 px (no keypoint whose
//   descriptor window straddles the canopy's edge); docs/elements/siftmatch.md "Contrast 0.02".
// - refine: the two-layer test and its refinements (min_zncc 0.9, min_zncc_drop 0.05,
//   layer_tolerance 0.5, layer_centre_tolerance 0.7, layer_min_zncc 0.7,
//   layer_centre_min_zncc 0.6) and relocation by 1 px; docs/elements/siftmatch.md "The
//   two-layer test".
// Two values depend on the frame: the detection scale (auto_scale of the view's width) and the
// disparity range (from min_depth_mm..max_depth_mm and the rig's geometry); for_view sets both.
struct SiftmatchPreset {
  // Automatic scale: detect on a copy at most this wide. SIFT upsamples its input 2x first, so
  // its base octave is then at most 1296 px wide whatever the camera's resolution.
  static constexpr double kAutoScaleWidth = 648.0;
  // The depth range (mm) the disparity range is derived from when it is not set.
  static constexpr double kMinDepthMm = 500.0;
  static constexpr double kMaxDepthMm = 10000.0;

  // The frame-independent defaults: detection scale 1, no disparity bounds.
  static MatchParams params();
  // The largest of 1, 1/2, 1/4, ... that brings a view of this width to kAutoScaleWidth or
  // below. Powers of two keep the keypoints of different camera resolutions comparable.
  static double auto_scale(int view_width);
  // params() for one frame: auto_scale(view_width) and the disparities of kMinDepthMm..
  // kMaxDepthMm for this geometry (disparity_range_for_depth; throws as it does).
  static MatchParams for_view(const StereoGeometry &geometry, int view_width);
};

} // namespace treestereo
