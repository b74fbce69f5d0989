// The project's own SIFT for rectified stereo views: Lowe's detector (difference-of-Gaussian
// extrema, sub-pixel location, contrast and edge tests) with upright descriptors.
//
// Why not OpenCV's: on rectified views the rows of both images are the epipolar lines, so the
// keypoint's dominant orientation carries nothing the matcher needs. OpenCV gives a keypoint one
// descriptor per dominant orientation (about 17 % more descriptors for the same places) and
// spends its orientation histograms on every keypoint; its API also builds the pyramid again
// when descriptors are computed apart from detection. This one builds the pyramid once, keeps
// it, and describes only the keypoints it is asked for (after a caller has dropped those that
// cannot match), each once, at angle 0.
//
// Conventions follow OpenCV 4.6's SIFT (so the matchers' thresholds carry over): 3 layers per
// octave, sigma 1.6, a first octave upsampled 2x, descriptors of 4x4 cells x 8 orientations
// normalised, clipped at 0.2, renormalised and scaled to 0..255 (stored as CV_32F). Positions
// are exact: no +0.25 px offset from the upsampling (OpenCV 4.6 has one).
#pragma once

#include <opencv2/core.hpp>

#include <vector>

namespace treestereo {

struct SiftParams {
  int layers = 3;                    // scales per octave
  double sigma = 1.6;                // blur of each octave's first layer
  double contrast_threshold = 0.04;  // on [0,1] grey, divided by `layers` (OpenCV's convention)
  double edge_threshold = 10.0;      // ratio of principal curvatures allowed
};

// The scale space of one image: Gaussian and difference-of-Gaussian layers per octave.
struct SiftPyramid {
  std::vector<std::vector<cv::Mat>> gauss; // [octave][layer], CV_32F, layers + 3 per octave
  std::vector<std::vector<cv::Mat>> dog;   // [octave][layer], layers + 2 per octave
};

class UprightSift {
public:
  explicit UprightSift(const SiftParams &params = {});

  // Builds `pyr` for `gray` (CV_8UC1) and returns its keypoints in `gray`'s pixel coordinates
  // (pixel centres at integers), in no particular order. `mask`: empty or
  // CV_8UC1 of gray's size; a keypoint is kept where it is non-zero at its rounded position.
  // Keypoint fields: pt, size (diameter, 2 x sigma in px of `gray`), response (|contrast|),
  // octave (the pyramid's octave index + (layer << 8)), angle 0.
  std::vector<cv::KeyPoint> detect(const cv::Mat &gray, const cv::Mat &mask,
                                   SiftPyramid &pyr) const;

  // One 128-float row per keypoint of `kps` (as detect() returned them, any subset, any order).
  // With `needed` (one flag per keypoint), only the flagged rows are computed, the others are 0.
  cv::Mat describe(const SiftPyramid &pyr, const std::vector<cv::KeyPoint> &kps,
                   const std::vector<char> &needed = {}) const;

  const SiftParams &params() const { return params_; }

private:
  SiftParams params_;
  std::vector<double> layer_sigma_; // incremental blur from layer i-1 to layer i
};

} // namespace treestereo
