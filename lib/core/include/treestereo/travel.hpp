// The rig's motion between two consecutive frames, from stereo alone (DESIGN.md "In an orchard":
// travel is the rig's motion along the row since the previous frame).
//
//  1. Points of the current frame (3D, with their rectified-left pixel) are thinned to a spread
//     set, preferring points away from depth edges (a patch across an edge holds two surfaces
//     that part between frames); each one's right pixel follows from its depth
//     (xr = xl - d, d = fx b / Z + doffs).
//  2. A coarse search over the travel finds where the points stood in the previous left view
//     (a point at depth Z stood fx T / Z px further right for a travel T): the start of the
//     tracks, so that large motions (2 m/s at 7 frames/s is 250 px at 1296 px) need no deep
//     pyramid. Near the expected travel when one is given (the odometer gives the last step).
//  3. Both pixels are tracked back into the previous left and right views with pyramidal
//     Lucas-Kanade; a track must come back to where it started (forward-backward check), and
//     the two previous pixels must lie on one rectified row.
//  4. The previous disparity gives the previous 3D point; rigid_align() finds the rotation and
//     translation that carry the previous points onto the current ones (RANSAC + least squares)
//     and which points agree with it.
//  5. The motion is refined on those points by their reprojection into the previous views
//     (Gauss-Newton, robust, tracks far off set aside): a tracked pixel is far more certain than
//     the depth triangulated from it, whose error grows with Z^2. Over a narrow stretch of
//     canopy at one depth a turn and a move along the row shift the image almost alike, so a
//     second refinement starts from no turn (translation first, then all six parameters), and
//     the one that brings more points within a pixel is kept. That turn stands only when the
//     data asks for it: its three parameters must lower the robust cost of the residuals by more
//     than the Bayesian information criterion charges for them (n ln(c_translation / c_turn) >
//     3 ln n, n residuals), else the translation alone is the motion. On a straight drive the
//     tracks' noise otherwise shows as a turn of a few hundredths of a degree that takes its
//     share of the travel (0.05 degrees at 2 m is 1.7 mm), and the travel read short.
//  6. The rig's displacement is minus the translation; travel is its component along the row.
//
// Frames: every point and the motion are in the rectified-left camera frame (mm; x right,
// y down, z forward). A static scene point seen at X_prev in the previous frame is at
// X_cur = R X_prev + t in the current one; the rig moved by -t (current frame's axes, for a
// rotation as small as between two frames). Driving towards +x (the scene slides left in the
// image) is positive travel, as SceneRenderer::travel_mm counts it.
#pragma once

#include "treestereo/canopy.hpp"
#include "treestereo/types.hpp"

