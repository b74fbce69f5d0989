// The row map against a constructed row: flat canopies of known extent (along the row and in
// height) and depth, a 10 cm gap between two of them, seen by a level camera 950 mm above the
// ground while the rig drives by. Masks and points are cast exactly; the map must give the
// cells' truth.
#include "treestereo/errors.hpp"
#include "treestereo/rowmap.hpp"
#include "treestereo/spray.hpp"
#include "simple_geometry.hpp"

#include <opencv2/imgcodecs.hpp>

#include <gtest/gtest.h>

#include <climits>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

using namespace treestereo;

namespace {

StereoGeometry camera()
{
  return simple_geometry(cv::Size(1296, 972), 1100, 50);
}

constexpr double kCameraHeight = 950;

// A flat canopy facing the camera: world x [x0, x1], height above the ground [h0, h1], depth z.
struct Wall {
  double x0, x1, h0, h1, z;
};

// Canopy A 1.0-1.6 m at 2 m, a 10 cm gap, canopy B 1.7-2.3 m at 2.2 m, a 0.5 m gap, canopy C
// 2.8-3.3 m at 1.9 m (all bin edges of 50 mm bins, so each bin is wholly in or out).
const std::vector<Wall> kWalls = {{1000, 1600, 500, 1450, 2000},
                                  {1700, 2300, 700, 1300, 2200},
                                  {2800, 3300, 600, 1600, 1900}};

// Mode tree's case: a narrow tree (1.0-1.3 m at 2 m) and a wide one (1.4-2.4 m at 2.2 m), the
// cut between them at 1.35 m.
const std::vector<Wall> kNarrowAndWide = {{1000, 1300, 500, 1450, 2000},
                                          {1400, 2400, 700, 1300, 2200}};

struct View {
  cv::Mat mask;
  std::vector<PixelPoint> points;
};

// `walls` as cameras yawed `yaw_deg` about the vertical against the row (turned towards +x: the
// row's direction in their frame is (cos, 0, sin)) see them: each pixel's ray, turned into the
// row's frame, meets the wall's plane at the row depth w.z. 0: straight across the row.
View cast(const StereoGeometry &g, const std::vector<Wall> &walls, double position_mm,
          double yaw_deg = 0)
{
  const double c = std::cos(yaw_deg * CV_PI / 180), s = std::sin(yaw_deg * CV_PI / 180);
  View out;
  out.mask = cv::Mat::zeros(g.view_size, CV_8U);
  for (int v = 0; v < g.view_size.height; ++v)
    for (int u = 0; u < g.view_size.width; ++u) {
      const double tx = (u - g.cx[LEFT]) / g.fx, ty = (v - g.cy) / g.fy;
      for (const Wall &w : walls) { // nearest first is not needed: they do not overlap in x
        const double Z = w.z / (c - tx * s), X = tx * Z, Y = ty * Z;
        const double x = X * c + Z * s + position_mm, h = kCameraHeight - Y;
        if (x < w.x0 || x >= w.x1 || h < w.h0 || h >= w.h1) // half open, as the bins
          continue;
        out.mask.at<uchar>(v, u) = 255;
        if (u % 10 == 0 && v % 10 == 0) {
          PixelPoint p;
          p.px = cv::Point2f(float(u), float(v));
          p.p.x = float(X);
          p.p.y = float(Y);
          p.p.z = float(Z);
          out.points.push_back(p);
        }
        break;
      }
    }
  return out;
}

GroundPlane level_ground()
{
  GroundPlane p;
  p.found = true;
  p.normal = cv::Vec3d(0, -1, 0);
  p.d = kCameraHeight;
  return p;
}

// The true fill of a bin's band: the share of its height the wall covers, when the wall covers
// the bin along the row.
double true_fill(long bin, int band, double *distance_m)
{
  const double x0 = bin * 50.0, x1 = x0 + 50.0;
  const double b0 = 400 + 300 * band, b1 = b0 + 300;
  for (const Wall &w : kWalls)
    if (x0 >= w.x0 && x1 <= w.x1) {
      const double cover = std::max(0.0, std::min(b1, w.h1) - std::max(b0, w.h0));
      *distance_m = w.z / 1000.0;
      return cover / 300.0;
    }
  *distance_m = 0;
  return 0;
}

// The cells of bins 10-74 (0.5 to 3.75 m: every bin some frame sees near the centre) against
// true_fill(), their distances too when `distances`. Returns how many are present.
int expect_constructed_cells(const RowMap &map, bool distances)
{
  int present = 0;
  for (long b = 10; b < 75; ++b)
    for (int k = 0; k < 4; ++k) {
      SCOPED_TRACE("bin " + std::to_string(b) + " band " + std::to_string(k));
      double d = 0;
      const double fill = true_fill(b, k, &d);
      const RowMapCell c = map.cell(b, k);
      EXPECT_TRUE(c.seen);
      EXPECT_NEAR(c.fill, fill, 0.03);
      EXPECT_EQ(c.present, fill > 0);
      if (fill > 0 && distances) {
        EXPECT_NEAR(c.distance_m, d, 0.001);
      }
      present += c.present;
    }
  return present;
}

// The map of `walls` from frames every step_mm from 0 to to_mm.
RowMap build_of(const std::vector<Wall> &walls, double step_mm, double to_mm)
{
  const StereoGeometry g = camera();
  RowMap map;
  for (double pos = 0; pos <= to_mm; pos += step_mm) {
    const View v = cast(g, walls, pos);
    map.add_frame(v.mask, v.points, g, level_ground(), pos);
  }
  return map;
}

RowMap build(double step_mm = 100)
{
  return build_of(kWalls, step_mm, 4000);
}

std::vector<TreeRecord> trees()
{
  std::vector<TreeRecord> out;
  for (std::size_t i = 0; i < kWalls.size(); ++i) {
    TreeRecord r;
    r.id = int(i) + 1;
    r.start_m = kWalls[i].x0 / 1000.0;
    r.end_m = kWalls[i].x1 / 1000.0;
    r.position_m = 0.5 * (r.start_m + r.end_m);
    r.complete = true;
    out.push_back(r);
  }
  return out;
}

// The commands of a planner without valve latency fed as spraycontrol feeds it: at each frame
// position from 0 to to_mm, every step_mm, `frame` (when given: adds that frame to the map),
// then the bins of `map` final there; at the end the bins not final yet (as at EOS). Without
// `frame`, `map` is complete before the first position.
std::vector<SectionCommand> plan_commands(const RowMap &map, double step_mm, double to_mm,
                                          const std::function<void(double)> &frame = {})
{
  SprayParams sp;
  sp.valve_latency_ns = 0;
  SprayPlanner planner(sp);
  long next = LONG_MIN;
  std::vector<SectionCommand> cmds;
  for (double pos = 0; pos <= to_mm; pos += step_mm) {
    if (frame)
      frame(pos);
    const auto got = planner.update(std::int64_t(pos * 1e6), pos / 1000.0,
                                    take_final_slices(map, pos, next, {}));
    cmds.insert(cmds.end(), got.begin(), got.end());
  }
  const auto rest =
      planner.finish(take_final_slices(map, std::numeric_limits<double>::infinity(), next, {}));
  cmds.insert(cmds.end(), rest.begin(), rest.end());
  return cmds;
}

// Section `section` of `cmds` sprays `stretches` (m, each end to a pixel).
void expect_sprayed(const std::vector<SectionCommand> &cmds, int section,
                    const std::vector<std::pair<double, double>> &stretches)
{
  std::vector<SprayedStretch> got;
  for (const SprayedStretch &st : sprayed_stretches(cmds))
    if (st.section == section)
      got.push_back(st);
  ASSERT_EQ(got.size(), stretches.size());
  const double px = 2.5e-3; // m
  for (std::size_t i = 0; i < stretches.size(); ++i) {
    EXPECT_NEAR(got[i].start_m, stretches[i].first, px) << "stretch " << i;
    EXPECT_NEAR(got[i].end_m, stretches[i].second, px) << "stretch " << i;
  }
}

} // namespace

