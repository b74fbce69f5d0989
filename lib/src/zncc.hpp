// Internal (not installed): zero-mean normalised cross-correlation of square patches on the rows
// of a rectified pair, shared by match refinement (refine.cpp) and densification (densify.cpp).
// Images are CV_8UC1; callers keep every patch inside the image.
#pragma once

#include <opencv2/core.hpp>

#include <cmath>
#include <cstdint>
#include <vector>

namespace treestereo::detail {

// Zero-mean copy of the (2h+1)^2 patch centred at (cx, cy) and its norm; false when it has no
// texture (a flat patch has no correlation peak to find).
bool centred_patch(const cv::Mat &img, int cx, int cy, int h, std::vector<float> &out,
                   double &norm);

// ZNCC of the centred left patch against the right patch centred at (cx, cy); -1 when the right
// patch is flat.
double zncc(const std::vector<float> &lc, double lnorm, const cv::Mat &img, int cx, int cy,
            int h);

// Linear interpolation of a row at x (x within [0, cols - 1)).
inline double sample(const std::uint8_t *row, double x)
{
  const int i = int(std::floor(x));
  const double f = x - i;
  return (1.0 - f) * row[i] + f * row[i + 1];
}

// Sub-pixel vertex of a parabola through the scores at offsets -1, 0, +1 of a peak (clamped to
// +-0.5; 0 when the three do not form a peak).
double parabola_offset(double c_minus, double c0, double c_plus);

// Gauss-Newton steps on the right patch's x position xr (sub-pixel, same row cy): minimises the
// difference of the zero-mean, unit-norm left and right patches, the right one interpolated
// linearly. Returns xr unchanged when a step would leave the image or +-1 px around the start.
double gauss_newton_x(const std::vector<float> &lc, double lnorm, const cv::Mat &img, double xr,
                      int cy, int h);

} // namespace treestereo::detail
