// Plain data shared by the algorithms of lib/: what one stage hands the next.
// Mirrors of the GstMetas (gst/meta) without GStreamer, so lib/ stays OpenCV-only.
#pragma once

#include <opencv2/core.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace treestereo {

// Position of the R, G and B bytes inside one packed pixel of `channels` bytes (3 or 4; the
// fourth is padding or alpha). Default: OpenCV's BGR.
struct ChannelOrder {
  int r = 2, g = 1, b = 0;
  int channels = 3;
};

// A pair of rectified views as the stream carries them.
enum { LEFT = 0, RIGHT = 1 };

// Geometry of a rectified stereo pair (the geometry meta). Pixel units unless named.
struct StereoGeometry {
  cv::Size view_size;          // one view
  double fx = 0, fy = 0;       // rectified focal length (px), shared by both views
  double cx[2] = {0, 0};       // principal point x per view (px)
  double cy = 0;               // principal point y (px), shared after rectification
  double baseline_mm = 0;      // distance between the optical centres
  cv::Matx44d Q = cv::Matx44d::zeros(); // disparity-to-depth (cv::stereoRectify), d = xl - xr
  cv::Matx33d R1 = cv::Matx33d::eye();  // left camera frame -> rectified-left frame

  // x-difference of the principal points: Z = fx * baseline_mm / (d - doffs()).
  double doffs() const { return cx[0] - cx[1]; }
  bool valid() const { return fx > 0 && baseline_mm > 0 && view_size.area() > 0; }
};

// "fx=1100.000000 baseline_mm=120.000000 view 1296x972": what valid() looks at, for an error's
// detail.
inline std::string describe(const StereoGeometry &g)
{
  return "fx=" + std::to_string(g.fx) + " baseline_mm=" + std::to_string(g.baseline_mm) +
         " view " + std::to_string(g.view_size.width) + "x" + std::to_string(g.view_size.height);
}

// Throws BadInput (errors.hpp) unless `g` is valid() with a finite focal length and baseline:
// "The stereo geometry is not valid: <needs> needs a calibrated, rectified pair (...)", the
// detail "<where>: " + describe(g). The one check of every lib function that takes a geometry.
void require_valid(const StereoGeometry &g, const char *needs, const char *where);

// One stereo correspondence in rectified pixels, each view in its own coordinates.
struct StereoMatch {
  float xl = 0, yl = 0; // left view
  float xr = 0, yr = 0; // right view
  float score = 0;      // the matcher's score, smaller is better
  float disparity() const { return xl - xr; }
};

// A 3D point in the rectified-left camera frame (mm; x right, y down, z forward).
struct Point3 {
  float x = 0, y = 0, z = 0;
  std::uint32_t match_index = 0; // index into the matches it comes from
  bool valid = true;             // false when dropped as out of range or an outlier
};

// The canopy as segmentation finds it in one view (the vegetation meta, per view).
struct Silhouette {
  bool present = false;            // false: nothing found, every other field is empty/zero
  double threshold = 0;            // index threshold used
  cv::Mat mask;                    // CV_8U, view size, 255 = canopy
  std::vector<cv::Point> contour;  // outer contour of the largest region
  double area_px = 0;              // canopy area
  double perimeter_px = 0;         // outer perimeter of the kept region(s)
  double complexity = 0;           // perimeter^2 / (4 pi area)
  cv::Point2d centroid;            // px
  cv::Rect bbox;                   // px
  int n_regions = 0;               // connected regions kept
};

} // namespace treestereo