TEST(RowMap, DefaultBands)
{
  RowMap map;
  ASSERT_EQ(map.n_bands(), 4);
  EXPECT_DOUBLE_EQ(map.band_edges_mm().front(), 400);
  EXPECT_DOUBLE_EQ(map.band_edges_mm()[1], 700);
  EXPECT_DOUBLE_EQ(map.band_edges_mm().back(), 1600);
}

TEST(RowMap, CellsMatchTheConstructedRow)
{
  const RowMap map = build();
  ASSERT_FALSE(map.empty());
  EXPECT_EQ(expect_constructed_cells(map, true), 12 * 4 + 12 * 2 + 10 * 4);
  // The 10 cm gap (bins 32 and 33, 1.60-1.70 m) is empty in every band.
  for (int k = 0; k < 4; ++k) {
    EXPECT_FALSE(map.cell(32, k).present);
    EXPECT_FALSE(map.cell(33, k).present);
  }
}

TEST(RowMap, CamerasYawedOnTheRigPlaceTheRowAlongItsDirection)
{
  // Yawed 5 degrees, the cameras' X reads the row about Z sin 5 degrees short (174 mm at 2 m);
  // along the row's direction the cells are the straight cameras'.
  const double deg = 5, c = std::cos(deg * CV_PI / 180), s = std::sin(deg * CV_PI / 180);
  const StereoGeometry g = camera();
  RowMap along, across;
  for (double pos = 0; pos <= 4000; pos += 100) {
    const View v = cast(g, kWalls, pos, deg);
    along.add_frame(v.mask, v.points, g, level_ground(), pos, cv::Vec3d(c, 0, s));
    across.add_frame(v.mask, v.points, g, level_ground(), pos);
  }
  // Turned cameras see the walls at a slant: their near face is not the straight cameras' depth.
  EXPECT_EQ(expect_constructed_cells(along, false), 12 * 4 + 12 * 2 + 10 * 4);
  // Read along the cameras' x the row comes about Z sin 5 degrees early: canopy A (1.0-1.6 m at
  // 2 m) from 0.80 m, and the gap after it (1.6-1.7 m) where the map's gap bins hold canopy B
  // (from 1.7 m at 2.2 m).
  for (long b : {16L, 17L, 18L, 19L}) {
    EXPECT_FALSE(along.cell(b, 1).present) << "bin " << b;
    EXPECT_TRUE(across.cell(b, 1).present) << "bin " << b;
  }
  EXPECT_TRUE(across.cell(32, 1).present);
  EXPECT_TRUE(across.cell(33, 1).present);
  EXPECT_THROW(along.add_frame(cv::Mat::zeros(g.view_size, CV_8U), {}, g, level_ground(), 0,
                               cv::Vec3d(0, 0, 1)),
               BadInput);
}

