// A rectified stereo geometry for the unit tests: one focal length, both principal points at the
// view's centre (no doffs), the given baseline.
#pragma once

#include "treestereo/types.hpp"

#include <opencv2/core.hpp>

inline treestereo::StereoGeometry simple_geometry(cv::Size size, double f, double baseline_mm)
{
  treestereo::StereoGeometry g;
  g.view_size = size;
  g.fx = g.fy = f;
  g.cx[treestereo::LEFT] = g.cx[treestereo::RIGHT] = size.width / 2.0;
  g.cy = size.height / 2.0;
  g.baseline_mm = baseline_mm;
  return g;
}
