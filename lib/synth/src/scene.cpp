#include "treestereo/scene.hpp"

#include "scene_materials.hpp"
#include "scene_noise.hpp"
#include "treestereo/errors.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace treestereo {

using namespace scene_noise;
using cv::Vec3d;

// ---------------------------------------------------------------------------------------------
// Parameters and the rig

namespace {

void require(bool ok, const char *name, double value, const char *range)
{
  if (ok)
    return;
  std::ostringstream s;
  s << "scene parameter " << name << " = " << value << " is out of range: " << range;
  throw BadSettings(s.str());
}

constexpr int kMaxWidth = 2592, kMaxHeight = 1944;

} // namespace

const char *scene_kind_name(SceneKind kind)
{
  switch (kind) {
  case SceneKind::Orchard:
    return "orchard";
  case SceneKind::Hedgerow:
    return "hedgerow";
  default:
    return "lab";
  }
}

SceneKind scene_kind_from_name(const std::string &name)
{
  for (SceneKind k : {SceneKind::Lab, SceneKind::Orchard, SceneKind::Hedgerow})
    if (name == scene_kind_name(k))
      return k;
  throw BadSettings("unknown scene '" + name + "': valid scenes are lab, orchard, hedgerow");
}

namespace {

// Size factors of the trees around the tree in front (of the nominal canopy).
constexpr double kRowWidthLo = 0.85, kRowWidthHi = 1.15, kRowHeightLo = 0.85, kRowHeightHi = 1.1;
constexpr double kRowDepthLo = 0.85, kRowDepthHi = 1.15;
constexpr double kBackSizeLo = 0.9, kBackSizeHi = 1.3;
constexpr double kBackStepLo = 1100.0, kBackStepHi = 1700.0; // trunk to trunk in the back row

// The far side of the back row's deepest canopy (mm).
double back_row_far_mm(const SceneParams &p)
{
  return p.distance_mm + p.row_spacing_mm + 0.5 * kBackSizeHi * p.canopy_depth_mm;
}

} // namespace

SceneParams resolve_scene_params(const SceneParams &params)
{
  SceneParams p = params;
  const bool hedge = p.kind == SceneKind::Hedgerow;
  if (std::isnan(p.row_gap_min_mm))
    p.row_gap_min_mm = hedge ? -0.15 * p.canopy_width_mm : 200.0;
  if (std::isnan(p.row_gap_max_mm))
    p.row_gap_max_mm = hedge ? 0.0 : 600.0;
  if (std::isnan(p.row_spacing_mm))
    p.row_spacing_mm = 3500.0;
  if (p.kind != SceneKind::Lab &&
      p.background_distance_mm == SceneParams{}.background_distance_mm &&
      std::isfinite(p.row_spacing_mm) && std::isfinite(p.canopy_depth_mm))
    p.background_distance_mm = std::max(p.background_distance_mm, back_row_far_mm(p) + 3000.0);
  return p;
}

void validate_scene_params(const SceneParams &params)
{
  const SceneParams p = resolve_scene_params(params);
  require(p.kind == SceneKind::Lab || p.kind == SceneKind::Orchard || p.kind == SceneKind::Hedgerow,
          "kind", double(int(p.kind)), "Lab, Orchard or Hedgerow");
  auto finite = [](double v) { return std::isfinite(v); };
  require(p.image_size.width >= 64 && p.image_size.width <= kMaxWidth, "image width",
          p.image_size.width, "64 to 2592 pixels");
  require(p.image_size.height >= 48 && p.image_size.height <= kMaxHeight, "image height",
          p.image_size.height, "48 to 1944 pixels");
  require(finite(p.distance_mm) && p.distance_mm >= 500 && p.distance_mm <= 6000, "distance_mm",
          p.distance_mm, "500 to 6000 mm");
  require(finite(p.tree_x_mm) && std::abs(p.tree_x_mm) <= 5000, "tree_x_mm", p.tree_x_mm,
          "-5000 to 5000 mm");
  require(finite(p.canopy_height_mm) && p.canopy_height_mm >= 100 && p.canopy_height_mm <= 4000,
          "canopy_height_mm", p.canopy_height_mm, "100 to 4000 mm");
  require(finite(p.canopy_width_mm) && p.canopy_width_mm >= 100 && p.canopy_width_mm <= 4000,
          "canopy_width_mm", p.canopy_width_mm, "100 to 4000 mm");
  require(finite(p.canopy_depth_mm) && p.canopy_depth_mm >= 100 && p.canopy_depth_mm <= 4000,
          "canopy_depth_mm", p.canopy_depth_mm, "100 to 4000 mm");
  require(p.canopy_depth_mm < 2.0 * p.distance_mm - 200, "canopy_depth_mm", p.canopy_depth_mm,
          "less than twice the distance minus 200 mm (the canopy must be in front of the camera)");
  require(finite(p.trunk_height_mm) && p.trunk_height_mm >= 0 && p.trunk_height_mm <= 3000,
          "trunk_height_mm", p.trunk_height_mm, "0 to 3000 mm");
  require(finite(p.trunk_radius_mm) && p.trunk_radius_mm >= 5 && p.trunk_radius_mm <= 300,
          "trunk_radius_mm", p.trunk_radius_mm, "5 to 300 mm");
  require(finite(p.camera_height_mm) && p.camera_height_mm >= 100 && p.camera_height_mm <= 5000,
          "camera_height_mm", p.camera_height_mm, "100 to 5000 mm");
  require(finite(p.background_distance_mm) &&
              p.background_distance_mm >= p.distance_mm + 0.5 * p.canopy_depth_mm + 500 &&
              p.background_distance_mm <= 100000,
          "background_distance_mm", p.background_distance_mm,
          "at least 500 mm behind the canopy, at most 100 m");
  require(finite(p.baseline_mm) && p.baseline_mm >= 5 && p.baseline_mm <= 1000, "baseline_mm",
          p.baseline_mm, "5 to 1000 mm");
  require(finite(p.speed_m_s) && std::abs(p.speed_m_s) <= 20, "speed_m_s", p.speed_m_s,
          "-20 to 20 m/s");
  require(finite(p.framerate) && p.framerate > 0 && p.framerate <= 1000, "framerate",
          p.framerate, "above 0, at most 1000 frames/s");
  require(finite(p.tree_spacing_mm) && p.tree_spacing_mm >= p.canopy_width_mm &&
              p.tree_spacing_mm <= 100000,
          "tree_spacing_mm", p.tree_spacing_mm, "at least the canopy width, at most 100 m");
  require(finite(p.light) && p.light >= 0.1 && p.light <= 3, "light", p.light, "0.1 to 3");
  require(finite(p.noise) && p.noise >= 0 && p.noise <= 50, "noise", p.noise,
          "0 to 50 levels");
  require(p.clusters == 0 || (p.clusters >= 1 && p.clusters <= 400), "clusters", p.clusters,
          "0 (from the seed) or 1 to 400");
  require(finite(p.gap_fraction) && p.gap_fraction >= 0 && p.gap_fraction <= 0.8,
          "gap_fraction", p.gap_fraction, "0 to 0.8");
  if (p.kind == SceneKind::Lab)
    return;
  require(finite(p.row_gap_min_mm) && p.row_gap_min_mm >= -0.5 * p.canopy_width_mm &&
              p.row_gap_min_mm <= 20000,
          "row_gap_min_mm", p.row_gap_min_mm,
          "-0.5 canopy_width_mm (half overlapping canopies) to 20000 mm");
  require(finite(p.row_gap_max_mm) && p.row_gap_max_mm >= p.row_gap_min_mm &&
              p.row_gap_max_mm <= 20000,
          "row_gap_max_mm", p.row_gap_max_mm, "row_gap_min_mm to 20000 mm");
  require(p.touching_pair == SceneParams::kNoTouchingPair ||
              (p.touching_pair >= -100 && p.touching_pair <= 100),
          "touching_pair", p.touching_pair, "-100 to 100 (or none)");
  require(finite(p.row_spacing_mm) && p.row_spacing_mm >= 1500 && p.row_spacing_mm <= 8000,
          "row_spacing_mm", p.row_spacing_mm, "1500 to 8000 mm");
  require(p.row_spacing_mm >= 1.3 * p.canopy_depth_mm, "row_spacing_mm", p.row_spacing_mm,
          "at least 1.3 times canopy_depth_mm (the rows' canopies must not meet)");
  require(kRowDepthHi * p.canopy_depth_mm < 2.0 * p.distance_mm - 200, "canopy_depth_mm",
          p.canopy_depth_mm,
          "less than (twice the distance minus 200 mm) / 1.15 (every near-row canopy in front of "
          "the camera)");
  require(p.background_distance_mm >= back_row_far_mm(p) + 1000, "background_distance_mm",
          p.background_distance_mm, "at least 1 m behind the back row's canopies");
}

