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
#pragma once

#include "treestereo/calibration.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <memory>
#include <vector>

namespace treestereo {

struct SceneParams {
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
  double background_distance_mm = 10000.0; // the wall behind the row, 8000-15000
  double baseline_mm = 50.0;           // -T.x of the rig

  // Motion: the rig drives along +x; trees repeat every tree_spacing_mm, each its own tree.
  double speed_m_s = 0.0;              // lateral speed of the sprayer
  double framerate = 7.0;              // frames per second (for the speed)
  double tree_spacing_mm = 3000.0;     // only the tree nearest to the camera is rendered

  // Appearance.
  double light = 1.0;                  // light level, 0.7-1.3 is the paper's +-30 %
  double noise = 2.0;                  // sensor noise standard deviation (8-bit levels), 0 = none
  int clusters = 0;                    // leaf clusters, 0 = from the seed in [30, 80]
  double gap_fraction = 0.3;           // share of leaf cells that are holes, 0-0.8
  bool optical_blur = true;            // a 0.5 px Gaussian lens blur before the noise
};

// Throws std::runtime_error naming the parameter when a value is out of its range.
void validate_scene_params(const SceneParams &params);

// What the first surface along a pixel's ray is.
enum class SurfaceLabel : std::uint8_t { Sky = 0, Ground = 1, Background = 2, Trunk = 3, Leaf = 4 };

// The truth of one rendered view of one frame.
//
// Per-pixel maps are those of the rendered (distorted, unrectified) view. The point-based values
// (canopy_points_mm, distance..., centroid, trunk) are in `frame` coordinates: the rendered
// view's camera frame as render() returns them, or whatever truth_in_frame() rotated them into.
struct GroundTruth {
  int view = 0;
  std::uint64_t frame = 0;

  // The tree itself (independent of the view): extents of the union of the clusters, m,
  // along the scene's (left camera's) axes: height along y, width along x, depth along z.
  double canopy_height_m = 0, canopy_width_m = 0, canopy_depth_m = 0;

  // The trunk axis at the height of the canopy's centre, in `frame` (mm), its Z and X in m.
  cv::Vec3d trunk_point_mm;
  double trunk_distance_m = 0;
  double lateral_offset_m = 0;

  cv::Mat depth;       // CV_32F, mm, Z of the first hit in this view's camera frame, 0 = sky
  cv::Mat labels;      // CV_8U, SurfaceLabel of the first hit
  cv::Mat canopy_mask; // CV_8U, 255 where the first hit is a leaf

  // The visible canopy surface: one point per canopy pixel (row-major order), mm, in `frame`.
  std::vector<cv::Point3f> canopy_points_mm;
  // Statistics of those points' Z (m): median, 5th and 95th percentile, thickness = p95 - p05.
  double distance_m = 0, depth_p05_m = 0, depth_p95_m = 0, thickness_m = 0;
  cv::Vec3d centroid_m; // mean of the visible canopy points, m
};

// The same truth with every point-based value rotated by R (X' = R X) and its statistics
// recomputed, e.g. R = R1 of cv::stereoRectify for the rectified-left frame. The per-pixel maps
// and the tree's extents are kept as they are.
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

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

} // namespace treestereo
