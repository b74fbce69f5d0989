// Inside the library: cutting thin strips off a mask.
#pragma once

#include <opencv2/imgproc.hpp>

namespace treestereo::detail {

// Cuts off `mask` (CV_8U, 0 or 255) what is less than `min_height_px` tall (a vertical run of
// the mask shorter than that through every one of its pixels) and lies more than `reach_px`
// from what is that tall (the body). A horizontal strip a few pixels tall that runs out of a
// blob goes, save its first `reach_px`; a leaf sticking out of a crown's edge by less than that
// stays, and so does every pixel of a run at least `min_height_px` tall.
inline void cut_thin_strips(cv::Mat &mask, int min_height_px, int reach_px)
{
  cv::Mat body;
  cv::morphologyEx(mask, body, cv::MORPH_OPEN,
                   cv::getStructuringElement(cv::MORPH_RECT, cv::Size(1, min_height_px)));
  cv::dilate(body, body,
             cv::getStructuringElement(cv::MORPH_ELLIPSE,
                                       cv::Size(2 * reach_px + 1, 2 * reach_px + 1)));
  mask &= body;
}

} // namespace treestereo::detail
