// Annotation of a stereo frame with what the analysis found: the algorithm behind `treeoverlay`.
// Draws onto a packed 8-bit colour image in place (cv::Mat of 3 or 4 channels, any channel
// order), from plain lib/ types, so the element only maps metas to these structs.
//
// What is drawn (each layer can be switched off in OverlayStyle):
//  - rejected: vegetation that depth rejected (colour said plant, the 3D canopy said not this
//    tree: grass, the next row, the neighbours), tinted a neutral grey-blue in the left view;
//  - contour: the canopy's outer contour per view, yellow;
//  - box: the canopy's bounding box per view, cyan;
//  - matches: a dot per match in each view (or, style kLines, a line from the left point to the
//    right point: across the two halves of a side-by-side frame, or as the disparity vector
//    within the left view when only one view is drawn), coloured by depth with depth_color();
//    a match without a valid depth is grey;
//  - bands: per present band a horizontal segment from its left to its right edge at the band's
//    vertical centre, with end ticks spanning the band's top..bottom, coloured by its depth;
//  - text: a dark panel at the top left of the left view with one line per text line and,
//    when matches were coloured, a legend bar from near to far with their depths.
// Line widths, dot radii and the font scale with the view size (see OverlayScale), so the
// drawing reads the same at 320x240 and at 2592x1944.
#pragma once

#include "treestereo/metrics.hpp"
#include "treestereo/types.hpp"

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace treestereo {

// The pixel layout is a ChannelOrder (types.hpp); channels that are none of R, G, B (padding x
// or alpha A) are written as 255 where something is drawn.

struct Rgb {
  unsigned char r = 0, g = 0, b = 0;
  bool operator==(const Rgb &o) const { return r == o.r && g == o.g && b == o.b; }
};

// The fixed colours of the layers (RGB).
inline constexpr Rgb kContourColor{255, 230, 0};  // yellow
inline constexpr Rgb kBoxColor{0, 230, 255};      // cyan
inline constexpr Rgb kUnknownDepthColor{150, 150, 150};
inline constexpr Rgb kTextColor{255, 255, 255};
// Rejected vegetation: each colour channel becomes the mean of the pixel's and this one's.
inline constexpr Rgb kRejectedColor{110, 130, 170};

// The depth colour map: t = 0 (near) is red, through magenta and violet, to t = 1 (far) blue;
// saturated, bright and without green, so it stands out on foliage. t is clamped to [0, 1].
Rgb depth_color(double t);

enum class MatchStyle { kDots, kLines };

struct OverlayStyle {
  bool contour = true, box = true, matches = true, bands = true, text = true;
  bool rejected = true;
  MatchStyle match_style = MatchStyle::kDots;
  // Depth range of the colour map (m). Both 0: from the data, the 5th..95th percentile of the
  // known match depths (and band depths when there are no matches).
  double depth_near_m = 0, depth_far_m = 0;
};

// Sizes derived from one view's size: unit = max(view width, view height) / 640.
struct OverlayScale {
  double unit = 1;
  int line = 1;      // line thickness (px)
  int dot = 2;       // dot radius (px)
  double font = 0.5; // cv::putText font scale (FONT_HERSHEY_SIMPLEX)
  int font_thickness = 1;
};
OverlayScale overlay_scale(cv::Size view);

// Everything to draw. Pixel coordinates are each view's own (as in the metas).
struct OverlayScene {
  // Views the image holds: 2 = left and right side by side (each half the width), 1 = the left
  // view alone (right-view items are then not drawn).
  int n_views = 2;
  Silhouette views[2];             // uses present, contour and bbox; the mask is ignored
  std::vector<StereoMatch> matches;
  // Depth (m) per match, same length as matches or empty; <= 0 or not finite = unknown.
  std::vector<double> match_depth_m;
  // Bands from treemetrics, drawn when geometry is valid and band_depth_m > 0: metres are
  // projected to left-view pixels at band_depth_m (see band_segment()).
  std::vector<Band> bands;
  StereoGeometry geometry;
  double band_depth_m = 0;
  std::vector<std::string> text;   // the text panel's lines; empty: no panel
  // The left view's vegetation that is not canopy (CV_8U of the view's size, non-zero =
  // rejected; see rejected_vegetation()); empty: nothing to tint.
  cv::Mat rejected;
};

// The vegetation pixels that are not canopy: vegetation AND NOT canopy (both CV_8U of one size;
// an empty canopy rejects all the vegetation). A new matrix.
cv::Mat rejected_vegetation(const cv::Mat &vegetation, const cv::Mat &canopy);

// A band as left-view pixels: its edges projected as x = fx * X / Z + cx, y = fy * Y / Z + cy at
// depth Z = depth_m. treemetrics converts the silhouette's edges to metres at the canopy's
// centre depth (its centroid's Z), so that depth brings the band back onto the silhouette; the
// band's own depth is its nearest face, in front of that, and would draw it too wide.
struct BandSegment {
  double x_left = 0, x_right = 0, y_top = 0, y_bottom = 0;
};
// Throws std::runtime_error when the geometry is invalid or depth_m is not > 0.
BandSegment band_segment(const Band &band, const StereoGeometry &geometry, double depth_m);

// The text panel's lines for a frame's metrics: "no tree" when the tree is absent; otherwise
// distance, height, width, thickness in metres with two decimals ("height >= 1.20 m" when the
// canopy touches the top or bottom border, width likewise for left/right), each followed by the
// smoothed value in brackets when `smoothed` is given and reads differently, and a line with the
// numbers of points and matches; with `confidence`, then a line "conf 0.93" (the share of the
// silhouette with depth support).
std::vector<std::string> metrics_text(const TreeMetrics &metrics, const TreeMetrics *smoothed,
                                      bool confidence = false);

// Draws the scene onto `image` (CV_8UC3 or CV_8UC4 per `order`.channels; n_views views side by
// side). Throws std::runtime_error on an image type that does not match the order, or an odd
// width with two views.
void draw_overlay(cv::Mat &image, const ChannelOrder &order, const OverlayScene &scene,
                  const OverlayStyle &style);

} // namespace treestereo
