// The row map: the near row's canopy as a grid of travel bins (along the row) by height bands
// (above the ground), what a sprayer's nozzle sections need (DESIGN.md "In an orchard": the row
// map, CSV rows position_m, band, present, distance_m, fill; and seen, which tells a cell no frame
// saw from one seen empty).
//
// Bands are fixed heights above the ground, not shares of each tree's height: a sprayer's
// nozzle sections sit at fixed heights on the boom. Band 0 is the lowest. Defaults: 400 to
// 1600 mm in 4 bands of 300 mm, for the renderer's orchard (SceneParams: a 500 mm clear trunk
// under a 900 mm canopy, neighbours 0.85-1.1 times as high, so canopies span about 0.5-1.5 m;
// the camera at 950 mm sees the middle bands straight on).
//
// Per frame (add_frame): the canopy mask of the left rectified view, the canopy's 3D points with
// their pixels, the geometry, the ground plane (select_canopy()'s, or one from the rig's camera
// height and pitch: rig_ground()) and the rig's position along the row. Each pixel is placed at
// the canopy's depth around it. A block (strip_px columns by 4 * strip_px rows) with 3 or more
// points in it and the strips beside it takes their least-squares line of depth down the view
// (held to their depths' range), so the depth follows the crown's curve within the block; a
// block without takes the median of the nearest such block in its rows (within 6 strips), else
// its strip's (strips without points take the nearest strip's, columns far from any point the
// canopy's median depth). The crown's top and bottom lie deeper than its front, so a strip's one
// depth would place the top too low and the bottom too high. Above a strip's topmost block with
// points (and below its bottommost) no point reaches the limb, and a flat depth there would place
// the rim at the depth of the last points, too near: a round crown's rim lies near its middle's
// depth. There each column follows a circle in its plane tangent to that block's line at its
// points' centroid and to the silhouette's ray at the column's top (bottom) canopy row, its
// radius at most half the column's canopy chord (a sphere's section through the column is a
// circle of that size), its depth from the centroid's to that much deeper; a fit that comes
// nearer towards the limb is taken as flat, and a limb at the image's edge has no arc. Without
// it the thin caps of crowns just above a band's edge were missed (docs/results.md, "Travel on
// the keypoints, and the crown's limb in the row map"). Its world x is the position plus its
// place along the row (along_row()), its height the ground plane's height of the 3D point. A
// cell (bin, band) of that frame:
//  - fill: the share of the cell's pixels (those the view has of it) that are canopy;
//  - lo_m / hi_m: the world x of its leftmost and rightmost canopy pixel columns;
//  - distance_m: the near face, the 5th percentile of the depths of the points in the cell, or,
//    without points, the smallest column depth of its canopy pixels.
//  - present: fill >= min_fill; or, under it, canopy that rises into the cell from the band
//    below it (consecutive canopy rows of a column in both) and holds 3 rows or more of the
//    cell's band, in columns that span more than a fifth of a bin along the row. That is a
//    crown's cap a few millimetres into the band: a cap 10 mm into a 300 mm band fills 2 % of it
//    at most, and caps under min_fill were a top band's missing stretches (docs/results.md
//    "A crown's cap a few millimetres into a band"). One or two rows may be a pixel's spill, or
//    where the limb's depth model (below) places a flat top's edge (4 mm at 2.2 m), across the
//    band's edge. A speck has no canopy under it across a band's edge. Not downwards: placed
//    by the lower limb's arc, the undersides of two touching crowns hung 3 rows into the band
//    below across the gap between their lower parts, and a 15 cm gap there was lost. Or, under
//    min_fill, canopy that goes on into a present neighbour's (on either side: both reach their
//    common edge within a fifth of a bin) and reaches more than a fifth of a bin into the cell:
//    the cap's thin ends, under 3 rows (docs/results.md "Where the drive-by's remaining misses
//    come from"). min_fill keeps specks out, not the canopy's own ends. cell() decides the
//    last, so a bin's presence is known once its neighbours are final too.
// Each bin (all bands) is taken from the frame that sees the bin's centre nearest the image
// centre, among the frames that see the whole bin: there a depth error moves a pixel least
// along the row (X = Z * (u - cx) / fx, and (u - cx) is smallest), the crown's side is least
// foreshortened into its front, and the bin is far from the image edge, where the canopy is cut.
// A frame whose mask holds one tree alone (stereodepth's mode tree: the canopy between the cuts
// halfway to its neighbours) does not speak for its bins outside that span: a neighbour's canopy
// in view is not in its mask, and the bin would read empty. Those bins come from the frames
// whose span holds them; until one comes they are unseen. A part of the row that is no frame's
// tree stays unseen: beside the last tree in view at the end of a run, and behind the first one
// at its start unless that frame's mask of the whole row is added for it (stereodepth's row
// view of a stream's first frame, fed with the span beside the tree's: feed_row_map()).
// A band the nearest frame reads empty is present when two frames whose span holds the bin, and
// that see its centre within a slope of 0.1 of the axis, saw it present (the nearest of them
// gives the cell): a cap a few millimetres into a band is at the edge of what one frame
// resolves, and the nearest frame alone missed whole stretches of the top band that the frames
// beside it saw (docs/results.md "Two frames that see a band's canopy outvote the nearest").
// One frame is not enough: a false canopy one frame sees at its view's edge stays out.
// A band the chosen frame does not see (above or below the image) is unseen: present = false.
#pragma once