StereoCalibration rig_calibration(const SceneParams &p)
{
  validate_scene_params(p);
  // The paper's MATLAB calibration of two MER-500 cameras (2592x1944), scaled to the width;
  // the principal points keep their offset from the centre when the aspect ratio differs.
  const double s = double(p.image_size.width) / kMaxWidth;
  const double dy = 0.5 * (p.image_size.height - kMaxHeight * s);
  auto camera = [&](double fx, double fy, double cx, double cy) -> cv::Mat {
    return (cv::Mat_<double>(3, 3) << fx * s, 0, cx * s, 0, fy * s, cy * s + dy, 0, 0, 1);
  };
  StereoCalibration c;
  c.image_size = p.image_size;
  c.M1 = camera(3503.12, 3504.61, 1207.31, 967.84);
  c.M2 = camera(3511.25, 3511.71, 1198.93, 960.13);
  // An 8 mm lens on a 5.7 mm sensor: about 1 % barrel distortion in the corners.
  c.D1 = (cv::Mat_<double>(1, 5) << -0.082, 0.134, 0.00041, -0.00032, -0.031);
  c.D2 = (cv::Mat_<double>(1, 5) << -0.077, 0.118, -0.00028, 0.00037, -0.024);
  // 0.55 degrees mostly about y (toe-in), a little pitch and roll: rows differ by a few pixels.
  const cv::Vec3d rvec(0.0035, -0.0085, 0.0025);
  cv::Rodrigues(rvec, c.R);
  c.T = (cv::Mat_<double>(3, 1) << -p.baseline_mm, 0.35, -0.25);
  c.pixel_size_um = 2.2 / s;
  return c;
}

// ---------------------------------------------------------------------------------------------
// The tree