TEST(RowMap, CanopyEdgesWithinTheBins)
{
  // Canopies whose ends fall inside bins: 1.020-1.590 m at 2 m, 1.713-2.262 m at 2.2 m. The
  // cells holding an end know where in the bin the canopy stops (a pixel is 1.8-2 mm there).
  const RowMap map =
      build_of({{1020, 1590, 500, 1450, 2000}, {1713, 2262, 700, 1300, 2200}}, 100, 4000);
  const double px = 2.5e-3; // m
  for (int k = 1; k <= 2; ++k) {
    SCOPED_TRACE("band " + std::to_string(k));
    EXPECT_NEAR(map.cell(20, k).lo_m, 1.020, px);  // bin 1.000-1.050
    EXPECT_NEAR(map.cell(20, k).hi_m, 1.050, px);
    EXPECT_NEAR(map.cell(31, k).lo_m, 1.550, px);  // bin 1.550-1.600
    EXPECT_NEAR(map.cell(31, k).hi_m, 1.590, px);
    EXPECT_NEAR(map.cell(34, k).lo_m, 1.713, px);
    EXPECT_NEAR(map.cell(45, k).hi_m, 2.262, px);
    EXPECT_NEAR(map.cell(25, k).lo_m, 1.250, px); // inside: the whole bin
    EXPECT_NEAR(map.cell(25, k).hi_m, 1.300, px);
  }

  // The sprayer switches at those edges, not at the bins': the 123 mm gap closes the valve
  // from 1.590 to 1.713 m.
  expect_sprayed(plan_commands(map, 100, 4000), 1, {{1.020, 1.590}, {1.713, 2.262}});
}

TEST(RowMap, ASliverOfCanopyEndingAStretchIsPresent)
{
  // A canopy fills band 2 (1.0-1.3 m) from 1.0 to 1.5 m, then enters it by 4 mm only for
  // 40 mm more: bin 30 (1.50-1.55 m) holds 4 / 300 of the band over 40 of its 50 mm, a fill
  // of 0.011, under min_fill. A speck of the same size stands alone at 2.50 m.
  const RowMap map = build_of({{1000, 1500, 500, 1300, 2000},
                               {1500, 1540, 500, 1004, 2000},
                               {2500, 2540, 1000, 1004, 2000}},
                              100, 4000);
  const double px = 2.5e-3; // m
  const RowMapCell end = map.cell(30, 2);
  EXPECT_LT(end.fill, RowMapParams().min_fill);
  EXPECT_GT(end.fill, 0.0);
  EXPECT_TRUE(end.present); // it goes on from bin 29's canopy
  EXPECT_NEAR(end.lo_m, 1.500, px);
  EXPECT_NEAR(end.hi_m, 1.540, px);
  EXPECT_NEAR(end.distance_m, 2.0, 0.001);
  const RowMapCell speck = map.cell(50, 2);
  EXPECT_GT(speck.fill, 0.0);
  EXPECT_FALSE(speck.present); // no present neighbour: a speck, not canopy to spray
  EXPECT_EQ(speck.distance_m, 0.0);
  EXPECT_FALSE(map.cell(31, 2).present);

  // The section closes where the sliver ends, not at the bin's edge before it.
  expect_sprayed(plan_commands(map, 100, 4000), 2, {{1.000, 1.540}});
}

TEST(RowMap, AFrameOfOneTreeSpeaksForItsPartOfTheRowOnly)
{
  // Mode tree: each frame's mask holds only the tree whose centre is nearest the optical axis,
  // its part of the row ending halfway across the gaps. A narrow tree (1.0-1.3 m) beside a
  // wide one (1.4-2.4 m): at 1.40-1.52 m the rig is nearer the narrow one's centre, so the
  // frames that see the wide one's first bins nearest the image centre do not hold it.
  const std::vector<Wall> &walls = kNarrowAndWide;
  const StereoGeometry g = camera();
  const double inf = std::numeric_limits<double>::infinity();
  RowMap with_span, without;
  for (double pos = 0; pos <= 4000; pos += 100) {
    const std::size_t i = std::abs(0.5 * (walls[0].x0 + walls[0].x1) - pos) <=
                                  std::abs(0.5 * (walls[1].x0 + walls[1].x1) - pos)
                              ? 0
                              : 1;
    const View v = cast(g, {walls[i]}, pos);
    const double cut = 0.5 * (walls[0].x1 + walls[1].x0) - pos; // camera X of the cut
    with_span.add_frame(v.mask, v.points, g, level_ground(), pos, cv::Vec3d(1, 0, 0),
                        i == 0 ? -inf : cut, i == 0 ? cut : inf);
    without.add_frame(v.mask, v.points, g, level_ground(), pos);
  }
  int lost_without = 0;
  for (long b = 20; b < 48; ++b)
    for (int k = 0; k < 4; ++k) {
      SCOPED_TRACE("bin " + std::to_string(b) + " band " + std::to_string(k));
      const double x0 = b * 50.0, b0 = 400 + 300 * k;
      bool truth = false;
      for (const Wall &w : walls)
        truth = truth || (x0 >= w.x0 && x0 + 50 <= w.x1 && w.h1 > b0 && w.h0 < b0 + 300);
      EXPECT_EQ(with_span.cell(b, k).present, truth);
      lost_without += truth && !without.cell(b, k).present;
    }
  // The case is there: without the spans, the wide tree's first bins read empty.
  EXPECT_GE(lost_without, 4);
}

