#include "treestereo/features.hpp"

#include "treestereo/errors.hpp"

#include <opencv2/imgproc.hpp>

#include <chrono>
#include <stdexcept>
#include <string>

namespace treestereo {

cv::Mat to_gray8(const cv::Mat &view)
{
  if (view.empty())
    throw BadInput("The view is empty: give an image.",
                   "to_gray8: empty cv::Mat");
  if (view.depth() != CV_8U)
    throw BadInput("The view is not 8-bit: give 8-bit grey or colour frames.",
                   "to_gray8: depth " + std::to_string(view.depth()));
  switch (view.channels()) {
  case 1:
    return view;
  case 3: {
    cv::Mat g;
    cv::cvtColor(view, g, cv::COLOR_BGR2GRAY);
    return g;
  }
  case 4: {
    cv::Mat g;
    cv::cvtColor(view, g, cv::COLOR_BGRA2GRAY);
    return g;
  }
  default:
    throw BadInput("The view has an unusable number of channels: give grey, BGR or BGRA (1, 3 "
                   "or 4 channels).",
                   "to_gray8: " + std::to_string(view.channels()) + " channels");
  }
}

cv::Mat to_gray8(const cv::Mat &view, const ChannelOrder &order)
{
  if (view.channels() == 1)
    return to_gray8(view);
  if (view.depth() != CV_8U || view.channels() != order.channels || order.r < 0 || order.g < 0 ||
      order.b < 0 || order.r >= order.channels || order.g >= order.channels ||
      order.b >= order.channels)
    throw BadInput("The view does not match its pixel layout: give an 8-bit view with the "
                   "layout's channel count and R, G, B within it.",
                   "to_gray8: view of " + std::to_string(view.channels()) + " channels, depth " +
                       std::to_string(view.depth()) + "; layout of " +
                       std::to_string(order.channels) + " channels, r=" +
                       std::to_string(order.r) + " g=" + std::to_string(order.g) +
                       " b=" + std::to_string(order.b));
  // The usual layouts by cvtColor (fixed-point, ten times faster than the general transform;
  // the two agree within one grey level).
  const bool rgb = order.r == 0 && order.g == 1 && order.b == 2;
  const bool bgr = order.r == 2 && order.g == 1 && order.b == 0;
  if (rgb || bgr) {
    cv::Mat out;
    if (order.channels == 3)
      cv::cvtColor(view, out, rgb ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY);
    else if (order.channels == 4)
      cv::cvtColor(view, out, rgb ? cv::COLOR_RGBA2GRAY : cv::COLOR_BGRA2GRAY);
    if (!out.empty())
      return out;
  }
  cv::Matx<float, 1, 4> w = cv::Matx<float, 1, 4>::zeros();
  w(0, order.r) = 0.299f;
  w(0, order.g) = 0.587f;
  w(0, order.b) = 0.114f;
  cv::Mat out;
  cv::transform(view, out, cv::Mat(w).colRange(0, order.channels));
  return out;
}

void check_mask(const cv::Mat &mask, const cv::Size &view_size, const char *where)
{
  if (mask.type() != CV_8UC1 || mask.size() != view_size)
    throw BadInput("The mask does not fit the view: give a one-channel 8-bit mask of the view's "
                   "size.",
                   std::string(where) + ": mask type " + std::to_string(mask.type()) + ", " +
                       std::to_string(mask.cols) + "x" + std::to_string(mask.rows) +
                       " for a view of " + std::to_string(view_size.width) + "x" +
                       std::to_string(view_size.height));
}

cv::Rect detection_region(const cv::Size &view_size, const cv::Mat &mask, int margin)
{
  const cv::Rect whole(cv::Point(0, 0), view_size);
  if (mask.empty())
    return whole;
  check_mask(mask, view_size, "detection_region");
  cv::Rect box = cv::boundingRect(mask); // bounding box of the non-zero pixels
  if (box.area() == 0)
    return cv::Rect();
  box.x -= margin;
  box.y -= margin;
  box.width += 2 * margin;
  box.height += 2 * margin;
  return box & whole;
}

namespace {
const DetectParams &checked(const DetectParams &params)
{
  if (!(params.scale > 0.0 && params.scale <= 1.0))
    throw BadSettings("The feature detection scale is out of range: set it above 0, at most 1.",
                      "DetectParams.scale = " + std::to_string(params.scale));
  if (params.nfeatures < 0)
    throw BadSettings("The feature detection setting nfeatures is out of range: set it to 0 or "
                      "more.",
                      "DetectParams.nfeatures = " + std::to_string(params.nfeatures));
  if (!(params.contrast_threshold > 0.0))
    throw BadSettings("The feature detection setting contrast_threshold is out of range: set it "
                      "above 0.",
                      "DetectParams.contrast_threshold = " +
                          std::to_string(params.contrast_threshold));
  if (params.roi_margin < 0)
    throw BadSettings("The feature detection setting roi_margin is out of range: set it to 0 or "
                      "more.",
                      "DetectParams.roi_margin = " + std::to_string(params.roi_margin));
  if (params.mask_inset < 0)
    throw BadSettings("The feature detection setting mask_inset is out of range: set it to 0 or "
                      "more.",
                      "DetectParams.mask_inset = " + std::to_string(params.mask_inset));
  return params;
}

// Both engines: 3 layers per octave, sigma 1.6, edge threshold 10 (OpenCV's defaults).
SiftParams sift_params(const DetectParams &params)
{
  return SiftParams{3, 1.6, params.contrast_threshold, 10.0};
}
} // namespace

FeatureDetector::FeatureDetector(const DetectParams &params)
    : params_(checked(params)), upright_(sift_params(params))
{
  const SiftParams &sp = upright_.params();
  // Float descriptors for the matchers.
  sift_ = cv::SIFT::create(params.nfeatures, sp.layers, sp.contrast_threshold, sp.edge_threshold,
                           sp.sigma, CV_32F);
  if (params.mask_inset > 0) {
    const int d = 2 * params.mask_inset + 1;
    inset_kernel_ = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(d, d));
  }
}