namespace {

struct Cluster {
  Vec3d c, r;       // centre and semi-axes (mm, camera frame)
  double rb = 0;    // bounding-sphere radius
  int tree = 0;     // the tree it belongs to, in the frame's list of trees
};

struct Tree {
  double x = 0, z = 0;          // trunk axis in the camera frame
  double y_ground = 0, y_top = 0; // trunk from the ground up to the canopy centre
  Vec3d centre, half;           // canopy envelope (extents of the union), camera frame
  std::vector<Cluster> clusters;
  std::uint32_t seed = 0;       // texture seed of this tree
  std::int64_t k = 0;           // index in its row
  SurfaceLabel leaf = SurfaceLabel::Leaf; // label of its leaves
  // Bounding sphere about centre: holds every cluster's sphere and the trunk.
  double rb = 0;
};

// The key of tree k of the back row in make_tree's generator (the near row's are k itself).
constexpr std::uint64_t kBackRowKey = 0x6261636b00000000ULL;

// Tree `key` (k of the near row), its trunk at camera-frame (x_cam, z), canopy extents `size`
// (width, height, depth, mm) on the scene's trunk height.
Tree make_tree(const SceneParams &p, std::uint64_t key, double x_cam, double z, const Vec3d &size)
{
  Rng rng(hash64(p.seed) ^ hash64(key * 0x9e3779b97f4a7c15ULL + 17U));
  Tree t;
  t.seed = std::uint32_t(rng.next() >> 32);
  t.x = x_cam;
  t.z = z;
  t.y_ground = p.camera_height_mm;
  const double bottom = p.camera_height_mm - p.trunk_height_mm;
  t.centre = Vec3d(x_cam, bottom - 0.5 * size[1], z);
  t.half = Vec3d(0.5 * size[0], 0.5 * size[1], 0.5 * size[2]);
  t.y_top = t.centre[1];

  const int n = p.clusters > 0 ? p.clusters : 30 + int(rng.next() % 51U);
  // Cluster size so that the clusters fill the envelope about 1.7 times over.
  const double envelope = t.half[0] * t.half[1] * t.half[2];
  const double r_mean = std::cbrt(1.7 * envelope / n);
  std::vector<Cluster> cl(static_cast<std::size_t>(n));
  for (auto &c : cl) {
    Vec3d u;
    do {
      u = Vec3d(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
    } while (u.dot(u) > 1.0);
    const double r = r_mean * rng.uniform(0.7, 1.3);
    c.r = Vec3d(r * rng.uniform(0.9, 1.1), r * rng.uniform(0.75, 0.95), r * rng.uniform(0.9, 1.1));
    c.c = Vec3d(u[0] * t.half[0], u[1] * t.half[1], u[2] * t.half[2]) * 0.8;
  }
  // Map each axis so the union spans the requested extent exactly: the truth is then both
  // what was asked for and what the geometry is.
  for (int a = 0; a < 3; ++a) {
    double lo = std::numeric_limits<double>::max(), hi = -lo;
    for (const auto &c : cl) {
      lo = std::min(lo, c.c[a] - c.r[a]);
      hi = std::max(hi, c.c[a] + c.r[a]);
    }
    const double scale = 2.0 * t.half[a] / (hi - lo), mid = 0.5 * (lo + hi);
    for (auto &c : cl) {
      c.c[a] = (c.c[a] - mid) * scale + t.centre[a];
      c.r[a] *= scale;
    }
  }
  for (auto &c : cl) {
    c.rb = std::max(c.r[0], std::max(c.r[1], c.r[2]));
    t.rb = std::max(t.rb, cv::norm(c.c - t.centre) + c.rb);
  }
  t.rb = std::max(t.rb, std::hypot(t.y_ground - t.centre[1], p.trunk_radius_mm)) + 1.0;
  t.clusters = std::move(cl);
  return t;
}

// Tree k of the Lab row, its trunk at camera-frame x = x_cam.
Tree make_lab_tree(const SceneParams &p, std::int64_t k, double x_cam)
{
  Tree t = make_tree(p, std::uint64_t(k), x_cam, p.distance_mm,
                     Vec3d(p.canopy_width_mm, p.canopy_height_mm, p.canopy_depth_mm));
  t.k = k;
  return t;
}

// ---------------------------------------------------------------------------------------------
// The rows of Orchard and Hedgerow

// One tree's place in a row: trunk at world x, canopy extents (mm).
struct RowSlot {
  double x = 0;
  Vec3d size;
};

// A row of trees along x: kSlots trees laid out from the seed around k = 0, repeated with
// period `period` beyond them (tree k has the place of slot k mod kSlots, its own clusters).
struct Row {
  static constexpr int kHalf = 200, kSlots = 2 * kHalf + 1;
  std::vector<RowSlot> slots; // k = -kHalf .. kHalf
  double period = 0;
  double z = 0;
  double max_half_width = 0;  // of any canopy of the row

  RowSlot slot(std::int64_t k) const
  {
    const std::int64_t j = k + kHalf;
    std::int64_t q = j / kSlots, r = j % kSlots;
    if (r < 0) {
      r += kSlots;
      --q;
    }
    RowSlot s = slots[std::size_t(r)];
    s.x += double(q) * period;
    return s;
  }

  // The tree whose trunk is nearest to world x.
  std::int64_t nearest(double x) const
  {
    const double x0 = slots.front().x;
    const std::int64_t q = std::int64_t(std::floor((x - x0) / period));
    const double xr = x - double(q) * period;
    auto it = std::lower_bound(slots.begin(), slots.end(), xr,
                               [](const RowSlot &s, double v) { return s.x < v; });
    std::int64_t k = std::int64_t(it - slots.begin()) - kHalf + q * kSlots;
    std::int64_t best = k;
    for (std::int64_t c = k - 1; c <= k + 1; ++c)
      if (std::abs(slot(c).x - x) < std::abs(slot(best).x - x))
        best = c;
    return best;
  }

  // Trees whose canopy may overlap world x in [lo, hi].
  std::pair<std::int64_t, std::int64_t> range(double lo, double hi) const
  {
    std::int64_t a = nearest(lo), b = nearest(hi);
    while (slot(a - 1).x + max_half_width >= lo)
      --a;
    while (slot(b + 1).x - max_half_width <= hi)
      ++b;
    return {a, b};
  }
};

// Uniform in [lo, hi] from a hash of the seed, a row, a tree and a draw.
double row_uniform(const SceneParams &p, std::uint64_t row, std::int64_t k, std::uint64_t draw,
                   double lo, double hi)
{
  const std::uint64_t h = hash64(hash64(p.seed + 0x5eedULL) ^
                                 hash64(row * 0x100000001b3ULL + std::uint64_t(k) * 8 + draw));
  return lo + (hi - lo) * double(h >> 11) * (1.0 / 9007199254740992.0);
}

Row near_row(const SceneParams &p)
{
  Row row;
  row.z = p.distance_mm;
  row.slots.resize(Row::kSlots);
  const Vec3d nominal(p.canopy_width_mm, p.canopy_height_mm, p.canopy_depth_mm);
  auto size = [&](std::int64_t k) {
    if (k == 0)
      return nominal;
    return Vec3d(nominal[0] * row_uniform(p, 1, k, 0, kRowWidthLo, kRowWidthHi),
                 nominal[1] * row_uniform(p, 1, k, 1, kRowHeightLo, kRowHeightHi),
                 nominal[2] * row_uniform(p, 1, k, 2, kRowDepthLo, kRowDepthHi));
  };
  // gap(k): between the canopies of trees k and k + 1.
  auto gap = [&](std::int64_t k) {
    if (p.touching_pair != SceneParams::kNoTouchingPair && k == p.touching_pair)
      return -SceneParams::kTouchingOverlapMm;
    return row_uniform(p, 1, k, 3, p.row_gap_min_mm, p.row_gap_max_mm);
  };
  auto at = [&](std::int64_t k) -> RowSlot & { return row.slots[std::size_t(k + Row::kHalf)]; };
  at(0) = RowSlot{p.tree_x_mm, nominal};
  for (std::int64_t k = 1; k <= Row::kHalf; ++k) {
    at(k).size = size(k);
    at(k).x = at(k - 1).x + 0.5 * at(k - 1).size[0] + gap(k - 1) + 0.5 * at(k).size[0];
  }
  for (std::int64_t k = -1; k >= -Row::kHalf; --k) {
    at(k).size = size(k);
    at(k).x = at(k + 1).x - 0.5 * at(k + 1).size[0] - gap(k) - 0.5 * at(k).size[0];
  }
  // Beyond the slots the row repeats: tree kHalf + 1 stands where tree -kHalf would follow it.
  const RowSlot &first = row.slots.front(), &last = row.slots.back();
  row.period = (last.x + 0.5 * last.size[0] + gap(Row::kHalf) + 0.5 * first.size[0]) - first.x;
  row.max_half_width = 0.5 * kRowWidthHi * p.canopy_width_mm;
  return row;
}

Row back_row(const SceneParams &p)
{
  Row row;
  row.z = p.distance_mm + p.row_spacing_mm;
  row.slots.resize(Row::kSlots);
  const Vec3d nominal(p.canopy_width_mm, p.canopy_height_mm, p.canopy_depth_mm);
  auto at = [&](std::int64_t k) -> RowSlot & { return row.slots[std::size_t(k + Row::kHalf)]; };
  auto size = [&](std::int64_t k) {
    return Vec3d(nominal[0] * row_uniform(p, 2, k, 0, kBackSizeLo, kBackSizeHi),
                 nominal[1] * row_uniform(p, 2, k, 1, kBackSizeLo, kBackSizeHi),
                 nominal[2] * row_uniform(p, 2, k, 2, kBackSizeLo, kBackSizeHi));
  };
  auto step = [&](std::int64_t k) { return row_uniform(p, 2, k, 3, kBackStepLo, kBackStepHi); };
  at(0) = RowSlot{p.tree_x_mm + row_uniform(p, 2, 0, 4, -0.5, 0.5) * kBackStepLo, size(0)};
  for (std::int64_t k = 1; k <= Row::kHalf; ++k)
    at(k) = RowSlot{at(k - 1).x + step(k - 1), size(k)};
  for (std::int64_t k = -1; k >= -Row::kHalf; --k)
    at(k) = RowSlot{at(k + 1).x - step(k), size(k)};
  row.period = row.slots.back().x + step(Row::kHalf) - row.slots.front().x;
  row.max_half_width = 0.5 * kBackSizeHi * p.canopy_width_mm;
  return row;
}

// ---------------------------------------------------------------------------------------------
// Ray casting. A ray is o + t d with d = R^T (x, y, 1) for the view's normalised coordinates, so
// t is the Z of the hit in that view's camera frame.

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kTile = 16;
constexpr double kWallHeightMm = 3500.0;

struct Hit {
  double t = 0;
  SurfaceLabel label = SurfaceLabel::Sky;
  int tree = -1; // the tree of a leaf or trunk hit, in the frame's list of trees
  cv::Vec3f rgb;
};

struct Crossing {
  double t;
  int cluster;
  bool entry;
};

// Entry and exit of an ellipsoid, false when missed.
bool hit_ellipsoid(const Cluster &c, const Vec3d &o, const Vec3d &d, double &t0, double &t1)
{
  const Vec3d oc((o[0] - c.c[0]) / c.r[0], (o[1] - c.c[1]) / c.r[1], (o[2] - c.c[2]) / c.r[2]);
  const Vec3d dd(d[0] / c.r[0], d[1] / c.r[1], d[2] / c.r[2]);
  const double a = dd.dot(dd), b = oc.dot(dd), cc = oc.dot(oc) - 1.0;
  const double disc = b * b - a * cc;
  if (disc <= 0)
    return false;
  const double s = std::sqrt(disc);
  // The numerically stable pair of roots.
  const double q = b > 0 ? -(b + s) : -(b - s);
  double r0 = q / a, r1 = cc / q;
  if (r0 > r1)
    std::swap(r0, r1);
  t0 = r0;
  t1 = r1;
  return t1 > 0;
}

double hit_trunk(const Tree &tree, double radius, const Vec3d &o, const Vec3d &d)
{
  const double ox = o[0] - tree.x, oz = o[2] - tree.z;
  const double a = d[0] * d[0] + d[2] * d[2], b = ox * d[0] + oz * d[2];
  const double c = ox * ox + oz * oz - radius * radius;
  const double disc = b * b - a * c;
  if (disc <= 0 || a <= 0)
    return kInf;
  const double s = std::sqrt(disc);
  const double q = b > 0 ? -(b + s) : -(b - s);
  const double t = std::min(q / a, c / q);
  if (t <= 0)
    return kInf;
  const double y = o[1] + t * d[1];
  return (y >= tree.y_top && y <= tree.y_ground) ? t : kInf;
}

struct TraceContext {
  const SceneParams *p;
  const std::vector<Tree> *trees;
  const std::vector<Cluster> *clusters; // of every tree, Cluster::tree says whose
  double travel;   // world x of the camera frame's origin
  double fx;       // px per unit normalised coordinate (for footprints)
};

// What a tile's rays can hit: these trees' trunks and these clusters (indices into the
// TraceContext's lists); xs has room for two crossings per cluster.
struct TileCandidates {
  const std::uint16_t *trees;
  int n_trees;
  const std::uint32_t *clusters;
  int n_clusters;
};

Vec3d ellipsoid_normal(const Cluster &c, const Vec3d &pt)
{
  return cv::normalize(Vec3d((pt[0] - c.c[0]) / (c.r[0] * c.r[0]), (pt[1] - c.c[1]) / (c.r[1] * c.r[1]),
                             (pt[2] - c.c[2]) / (c.r[2] * c.r[2])));
}

Hit shade_leaf(const TraceContext &cx, const Tree &tree, Vec3d n, const Vec3d &pt, const Vec3d &d,
               double t, bool entry, const scene_materials::LeafSample &leaf)
{
  if (n.dot(d) > 0) // the normal facing the camera, also inside a shell seen through a hole
    n = -n;
  const Vec3d rel((pt[0] - tree.centre[0]) / tree.half[0], (pt[1] - tree.centre[1]) / tree.half[1],
                  (pt[2] - tree.centre[2]) / tree.half[2]);
  const double depth_in = 1.0 - std::min(1.0, std::sqrt(rel.dot(rel)));
  const Vec3d local(pt[0] - tree.x, pt[1], pt[2] - tree.z);
  Hit h;
  h.t = t;
  h.label = tree.leaf;
  h.rgb = scene_materials::leaf_color(leaf, local, n, depth_in, !entry, t / cx.fx, tree.seed);
  return h;
}

Hit trace(const TraceContext &cx, const Vec3d &o, const Vec3d &d, const TileCandidates &cand,
          Crossing *xs)
{
  const SceneParams &p = *cx.p;
  const std::vector<Tree> &trees = *cx.trees;
  const std::vector<Cluster> &clusters = *cx.clusters;
  Hit best;
  best.t = kInf;

  // The wall and, above it, the sky.
  if (d[2] > 0) {
    const double t = (p.background_distance_mm - o[2]) / d[2];
    if (o[1] + t * d[1] >= p.camera_height_mm - kWallHeightMm) {
      best.t = t;
      best.label = SurfaceLabel::Background;
    }
  }
  if (d[1] > 0) {
    const double t = (p.camera_height_mm - o[1]) / d[1];
    if (t < best.t) {
      best.t = t;
      best.label = SurfaceLabel::Ground;
    }
  }
  for (int i = 0; i < cand.n_trees; ++i) {
    const double t_trunk = hit_trunk(trees[cand.trees[i]], p.trunk_radius_mm, o, d);
    if (t_trunk < best.t) {
      best.t = t_trunk;
      best.label = SurfaceLabel::Trunk;
      best.tree = cand.trees[i];
    }
  }

  // The canopies: walk the shells of the clusters front to back until a leaf (not a hole).
  int n = 0;
  for (int i = 0; i < cand.n_clusters; ++i) {
    double t0, t1;
    const int ci = int(cand.clusters[i]);
    const Cluster &c = clusters[std::size_t(ci)];
    if (!hit_ellipsoid(c, o, d, t0, t1) || t0 >= best.t)
      continue;
    if (t0 > 0)
      xs[n++] = Crossing{t0, ci, true};
    if (t1 < best.t)
      xs[n++] = Crossing{t1, ci, false};
  }
  std::sort(xs, xs + n, [](const Crossing &a, const Crossing &b) { return a.t < b.t; });
  for (int i = 0; i < n; ++i) {
    const Crossing &x = xs[i];
    if (x.t >= best.t)
      break;
    const Vec3d pt = o + x.t * d;
    const Cluster &c = clusters[std::size_t(x.cluster)];
    const Tree &tree = trees[std::size_t(c.tree)];
    const Vec3d n = ellipsoid_normal(c, pt);
    const double grazing = 1.0 - std::abs(n.dot(d)) / std::sqrt(d.dot(d));
    const Vec3d local(pt[0] - tree.x, pt[1], pt[2] - tree.z);
    const auto leaf = scene_materials::leaf_sample(local, n, grazing, tree.seed, p.gap_fraction);
    if (leaf.hole)
      continue;
    Hit h = shade_leaf(cx, tree, n, pt, d, x.t, x.entry, leaf);
    h.tree = c.tree;
    return h;
  }

  const double footprint = best.t / cx.fx;
  const Vec3d pt = o + best.t * d;
  switch (best.label) {
  case SurfaceLabel::Background:
    best.rgb = scene_materials::wall_color(pt[0] + cx.travel, p.camera_height_mm - pt[1], footprint,
                                           std::uint32_t(p.seed));
    break;
  case SurfaceLabel::Ground:
    best.rgb = p.kind == SceneKind::Lab
                   ? scene_materials::soil_color(pt[0] + cx.travel, pt[2], footprint,
                                                 std::uint32_t(p.seed))
                   : scene_materials::grass_color(pt[0] + cx.travel, pt[2], footprint,
                                                  std::uint32_t(p.seed));
    break;
  case SurfaceLabel::Trunk: {
    const Tree &tree = trees[std::size_t(best.tree)];
    const Vec3d n = cv::normalize(Vec3d(pt[0] - tree.x, 0, pt[2] - tree.z));
    const double arc = std::atan2(n[2], n[0]) * p.trunk_radius_mm;
    best.rgb = scene_materials::bark_color(arc, pt[1], n, footprint, tree.seed);
    break;
  }
  default:
    best.t = 0;
    best.rgb = scene_materials::sky_color(cv::normalize(d)[1]);
    break;
  }
  return best;
}

} // namespace
// ---------------------------------------------------------------------------------------------
// Ground truth

namespace {

// Distance, percentiles and centroid of the visible canopy points.
void fill_point_statistics(GroundTruth &g)
{
  g.distance_m = g.depth_p05_m = g.depth_p95_m = g.thickness_m = 0;
  g.centroid_m = cv::Vec3d(0, 0, 0);
  g.trunk_distance_m = g.trunk_point_mm[2] / 1000.0;
  g.lateral_offset_m = g.trunk_point_mm[0] / 1000.0;
  if (g.canopy_points_mm.empty())
    return;
  std::vector<double> z;
  z.reserve(g.canopy_points_mm.size());
  cv::Vec3d sum(0, 0, 0);
  for (const auto &q : g.canopy_points_mm) {
    z.push_back(q.z / 1000.0);
    sum += cv::Vec3d(q.x, q.y, q.z);
  }
  const Summary s = summarize(z);
  g.distance_m = s.median;
  g.depth_p05_m = s.p05;
  g.depth_p95_m = s.p95;
  g.thickness_m = s.p95 - s.p05;
  g.centroid_m = sum / (1000.0 * double(g.canopy_points_mm.size()));
}

} // namespace

GroundTruth truth_in_frame(const GroundTruth &truth, const cv::Matx33d &R)
{
  const cv::Matx33d should_be_eye = R.t() * R;
  if (std::abs(cv::determinant(R) - 1.0) > 1e-6 || cv::norm(should_be_eye - cv::Matx33d::eye()) > 1e-6)
    throw std::runtime_error("truth_in_frame: R is not a rotation matrix (R^T R != I or det != 1)");
  GroundTruth g = truth;
  for (auto *points : {&g.canopy_points_mm, &g.row_points_mm})
    for (auto &q : *points) {
      const cv::Vec3d r = R * cv::Vec3d(q.x, q.y, q.z);
      q = cv::Point3f(float(r[0]), float(r[1]), float(r[2]));
    }
  g.trunk_point_mm = R * truth.trunk_point_mm;
  fill_point_statistics(g);
  return g;
}

// ---------------------------------------------------------------------------------------------
// The renderer

namespace {

// The rays of one tile of pixels, as a cone from the view's optical centre.
struct Cone {
  Vec3d axis;
  double cos_t = 1, sin_t = 0;
};

struct View {
  cv::Mat rays;          // CV_32FC2 normalised undistorted coordinates per pixel
  cv::Matx33d Rt;        // view camera frame -> scene (left camera) frame
  Vec3d origin;          // optical centre in the scene frame
  cv::Matx33d R;         // scene -> view camera frame (with T below)
  Vec3d T;
  double fx = 0;
  // The largest |x/z| of a ray (half the view's width at unit depth).
  double tan_x = 0;
  std::vector<Cone> cones;
  int tiles_x = 0, tiles_y = 0;
};

cv::Mat undistorted_rays(const cv::Mat &M, const cv::Mat &D, cv::Size size)
{
  std::vector<cv::Point2f> px;
  px.reserve(std::size_t(size.area()));
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x)
      px.emplace_back(float(x), float(y));
  // OpenCV's 5 fixed-point iterations invert this mild distortion to 1e-4 px (the test checks
  // the round trip); the rows are independent, so they are split over the threads.
  cv::Mat rays(size, CV_32FC2);
  cv::parallel_for_(cv::Range(0, size.height), [&](const cv::Range &rows) {
    const cv::Mat src(1, rows.size() * size.width, CV_32FC2, px.data() + std::size_t(rows.start) * std::size_t(size.width));
    cv::Mat dst = rays.rowRange(rows).reshape(2, 1);
    cv::undistortPoints(src, dst, M, D);
  }, 16);
  return rays;
}

void build_cones(View &v, cv::Size size)
{
  v.tiles_x = (size.width + kTile - 1) / kTile;
  v.tiles_y = (size.height + kTile - 1) / kTile;
  v.cones.assign(std::size_t(v.tiles_x * v.tiles_y), Cone{});
  for (int ty = 0; ty < v.tiles_y; ++ty)
    for (int tx = 0; tx < v.tiles_x; ++tx) {
      const int x0 = tx * kTile, y0 = ty * kTile;
      const int x1 = std::min(size.width, x0 + kTile), y1 = std::min(size.height, y0 + kTile);
      std::vector<Vec3d> dirs;
      Vec3d sum(0, 0, 0);
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
          const cv::Vec2f r = v.rays.at<cv::Vec2f>(y, x);
          dirs.push_back(cv::normalize(v.Rt * Vec3d(r[0], r[1], 1.0)));
          sum += dirs.back();
        }
      Cone &c = v.cones[std::size_t(ty * v.tiles_x + tx)];
      c.axis = cv::normalize(sum);
      for (const auto &d : dirs)
        c.cos_t = std::min(c.cos_t, c.axis.dot(d));
      c.cos_t = std::max(-1.0, c.cos_t - 1e-9);
      c.sin_t = std::sqrt(std::max(0.0, 1.0 - c.cos_t * c.cos_t));
    }
}