TEST(RowMap, TheRowViewOfTheFirstFrameSpeaksForThePartBehindItsTree)
{
  // The run begins with the wide tree (1.4-2.4 m) in front and the narrow one (1.0-1.3 m) at the
  // view's left edge; later frames, further along, never take the narrow one for their tree.
  const std::vector<Wall> &walls = kNarrowAndWide;
  RowMap tree_only, with_row;
  const StereoGeometry g = camera();
  constexpr double inf = std::numeric_limits<double>::infinity();
  for (double pos = 2300; pos <= 3500; pos += 100) {
    const View v = cast(g, {walls[1]}, pos);
    const double cut = 1350 - pos; // camera X of the cut between them
    for (RowMap *m : {&tree_only, &with_row})
      m->add_frame(v.mask, v.points, g, level_ground(), pos, cv::Vec3d(1, 0, 0), cut, inf);
    if (pos == 2300) { // stereodepth's row view: both trees, for the span beside the tree's
      const View row = cast(g, walls, pos);
      with_row.add_frame(row.mask, row.points, g, level_ground(), pos, cv::Vec3d(1, 0, 0), -inf,
                         cut);
    }
  }
  // The view's left edge at the narrow tree's depth is at 1.121 m: bins 23-25 are whole in it.
  for (long b = 23; b <= 25; ++b)
    for (int k = 0; k < 4; ++k) {
      SCOPED_TRACE("bin " + std::to_string(b) + " band " + std::to_string(k));
      // Its mask says nothing of them: unseen, not seen empty.
      EXPECT_FALSE(tree_only.cell(b, k).seen);
      EXPECT_FALSE(tree_only.cell(b, k).present);
      EXPECT_TRUE(with_row.cell(b, k).present);
      EXPECT_NEAR(with_row.cell(b, k).distance_m, 2.0, 0.01);
    }
  // The gap between them is seen empty; the wide tree is as without the row view.
  EXPECT_TRUE(with_row.cell(26, 1).seen);
  EXPECT_FALSE(with_row.cell(26, 1).present);
  for (long b = 28; b < 48; ++b)
    for (int k = 0; k < 4; ++k)
      EXPECT_EQ(with_row.cell(b, k).present, tree_only.cell(b, k).present);
}

TEST(RowMap, ACrownsTopIsPlacedAtItsOwnDepth)
{
  // A crown's front at 2 m from 0.5 to 1.0 m above the ground, its top 0.6 m further back, 1.3
  // to 1.55 m: at the front's depth the top's pixels would read 1.22-1.41 m, a third of them in
  // band 2 (1.0-1.3 m), which holds no canopy.
  const RowMap map =
      build_of({{1000, 1600, 500, 1000, 2000}, {1000, 1600, 1300, 1550, 2600}}, 100, 2500);
  for (long b = 22; b <= 29; ++b) {
    SCOPED_TRACE("bin " + std::to_string(b));
    EXPECT_NEAR(map.cell(b, 0).fill, 0.2 / 0.3, 0.03); // 0.4-0.7 m: 0.5-0.7 is canopy
    EXPECT_LT(map.cell(b, 2).fill, 0.03);               // 1.0-1.3 m: none
    EXPECT_NEAR(map.cell(b, 3).fill, 0.25 / 0.3, 0.03);
    EXPECT_NEAR(map.cell(b, 3).distance_m, 2.6, 0.001);
  }
}

// A round crown: a sphere of radius 350 mm whose centre is 1050 mm above the ground and 2350 mm
// from the camera, at x = 2 m along the row. Stereo matches only where the leaves face the camera
// within 60 degrees: none in the rows next to the silhouette. Its top band (1.3-1.6 m) holds the
// cap above 1.3 m; the visible surface there reaches x = 2000 +- sqrt(350^2 - 250^2) at most,
// less what the camera's rays graze.
struct Sphere {
  double x, h, z, r;
};

View cast_sphere(const StereoGeometry &g, const Sphere &s, double position_mm)
{
  View out;
  out.mask = cv::Mat::zeros(g.view_size, CV_8U);
  const cv::Vec3d c(s.x - position_mm, kCameraHeight - s.h, s.z); // camera frame, y down
  for (int v = 0; v < g.view_size.height; ++v)
    for (int u = 0; u < g.view_size.width; ++u) {
      cv::Vec3d d((u - g.cx[LEFT]) / g.fx, (v - g.cy) / g.fy, 1.0);
      d /= cv::norm(d);
      const double b = d.dot(c), disc = b * b - (c.dot(c) - s.r * s.r);
      if (disc < 0)
        continue;
      const double t = b - std::sqrt(disc);
      const cv::Vec3d P = t * d, n = (P - c) / s.r;
      out.mask.at<uchar>(v, u) = 255;
      if (u % 10 == 0 && v % 10 == 0 && -n.dot(d) >= std::cos(60.0 * 3.14159265358979 / 180)) {
        PixelPoint p;
        p.px = cv::Point2f(float(u), float(v));
        p.p.x = float(P[0]);
        p.p.y = float(P[1]);
        p.p.z = float(P[2]);
        out.points.push_back(p);
      }
    }
  return out;
}

