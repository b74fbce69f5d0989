// The canopy in front, decided in 3D: which vegetation pixels belong to the row being sprayed.
//
// Colour says "plant"; in an orchard the grass, the next row and the tree's neighbours are all
// plants. Depth says which of them is the canopy to spray (DESIGN.md "In an orchard"):
//
//  1. The ground: a plane fitted to the vegetation points (RANSAC, normal within
//     ground_max_tilt_deg of the camera's vertical), or the rig's camera height and pitch.
//     Points less than min_height_mm above it are ground (grass), not canopy.
//  2. The near row: the nearest dominant depth layer of the remaining points (a histogram of
//     their depths, each point weighted by the image area it stands for), from its front to
//     the first empty stretch of layer_gap_mm behind it, and halfway into that stretch; or the
//     user's spray zone [near_mm, far_mm].
//  3. Along the row (mode Tree): the near row's points, projected onto x (metres), fall into
//     segments separated by empty stretches of at least min_gap_mm. The tree in front is the
//     segment that holds the optical axis, or else the one nearest to it. Mode Row keeps every
//     segment (a hedgerow, a fruit wall).
//  4. The mask: inside a connected region of the vegetation mask whose depth samples all agree,
//     the colour edge is kept as it is. Where samples of the selected canopy and of anything
//     else (the next row behind, a neighbour, the grass) share a region, each pixel goes to the
//     nearest sample's class, and along that seam each pixel is tested again by
//     photo-consistency: its patch is compared with the right view at the canopy's disparity
//     and at the other class's disparity, and the better one wins (a pixel the canopy loses is
//     tried over the canopy's range of disparities too: a cluster behind the nearest one, peeking
//     out beside it where no sample lies). Pixels that no sample reaches (1.5 sample spacings)
//     are canopy only where the canopy encloses them.
//
// No shape model and no ground truth: only the views, the colour mask and the 3D points.
#pragma once

#include "treestereo/densify.hpp"
#include "treestereo/depth.hpp"
#include "treestereo/types.hpp"

#include <opencv2/core.hpp>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace treestereo {

enum class CanopyMode { Tree, Row };
const char *canopy_mode_name(CanopyMode mode);               // "tree", "row"
CanopyMode canopy_mode_from_name(const std::string &name);   // throws on an unknown name

enum class GroundModel { Off, Fit, Rig };
const char *ground_model_name(GroundModel model);            // "off", "fit", "rig"
GroundModel ground_model_from_name(const std::string &name); // throws on an unknown name

// A plane n . X + d = 0 in the rectified-left frame (mm), n of unit length pointing up (-y).
struct GroundPlane {
  bool found = false;
  cv::Vec3d normal{0, -1, 0};
  double d = 0;
  std::size_t inliers = 0;
  // Fit with a prior (CanopyParams::ground_prior): no plane of this frame agreed with the prior,
  // which is returned (found, held, inliers 0).
  bool held = false;
  // Height of a point above the plane (mm, positive above).
  double height_of(const cv::Point3d &p) const { return normal.dot(cv::Vec3d(p.x, p.y, p.z)) + d; }
};

// The ground from frame to frame, for CanopyParams::ground_prior: the last plane a frame fitted
// on its own points. A prior held for more than max_held frames in a row (the rig was tilted or
// lifted for good, or the prior was wrong) is dropped, and the next frame fits freely.
class GroundTracker {
public:
  explicit GroundTracker(int max_held = 7) : max_held_(max_held) {}
  // The prior for the next frame (found = false: none).
  const GroundPlane &prior() const { return prior_; }
  // The ground the frame ended with (select_canopy's CanopyResult::ground).
  void update(const GroundPlane &ground);
  // A new stream, or a break in it (a discontinuity): no prior.
  void reset() { *this = GroundTracker(max_held_); }

private:
  int max_held_;
  int held_ = 0;
  GroundPlane prior_;
};

struct CanopyParams {
  CanopyMode mode = CanopyMode::Tree;
  // The spray zone in depth (Z, mm). Both 0: the near row found from the data. Otherwise the
  // canopy is what lies in [near_mm, far_mm] (far_mm 0: no far limit).
  double near_mm = 0, far_mm = 0;
  // Height above the ground (mm): canopy between these (max 0: no upper limit).
  double min_height_mm = 250, max_height_mm = 0;
  GroundModel ground = GroundModel::Fit;
  double camera_height_mm = 0;  // GroundModel::Rig: optical centre above the ground
  double camera_pitch_deg = 0;  // GroundModel::Rig: positive = looking down
  double ground_max_tilt_deg = 25; // Fit: the plane's normal within this of the camera's y axis
  double ground_tolerance_mm = 40; // Fit: inlier distance
  // Fit: the ground of the frames before (found = false: none; GroundTracker keeps it). The rig
  // is rigid, so this frame's ground lies near it: a candidate plane tilted more than
  // ground_prior_tilt_deg from it, or with the camera more than ground_prior_shift_mm higher or
  // lower above it, is refused (a slice of canopy, the slope of a crown or of the next row), and
  // when no plane agrees the prior is kept (GroundPlane::held).
  GroundPlane ground_prior;
  double ground_prior_tilt_deg = 6, ground_prior_shift_mm = 150;
  // The near row: histogram bins, a layer must hold this share of the weight, and it ends at
  // the first empty stretch this long (or max_row_depth_mm behind its front).
  double layer_bin_mm = 50, layer_min_share = 0.12, layer_gap_mm = 400;
  double max_row_depth_mm = 1600;
  // Along the row: empty stretches at least this long separate trees (mode Tree).
  double min_gap_mm = 80;
  // Touching crowns (mode Tree): a stretch without a gap is cut where its top dips between two
  // higher crowns by at least valley_share of the lower crown's height above the stretch's
  // lowest canopy, each side at least min_crown_mm wide. Two round crowns that meet have such a
  // notch in their top line where they meet (about a third of their height when they overlap by
  // 5 % of their width); one crown's top does not dip that deep. 0: no cut.
  double valley_share = 0.2;
  double min_crown_mm = 250;
  // The spacing of the points' grid (px): a canopy point speaks for the vegetation within 1.5
  // spacings of it. 0 = estimated as sqrt(vegetation area / points).
  double sample_spacing_px = 0;
  // The seam test: half window of the patches (px); 0 = off (nearest sample only).
  int seam_half_window = 3;
};