// Whether a sphere meets the cone of a tile's rays from `origin`.
bool sphere_meets_cone(const Cone &cone, const Vec3d &origin, const Vec3d &centre, double rb)
{
  const Vec3d w = centre - origin;
  const double dist = std::sqrt(w.dot(w));
  if (dist <= rb)
    return true;
  const double sin_b = rb / dist, cos_b = std::sqrt(1.0 - sin_b * sin_b);
  return w.dot(cone.axis) / dist >= cone.cos_t * cos_b - cone.sin_t * sin_b - 1e-9;
}

// Per tile, the trees whose bounding sphere meets the tile's cone and, of those, the clusters
// whose bounding sphere does.
struct Candidates {
  std::vector<std::uint16_t> trees;
  std::vector<int> tree_offset;
  std::vector<std::uint32_t> clusters;
  std::vector<int> offset;
  int max_clusters = 0; // in any one tile

  TileCandidates tile(std::size_t i) const
  {
    return TileCandidates{trees.data() + tree_offset[i], tree_offset[i + 1] - tree_offset[i],
                          clusters.data() + offset[i], offset[i + 1] - offset[i]};
  }
};

void tile_candidates(const View &v, const std::vector<Tree> &trees,
                     const std::vector<Cluster> &clusters, const std::vector<std::size_t> &first,
                     Candidates &out)
{
  if (trees.size() > 65535 || clusters.size() > std::numeric_limits<std::uint32_t>::max())
    throw std::runtime_error("SceneRenderer: too many trees in view (at most 65535)");
  out.tree_offset.assign(v.cones.size() + 1, 0);
  out.offset.assign(v.cones.size() + 1, 0);
  out.trees.clear();
  out.clusters.clear();
  out.max_clusters = 0;
  for (std::size_t i = 0; i < v.cones.size(); ++i) {
    const Cone &cone = v.cones[i];
    for (std::size_t t = 0; t < trees.size(); ++t) {
      if (!sphere_meets_cone(cone, v.origin, trees[t].centre, trees[t].rb))
        continue;
      out.trees.push_back(std::uint16_t(t));
      for (std::size_t k = first[t]; k < first[t + 1]; ++k)
        if (sphere_meets_cone(cone, v.origin, clusters[k].c, clusters[k].rb))
          out.clusters.push_back(std::uint32_t(k));
    }
    out.tree_offset[i + 1] = int(out.trees.size());
    out.offset[i + 1] = int(out.clusters.size());
    out.max_clusters = std::max(out.max_clusters, out.offset[i + 1] - out.offset[i]);
  }
}