// The visible surface's extent along the row within heights [h0, h1) from the camera at
// position_mm: the sphere's points facing it (x, then h on a fine grid).
void visible_extent(const Sphere &s, double position_mm, double h0, double h1, double &lo,
                    double &hi)
{
  lo = std::numeric_limits<double>::infinity();
  hi = -lo;
  const cv::Vec3d cam(position_mm, kCameraHeight, 0), c(s.x, s.h, s.z);
  for (double x = s.x - s.r; x <= s.x + s.r; x += 0.25)
    for (double h = std::max(h0, s.h - s.r); h < std::min(h1, s.h + s.r); h += 0.25) {
      const double dz2 = s.r * s.r - (x - s.x) * (x - s.x) - (h - s.h) * (h - s.h);
      if (dz2 < 0)
        continue;
      const cv::Vec3d P(x, h, s.z - std::sqrt(dz2)); // the near half: the far one is hidden
      if ((cam - P).dot(P - c) > 0) {
        lo = std::min(lo, x);
        hi = std::max(hi, x);
      }
    }
}

// The top band (1.3-1.6 m) of a crown's map, seen by frames every 100 mm from 1 to 3 m: its
// present bins (first to last; none when last < first), whether they are one stretch, the
// fullest cell's fill, the canopy's extent along them (m: the first's lo_m to the last's
// hi_m), and the truth's: the visible surface's extent within the band (mm), each end as the
// frame the map takes its bin from sees it, the one nearest the bin's centre.
struct TopBand {
  long first = 0, last = -1;
  bool one_stretch = true;
  double max_fill = 0;
  double lo_m = 0, hi_m = 0;
  double true_lo_mm = 0, true_hi_mm = 0;
};

TopBand top_band_of(const Sphere &crown, const RowMapParams &params)
{
  const StereoGeometry g = camera();
  RowMap map(params);
  for (double pos = 1000; pos <= 3000; pos += 100) {
    const View v = cast_sphere(g, crown, pos);
    map.add_frame(v.mask, v.points, g, level_ground(), pos);
  }
  TopBand t;
  for (long b = map.first_bin(); b <= map.last_bin(); ++b) {
    const RowMapCell c = map.cell(b, 3);
    t.max_fill = std::max(t.max_fill, c.fill);
    if (!c.present)
      continue;
    if (t.last < t.first)
      t.first = b, t.lo_m = c.lo_m;
    else
      t.one_stretch = t.one_stretch && b == t.last + 1;
    t.last = b;
    t.hi_m = c.hi_m;
  }
  auto frame_of = [](long b) { return std::round((b + 0.5) * 50 / 100) * 100; };
  double unused = 0;
  visible_extent(crown, frame_of(t.first), 1300, 1600, t.true_lo_mm, unused);
  visible_extent(crown, frame_of(t.last), 1300, 1600, unused, t.true_hi_mm);
  return t;
}

TEST(RowMap, ARoundCrownsCapReachesItsLimb)
{
  RowMapParams params;
  params.min_fill = 0; // every canopy pixel counts: the cap thins to nothing at its ends
  const TopBand t = top_band_of(Sphere{2000, 1050, 2350, 350}, params);
  ASSERT_GE(t.last, t.first);
  EXPECT_NEAR(t.lo_m, t.true_lo_mm / 1000, 0.01);
  EXPECT_NEAR(t.hi_m, t.true_hi_mm / 1000, 0.01);
}

TEST(RowMap, ACapAFewMillimetresIntoABandIsPresent)
{
  // A crown whose top rises 14 mm into the top band (1.3-1.6 m), its visible surface about 10:
  // its cap there is 165 mm long along the row and fills at most 2 % of a cell's 300 mm, under
  // min_fill over the whole cap. It is the crown going on from the band below, not a speck:
  // present as one stretch. A column counts where the cap holds 3 pixel rows of the band (6 mm
  // at 2.3 m here); the cap's last 2-3 cm at each end are thinner, and come in only where they
  // reach into a present neighbour's bin.
  const Sphere crown{2000, 964, 2350, 350};
  const TopBand t = top_band_of(crown, RowMapParams());
  EXPECT_LT(t.max_fill, RowMapParams().min_fill);
  ASSERT_GE(t.last, t.first) << "the cap is missing";
  EXPECT_TRUE(t.one_stretch);
  EXPECT_GT(t.true_hi_mm - t.true_lo_mm, 150); // a cap worth spraying (min_canopy 100 mm)
  EXPECT_GE(t.lo_m, t.true_lo_mm / 1000 - 0.005);
  EXPECT_LE(t.lo_m, t.true_lo_mm / 1000 + 0.035);
  EXPECT_LE(t.hi_m, t.true_hi_mm / 1000 + 0.005);
  EXPECT_GE(t.hi_m, t.true_hi_mm / 1000 - 0.035);
}

