// Seeded densification: an even sample of the canopy's visible surface from a few sparse matches.
//
// Why: the canopy's distance and thickness are statistics of its visible surface (DESIGN.md:
// median and p95 - p05 of the canopy points' Z), but SIFT keypoints crowd on the contrasted front
// leaves and miss the leaves seen through the gaps, so the median of the matched points sits in
// front of the surface's median and, resting on a few hundred points of a 0.3-0.6 m deep canopy,
// scatters by about 0.6 cm from frame to frame (docs/results.md, "Accuracy").
//
// How: the sparse matches (seeds) bound the canopy's disparities; every `step`-th pixel of the
// left vegetation mask (a regular grid, so each grid point stands for the same area) is matched
// along its row by ZNCC of a (2*half_window+1)^2 patch over that disparity window. A grid point is
// kept only when the correlation peak is clear: at least min_zncc, inside the window (not at
// its ends, where the true peak may lie outside), beating every score at least two pixels away
// by min_margin, and confirmed from the right view (the best left partner of the right patch
// lies within one pixel of the grid point: left-right consistency, which removes most points
// whose patch straddles a depth edge). Its sub-pixel disparity comes as in refine_matches(): a
// parabola through the peak, then Gauss-Newton steps on the interpolated right patch.
// No ground truth, no shape model: only the two views, the mask and the seeds.
#pragma once

#include "treestereo/types.hpp"

#include <opencv2/core.hpp>

#include <cstddef>
#include <vector>

namespace treestereo {

struct DensifyParams {
  // Grid step (px) in x and y over the left mask. 0 = automatic: the step that gives about
  // target_points grid points on the mask (at least 1).
  int step = 0;
  int target_points = 4000;
  int half_window = 3;        // 7x7 patches, as refine_matches(): fewer straddle a depth edge
  double min_zncc = 0.8;      // the correlation peak must reach this
  double min_margin = 0.05;   // and beat every score >= 2 px from it by this much
  bool left_right_check = true;
  // The disparity window: [p_lo - margin, p_hi + margin] of the seeds' disparities with
  // p_lo, p_hi the seed_percentile-th and (100 - seed_percentile)-th percentiles.
  double seed_percentile = 1.0;
  double search_margin_px = 3.0;
  int min_seeds = 10;         // fewer seeds: nothing to bound the search, no grid points
  // A finer grid near the silhouette's extremes, where the canopy's 3D extremes are (they
  // belong to clusters near or behind the edge, projecting within a few % of the extent inside
  // it): the mask pixels within edge_band x the box's height of its top and bottom rows and
  // within edge_band x its width of its leftmost and rightmost columns are sampled every
  // edge_step px (0 = automatic: the view's width / 648, at least 2: 2 px at 1296x972, 4 px at
  // 2592x1944, the same angle from 1296 px up; not 1 px, where the 7x7 patches of neighbouring
  // points overlap so much that one patch matched wrong gives several wrong points, enough to
  // move treemetrics' extreme-points: 640x480 read +3.4 % high on a tree with 1 px, -1.1 % with
  // 2 px). edge_band 0 = off. On the synthetic orchard at 1296x972 (0.04 and 2 px) it adds
  // about 3000 grid points to the 4000 of the even grid.
  double edge_band = 0.04;
  int edge_step = 0;
  // Where R, G and B sit in the views' pixels (3 or 4 channels; ignored for grey views). Only
  // the canopy's box and the columns of the right view its disparities reach are converted.
  ChannelOrder order;
};

struct DensifyStats {
  int step = 0;                        // grid step used (px)
  int edge_step = 0;                   // the edge bands' step (px; 0 when off)
  int min_disparity = 0, max_disparity = 0; // the integer window searched (0/0 when skipped)
  std::size_t grid = 0;                // grid points on the mask with the patch in the view
  std::size_t kept = 0;                // matched
  std::size_t flat = 0;                // left patch without texture
  std::size_t weak = 0;                // peak below min_zncc, or at the window's end
  std::size_t ambiguous = 0;           // a second peak within min_margin
  std::size_t inconsistent = 0;        // the left-right check failed
};

// Grid matches of the canopy, sorted by row then column; yr = yl, score = 1 - ZNCC (smaller is
// better, as StereoMatch's score). `left`, `right`: the rectified views (8-bit grey, or colour
// as params.order says, the same size); `mask_left`: CV_8U of that size, non-zero = canopy; `seeds`: matches of the
// same pair (e.g. SIFT's). Fewer than min_seeds seeds: an empty result. Throws
// BadInput on inconsistent input, BadSettings on parameters out of range.
std::vector<StereoMatch> densify_matches(const cv::Mat &left, const cv::Mat &right,
                                         const cv::Mat &mask_left,
                                         const std::vector<StereoMatch> &seeds,
                                         const DensifyParams &params,
                                         DensifyStats *stats = nullptr);

} // namespace treestereo