// Gaussian with unit variance from a hash: the sum of four uniform bytes (Irwin-Hall).
inline float gauss(std::uint32_t h)
{
  const int s = int(h & 255U) + int((h >> 8) & 255U) + int((h >> 16) & 255U) + int(h >> 24);
  return float(s - 510) * (1.0f / 147.8f);
}

} // namespace

struct SceneRenderer::Impl {
  SceneParams p; // resolved
  StereoCalibration calib;
  View views[2];
  Row near, back; // Orchard and Hedgerow

  // Index k of the near-row tree whose trunk is nearest to the left camera's optical axis.
  std::int64_t front_tree(double travel) const
  {
    if (p.kind == SceneKind::Lab)
      return std::int64_t(std::round((travel - p.tree_x_mm) / p.tree_spacing_mm));
    return near.nearest(travel);
  }

  // The trees view v can see at this travel (camera-frame positions); front: the index of the
  // tree in front in that list, -1 when it is not in it.
  std::vector<Tree> trees_in_view(const View &v, double travel, int &front) const;
};

std::vector<Tree> SceneRenderer::Impl::trees_in_view(const View &v, double travel, int &front) const
{
  std::vector<Tree> trees;
  const std::int64_t k_front = front_tree(travel);
  front = -1;
  if (p.kind == SceneKind::Lab) {
    // The row of trees slides by; the nearest one is in view.
    trees.push_back(
        make_lab_tree(p, k_front, p.tree_x_mm + double(k_front) * p.tree_spacing_mm - travel));
    front = 0;
    return trees;
  }
  auto add_row = [&](const Row &row, bool is_near) {
    // The view's x extent at the far side of the row's canopies, with a margin for the right
    // camera's offset and rotation; the tiles' cones cull exactly.
    const double z_far = row.z + 0.5 * kBackSizeHi * p.canopy_depth_mm;
    const double half = v.tan_x * z_far + std::abs(v.origin[0]) + 0.02 * z_far + 100.0;
    const auto ks = row.range(travel - half, travel + half);
    for (std::int64_t k = ks.first; k <= ks.second; ++k) {
      const RowSlot s = row.slot(k);
      Tree t = make_tree(p, is_near ? std::uint64_t(k) : kBackRowKey + std::uint64_t(k),
                         s.x - travel, row.z, s.size);
      t.k = k;
      t.leaf = !is_near       ? SurfaceLabel::BackLeaf
               : k == k_front ? SurfaceLabel::Leaf
                              : SurfaceLabel::RowLeaf;
      if (is_near && k == k_front)
        front = int(trees.size());
      trees.push_back(std::move(t));
    }
  };
  add_row(near, true);
  add_row(back, false);
  return trees;
}

