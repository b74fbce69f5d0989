#include "treestereo/presets.hpp"

namespace treestereo {

MatchParams SiftmatchPreset::params()
{
  MatchParams p;
  p.detect.engine = SiftEngine::Upright;
  p.detect.nfeatures = 0;
  p.detect.contrast_threshold = 0.02;
  p.detect.scale = 1.0;
  p.detect.use_mask = true;
  p.detect.mask_inset = 4;
  p.matcher.method = MatchMethod::Euclidean;
  p.matcher.ratio = 0.8;
  p.matcher.candidates = 5;
  p.matcher.constraints.epipolar_tolerance = 2.0;
  p.matcher.constraints.mutual = true;
  p.refine = true;
  RefineParams &r = p.refine_params;
  r.min_zncc = 0.9;
  r.min_zncc_drop = 0.05;
  r.layer_tolerance = 0.5;
  r.layer_half_window = 5;
  r.layer_search = 3;
  r.layer_centre_tolerance = 0.7;
  r.layer_min_zncc = 0.7;
  r.layer_centre_min_zncc = 0.6;
  r.relocate = 1;
  p.parallel_detect = true;
  return p;
}

double SiftmatchPreset::auto_scale(int view_width)
{
  double s = 1.0;
  while (view_width * s > kAutoScaleWidth)
    s *= 0.5;
  return s;
}

MatchParams SiftmatchPreset::for_view(const StereoGeometry &geometry, int view_width)
{
  MatchParams p = params();
  p.detect.scale = auto_scale(view_width);
  const DisparityRange r = disparity_range_for_depth(geometry, kMinDepthMm, kMaxDepthMm);
  p.matcher.constraints.min_disparity = r.min;
  p.matcher.constraints.max_disparity = r.max;
  return p;
}

} // namespace treestereo