// Throws BadSettings naming the field when a value is out of range.
void validate(const CanopyParams &params);

// What each input point was found to be.
enum class PointClass : std::uint8_t {
  Unknown = 0, // invalid on input, or off the vegetation mask
  Canopy,      // the selected canopy
  Neighbour,   // the near row, another tree (mode Tree)
  Behind,      // farther than the zone (the next row, the background)
  Front,       // nearer than the zone
  Ground,      // less than min_height_mm above the ground
  High,        // above max_height_mm
};

// One stretch of the near row along x, separated from the next by an empty stretch of at least
// min_gap_mm (mode Tree) or taken whole (mode Row: one per run all the same).
struct RowSegment {
  double lo_mm = 0, hi_mm = 0; // X extent of its points (rectified-left frame)
  // Z of the points at lo_mm and hi_mm (a limb behind the front reaches further out on an edge
  // ray; the edge test's fallback where the clearance below is unknown). 0: unknown.
  double lo_z_mm = 0, hi_z_mm = 0;
  // Y of those points (camera Y, downwards; mm). A view rolled against the row's direction places
  // a point along the row by its height too (along_row()). 0: unknown (the camera's height).
  double lo_y_mm = 0, hi_y_mm = 0;
  // How far inside the stereo view's left (lo) and right (hi) edge its points keep: the least
  // distance along x of any of its points from that edge's ray at the point's own depth (mm;
  // the rays of view_slopes(); below 0 for a point a little beyond). Whether the canopy goes on
  // beyond the edge is a question of every point that comes near it, not of the extreme point
  // alone: at 2 m the points stop a few cm inside the edge (the right view's black border,
  // the match's patch), and a deeper extreme point then seems clear of it. NaN: unknown (the
  // extreme point at lo_z_mm / hi_z_mm is then all there is).
  double lo_clear_mm = std::numeric_limits<double>::quiet_NaN();
  double hi_clear_mm = std::numeric_limits<double>::quiet_NaN();
  double near_mm = 0;          // the 5th percentile of its points' Z
  std::size_t n_points = 0;
  bool selected = false;       // part of the canopy this result reports
  // Cut from the segment before (lo) or after (hi) it where their crowns touch (a valley of the
  // top line, CanopyParams::valley_share), not separated by an empty stretch.
  bool joined_lo = false, joined_hi = false;
  // X of its trunk where it shows below the crown (find_trunk(); mm; NaN: not seen). Set for
  // the selected segment of mode Tree.
  double trunk_mm = std::numeric_limits<double>::quiet_NaN();
  double trunk_y_mm = 0; // Y (mm) of the rows trunk_mm was read in, well below the crown
};

struct CanopyResult {
  bool present = false;
  Silhouette silhouette;            // the canopy's mask and figures, as segmentation gives them
  double near_mm = 0, far_mm = 0;   // the zone used
  bool zone_from_data = true;       // false: the user's spray zone
  GroundPlane ground;
  int n_segments = 0;               // near-row segments along the row
  std::vector<RowSegment> segments; // those segments, left to right
  double left_mm = 0, right_mm = 0; // X extent of the selected canopy's points
  // Mode Tree: where the tree ends along the row, halfway across the gap to each neighbour
  // (X, mm; infinite where there is no neighbour). Canopy pixels and points beyond are not it.
  double cut_lo_mm = -std::numeric_limits<double>::infinity();
  double cut_hi_mm = std::numeric_limits<double>::infinity();
  std::vector<PointClass> classes;  // one per input point
  std::size_t n_canopy_points = 0;
  std::size_t n_seam_pixels = 0;    // pixels decided by the seam test
};

// A 3D point with the left-view pixel it was seen at.
struct PixelPoint {
  cv::Point2f px;  // rectified-left pixel
  Point3 p;        // mm; p.valid false: no depth
};