SceneRenderer::SceneRenderer(const SceneParams &params) : impl_(new Impl)
{
  validate_scene_params(params);
  Impl &m = *impl_;
  m.p = resolve_scene_params(params);
  m.calib = rig_calibration(params);
  const cv::Matx33d R(m.calib.R);
  const Vec3d T(m.calib.T.at<double>(0), m.calib.T.at<double>(1), m.calib.T.at<double>(2));
  for (int i = 0; i < 2; ++i) {
    View &v = m.views[i];
    const cv::Mat &M = i == 0 ? m.calib.M1 : m.calib.M2;
    v.rays = undistorted_rays(M, i == 0 ? m.calib.D1 : m.calib.D2, params.image_size);
    v.R = i == 0 ? cv::Matx33d::eye() : R;
    v.T = i == 0 ? Vec3d(0, 0, 0) : T;
    v.Rt = v.R.t();
    v.origin = -(v.Rt * v.T);
    v.fx = M.at<double>(0, 0);
    std::vector<cv::Mat> xy;
    cv::split(v.rays, xy);
    double lo = 0, hi = 0;
    cv::minMaxLoc(xy[0], &lo, &hi);
    v.tan_x = std::max(std::abs(lo), std::abs(hi));
    build_cones(v, params.image_size);
  }
  if (m.p.kind != SceneKind::Lab) {
    m.near = near_row(m.p);
    m.back = back_row(m.p);
  }
}

