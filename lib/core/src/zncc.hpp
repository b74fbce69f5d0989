// Internal (not installed): zero-mean normalised cross-correlation of square patches on the rows
// of a rectified pair, shared by match refinement (refine.cpp) and densification (densify.cpp).
// Images are CV_8UC1; callers keep every patch inside the image.
#pragma once

#include <opencv2/core.hpp>

#include <cmath>
#include <cstdint>
#include <vector>

namespace treestereo::detail {

// A patch of one view to correlate with the other: its pixels (each row padded with zeros to a
// multiple of 8, for the vector loop), their sums, and the zero-mean copy Gauss-Newton fits.
struct Patch {
  int h = 0;                        // half window
  std::vector<std::int16_t> pixels; // n() rows of stride(), zero beyond column n()
  int n() const { return 2 * h + 1; }              // side
  int stride() const { return (n() + 7) / 8 * 8; } // int16 per padded row
  std::vector<float> centred;       // n x n, the pixels less their mean
  double norm = 0;                  // of `centred`
  std::int64_t sum = 0, var = 0;    // sum of the pixels; n^2 * sum of squares - sum^2
};

// The (2h+1)^2 patch centred at (cx, cy); false when it has no texture (a flat patch has no
// correlation peak to find).
bool centred_patch(const cv::Mat &img, int cx, int cy, int h, Patch &out);

// ZNCC of the patch against the patch of `img` centred at (cx, cy) (the same size); -1 when the
// latter is flat. Computed from whole-number sums, so exactly, the same with or without the
// vector loop.
double zncc(const Patch &patch, const cv::Mat &img, int cx, int cy);

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
// difference of the zero-mean, unit-norm patch and right patch, the right one interpolated
// linearly. Returns xr unchanged when a step would leave the image or +-1 px around the start.
double gauss_newton_x(const Patch &patch, const cv::Mat &img, double xr, int cy);

} // namespace treestereo::detail