#include <opencv2/core.hpp>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace treestereo
{

// ---- Rigid alignment of corresponding 3D points ----

struct RigidParams {
  // RANSAC draws of 3 correspondences at most; fewer when the inlier share found so far makes a
  // clean draw certain at `confidence` (the usual adaptive stop).
  int iterations = 500;
  double confidence = 0.999;
  // A correspondence is an inlier when |R a + t - b| <= inlier_mm, or its own tolerance when
  // tolerances are given to rigid_align().
  double inlier_mm = 10.0;
  // Fewer inliers than this (at least 3): no motion found.
  int min_inliers = 6;
  std::uint64_t seed = 1; // the draws are reproducible
};

// Throws BadSettings naming the field when a value is out of range.
void validate(const RigidParams &params);

struct RigidResult {
  bool found = false;
  cv::Matx33d R = cv::Matx33d::eye(); // b = R a + t
  cv::Vec3d t{0, 0, 0};               // mm
  std::size_t inliers = 0;
  double rms_mm = 0;        // of the inliers' residuals |R a + t - b|
  std::vector<bool> inlier; // per correspondence (empty when not found)
};

// The rotation and translation (no scale) carrying `from` onto `to` (same length, pairwise
// correspondences), robust to outliers: RANSAC over 3-point samples, then a weighted
// least-squares fit (Kabsch, by SVD) on the inliers, repeated while the inlier set changes.
// `tolerance_mm`: empty, or one inlier distance per correspondence (e.g. growing with depth for
// stereo points); the fit weighs each inlier by 1 / tolerance^2. Fewer than 3 points, points on
// one line, or too few inliers: found = false. Throws BadInput on unequal lengths or a
// non-positive tolerance.
RigidResult rigid_align(const std::vector<cv::Point3d> &from, const std::vector<cv::Point3d> &to,
                        const RigidParams &params = RigidParams(),
                        const std::vector<double> &tolerance_mm = {});

// ---- The rig's motion from two stereo frames ----

struct TravelParams {
  // Points tracked per call at most, one per cell of a grid over their bounding box, the one
  // nearest the cell's centre (away from depth edges where the cell has such a point): the
  // spread keeps the fit away from one plane or one tree; the cap bounds the time.
  int max_points = 400;
  // Views are reduced to this scale before tracking (1 = full size). Half scale keeps a call at
  // 1296x972 near 10 ms on one core; the tracks still agree with the truth to about 0.2 px of
  // the full-size view.
  double scale = 0.5;
  // Lucas-Kanade window side (px, at the tracking scale) and pyramid levels above the tracking
  // scale. A small window straddles fewer depth edges (gaps in the leaves); after the coarse
  // search a track starts within a few pixels of its end (more where the rig also turned or a
  // depth is wrong), and 2 levels follow about 15 px of that at the tracking scale.
  int window = 9;
  int levels = 2;
  // The coarse search covers travels in [-max_travel_mm, max_travel_mm] (mm per frame). 500 mm
  // is 3.5 m/s at 7 frames/s. 0: no search, the tracks start where the points are now and the
  // pyramid alone must span the motion.
  double max_travel_mm = 500;
  // Forward-backward check: a track tracked back must return within this (px, full size).
  double max_fb_px = 0.5;
  // The previous left and right pixels must lie on one row within this (px, full size): the
  // views are rectified, so a larger difference is a wrong track.
  double max_row_px = 1.0;
  // Inlier tolerance of a point (mm): tol_mm + the depth error a disparity error of tol_px
  // makes at its depth (Z^2 tol_px / (fx b)): stereo depth is that much less certain far away.
  double tol_mm = 5.0;
  double tol_px = 0.3;
  // Fewer tracked points or inliers than this: no motion found.
  int min_inliers = 20;
  // RANSAC draws of the 3D fit at most (rigid_align stops earlier once a clean draw is certain).
  int ransac_iterations = 300;
  // Refine the 3D fit by the reprojection of its inliers (step 5); false: the 3D fit as it is,
  // several times less accurate along the row.
  bool refine = true;
};

// Throws BadSettings naming the field when a value is out of range.
void validate(const TravelParams &params);

struct Motion {
  bool found = false;
  // X_cur = R X_prev + t for a static point (rectified-left frames, mm).
  cv::Matx33d R = cv::Matx33d::eye();
  cv::Vec3d t{0, 0, 0};
  cv::Vec3d displacement_mm{0, 0, 0}; // the rig's motion, -t, in the current frame's axes
  cv::Vec3d along{1, 0, 0};           // the unit direction along the row used
  double travel_mm = 0;               // displacement_mm . along: positive towards +x
  double rotation_deg = 0;            // angle of R
  std::size_t points = 0;             // points tracked from (after thinning)
  std::size_t tracked = 0;            // passed both tracks, the checks and triangulation
  std::size_t inliers = 0;            // the points the motion rests on (refined: those kept)
  double rms_mm = 0;                  // the 3D fit's residual over its inliers
  double rms_px = -1;                 // the refined reprojection error (px); -1: not refined
  double prior_mm = 0;                // the coarse search's travel (along x), where tracks began
};

// The motion of the rig from the previous stereo frame to the current one. `prev_left`,
// `prev_right`, `left`, `right`: rectified views of the geometry's view size, all one type
// (CV_8UC1, or CV_8UC3 / CV_8UC4 in BGR(A)); `points`: the current frame's 3D points with their
// left pixels (invalid ones are skipped); `along`: the row's direction in the current frame's
// axes, as RowDirection::direction() gives it (is_row_direction()): the travel is the rig's
// displacement along it. Not the camera's x axis: on cameras yawed 5 degrees on the rig, x would
// read the travel 0.4 % short.
// `expected_mm`: the travel the rig likely made (mm, as Motion::prior_mm counts it), such as
// the last frame's; kNoExpectedTravel: unknown. Given, step 2 searches only within a quarter of
// it (at least 50 mm) either side: a repeating texture (a brick wall, a trellis, evenly spaced
// posts or trees) matches at every repeat, and over the whole range a repeat nearer zero may
// win. On the drive-by at 2 m/s, about one frame in 50 of the whole search's guesses sent every
// track astray (docs/results.md, "The travel on the whole view").
// found = false when too few points track or agree. Throws BadInput on inconsistent input,
// BadSettings on parameters out of range.
constexpr double kNoExpectedTravel = std::numeric_limits<double>::quiet_NaN();
Motion estimate_motion(const cv::Mat &prev_left, const cv::Mat &prev_right, const cv::Mat &left,
                       const cv::Mat &right, const std::vector<PixelPoint> &points,
                       const StereoGeometry &geometry, const TravelParams &params = TravelParams(),
                       const cv::Vec3d &along = cv::Vec3d(1, 0, 0),
                       double expected_mm = kNoExpectedTravel);

// ---- The travel over a sequence: key frames ----
//
// Each estimate_motion() carries a small error of its own (a fraction of a pixel in the tracks,
// a millimetre or two along the row), whatever the motion's size: summed frame after frame it
// grows with the number of frames, not with the distance. The odometer measures each frame from
// a key frame instead, as long as the travel since that key frame stays within key_span_mm; the
// position then carries one estimate's error per key frame, not per frame. At 7 frames/s and a
// 300 mm span that is one key frame in four at 0.5 m/s, in two at 1 m/s, and every frame from
// about 2 m/s on (where the tracks over a longer span would thin out). Each estimate's coarse
// search looks near the travel the last step makes likely, and over the whole range when that
// finds nothing.
struct OdometerParams {
  TravelParams travel;
  // The travel from the key frame to the frame measured, at most (mm); 0: always the previous
  // frame (no key frames).
  double key_span_mm = 300;
};

// Throws BadSettings naming the field when a value is out of range.
void validate(const OdometerParams &params);

struct OdometryStep {
  bool found = false;
  double travel_mm = 0;  // since the previous frame, along the row (positive towards +x)
  bool from_key = false; // measured from a key frame older than the previous frame
  Motion motion;         // the estimate it rests on (from the key frame, or the previous frame)
};

class Odometer {
public:
  explicit Odometer(const OdometerParams &params = OdometerParams()); // validates

  // Adds a frame: its rectified views (as estimate_motion() takes them), its 3D points with
  // their left pixels and the row's direction. The odometer keeps the views (cv::Mat shares the
  // pixels): they must not be written afterwards. The first frame, a frame of another size or
  // type, and a frame whose motion is found neither from the key frame nor from the previous
  // frame give found = false, and the frame starts a new key. Throws what estimate_motion()
  // throws.
  OdometryStep add(const cv::Mat &left, const cv::Mat &right, const std::vector<PixelPoint> &points,
                   const StereoGeometry &geometry, const cv::Vec3d &along = cv::Vec3d(1, 0, 0));

  // Forgets every frame kept: the next frame is a first one.
  void reset();
  // A frame was added since the last reset (the next one can be measured).
  bool has_previous() const { return !prev_[0].empty(); }

  const OdometerParams &params() const { return params_; }

private:
  OdometerParams params_;
  cv::Mat key_[2], prev_[2];
  double since_key_mm_ = 0; // travel from the key frame to the previous frame
  double last_step_mm_ = 0; // the last step measured: the next one's likely size
  bool has_step_ = false;   // the last frame's step was measured
  bool key_is_prev_ = true;
};

// ---- The row's direction ----
//
// The direction the rig drives in, in the rectified-left frame (unit, x component positive:
// driving either way along a row is one direction). The rectified x axis is the baseline's
// direction, not the driving direction: rectification turns both cameras, and the cameras sit on
// the rig at a yaw and roll of their own. A point's place along the row is its projection on this
// direction (along_row()). Its X alone is off by Z sin(yaw) + Y sin(roll): 7 mm at 2 m on the
// renderer's rig (docs/results.md, "The remaining height errors, and the row's direction from
// the motion"), 17 cm at 2 m for cameras yawed 5 degrees on the tractor.
//
// Estimated as the direction of the sum of the rig's displacements measured so far
// (Motion::displacement_mm, each turned to a positive x first). On a straight row each frame's
// own error (about 0.002 in the direction's z component per 143 mm frame on the drive-by)
// averages out, and so do the rig's ups and downs. A turning drive gets the mean direction. Not
// projected on the ground plane: the plane fitted to each frame's grass pitches by up to half a
// degree from frame to frame (docs/results.md, "The top band: neither the ground nor a rounder
// limb"), which would tilt the direction more than the displacements' own error does.
class RowDirection {
public:
  // The displacements must add up to min_span_mm before they stand for the direction.
  explicit RowDirection(double min_span_mm = kMinSpanMm);
  static constexpr double kMinSpanMm = 250;

  // Adds one measured displacement (mm, rectified-left frame). Not finite, or shorter than
  // kMinStepMm (a standing rig's tracks: their noise points anywhere and, turned to a positive
  // x, would add up along x): ignored.
  void add(const cv::Vec3d &displacement_mm);
  static constexpr double kMinStepMm = 10;
  // The unit direction. Before min_span_mm of displacements, or when they point more than 60
  // degrees off the x axis (cameras looking along the row, not across it): the x axis (in the
  // ground plane when it is found). The ground is not used otherwise.
  cv::Vec3d direction(const GroundPlane &ground = GroundPlane()) const;
  // The displacements add up to min_span_mm, within 60 degrees of the x axis.
  bool measured() const;
  void reset() { sum_ = cv::Vec3d(0, 0, 0); }

private:
  double min_span_mm_;
  cv::Vec3d sum_{0, 0, 0};
};

// `v` in the ground plane (its component along the normal removed) and normalised; `v` itself,
// normalised, when there is no ground or `v` stands (nearly) across it.
cv::Vec3d in_ground_plane(const cv::Vec3d &v, const GroundPlane &ground);

// Whether `d` can stand for the row's direction: a finite unit vector (within 1e-6) within 60
// degrees of the x axis, as RowDirection::direction() gives.
bool is_row_direction(const cv::Vec3d &d);

// The place along the row of point `p` (rectified-left frame, mm): its projection on the row's
// unit direction `d` (RowDirection::direction()). d = (1, 0, 0) gives p's X.
inline double along_row(const cv::Vec3d &p, const cv::Vec3d &d) { return p.dot(d); }

} // namespace treestereo