TEST(RowMap, GapShowsAtFasterTravelToo)
{
  // 2 m/s at 7 frames/s: 286 mm a frame.
  const RowMap map = build(2000.0 / 7.0);
  for (int k = 1; k < 3; ++k) {
    EXPECT_TRUE(map.cell(31, k).present);
    EXPECT_FALSE(map.cell(32, k).present);
    EXPECT_FALSE(map.cell(33, k).present);
    EXPECT_TRUE(map.cell(34, k).present);
  }
}

TEST(RowMap, NearestTheCentreWins)
{
  const StereoGeometry g = camera();
  RowMap map;
  // The row seen straight on at 1.3 m, then a frame at 2.5 m whose left edge (1.32 m at 2 m)
  // shows a false canopy over the gap at 1.6-1.7 m: the bins there were seen nearer the centre.
  View v = cast(g, kWalls, 1300);
  map.add_frame(v.mask, v.points, g, level_ground(), 1300);
  ASSERT_FALSE(map.cell(32, 1).present);
  std::vector<Wall> fake = kWalls;
  fake.push_back({1600, 1700, 500, 1500, 2000});
  v = cast(g, fake, 2500);
  map.add_frame(v.mask, v.points, g, level_ground(), 2500);
  EXPECT_FALSE(map.cell(32, 1).present);
  EXPECT_FALSE(map.cell(33, 1).present);
  // Bins the first frame did not see come from the second.
  EXPECT_TRUE(map.cell(60, 1).present); // the third canopy, 2.8-3.3 m at 1.9 m
  EXPECT_NEAR(map.cell(60, 1).distance_m, 1.9, 0.001);
}

TEST(RowMap, TwoFramesThatSeeABandsCanopyOutvoteTheNearest)
{
  // A canopy at 1.60-1.65 m (bin 32, in the gap) that the frame nearest it (at 1.625 m) does not
  // see: one other frame seeing it is not enough, two are.
  const StereoGeometry g = camera();
  std::vector<Wall> with = kWalls;
  with.push_back({1600, 1650, 500, 1500, 2000});
  RowMap map;
  auto add = [&](const std::vector<Wall> &walls, double pos) {
    const View v = cast(g, walls, pos);
    map.add_frame(v.mask, v.points, g, level_ground(), pos);
  };
  add(with, 1500);
  add(kWalls, 1625);
  EXPECT_FALSE(map.cell(32, 1).present);
  add(with, 1750);
  for (int k = 1; k < 4; ++k) {
    SCOPED_TRACE("band " + std::to_string(k));
    const RowMapCell c = map.cell(32, k);
    EXPECT_TRUE(c.present);
    EXPECT_NEAR(c.lo_m, 1.600, 2.5e-3);
    EXPECT_NEAR(c.hi_m, 1.650, 2.5e-3);
    EXPECT_NEAR(c.distance_m, 2.0, 0.001);
  }
  EXPECT_FALSE(map.cell(33, 1).present);
  // Which frame came first does not matter.
  RowMap later;
  for (const auto &[walls, pos] : std::vector<std::pair<std::vector<Wall>, double>>{
           {kWalls, 1625}, {with, 1750}, {with, 1500}}) {
    const View v = cast(g, walls, pos);
    later.add_frame(v.mask, v.points, g, level_ground(), pos);
  }
  EXPECT_TRUE(later.cell(32, 1).present);
}

TEST(RowMap, ACanopysEndReachesAsFarAsTheFramesNearItSawIt)
{
  // Canopy A ends at 1.600 m. The frame nearest that end (at 1.575 m) sees it only to 1.585 m,
  // as when a nearer leaf hides the rest from there; a frame at 1.700 m, 0.06 off its axis at
  // 2 m, sees it to 1.596 m; one at 2.200 m, 0.3 off its axis where a depth error moves a pixel
  // along the row three times as far, to 1.620 m. The canopy is what the frames near it saw of
  // it, together: the map's end and the valve's follow the second frame, not the third. (A
  // fourth frame, at 3.050 m, shows the third canopy whole.)
  const StereoGeometry g = camera();
  RowMap map;
  const std::vector<std::pair<double, double>> ends_at = {
      {1585, 1575}, {1596, 1700}, {1620, 2200}, {1600, 3050}}; // (end, frame position), mm
  for (const auto &[end_mm, pos] : ends_at) {
    std::vector<Wall> walls = kWalls;
    walls[0].x1 = end_mm;
    const View v = cast(g, walls, pos);
    map.add_frame(v.mask, v.points, g, level_ground(), pos);
  }
  const double px = 2.5e-3; // m
  for (int k = 1; k < 4; ++k) {
    SCOPED_TRACE("band " + std::to_string(k));
    EXPECT_NEAR(map.cell(31, k).lo_m, 1.550, px); // bin 1.550-1.600
    EXPECT_NEAR(map.cell(31, k).hi_m, 1.596, px);
    EXPECT_FALSE(map.cell(32, k).present); // the third frame's canopy there is no one's vote
  }
  expect_sprayed(plan_commands(map, 100, 4000), 1, {{1.0, 1.596}, {1.7, 2.3}, {2.8, 3.3}});
}

