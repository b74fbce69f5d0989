// The tree's measurements from its left silhouette and its 3D points: the algorithm behind
// `treemetrics`. Every field of DESIGN.md's "treemetrics measurements" table, rectified-left
// camera frame (x right, y down, z forward), metres.
//
// Height and width: the silhouette gives the canopy's extent as angles (exactly: its border
// pixels are rays tangent to the canopy); the 3D points give depths, but only of the canopy's
// visible front. A silhouette converted at the front face reads low (DESIGN: 10-15% on a round
// canopy), and the points' own X/Y spread reads low too (the visible limb lies in front of the
// canopy's widest section). `MetricsParams::extent_depth` chooses how the angles become metres:
//
//  - kTangentPoints (default): each bounding ray of the silhouette (leftmost, rightmost, top,
//    bottom) touches the canopy at one point; that point's depth converts that ray's slope:
//    X_left = t_left * Z_left, X_right = t_right * Z_right (Y likewise), so the extent needs
//    no shape model. Z of an edge comes from the points within tangent_fraction of the extent
//    from it: the surface recedes as sqrt(distance from the limb) there, so the depth is fitted
//    as b0 + b1 * sqrt(d) and b0 (the limb's depth) taken, over the points of the leaf cluster
//    that forms the edge (the outline's cap up to its first valley), d being each point's
//    distance inside the silhouette's own boundary on its row or column; b0 also when those
//    points do not recede (b1 >= 0: clusters at several depths). Between the edges the
//    conversion depth is interpolated linearly in slope (bands, area, perimeter). An edge on the
//    image border (see `clipped`) is no limb: it takes the median depth of those points instead,
//    a depth where its ray is inside the canopy, so that the extent stays a lower bound. On the
//    synthetic orchard (a union of ellipsoid clusters 0.9 x 0.7 x 0.6 m, whose depth and width
//    differ) kRoundCanopy read 3-5 % wide, because the tree is no solid of revolution and the
//    extreme clusters are not at the centre's depth; this reads within about 1.5 % (see
//    docs/results.md "## Accuracy" and bench/bench_extent.cpp).
//  - kRoundCanopy: the canopy is taken as a solid of revolution about a vertical axis
//    (a sphere, an ellipsoid, a cone: an orchard tree). Its nearest point is at depth
//    Z_near = Zc - R, and the left/right silhouette edge rays are tangent to its widest
//    horizontal section of radius R centred at (Xc, Zc). With the edge rays' angles th_l, th_r,
//    phi = (th_l + th_r)/2 and D = (th_r - th_l)/2 (in the XZ plane):
//        R = Z_near * sin D / (cos phi - sin D),  Zc = Z_near + R,  Xc = Zc * tan phi,
//    exact for any such solid. The vertical centre comes the same way from the top/bottom
//    rays (Yc = Zc * tan of their bisector) and each extent is the sum of the distances from
//    the centre to the two tangent planes: exact for a sphere (height and width) and for the
//    width of any solid of revolution; for the height of a tall ellipsoid seen from close by it
//    reads a few percent low. Z_near is a low percentile of the point depths
//    (near_percentile), which is what makes it robust and also its main error (a percentile
//    of p% sits about R*(1 - sqrt(1 - p/100)) behind the true front).
//  - kEdgePoints: converts the silhouette at the median depth of the points nearest the
//    silhouette's left and right edges (per row, within edge_fraction of the row's extent).
//  - kMidDepth: converts at median + thickness/2.
//  - kFrontFace: converts at `distance` (the median); kept to show how low it reads.
// kEdgePoints, kMidDepth and kFrontFace convert X = t*Z_ext with t = (x - cx)/fx (so bands, area and perimeter use
// the same Z_ext). kRoundCanopy reports the equivalent Z_ext = width / (t_r - t_l).
#pragma once

#include "treestereo/types.hpp"

#include <opencv2/core.hpp>

#include <cstddef>
#include <vector>

