// SIFT keypoints and descriptors of one rectified view, detected fast: only inside the
// vegetation's bounding box and optionally on a downscaled copy, reported at full resolution.
#pragma once

#include "treestereo/sift.hpp"
#include "treestereo/types.hpp"

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include <vector>

namespace treestereo {

// Which SIFT runs: OpenCV 4.6's (one descriptor per dominant orientation) or the project's own
// upright SIFT (sift.hpp: one descriptor per place, at angle 0, the pyramid built once).
enum class SiftEngine { OpenCV, Upright };

struct DetectParams {
  SiftEngine engine = SiftEngine::OpenCV;
  int nfeatures = 0;                 // keep the N strongest per view; 0 = all
  double contrast_threshold = 0.04;  // SIFT's contrastThreshold (Lowe: 0.03 on [0,1] / 3 layers)
  double scale = 1.0;                // detect on the view resized by this factor, (0, 1]
  bool use_mask = true;              // keypoints only where the mask is non-zero (when given)
  bool roi = true;                   // detect only in the mask's bounding box (when given)
  int roi_margin = 16;               // px at full resolution added around that box
  // Keypoints only where the mask, eroded by this many px of the detection image (a disc), is
  // set: none within mask_inset px of the canopy's edge, where SIFT's descriptor window (radius
  // ~10 x its scale) straddles the background at another depth. 0 = the mask as it is. The
  // view's border is not an edge (it does not erode the mask).
  int mask_inset = 0;
};

// Keypoints in the coordinates of the full-resolution view that was passed in.
struct Features {
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;       // CV_32F, one 128-float row per keypoint
  cv::Rect region;           // the part of the view detection ran on (full resolution)
  double scale = 1.0;        // the detection scale used
  double ms = 0;             // wall time of the detection

  std::size_t size() const { return keypoints.size(); }
};

// A view as 8-bit grey, without copying when it already is. Accepts CV_8UC1/3/4 (BGR/BGRA);
// anything else throws BadInput.
cv::Mat to_gray8(const cv::Mat &view);

// The same for packed pixels whose R, G and B sit where `order` says (RGB, xRGB, ABGR...; its
// channels must be the view's): 0.299 R + 0.587 G + 0.114 B, rounded.
cv::Mat to_gray8(const cv::Mat &view, const ChannelOrder &order);

// The region detection should run on: the bounding box of the mask's non-zero pixels grown by
// `margin` and clipped to the view; the whole view when the mask is empty; an empty rect when
// the mask has no non-zero pixel.
cv::Rect detection_region(const cv::Size &view_size, const cv::Mat &mask, int margin);

// Throws BadInput unless `mask` is CV_8UC1 of `view_size`; `where` (the caller) goes in the
// detail.
void check_mask(const cv::Mat &mask, const cv::Size &view_size, const char *where);

// Features found but not all described yet (FeatureDetector::locate): the upright engine keeps its
// pyramid and its keypoints in the detection image's coordinates for describe().
struct LocatedFeatures {
  Features features;                       // keypoints set; descriptors only from OpenCV's engine
  SiftPyramid pyramid;                     // the upright engine's
  std::vector<cv::KeyPoint> detection_kps; // the upright engine's, in the detection image
};

// One SIFT detector, created once and reused for every frame.
//
// Speed notes: SIFT starts one octave below the input (firstOctave = -1, the image is upsampled
// 2x with linear interpolation): OpenCV 4.6's API has no switch for it (`enable_precise_upscale`
// only exists from OpenCV 4.8) and the upright engine does the same, to find the same keypoints.
// The upright engine costs about 44 % fewer instructions (docs/results.md, "Upright SIFT engine
// (2026-12-01)"): no
// orientation histograms, one descriptor per place, none for keypoints a caller does not need
// (locate / describe). Because of the upsampling, detecting at scale 0.5 still builds a base
// octave at about the view's full size, but from an interpolated half-size image:
// it costs roughly a quarter of full-resolution detection and finds the coarser keypoints.
// Cropping to the canopy's box first is the other big saving.
class FeatureDetector {
public:
  explicit FeatureDetector(const DetectParams &params = {});

  // `view`: 8-bit grey, BGR or BGRA, possibly a ROI of a side-by-side frame. `mask`: empty, or
  // CV_8U of the view's size. Throws BadInput on bad input.
  Features detect(const cv::Mat &view, const cv::Mat &mask = cv::Mat()) const;

  // The same in two steps, so that a caller can skip the descriptors of keypoints it will not
  // use (those without a candidate in the other view): locate() finds the keypoints; describe()
  // computes the descriptors of the keypoints whose `needed` entry is non-zero (all when
  // `needed` is empty) and gives the others a row of zeros. OpenCV's engine describes every
  // keypoint in locate() (its API cannot describe later without building the pyramid again).
  LocatedFeatures locate(const cv::Mat &view, const cv::Mat &mask = cv::Mat()) const;
  Features describe(LocatedFeatures &&located, const std::vector<char> &needed = {}) const;

  const DetectParams &params() const { return params_; }

private:
  DetectParams params_;
  cv::Ptr<cv::SIFT> sift_;      // the OpenCV engine
  UprightSift upright_;         // the upright engine
  cv::Mat inset_kernel_; // a disc of radius mask_inset; empty when it is 0
};

// One-shot convenience: creates a detector and runs it once.
Features detect_features(const cv::Mat &view, const cv::Mat &mask, const DetectParams &params);

} // namespace treestereo