TEST(RowMap, TheSprayerWaitsForTheFramesStillToVote)
{
  // A canopy at 2.50-2.65 m (in the gap before the third) that the frames nearest its bins do
  // not see and the frames from 2.675 m on do: two of them outvote the nearest. The sprayer,
  // fed frame by frame as spraycontrol feeds it (frames every 25 mm at 1 m/s), must wait for
  // those votes: taken when the rig passed the next bin's centre, bin 52 (2.60-2.65 m) would be
  // planned empty before a frame saw it, and the valve would stay shut where the map shows
  // canopy.
  const StereoGeometry g = camera();
  std::vector<Wall> with = kWalls;
  with.push_back({2500, 2650, 500, 1500, 2000});
  RowMap map;
  const auto cmds = plan_commands(map, 25, 4000, [&](double pos) {
    const View v = cast(g, pos >= 2675 ? with : kWalls, pos);
    map.add_frame(v.mask, v.points, g, level_ground(), pos);
  });
  for (long b = 50; b <= 52; ++b)
    EXPECT_TRUE(map.cell(b, 1).present) << "bin " << b;
  EXPECT_GT(map.settle_mm(), 150); // a slope of 0.1 at the canopy's 1.9-2.2 m
  expect_sprayed(cmds, 1, {{1.0, 1.6}, {1.7, 2.3}, {2.5, 2.65}, {2.8, 3.3}});
}

TEST(RowMap, CsvHeaderAndRows)
{
  const RowMap map = build();
  const std::string path = testing::TempDir() + "rowmap_test.csv";
  map.write_csv(path);
  std::ifstream f(path);
  std::string line;
  ASSERT_TRUE(std::getline(f, line));
  EXPECT_EQ(line, "position_m,band,present,distance_m,fill,seen");
  std::size_t rows = 0, unseen = 0;
  bool found = false, found_gap = false;
  while (std::getline(f, line)) {
    ++rows;
    // The last column: whether a frame saw the cell, as the map has it.
    const double at = std::stod(line.substr(0, line.find(',')));
    const int k = std::stoi(line.substr(line.find(',') + 1));
    const long bin = std::lround(at / 0.05 - 0.5);
    const bool seen = line.back() == '1';
    EXPECT_TRUE(line.back() == '1' || line.back() == '0') << line;
    EXPECT_EQ(seen, map.cell(bin, k).seen) << line;
    unseen += !seen;
    double pos = 0, dist = 0, fill = 0;
    int band = 0, present = 0;
    if (std::sscanf(line.c_str(), "%lf,%d,%d,%lf,%lf", &pos, &band, &present, &dist, &fill) ==
            5 &&
        std::abs(pos - 1.275) < 1e-9 && band == 1) {
      found = true;
      EXPECT_EQ(present, 1);
      EXPECT_NEAR(dist, 2.0, 0.001);
      EXPECT_NEAR(fill, 1.0, 0.03);
    }
    if (line.rfind("1.6250,2,0,,", 0) == 0) {
      found_gap = true;
      EXPECT_TRUE(seen) << "a gap seen empty: " << line;
    }
  }
  EXPECT_TRUE(found);
  EXPECT_TRUE(found_gap);
  EXPECT_EQ(unseen, 0u); // every band in view of some frame
  EXPECT_EQ(rows, std::size_t(map.last_bin() - map.first_bin() + 1) * 4);
  EXPECT_GT(map.last_bin() - map.first_bin(), 90); // -1.2 to 5.2 m at least
  std::remove(path.c_str());

  // Bands up to 6 m: the top ones above the view. Unseen, not empty: seen 0.
  RowMapParams high;
  high.max_height_mm = 6000;
  RowMap tall(high);
  const StereoGeometry g = camera();
  const View v = cast(g, kWalls, 1000);
  tall.add_frame(v.mask, v.points, g, level_ground(), 1000);
  ASSERT_FALSE(tall.cell(tall.first_bin(), 3).seen);
  tall.write_csv(path);
  std::ifstream t(path);
  std::getline(t, line);
  std::size_t top_rows = 0, top_unseen = 0;
  while (std::getline(t, line))
    if (line.find(",3,") != std::string::npos) {
      ++top_rows;
      top_unseen += line.size() > 2 && line.compare(line.size() - 2, 2, ",0") == 0;
      EXPECT_NE(line.find(",3,0,,"), std::string::npos) << line;
    }
  EXPECT_GT(top_rows, 0u);
  EXPECT_EQ(top_unseen, top_rows);

}

