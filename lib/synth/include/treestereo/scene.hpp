// The synthetic stereo orchard: a ray-cast tree in a row, seen by a calibrated, distorted,
// slightly misaligned stereo rig, with exact ground truth. The `treetestsrc` element and every
// accuracy test of treestereo are built on it.
//
// Frames and units: the scene is described in the LEFT camera's frame of the current frame
// (millimetres; x right, y down, z forward). The ground is the plane y = camera_height_mm.
// The tree's trunk is a vertical cylinder at (x = lateral offset, z = distance_mm); its canopy is
// a union of 30-80 axis-aligned ellipsoidal leaf clusters whose surface is a shell of leaves
// with gaps (a 3D cellular texture decides leaf or hole, so some rays pass through a cluster).
// Behind the tree: ground (soil) up to a textured wall at background_distance_mm, sky above it.
// Every texture is a function of the 3D surface point, never of the pixel, so both views see
// the same features. Shading is Lambertian with one fixed light from above-left-front.
//
// Default tree (document of the choice): the paper's tree measured 1.215 m x 0.48 m including
// its trunk, but its camera (fx = 3503 px on a 1944 px high sensor) sees only 1.11 m vertically
// at 2 m, so a 1.2 m canopy would always be clipped. The default canopy is 0.90 m high, 0.70 m
// wide and 0.60 m deep on a 0.50 m clear trunk (a 1.4 m tree): at 1.8-2.5 m it fits in the view
// with margins, at 1.5 m its top and bottom touch the image borders.
//
// Scene kinds (SceneParams::kind): Lab is the tree alone on soil as above. Orchard and Hedgerow
// stand it in a row on mown grass (green with dry patches): the near row along x at
// z = distance_mm, tree k = 0 at tree_x_mm exactly the Lab tree, its neighbours each their own
// tree (width and depth 0.85-1.15, height 0.85-1.1 times the canopy's, from the seed) with a gap
// of U(row_gap_min_mm, row_gap_max_mm) between canopies (Orchard: free standing trees;
// Hedgerow: canopies touching or overlapping), and a second row behind at distance_mm +
// row_spacing_mm (trunks every 1.1-1.7 m, canopies 0.9-1.3 times the size). Beyond 200 trees
// either side of k = 0 each row's layout repeats (the trees themselves do not). The trees stay
// fixed to the ground while the rig drives by; every tree that can be in view is rendered.
#pragma once

#include "treestereo/calibration.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace treestereo {

enum class SceneKind { Lab, Orchard, Hedgerow };

// A SceneParams value meaning "the scene kind's default".
constexpr double kSceneDefault = std::numeric_limits<double>::quiet_NaN();

// "lab", "orchard", "hedgerow"; scene_kind_from_name throws std::runtime_error listing the valid
// names for any other.
const char *scene_kind_name(SceneKind kind);
SceneKind scene_kind_from_name(const std::string &name);

struct SceneParams {
  SceneKind kind = SceneKind::Lab;     // what surrounds the tree (see the top of this header)
  std::uint64_t seed = 1;              // the tree (clusters, textures) and the noise
  cv::Size image_size{1296, 972};      // of both views; at most 2592x1944, at least 64x48

  // Geometry (mm).
  double distance_mm = 2000.0;         // left camera to the trunk axis (Z), meaningful 1500-2500
  double tree_x_mm = 0.0;              // trunk axis x at frame 0
  double canopy_height_mm = 900.0;     // exact vertical extent of the union of clusters
  double canopy_width_mm = 700.0;      // exact horizontal (x) extent
  double canopy_depth_mm = 600.0;      // exact z extent
  double trunk_height_mm = 500.0;      // ground to the canopy's lowest point
  double trunk_radius_mm = 45.0;
  double camera_height_mm = 950.0;     // optical centre above the ground
  double background_distance_mm = 10000.0; // the wall behind the row, 8000-15000; Orchard and
                                           // Hedgerow raise this default value to 3 m behind
                                           // the back row when that is further
  double baseline_mm = 50.0;           // -T.x of the rig