SceneRenderer::~SceneRenderer() = default;

const SceneParams &SceneRenderer::params() const { return impl_->p; }
const StereoCalibration &SceneRenderer::calibration() const { return impl_->calib; }

const cv::Mat &SceneRenderer::normalized_rays(int view) const
{
  if (view != 0 && view != 1)
    throw std::runtime_error("SceneRenderer: view must be 0 (left) or 1 (right)");
  return impl_->views[view].rays;
}

double SceneRenderer::travel_mm(std::uint64_t frame) const
{
  return impl_->p.speed_m_s * 1000.0 * double(frame) / impl_->p.framerate;
}

void SceneRenderer::render(int view, std::uint64_t frame, cv::Mat &rgb, GroundTruth *truth) const
{
  if (view != 0 && view != 1)
    throw std::runtime_error("SceneRenderer::render: view must be 0 (left) or 1 (right)");
  const Impl &m = *impl_;
  const SceneParams &p = m.p;
  const View &v = m.views[view];
  const cv::Size size = p.image_size;

  const double travel = travel_mm(frame);
  int front = -1;
  std::vector<Tree> trees = m.trees_in_view(v, travel, front);
  std::vector<Cluster> clusters;
  std::vector<std::size_t> first{0};
  for (std::size_t t = 0; t < trees.size(); ++t) {
    for (Cluster c : trees[t].clusters) {
      c.tree = int(t);
      clusters.push_back(c);
    }
    first.push_back(clusters.size());
  }
  Candidates cand;
  tile_candidates(v, trees, clusters, first, cand);

  // The near-row index of each tree, as tree_index stores it.
  std::vector<std::int16_t> row_index(trees.size(), kNoTree);
  for (std::size_t t = 0; t < trees.size(); ++t)
    if (trees[t].leaf != SurfaceLabel::BackLeaf)
      row_index[t] =
          std::int16_t(std::max<std::int64_t>(-32767, std::min<std::int64_t>(32767, trees[t].k)));

  rgb.create(size, CV_8UC3);
  cv::Mat depth(size, CV_32F), labels(size, CV_8U), tree_index(size, CV_16S);
  const TraceContext cx{&p, &trees, &clusters, travel, v.fx};
  const float gain = float(p.light);
  cv::parallel_for_(
      cv::Range(0, size.height),
      [&](const cv::Range &rows) {
        std::vector<Crossing> xs(std::size_t(2 * cand.max_clusters + 2));
        for (int y = rows.start; y < rows.end; ++y) {
          const cv::Vec2f *ray = v.rays.ptr<cv::Vec2f>(y);
          cv::Vec3b *out = rgb.ptr<cv::Vec3b>(y);
          float *z = depth.ptr<float>(y);
          std::uint8_t *lab = labels.ptr<std::uint8_t>(y);
          std::int16_t *idx = tree_index.ptr<std::int16_t>(y);
          const int tile_row = (y / kTile) * v.tiles_x;
          for (int x = 0; x < size.width; ++x) {
            const int tile = tile_row + x / kTile;
            const Vec3d d = v.Rt * Vec3d(ray[x][0], ray[x][1], 1.0);
            const Hit h = trace(cx, v.origin, d, cand.tile(std::size_t(tile)), xs.data());
            out[x] = cv::Vec3b(cv::saturate_cast<uchar>(h.rgb[0] * gain),
                               cv::saturate_cast<uchar>(h.rgb[1] * gain),
                               cv::saturate_cast<uchar>(h.rgb[2] * gain));
            z[x] = float(h.t);
            lab[x] = std::uint8_t(h.label);
            idx[x] = h.tree >= 0 ? row_index[std::size_t(h.tree)] : kNoTree;
          }
        }
      },
      std::max(1.0, size.height / 8.0));

  if (p.optical_blur)
    cv::GaussianBlur(rgb, rgb, cv::Size(3, 3), 0.5, 0.5, cv::BORDER_REPLICATE);

  if (p.noise > 0) {
    const std::uint32_t key = hash32(std::uint32_t(hash64(p.seed * 2 + std::uint64_t(view)) ^
                                                   hash64(frame + 0x51ed27ULL)));
    const float sigma = float(p.noise);
    cv::parallel_for_(cv::Range(0, size.height), [&](const cv::Range &rows) {
      for (int y = rows.start; y < rows.end; ++y) {
        uchar *px = rgb.ptr<uchar>(y);
        const std::uint32_t hy = hash_y(y, key);
        for (int i = 0; i < size.width * 3; ++i)
          px[i] = cv::saturate_cast<uchar>(float(px[i]) + sigma * gauss(hash_x(i, hy)));
      }
    }, std::max(1.0, size.height / 8.0));
  }

  if (!truth)
    return;
  GroundTruth &g = *truth;
  g = GroundTruth{};
  g.view = view;
  g.frame = frame;
  g.front_tree = int(m.front_tree(travel));
  // The tree in front, also when this view does not see it.
  const Tree tree = front >= 0 ? trees[std::size_t(front)] : [&] {
    const RowSlot sl = m.near.slot(g.front_tree);
    return make_tree(p, std::uint64_t(std::int64_t(g.front_tree)), sl.x - travel, m.near.z,
                     sl.size);
  }();
  double lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};
  for (const auto &c : tree.clusters)
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], c.c[a] - c.r[a]);
      hi[a] = std::max(hi[a], c.c[a] + c.r[a]);
    }
  g.canopy_width_m = (hi[0] - lo[0]) / 1000.0;
  g.canopy_height_m = (hi[1] - lo[1]) / 1000.0;
  g.canopy_depth_m = (hi[2] - lo[2]) / 1000.0;
  g.trunk_point_mm = v.R * Vec3d(tree.x, tree.centre[1], tree.z) + v.T;
  g.depth = depth;
  g.labels = labels;
  g.tree_index = tree_index;
  cv::compare(labels, int(SurfaceLabel::Leaf), g.canopy_mask, cv::CMP_EQ);
  cv::Mat row_leaf;
  cv::compare(labels, int(SurfaceLabel::RowLeaf), row_leaf, cv::CMP_EQ);
  cv::bitwise_or(g.canopy_mask, row_leaf, g.row_mask);
  g.canopy_points_mm.reserve(std::size_t(cv::countNonZero(g.canopy_mask)));
  g.row_points_mm.reserve(std::size_t(cv::countNonZero(g.row_mask)));
  for (int y = 0; y < size.height; ++y) {
    const std::uint8_t *lab = labels.ptr<std::uint8_t>(y);
    const float *z = depth.ptr<float>(y);
    const cv::Vec2f *ray = v.rays.ptr<cv::Vec2f>(y);
    for (int x = 0; x < size.width; ++x) {
      const bool leaf = lab[x] == std::uint8_t(SurfaceLabel::Leaf);
      if (!leaf && lab[x] != std::uint8_t(SurfaceLabel::RowLeaf))
        continue;
      const cv::Point3f q(ray[x][0] * z[x], ray[x][1] * z[x], z[x]);
      if (leaf)
        g.canopy_points_mm.push_back(q);
      g.row_points_mm.push_back(q);
    }
  }
  fill_point_statistics(g);
}

