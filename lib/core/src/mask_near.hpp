// Inside the library: whether a point's pixel lies on a mask or next to it.
#pragma once

#include <opencv2/core.hpp>

namespace treestereo {

// True when pixel (u, v) or one of its 8 neighbours is non-zero in `mask` (CV_8U): a point's
// pixel, rounded, may fall just off the silhouette it was measured on.
inline bool on_mask_or_beside(const cv::Mat &mask, int u, int v)
{
  for (int dv = -1; dv <= 1; ++dv)
    for (int du = -1; du <= 1; ++du) {
      const int x = u + du, y = v + dv;
      if (x >= 0 && y >= 0 && x < mask.cols && y < mask.rows && mask.at<uchar>(y, x))
        return true;
    }
  return false;
}

} // namespace treestereo