TEST(RowMap, PngWrittenWithItsSize)
{
  const RowMap map = build();
  const std::string path = testing::TempDir() + "rowmap_test.png";
  map.write_png(path, trees());
  const cv::Mat img = cv::imread(path, cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty());
  const int bins = int(map.last_bin() - map.first_bin() + 1);
  // 8 px a bin, 160 px a metre of height up to 1.6 m, the margins.
  EXPECT_EQ(img.cols, 70 + bins * 8 + 20);
  EXPECT_EQ(img.rows, 50 + 256 + 80);
  EXPECT_EQ(img.size(), map.render_size());
  // The gap's cells dark grey, the canopy's coloured, at the middle of band 1 (0.85 m).
  const int y = 50 + 256 - int(std::lround(0.85 * 160));
  auto x_of = [&](long b) { return 70 + int(b - map.first_bin()) * 8 + 4; };
  EXPECT_EQ(img.at<cv::Vec3b>(y, x_of(32)), cv::Vec3b(60, 60, 60));
  EXPECT_EQ(img.at<cv::Vec3b>(y, x_of(33)), cv::Vec3b(60, 60, 60));
  const cv::Vec3b a = img.at<cv::Vec3b>(y, x_of(25)), b = img.at<cv::Vec3b>(y, x_of(40));
  EXPECT_NE(a, cv::Vec3b(60, 60, 60));
  EXPECT_NE(a, b); // 2.0 m and 2.2 m differ in colour
  std::remove(path.c_str());
}

// The valve timeline under the map: one strip per section on the map's travel axis, green where
// the valve is open; a stretch left open runs to the map's end.
TEST(RowMap, ValveTimelineUnderTheMap)
{
  const RowMap map = build();
  const double lo = double(map.first_bin()) * 0.05, hi = double(map.last_bin() + 1) * 0.05;
  const std::vector<SprayedStretch> sprayed = {
      {0, lo + 0.5, lo + 1.0}, {1, lo + 0.2, lo + 0.3},
      {3, lo + 1.5, std::numeric_limits<double>::infinity()}};
  const cv::Mat img = map.render_with_timeline(trees(), sprayed, 4);
  const cv::Mat plain = map.render(trees());
  ASSERT_EQ(img.cols, plain.cols);
  ASSERT_EQ(img.rows, plain.rows + RowMap::kTimelineTop + 4 * RowMap::kStripHeight);
  EXPECT_EQ(cv::norm(img(cv::Rect(0, 0, plain.cols, plain.rows)), plain, cv::NORM_INF), 0.0);
  auto x_of = [&](double m) { return RowMap::kMarginLeft + int(std::lround((m / 0.05 - double(map.first_bin())) * 8)); };
  auto y_of = [&](int section) {
    return plain.rows + RowMap::kTimelineTop + (3 - section) * RowMap::kStripHeight +
           RowMap::kStripHeight / 2;
  };
  const cv::Vec3b open(40, 120, 20), closed(225, 225, 225);
  EXPECT_EQ(img.at<cv::Vec3b>(y_of(0), x_of(lo + 0.75)), open);
  EXPECT_EQ(img.at<cv::Vec3b>(y_of(0), x_of(lo + 1.2)), closed);
  EXPECT_EQ(img.at<cv::Vec3b>(y_of(1), x_of(lo + 0.25)), open);
  EXPECT_EQ(img.at<cv::Vec3b>(y_of(1), x_of(lo + 0.75)), closed);
  EXPECT_EQ(img.at<cv::Vec3b>(y_of(2), x_of(lo + 0.75)), closed);
  EXPECT_EQ(img.at<cv::Vec3b>(y_of(3), x_of(hi - 0.05)), open);
  EXPECT_EQ(img.at<cv::Vec3b>(y_of(3), x_of(lo + 1.2)), closed);

  EXPECT_THROW(map.render_with_timeline({}, sprayed, 3), std::runtime_error); // section 3
  EXPECT_THROW(map.render_with_timeline({}, {{0, 1.0, 0.5}}, 1), std::runtime_error);
  EXPECT_EQ(with_extension("out/demo-sections.jsonl", ".png"), "out/demo-sections.png");
  EXPECT_EQ(with_extension("a.b/map", ".png"), "a.b/map.png");
}

TEST(RowMap, ErrorsNameThePath)
{
  const RowMap map = build(400);
  const std::string bad = "/nonexistent-treestereo-dir/sub/map";
  for (const std::string ext : {".csv", ".png"}) {
    try {
      if (ext == ".csv")
        map.write_csv(bad + ext);
      else
        map.write_png(bad + ext);
      FAIL() << "no error for " << ext;
    } catch (const FileError &e) {
      EXPECT_NE(std::string(e.what()).find(bad + ext), std::string::npos) << e.what();
      EXPECT_EQ(e.path(), bad + ext);
      EXPECT_EQ(e.access(), FileAccess::Write);
    }
  }
  RowMap empty;
  EXPECT_THROW(empty.write_png(testing::TempDir() + "empty.png"), std::runtime_error);
}

TEST(RowMap, RejectsBadInput)
{
  RowMapParams p;
  p.band_edges_mm = {400, 300, 900};
  try {
    RowMap m(p);
    FAIL() << "no error";
  } catch (const std::runtime_error &e) {
    EXPECT_NE(std::string(e.what()).find("band_edges_mm"), std::string::npos);
  }
  p = RowMapParams();
  p.bin_mm = 0;
  EXPECT_THROW(RowMap m(p), BadSettings);
  RowMap map;
  const StereoGeometry g = camera();
  EXPECT_THROW(map.add_frame(cv::Mat::zeros(10, 10, CV_8U), {}, g, level_ground(), 0), BadInput);
  GroundPlane none;
  EXPECT_THROW(map.add_frame(cv::Mat::zeros(g.view_size, CV_8U), {}, g, none, 0), BadInput);
}