#include "treestereo/canopy.hpp"
#include "treestereo/rowtrack.hpp"
#include "treestereo/travel.hpp"
#include "treestereo/types.hpp"

#include <opencv2/core.hpp>

#include <limits>
#include <map>
#include <string>
#include <vector>

namespace treestereo {

struct RowMapParams {
  double bin_mm = 50;  // travel bin along the row
  // Band edges, heights above the ground (mm), ascending, at least two; empty = n_bands equal
  // bands from min_height_mm to max_height_mm.
  std::vector<double> band_edges_mm;
  double min_height_mm = 400, max_height_mm = 1600;
  int n_bands = 4;
  // A cell is present from this share of canopy on (a stray pixel is no canopy to spray).
  double min_fill = 0.02;
  // Columns per depth strip (px): the points of a strip give its columns' depth.
  int strip_px = 8;
};

// Throws std::runtime_error naming the field when a value is out of range.
void validate(const RowMapParams &params);

// The ground of a rig whose optical centre is camera_height_mm above it, pitched down by
// pitch_deg, in the rectified-left frame (as select_canopy's GroundModel::Rig).
GroundPlane rig_ground(const StereoGeometry &geometry, double camera_height_mm, double pitch_deg);

struct RowMapCell {
  bool seen = false;     // a frame saw this cell (within its span)
  bool present = false;  // canopy in it (fill >= min_fill, a cap rising from the band below, or a
                         // present neighbour's end)
  double distance_m = 0; // near-face depth, when present
  double fill = 0;       // share of the cell covered by canopy (0..1)
  // Where along the row its canopy pixels lie (world x, m), when present: a sprayer's section
  // switches at the canopy's edge, not at the bin's. The frames that see the bin near their
  // axis (those that vote, see rowmap.cpp) reach as far as any of them saw canopy: each sees
  // what nearer leaves leave visible from its place, and the canopy is all of that.
  double lo_m = 0, hi_m = 0;
};

// `path` with its extension (after the last dot of its last component, if any) replaced by
// `extension` (with its dot): the picture beside a CSV or a JSON-lines file.
std::string with_extension(const std::string &path, const std::string &extension);

// A stretch along the row a nozzle section sprays (world x, m, start_m < end_m), for the valve
// timeline under the map's picture (spray.hpp's sprayed_stretches() makes them from commands).
struct SprayedStretch {
  int section = 0; // 0 = the lowest
  double start_m = 0, end_m = 0; // end_m may be +infinity: open to the end of the data
};

struct RowMapRenderParams {
  int px_per_bin = 8;        // width of a bin (px)
  double px_per_m_height = 160; // height scale (px per m above the ground)
  // Colour scale of the distance (m); both 0: from the cells present.
  double distance_min_m = 0, distance_max_m = 0;
};

class RowMap {
public:
  explicit RowMap(const RowMapParams &params = RowMapParams()); // validates

  // Adds one frame. `canopy_mask`: CV_8U of the view size, non-zero = canopy (the left
  // rectified view); `points`: the canopy's 3D points (invalid ones and those off the mask are
  // ignored); `ground`: must be found; `row_direction`: the row's direction in the rectified-left
  // frame (RowDirection::direction(); a point's world x is position_mm + along_row());
  // `span_lo_mm`, `span_hi_mm`: the X range (rectified-left frame, at the canopy's depth) the
  // mask speaks for (CanopyResult::cut_lo_mm, cut_hi_mm; infinite: all the view). Throws
  // std::runtime_error on inconsistent input.
  void add_frame(const cv::Mat &canopy_mask, const std::vector<PixelPoint> &points,
                 const StereoGeometry &geometry, const GroundPlane &ground, double position_mm,
                 const cv::Vec3d &row_direction = cv::Vec3d(1, 0, 0),
                 double span_lo_mm = -std::numeric_limits<double>::infinity(),
                 double span_hi_mm = std::numeric_limits<double>::infinity());