  // Motion: the rig drives along +x. Lab: trees repeat every tree_spacing_mm, each its own tree.
  double speed_m_s = 0.0;              // lateral speed of the sprayer
  double framerate = 7.0;              // frames per second (for the speed)
  double tree_spacing_mm = 3000.0;     // Lab: only the tree nearest to the camera is rendered

  // The rows of Orchard and Hedgerow (mm; NaN = the kind's default). Gap between neighbouring
  // canopies of the near row: Orchard 200-600, Hedgerow -0.15 canopy_width_mm to 0 (overlap).
  double row_gap_min_mm = kSceneDefault;
  double row_gap_max_mm = kSceneDefault;
  double row_spacing_mm = kSceneDefault; // near row to the next row behind: 3500 (1500-8000)
  // Orchard and Hedgerow: the canopies of near-row trees k and k + 1 touch (they overlap by
  // kTouchingOverlapMm, whatever the drawn gap), for a row where two trees grew into each
  // other. kNoTouchingPair: none.
  static constexpr int kNoTouchingPair = std::numeric_limits<int>::min();
  static constexpr double kTouchingOverlapMm = 50.0;
  int touching_pair = kNoTouchingPair;

  // Appearance.
  double light = 1.0;                  // light level, 0.7-1.3 is the paper's +-30 %
  double noise = 2.0;                  // sensor noise standard deviation (8-bit levels), 0 = none
  int clusters = 0;                    // leaf clusters, 0 = from the seed in [30, 80]
  double gap_fraction = 0.3;           // share of leaf cells that are holes, 0-0.8
  bool optical_blur = true;            // a 0.5 px Gaussian lens blur before the noise
};

// Throws std::runtime_error naming the parameter when a value is out of its range (after the
// kind's defaults are filled in).
void validate_scene_params(const SceneParams &params);

// The parameters with every kSceneDefault replaced by the kind's value and, for Orchard and
// Hedgerow, a background_distance_mm left at its default moved behind the back row. What
// SceneRenderer::params() returns. Does not validate.
SceneParams resolve_scene_params(const SceneParams &params);

// What the first surface along a pixel's ray is. Leaf: the tree in front (see GroundTruth);
// RowLeaf: another tree of the near row; BackLeaf: a tree of the row behind. Trunk: any trunk.
// Ground is soil (Lab) or grass.
enum class SurfaceLabel : std::uint8_t {
  Sky = 0,
  Ground = 1,
  Background = 2,
  Trunk = 3,
  Leaf = 4,
  RowLeaf = 5,
  BackLeaf = 6
};

// GroundTruth::tree_index where the pixel is not on a near-row tree.
constexpr std::int16_t kNoTree = -32768;

// A tree of the near row, in world coordinates (the camera frame of frame 0: x along the row).
struct RowTree {
  int index = 0;                 // k: 0 is the tree at tree_x_mm
  double x_m = 0;                // trunk axis
  double start_m = 0, end_m = 0; // the canopy's extent along x (exact union of its clusters)
  double height_m = 0, width_m = 0, depth_m = 0; // canopy extents
  double top_m = 0, bottom_m = 0; // the canopy's highest and lowest Y (camera axes, y down)
  double distance_m = 0;          // trunk axis Z
};

// The truth of one rendered view of one frame.
//
// Per-pixel maps are those of the rendered (distorted, unrectified) view. The point-based values
// (canopy_points_mm, distance..., centroid, trunk) are in `frame` coordinates: the rendered
// view's camera frame as render() returns them, or whatever truth_in_frame() rotated them into.
struct GroundTruth {
  int view = 0;
  std::uint64_t frame = 0;

  // The tree in front: the near-row tree whose trunk axis is nearest to the optical axis at this
  // frame (Lab: the one tree rendered). Every canopy_ and trunk value below is about it.
  int front_tree = 0;

