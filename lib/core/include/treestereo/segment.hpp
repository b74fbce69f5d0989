// Vegetation segmentation: separates the canopy from soil, sky and posts with a colour
// vegetation index and describes it by area, centroid ("gravity"), perimeter and shape
// complexity, as the paper does with its "super green" 2G-R-B factor.
//
// Pipeline per view: index per pixel (integer arithmetic, row stripes in parallel, histogram
// merged per stripe) -> threshold (Otsu on the index histogram, or fixed) -> open (by
// reconstruction) then close -> connected components (keep the largest, or all above
// min_area) -> figures.
#pragma once

#include "treestereo/types.hpp"

#include <opencv2/core.hpp>

#include <optional>
#include <string>
#include <vector>

namespace treestereo {

// The colour index. R, G, B below are 0..255; r, g, b = R/S, G/S, B/S with S = R+G+B.
// Threshold units (SegmentParams::threshold and Silhouette::threshold) are the index itself:
//   Exg         2G-R-B (the paper's)                  in [-510, 510]
//   ExgExr      ExG - ExR, ExR = 1.4R-G: 3G-2.4R-B    in [-867, 765]  (0 is the classic cut)
//   ExgNorm     2g-r-b                                in [-1, 2]
//   ExgExrNorm  3g-2.4r-b                             in [-2.4, 3]    (0 is the classic cut)
// The normalised ones do not move when the light gets brighter or darker (all channels x k).
// They are quantised to 1/512 (ExgNorm) and 1/256 (ExgExrNorm), ExgExr to 1/5.
enum class VegIndex { Exg, ExgExr, ExgNorm, ExgExrNorm };

// "exg", "exg-exr", "exg-norm", "exg-exr-norm" (the names of the element's property).
const char *veg_index_name(VegIndex index);
// Inverse of veg_index_name; throws std::runtime_error listing the valid names.
VegIndex veg_index_from_name(const std::string &name);
// All four, in the order above (benchmarks and reports loop over them).
std::vector<VegIndex> all_veg_indices();

// Which connected regions of the thresholded mask make the canopy.
enum class KeepMode {
  Largest, // the single largest region (one tree on a clear background)
  All,     // every region with at least min_area pixels (an orchard: depth picks the canopy)
};
const char *keep_mode_name(KeepMode mode);             // "largest", "all"
KeepMode keep_mode_from_name(const std::string &name); // throws on an unknown name

// ChannelOrder (types.hpp) gives the position of R, G and B; the channel count comes from the
// view's type.
// From a GStreamer-style format name: RGB, BGR, RGBx, BGRx, xRGB, xBGR, RGBA, BGRA, ARGB, ABGR
// (case-sensitive as GStreamer spells them). Throws std::runtime_error on anything else.
ChannelOrder channel_order_from_name(const std::string &format);

struct SegmentParams {
  VegIndex index = VegIndex::ExgNorm; // best on the real images, see docs/segmentation.md
  ChannelOrder order;
  // < 0: Otsu on the index histogram of the view (default). >= 0: fixed threshold in the
  // index's units (see VegIndex). A pixel is canopy when its index is strictly above it.
  double threshold = -1.0;
  // Otsu never goes below this (index units). A view without vegetation still has a bimodal
  // histogram (soil vs sky); the floor keeps Otsu from calling the greener half canopy.
  // Unset: 8 for Exg, 0 for ExgExr, 0.025 for ExgNorm, 0 for ExgExrNorm.
  std::optional<double> otsu_floor;
  // Pixels with R+G+B below this are background and are left out of the histogram: their
  // chromaticity is sensor noise (and an all-black frame must not produce a canopy). >= 1.
  // 12: shadowed leaves of the synthetic orchard at light 0.7 sit at R+G+B 12-24 and still
  // read green; 24 would cut them out (canopy IoU 0.93 instead of 0.97, see
  // docs/elements/exgsegment.md); the real-image coverage table did not change.
  int dark_floor = 12;
  // Diameter (px) of the elliptic element of a morphological open then close; 0 = off.
  // Rounded to the nearest odd size (at the work scale).
  // Opening removes specks smaller than it, closing fills gaps narrower than it.
  int morph_size = 5;
  // Opening by reconstruction: every region that survives the opening gets its whole
  // thresholded shape back (leaf tips, thin twigs of leaves narrower than morph_size), while
  // regions the opening removes entirely (specks) stay removed. Exact (until stable, not a
  // bounded number of geodesic dilations): the kept regions are the connected components
  // (8-connected) of the thresholded mask that touch the opened mask. The close step follows
  // as before. false = the plain opening, which shaves every edge detail narrower than
  // morph_size (the canopy's top read 2 px low on the synthetic orchard, docs/results.md).
  // No effect when morph_size is 0.
  bool reconstruct = true;
  // Sub-pixel edges: the pixels on either side of the final mask's boundary are classified
  // again by linear unmixing instead of by the index threshold. Each is written as
  // B + alpha (F - B), F and B the mean colours of the canopy and background pixels around it
  // (5x5, boundary pixels left out), and is canopy when alpha >= 0.5, i.e. when leaf covers at
  // least half of it. A normalised index of a pixel half leaf, half bright sky is much less
  // than half the leaf's (the sky's brightness dominates R+G+B), so the threshold alone drops
  // the canopy's outer row: 1.3 px at the top and 1.1 px at the bottom of the synthetic
  // orchard (docs/results.md). Left as thresholded where the two colours are within
  // unmix_min_contrast of each other (canopy on a green background: no reliable alpha).
  bool unmix_edges = true;
  double unmix_min_contrast = 24.0; // 8-bit levels, Euclidean in RGB
  // All by default: in an orchard the tree in front touches its neighbours, the next row and
  // the grass in the image, and the largest colour region may be any of them. The mask holds
  // all the vegetation and stereodepth's canopy decides in 3D which of it is the canopy.
  KeepMode keep = KeepMode::All;
  // Regions smaller than this (px, after morphology) are dropped in both keep modes.
  double min_area = 64.0;
  // Contour simplification (px) before the perimeter is measured: removes the staircase of
  // the pixel grid, which otherwise inflates a circle's perimeter by about 5.5 %. Multiplied
  // by the work scale: the upscaled edge carries ripples of that period.
  double contour_epsilon = 1.0;
  // Morphology and connected components run on the mask reduced by this integer factor
  // (block coverage), and the kept regions come back to full size by linear interpolation of
  // that coverage, so edges stay within about half a pixel. 0 = automatic: the smallest factor
  // that brings the work to at most 1.5 Mpx (1 up to 1296x972, 2 at 2592x1944). 1 = full size.
  // morph_size and min_area stay in full-size pixels.
  int work_scale = 0;
};

// Checks the params (names the offending field); throws std::runtime_error.
void validate(const SegmentParams &params);

// Reusable segmenter: keeps its scratch images between frames, so a stream of same-sized
// views does not allocate. One instance per thread (run() is not reentrant).
class VegetationSegmenter {
public:
  explicit VegetationSegmenter(const SegmentParams &params = SegmentParams());