  const RowMapParams &params() const { return params_; }
  const std::vector<double> &band_edges_mm() const { return edges_; }
  int n_bands() const { return int(edges_.size()) - 1; }
  bool empty() const { return bins_.empty(); }
  // First and last bin index seen (bin b covers [b, b + 1) * bin_mm of world x).
  long first_bin() const;
  long last_bin() const;
  // How far (mm along the row) the rig must have passed a bin's centre before no later frame
  // can change the bin: a frame nearer the bin's centre comes before the rig passes it, but one
  // that votes for a band (see the top) may come up to a slope of 0.1 past it, about 200 mm at
  // 2 m. At the last frame's canopy depth (0 before a frame with depth); a sprayer that takes a
  // bin sooner gives its valves what a later frame may still change.
  double settle_mm() const { return settle_mm_; }
  // The cell of bin b (index as above), band k (0 = lowest); an unseen default cell outside.
  // Its presence depends on bins b - 1 and b + 1 (see above).
  RowMapCell cell(long bin, int band) const;

  // One row per bin (first_bin() to last_bin()) and band, under kCsvHeader: position_m (the
  // bin's centre, m), band, present (0/1), distance_m (empty when not present), fill, seen (0/1:
  // no frame saw the cell, above or below the view or outside every frame's span; its present
  // 0 says nothing of canopy).
  // Throws std::runtime_error naming the path when it cannot be written.
  void write_csv(const std::string &path) const;
  static constexpr const char *kCsvHeader = "position_m,band,present,distance_m,fill,seen";

  // The map as a picture (CV_8UC3, BGR): travel along x (world x rising to the right), height
  // above the ground along y (ground at the bottom), each cell coloured by its distance
  // (cv::COLORMAP_TURBO; a scale bar below), cells seen without canopy dark grey, unseen cells
  // black; `trees`: their ids and extents (start_m to end_m) marked above the map.
  // Size: width = kMarginLeft + bins * px_per_bin + kMarginRight, height = kMarginTop +
  // round(top band edge (m) * px_per_m_height) + kMarginBottom (render_size()).
  cv::Mat render(const std::vector<TreeRecord> &trees = {},
                 const RowMapRenderParams &render = RowMapRenderParams()) const;
  cv::Size render_size(const RowMapRenderParams &render = RowMapRenderParams()) const;

  // render() with the valve timeline under it: one strip per section (the highest on top, as
  // the bands), on the map's travel axis, dark where the valve is open. `sections`: how many
  // strips (at least every stretch's section + 1). Adds kTimelineTop + sections * kStripHeight
  // rows at the bottom.
  cv::Mat render_with_timeline(const std::vector<TreeRecord> &trees,
                               const std::vector<SprayedStretch> &sprayed, int sections,
                               const RowMapRenderParams &render = RowMapRenderParams()) const;
  static constexpr int kTimelineTop = 24, kStripHeight = 16;
  static constexpr int kMarginLeft = 70, kMarginRight = 20, kMarginTop = 50, kMarginBottom = 80;

  // The map as a strip under a live view (treeoverlay's draw-map): travel from from_m to to_m
  // across `strip`'s width (CV_8UC3, BGR, drawn over), the bands from bottom to top over its
  // height; cells as render() colours them (distance over [distance_min_m, distance_max_m],
  // both 0: from the cells in the window), `now_m` (the camera's position) a white line.
  // Throws std::runtime_error on an empty strip or from_m >= to_m.
  void draw_strip(cv::Mat &strip, double from_m, double to_m, double now_m,
                  double distance_min_m = 0, double distance_max_m = 0) const;

  // render() written with cv::imwrite (the format from the extension). Throws std::runtime_error
  // naming the path when the map is empty or the file cannot be written.
  void write_png(const std::string &path, const std::vector<TreeRecord> &trees = {},
                 const RowMapRenderParams &render = RowMapRenderParams()) const;
  // The same with the valve timeline (render_with_timeline()).
  void write_png(const std::string &path, const std::vector<TreeRecord> &trees,
                 const std::vector<SprayedStretch> &sprayed, int sections,
                 const RowMapRenderParams &render = RowMapRenderParams()) const;

private:
  // A band's votes: the frames whose span holds the bin, near the axis, that saw it present
  // (see the top), and the cell of the nearest of them.
  struct Vote {
    int count = 0;
    double offset = std::numeric_limits<double>::infinity();
    RowMapCell cell;
    // where along the row the voting frames' canopy reaches, together (world x, m)
    double lo_m = std::numeric_limits<double>::infinity();
    double hi_m = -std::numeric_limits<double>::infinity();
  };
  struct Bin {
    bool in_span = false;     // the nearest frame's mask spoke for the bin (see add_frame)
    double centre_offset = 0; // |slope of the bin centre's ray| in the nearest frame
    std::vector<RowMapCell> nearest; // per band, as the nearest frame saw it
    std::vector<Vote> votes;         // per band
    // What the map holds of a band: the nearest frame's cell, or the votes' (see the top).
    RowMapCell cell(int band) const;
  };
  RowMapParams params_;
  std::vector<double> edges_;
  std::map<long, Bin> bins_;
  double settle_mm_ = 0;
};

} // namespace treestereo