namespace treestereo {

// (kTangentPoints last: the values are the treemetrics element's enum values.)
enum class ExtentDepth { kRoundCanopy, kEdgePoints, kMidDepth, kFrontFace, kTangentPoints };

struct MetricsParams {
  int n_bands = 5;               // horizontal bands, canopy top to bottom (>= 1)
  ExtentDepth extent_depth = ExtentDepth::kTangentPoints;
  double near_percentile = 2.0;  // kRoundCanopy: Z_near = this percentile of the depths
  double edge_fraction = 0.15;   // kEdgePoints: the outer part of each row's extent
  // kTangentPoints: the points within this fraction of the extent from an edge (at least
  // tangent_min_points of them, the band widens until so) give that edge's depth.
  double tangent_fraction = 0.1;
  int tangent_min_points = 15;
  // kTangentPoints: the canopy reaches past each limb point. A bounding ray touches the
  // canopy at its limb, which is not the canopy's extreme point unless the ray is parallel to
  // the optical axis: where the surface is rounded with radius rho, the extreme lies
  // rho * (1 - cos(angle of the ray)) beyond the limb (18 mm for a 0.3 m sphere whose top ray
  // climbs 20 degrees). rho comes from the edge's own depth fit: a surface rounded with radius
  // rho is sqrt(2 rho d) in front of the silhouette's boundary at d mm inside it (d along the row
  // for the left/right edges, along the column for top/bottom), fitted as
  // z = b0 + b1 sqrt(d), rho = b1^2 / 2, capped at half the extent. It reads rho about 20-40 %
  // short on a sphere (rows away from the extreme cut smaller circles), so the correction is
  // partial: a 0.6 m sphere reads -1.3 % instead of -3.1 %. On the synthetic orchard the height
  // error with the true visible surface went from -0.31 % to 0.00 %, the chain's from -1.19 % to
  // -0.85 % (bench-densify, docs/results.md). No effect on a clipped edge or one whose depth fit
  // fell back to the median (no rounding measured).
  bool round_limbs = true;
  // Each edge of the extent (left, right, top, bottom) reaches at least as far as the
  // extreme_points-th most extreme canopy point in that direction (X or Y), when that is beyond
  // the silhouette's edge and the edge is not clipped; 0 = the silhouette's alone. The canopy's
  // 3D extreme often belongs to a cluster behind the one that forms the silhouette's edge: its
  // extreme projects inside the silhouette, where no depth for the bounding ray reaches it, but
  // its points are seen (with DensifyParams::edge_band sampling them). The 6th, not the first:
  // a point matched on the background beside an edge leaf lies too far out, and a handful of
  // them does not move the 6th. The chain on the synthetic orchard (bench-accuracy, 1296x972,
  // 1.6-2.5 m, tree seeds 1-6, 159 unclipped frames; docs/results.md "The canopy's extremes
  // from its points (2026-11-22)"), error
  // mean +- sd: height -1.20 +- 1.36 % -> -0.44 +- 1.32 %, width -0.75 +- 1.76 % -> -0.14 +-
  // 1.26 % (with DensifyParams::edge_band 0.04).
  int extreme_points = 6;
  // A band's nearest-face depth: this percentile of its points' depths (5 = robust to a
  // stray point, still the front). Bands with fewer than min_band_points points take it from
  // their neighbours (see Band::depth_measured).
  double band_depth_percentile = 5.0;
  int min_band_points = 3;
  // Points count only where they project onto the silhouette (within one pixel): matches
  // off the canopy (sky, ground, the next tree) do not move its figures.
  bool points_in_mask_only = true;
  // distance, thickness and each band's nearest-face depth as the canopy's visible surface has them: each point weighted by the
  // silhouette area nearest to it (its Voronoi cell inside the mask), so that points crowding on
  // the textured front leaves do not pull the median forward. false: every point counts once.
  bool area_weighted = true;
  // TreeMetrics::confidence: a silhouette pixel has depth support when a counted point lies
  // within this share of the view's width of it (0.015: 19 px at 1296 px wide, about the
  // spacing of stereodepth's densification grid, so that an evenly measured canopy reads ~1).
  double support_radius = 0.015;
};

struct Clipped {
  bool top = false, bottom = false, left = false, right = false;
  bool any() const { return top || bottom || left || right; }
};

// One horizontal slice of the canopy: what a frame measures of it, what a tree record keeps of it
// (rowtrack's fused bands) and what the band meta GstTreeStereoBand carries.
struct BandExtent {
  bool present = false;             // the silhouette has pixels in it; else the values are 0
  double top_m = 0, bottom_m = 0;   // Y of the band's top and bottom (y down)
  double left_m = 0, right_m = 0;   // X of the canopy's left and right edge in the band
  double width_m = 0;               // right - left
  double depth_m = 0;               // nearest-face depth (see Band)
  // Share (0..1) of the band's left-right extent covered by canopy: of the columns between the
  // band's leftmost and rightmost canopy pixel, those with canopy in at least one of the band's
  // rows (band_fill()). 0 when the band is absent.
  double fill = 0;
};

// A frame's band: its extent, and how its depth was found. The depth is band_depth_percentile of
// the band's point depths. A present band with too few points interpolates linearly between the
// nearest measured bands above and below (or copies the one measured neighbour side);
// depth_measured is then false. 0 when the band is absent or no band has points.
struct Band : BandExtent {
  bool depth_measured = false;
  std::size_t n_points = 0;
};

struct TreeMetrics {
  // False when there is no canopy or no valid canopy point; every other field is then zero.
  bool tree_present = false;
  double distance_m = 0;          // median Z of the canopy points
  double height_m = 0, width_m = 0; // real extents (see the top of this header)
  Clipped clipped;                // borders the silhouette touches: extents are lower bounds
  double thickness_m = 0;         // p95 - p05 of the points' Z
  double area_m2 = 0, perimeter_m = 0, complexity = 0;
  // The canopy's centre. kRoundCanopy: the model's centre (Xc, Yc, Zc), on the axis of the
  // solid of revolution (the silhouette's area centroid is not: perspective shifts it outwards
  // off-axis). Other modes: the silhouette's area centroid at the extent depth.
  cv::Point3d centroid_m;
  std::vector<Band> bands;        // n_bands, top to bottom (empty when no tree)
  std::size_t points = 0;         // valid points on the canopy the figures rest on
  std::size_t matches = 0;        // correspondences the points came from (points.size())
  double extent_depth_m = 0;      // the depth the silhouette was converted at (see header)
  // The extent's edges along X (camera frame, m; width_m = right_m - left_m) and the slopes
  // (X / Z) of the silhouette's bounding rays there. An edge seen near the optical axis is the
  // canopy's extreme along X whatever its depth: the ray grazes it along Z. Seen off the axis,
  // the ray grazes a limb in front, and a leaf cluster behind it that reaches further out is
  // hidden (TreeTracker takes each edge from the frame that sees it nearest the axis).
  double left_m = 0, right_m = 0, left_slope = 0, right_slope = 0;
  // How much of the silhouette has depth support (0..1): the share of its pixels within
  // MetricsParams::support_radius of a point that counts for the figures (depth_support() of
  // canopy.hpp). Low when the figures rest on a few points in one part of the canopy.
  double confidence = 0;
};

// Column coverage of a mask over rows [row0, row1) (clamped to the mask): the columns between
// the leftmost and rightmost non-zero pixel of those rows, and of them the share that has a
// non-zero pixel in at least one of the rows: covered / (right - left + 1). 0 (and left = right =
// -1) when the rows hold no non-zero pixel. The definition of Band::fill, public so that a ground
// truth mask is measured the same way. `mask`: CV_8U.
double band_fill(const cv::Mat &mask, int row0, int row1, int *left = nullptr,
                 int *right = nullptr);

// The image rows [start, end) of band `band` (0 = top) of `n_bands` over a silhouette whose
// bounding box is `bbox`: the box's height split evenly from its top pixel edge (bbox.y - 0.5),
// a row belonging to the band its centre falls in. How compute_tree_metrics() lays out
// TreeMetrics::bands, public so that a ground truth is measured over the same rows.
cv::Range band_rows(const cv::Rect &bbox, int n_bands, int band);

// Throws std::runtime_error when the geometry is invalid, the mask's size is not the view size,
// or the parameters are out of range.
TreeMetrics compute_tree_metrics(const Silhouette &left, const std::vector<Point3> &points,
                                 const StereoGeometry &geometry, const MetricsParams &params);

// Exponential smoothing across frames: out = alpha * previous + (1 - alpha) * current for the
// continuous fields (distances, extents, area, perimeter, complexity, centroid, confidence, band
// values and fill of bands present in both frames); flags and counts are the current frame's. alpha = 0 is off.
// A frame without a tree is passed on unchanged and forgets the history, so no stale value
// ever reaches a no-tree frame or the next tree. A change in the number of bands also resets.
class MetricsSmoother {
public:
  explicit MetricsSmoother(double alpha = 0.0);
  TreeMetrics update(const TreeMetrics &current);
  void reset() { has_state_ = false; }
  double alpha() const { return alpha_; }

private:
  double alpha_;
  bool has_state_ = false;
  TreeMetrics state_;
};

} // namespace treestereo