  // The tree itself (independent of the view): extents of the union of the clusters, m,
  // along the scene's (left camera's) axes: height along y, width along x, depth along z.
  double canopy_height_m = 0, canopy_width_m = 0, canopy_depth_m = 0;

  // The trunk axis at the height of the canopy's centre, in `frame` (mm), its Z and X in m.
  cv::Vec3d trunk_point_mm;
  double trunk_distance_m = 0;
  double lateral_offset_m = 0;

  cv::Mat depth;       // CV_32F, mm, Z of the first hit in this view's camera frame, 0 = sky
  cv::Mat labels;      // CV_8U, SurfaceLabel of the first hit
  cv::Mat canopy_mask; // CV_8U, 255 where the first hit is a leaf of the tree in front
  cv::Mat row_mask;    // CV_8U, 255 where it is a leaf of the near row (Leaf or RowLeaf)
  cv::Mat tree_index;  // CV_16S, near-row tree k of the leaf or trunk hit, else kNoTree

  // The visible canopy surface: one point per canopy pixel (row-major order), mm, in `frame`.
  std::vector<cv::Point3f> canopy_points_mm;
  // Statistics of those points' Z (m): median, 5th and 95th percentile, thickness = p95 - p05.
  double distance_m = 0, depth_p05_m = 0, depth_p95_m = 0, thickness_m = 0;
  cv::Vec3d centroid_m; // mean of the visible canopy points, m

  // The visible near row: one point per Leaf or RowLeaf pixel (row-major order), mm, in `frame`.
  std::vector<cv::Point3f> row_points_mm;
};

// The same truth with every point-based value (also row_points_mm) rotated by R (X' = R X) and its
// statistics recomputed, e.g. R = R1 of cv::stereoRectify for the rectified-left frame. The
// per-pixel maps and the tree's extents are kept as they are.
GroundTruth truth_in_frame(const GroundTruth &truth, const cv::Matx33d &R);

// The rig's calibration at params.image_size: the MER-500 intrinsics of the paper scaled to the
// width (fx = 3503.12 * width / 2592, the right camera slightly different), mild distortion
// (k1 k2 p1 p2 k3), R a 0.55 degree rotation, T = (-baseline, 0.35, -0.25) mm.
// OpenCV's convention: X_right = R * X_left + T.
StereoCalibration rig_calibration(const SceneParams &params);

// Renders views of the scene. Construction does the per-size work once (ray tables of both
// cameras, tile cones); render() is const and thread-safe.
class SceneRenderer {
public:
  explicit SceneRenderer(const SceneParams &params); // validates, throws std::runtime_error
  ~SceneRenderer();
  SceneRenderer(const SceneRenderer &) = delete;
  SceneRenderer &operator=(const SceneRenderer &) = delete;

  const SceneParams &params() const;
  const StereoCalibration &calibration() const;

  // Renders view 0 (left) or 1 (right) of `frame` into rgb (CV_8UC3, R,G,B order). When rgb
  // already has image_size and that type it is written in place (a wrapped buffer with any row
  // stride works), otherwise it is reallocated. When truth is not null it receives the ground
  // truth. Cost: the canopy's pixels dominate; see bench/bench_render.cpp.
  void render(int view, std::uint64_t frame, cv::Mat &rgb, GroundTruth *truth = nullptr) const;

  // The undistorted normalised coordinates (X/Z, Y/Z) of every pixel's ray in that view's
  // camera frame (CV_32FC2, image_size): a pixel's 3D hit is Z * (x, y, 1) with Z from depth.
  const cv::Mat &normalized_rays(int view) const;

  // How far the rig has driven at `frame` (mm along +x).
  double travel_mm(std::uint64_t frame) const;

  // The near-row trees whose canopy overlaps [from_mm, to_mm] in world x (camera-frame x plus
  // travel_mm), in order of k. Lab: the row of tree_spacing_mm (one tree rendered at a time).
  std::vector<RowTree> row_trees(double from_mm, double to_mm) const;

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

} // namespace treestereo