std::vector<RowTree> SceneRenderer::row_trees(double from_mm, double to_mm) const
{
  if (!std::isfinite(from_mm) || !std::isfinite(to_mm) || to_mm - from_mm > 1e7)
    throw std::runtime_error(
        "SceneRenderer::row_trees: the range must be finite and at most 10 km");
  const Impl &m = *impl_;
  const SceneParams &p = m.p;
  std::vector<RowTree> out;
  if (to_mm < from_mm)
    return out;
  auto add = [&](std::int64_t k, const Tree &t) {
    double lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};
    for (const auto &c : t.clusters)
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], c.c[a] - c.r[a]);
        hi[a] = std::max(hi[a], c.c[a] + c.r[a]);
      }
    if (hi[0] < from_mm || lo[0] > to_mm)
      return;
    RowTree r;
    r.index = int(k);
    r.x_m = t.x / 1000.0;
    r.start_m = lo[0] / 1000.0;
    r.end_m = hi[0] / 1000.0;
    r.width_m = (hi[0] - lo[0]) / 1000.0;
    r.height_m = (hi[1] - lo[1]) / 1000.0;
    r.top_m = lo[1] / 1000.0;
    r.bottom_m = hi[1] / 1000.0;
    r.depth_m = (hi[2] - lo[2]) / 1000.0;
    r.distance_m = t.z / 1000.0;
    out.push_back(r);
  };
  if (p.kind == SceneKind::Lab) {
    const double w = 0.5 * p.canopy_width_mm;
    const auto k0 = std::int64_t(std::ceil((from_mm - w - p.tree_x_mm) / p.tree_spacing_mm)) - 1;
    const auto k1 = std::int64_t(std::floor((to_mm + w - p.tree_x_mm) / p.tree_spacing_mm)) + 1;
    for (std::int64_t k = k0; k <= k1; ++k)
      add(k, make_lab_tree(p, k, p.tree_x_mm + double(k) * p.tree_spacing_mm));
    return out;
  }
  const auto ks = m.near.range(from_mm, to_mm);
  for (std::int64_t k = ks.first; k <= ks.second; ++k) {
    const RowSlot sl = m.near.slot(k);
    add(k, make_tree(p, std::uint64_t(k), sl.x, m.near.z, sl.size));
  }
  return out;
}

} // namespace treestereo