// Decides the canopy. `vegetation`: the colour mask of the left view (CV_8U, non-zero = plant);
// `points`: 3D points of the vegetation (any density; a grid is best); `left`, `right`: the
// rectified views (8-bit grey or as `order` says), for the seam test (may be empty: no seam
// test). `colour`: the silhouette `vegetation` is the mask of, if at hand: its box bounds the
// work, and when the canopy is all of it its figures are taken as they are. Throws
// BadInput on inconsistent input, BadSettings on parameters out of range.
CanopyResult select_canopy(const cv::Mat &vegetation, const std::vector<PixelPoint> &points,
                           const StereoGeometry &geometry, const CanopyParams &params,
                           const cv::Mat &left = cv::Mat(), const cv::Mat &right = cv::Mat(),
                           ChannelOrder order = ChannelOrder(),
                           const Silhouette *colour = nullptr);

// ---- The canopy's depth: densification, the 3D canopy, densification of the canopy ----
//
// What stereodepth runs with its canopy on: the seeds (SIFT's matches over all the vegetation)
// and a coarse grid of the whole vegetation mask (coarse_points grid points) are triangulated
// and select_canopy() decides the canopy; then the canopy alone is densified as densify_matches()
// does (`grid`), seeded by the matches that fell on it, and every point is triangulated and
// cleaned (`filter`). Points off the canopy's mask or outside its depth zone are kept with
// valid = false and counted in stats.dropped_zone.
// `row_view` (mode tree): also decide the near row's canopy as mode row would, on the same
// points, into CanopyDepth::row. The tree's mask speaks for its own part of the row only; the
// part behind the first tree in view is no later frame's tree, and the row map takes it from
// this mask (stereodepth asks for it on a stream's first frame). As costly again as the
// decision itself.
struct CanopyDepthParams {
  CanopyParams canopy;
  DensifyParams grid;
  DepthParams filter;
  int coarse_points = 1200;
  bool row_view = false;
};

struct CanopyDepth {
  CanopyResult canopy;
  // With CanopyDepthParams::row_view in mode tree: the near row's canopy (mode row's
  // silhouette); not present otherwise.
  Silhouette row;
  // The seeds followed by the canopy's grid matches, and one point per match (same order).
  std::vector<StereoMatch> matches;
  std::size_t n_seeds = 0;
  DepthResult depth;
  std::size_t coarse = 0; // grid points of the coarse pass
};

// `left`, `right`: the rectified views (grey, or colour as params.grid.order says);
// `vegetation`: the left view's colour silhouette (with its mask). Throws BadInput on bad input,
// BadSettings on coarse_points below 1.
CanopyDepth canopy_depth(const cv::Mat &left, const cv::Mat &right, const Silhouette &vegetation,
                         const std::vector<StereoMatch> &seeds, const StereoGeometry &geometry,
                         const CanopyDepthParams &params);

// Where the tree of `segment` stands: the X (mm, rectified-left frame) of the trunk's axis seen
// below its crown, NaN when none shows. A crown grown into its neighbour's hides part of itself;
// a pruned crown stands about its trunk, so the trunk tells how far the hidden part reaches
// (TreeTracker).
// - Where: the rows below the crown's lowest pixel (`canopy`) in the segment's columns, two
//   thirds of the way down to the ground under the crown (`ground`; the image's bottom when not
//   found): lower down the ground itself nears the trunk's depth.
// - What: runs of columns not plant in 90 % of those rows (`vegetation` zero) of which at least
//   half match the right view at a depth of the crown: from its front (segment.near_mm) to as
//   deep behind it as it is long, ZNCC >= 0.6 over a window of 5 columns. A patch of bare soil
//   behind lies deeper than the crown and does not match there.
// - In bare soil (a path, a herbicide strip under the row): a run that is not a trunk whole (too
//   wide, or mostly unmatched) may hold one. Matched again over the band's upper half, where the
//   soil seen behind the trunk lies further behind it, its stretches of columns whose best
//   disparity lies inside the crown's range, three quarters of them within 2 px of their median
//   (an upright trunk stands at one depth; the soil's drifts along the row), trimmed to the
//   first and last of those, are trunks as well. Their edges are where the match holds, within a
//   pixel or two.
// - Which: the widest run between 20 mm and a third of the segment across; none when a second
//   one is more than half as wide (two trunks, or a post: no telling which). Its axis stands
//   half its width behind the front the match saw.
// `left`, `right`: rectified grey views (CV_8UC1); `vegetation`, `canopy`: CV_8UC1 masks of the
// view. `row_y_mm`, when given and a trunk is found: the Y (mm) of the rows' middle at the axis.
// Throws BadInput when they do not fit the geometry's view, or the geometry is invalid.
double find_trunk(const cv::Mat &left, const cv::Mat &right, const cv::Mat &vegetation,
                  const cv::Mat &canopy, const RowSegment &segment, const GroundPlane &ground,
                  const StereoGeometry &geometry, double *row_y_mm = nullptr);

// The share of the mask's pixels within radius_px of a point: how much of a silhouette has depth
// support. 0 for an empty mask.
double depth_support(const cv::Mat &mask, const std::vector<cv::Point2f> &px, double radius_px);

} // namespace treestereo