LocatedFeatures FeatureDetector::locate(const cv::Mat &view, const cv::Mat &mask) const
{
  const auto t0 = std::chrono::steady_clock::now();
  const cv::Mat gray = to_gray8(view);
  LocatedFeatures located;
  Features &f = located.features;
  f.scale = params_.scale;
  const bool masked = params_.use_mask && !mask.empty();
  f.region = (masked && params_.roi) ? detection_region(gray.size(), mask, params_.roi_margin)
                                     : cv::Rect(cv::Point(0, 0), gray.size());
  if (masked)
    check_mask(mask, gray.size(), "FeatureDetector::locate");

  // Too small for SIFT's border and descriptor support: nothing to find.
  if (f.region.width * params_.scale >= 16 && f.region.height * params_.scale >= 16) {
    cv::Mat img = gray(f.region), m = masked ? mask(f.region) : cv::Mat();
    if (params_.scale != 1.0) {
      cv::Mat small, small_mask;
      cv::resize(img, small, cv::Size(), params_.scale, params_.scale, cv::INTER_AREA);
      if (!m.empty())
        cv::resize(m, small_mask, small.size(), 0, 0, cv::INTER_NEAREST);
      img = small;
      m = small_mask;
    }
    if (!m.empty() && !inset_kernel_.empty()) {
      cv::Mat eroded; // the default border value of erode is the maximum: borders do not erode
      cv::erode(m, eroded, inset_kernel_);
      m = eroded;
    }
    // OpenCV's SIFT upsamples with cv::resize (pixel-centre aligned: U(i) = I(i/2 - 0.25)) but
    // maps back by halving the coordinate, so every octave reports positions +0.25 px off (what
    // OpenCV >= 4.8's enable_precise_upscale fixes); the upright engine has no such offset.
    float bias = 0.f;
    if (params_.engine == SiftEngine::Upright) {
      located.detection_kps = upright_.detect(img, m, located.pyramid);
      if (params_.nfeatures > 0 && int(located.detection_kps.size()) > params_.nfeatures)
        cv::KeyPointsFilter::retainBest(located.detection_kps, params_.nfeatures);
      f.keypoints = located.detection_kps;
    } else {
      // An empty Mat is OpenCV's "no mask".
      sift_->detectAndCompute(img, m, f.keypoints, f.descriptors);
      bias = 0.25f;
    }
    // Pixel centres: resized pixel i covers [i/s, (i+1)/s) of the crop.
    const float inv = float(1.0 / params_.scale);
    for (cv::KeyPoint &kp : f.keypoints) {
      kp.pt.x = (kp.pt.x - bias + 0.5f) * inv - 0.5f + float(f.region.x);
      kp.pt.y = (kp.pt.y - bias + 0.5f) * inv - 0.5f + float(f.region.y);
      kp.size *= inv;
    }
  }
  f.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return located;
}

Features FeatureDetector::describe(LocatedFeatures &&located, const std::vector<char> &needed) const
{
  const auto t0 = std::chrono::steady_clock::now();
  Features f = std::move(located.features);
  if (!needed.empty() && needed.size() != f.keypoints.size())
    throw BadInput("The keypoints to describe do not match their flags: give one 'needed' flag "
                   "per keypoint.",
                   "FeatureDetector::describe: " + std::to_string(needed.size()) + " flags for " +
                       std::to_string(f.keypoints.size()) + " keypoints");
  if (params_.engine == SiftEngine::Upright)
    f.descriptors = upright_.describe(located.pyramid, located.detection_kps, needed);
  if (f.descriptors.empty())
    f.descriptors.create(0, 128, CV_32F);
  f.ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return f;
}

Features FeatureDetector::detect(const cv::Mat &view, const cv::Mat &mask) const
{
  return describe(locate(view, mask));
}

Features detect_features(const cv::Mat &view, const cv::Mat &mask, const DetectParams &params)
{
  return FeatureDetector(params).detect(view, mask);
}

} // namespace treestereo