  const SegmentParams &params() const { return params_; }

  // Segments one view. `view` is CV_8UC3 or CV_8UC4 and may be a ROI of a larger frame
  // (its step is honoured, nothing is copied). Throws std::runtime_error on other types
  // (a grey image carries no colour to segment) or an empty view.
  // out.mask is reused when it already has the view's size and CV_8U type (it may wrap
  // caller-owned memory, e.g. a mapped buffer); otherwise it is (re)allocated.
  // Every field of `out` is overwritten. When no canopy is found: present = false, mask all
  // zero, every number 0, contour empty. The perimeter is that of the outer contour(s) of
  // the kept region(s) moved half a pixel outward (the pixels' boundary, not their centres),
  // so a disc of radius r gives about 2 pi r and complexity about 1; area is the pixel count.
  void run(const cv::Mat &view, Silhouette &out);

  // The index of every pixel in the index's units (CV_32F, view size), dark pixels
  // (R+G+B < dark_floor) set to the index's minimum. For inspection and reports, not speed.
  cv::Mat index_image(const cv::Mat &view) const;

private:
  int work_scale_for(cv::Size view) const;
  int index_and_threshold(const cv::Mat &view, double &threshold);
  void coverage(int tcode, int f, cv::Mat &scratch);
  std::vector<uchar> kept_labels(int n, int f, int &n_kept) const;
  void final_mask(const std::vector<uchar> &keep, int f, cv::Mat &mask);
  void reconstruct(cv::Mat &opened);
  void unmix_edges(const cv::Mat &view, const cv::Rect &box, cv::Mat &mask);

  SegmentParams params_;
  std::vector<std::vector<int>> stripe_hist_;
  cv::Mat codes_;                      // CV_16S index codes, view size
  cv::Mat cov_, bin_, tmp_, fin_, up_; // work-scale coverage, binary, morphology, result; upscaled
  cv::Mat labels_, stats_, centroids_;
  std::vector<uchar> touched_; // per label of the thresholded mask: reached by the opening
  cv::Mat dil_, ero_, cls_; // unmix_edges: mask dilated / eroded by one pixel, pixel classes
  std::vector<std::vector<cv::Point>> flip_; // unmix_edges: per stripe, pixels that change
};

// The figures of a silhouette from its mask: out.mask (CV_8U, 255 = canopy, nothing outside
// `box`) gives area, centroid, outer contours (the largest kept), perimeter (each contour
// simplified by contour_epsilon px, moved half a pixel outward), complexity, bbox and n_regions
// (outer contours); present = true. Returns false, leaving `out` as it was, for an empty mask.
bool describe_silhouette(Silhouette &out, const cv::Rect &box, double contour_epsilon);

// One-shot convenience around VegetationSegmenter.
Silhouette segment_vegetation(const cv::Mat &view, const SegmentParams &params = SegmentParams());

// Otsu's threshold on a histogram: returns the bin index t that maximises the between-class
// variance of bins [0, t] vs (t, n). Returns -1 when the histogram has fewer than two
// non-empty bins (nothing to separate).
int otsu_bin(const std::vector<int> &hist);

} // namespace treestereo
