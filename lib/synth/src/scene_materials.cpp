#include "scene_materials.hpp"

#include "scene_noise.hpp"

#include <cmath>

namespace treestereo {
namespace scene_materials {

using namespace scene_noise;

namespace {

// Leaf cells are elongated horizontally: 34 mm wide, 24 mm high (apple leaves are 5-10 cm long,
// partly hidden by each other).
constexpr double kLeafCellX = 34.0, kLeafCellY = 24.0, kLeafCellZ = 34.0;

cv::Vec3f mix(const cv::Vec3f &a, const cv::Vec3f &b, float t) { return a + (b - a) * t; }

// Two-sided Lambert of thin leaves: light through a leaf from behind still shows a little.
float leaf_diffuse(const cv::Vec3d &n)
{
  const double ndl = n.dot(light_direction());
  return float(ndl > 0 ? ndl : -0.3 * ndl);
}

float lambert(const cv::Vec3d &n) { return float(std::max(0.0, n.dot(light_direction()))); }

} // namespace

cv::Vec3d light_direction()
{
  static const cv::Vec3d l = cv::normalize(cv::Vec3d(-0.35, -0.85, -0.40));
  return l;
}

LeafSample leaf_sample(const cv::Vec3d &p, const cv::Vec3d &normal, double grazing,
                       std::uint32_t tree_seed, double gap_fraction)
{
  const Cell c = worley(p[0] / kLeafCellX, p[1] / kLeafCellY, p[2] / kLeafCellZ, tree_seed);
  // Gaps cluster: a slow noise makes some parts of the canopy sparse, others dense.
  const float sparse = value_noise(p[0] / 170.0, p[1] / 170.0, p[2] / 170.0, tree_seed + 7U);
  float gap = float(gap_fraction) * (0.4f + 1.2f * sparse);
  // A cluster's rim is ragged: seen edge-on, most of its shell is gaps.
  gap += (1.0f - gap) * 0.85f * smoothstep(0.5f, 0.95f, float(grazing));
  LeafSample s;
  s.f1 = c.f1;
  s.f2 = c.f2;
  s.id = c.id;
  s.hole = unit(hash32(c.id ^ 0x5bd1e995U)) < gap;
  // Each leaf is an ellipse about its feature point, its axis a random direction in the
  // surface (in the cell space the cellular noise works in).
  const cv::Vec3f n(float(normal[0] * kLeafCellX), float(normal[1] * kLeafCellY),
                    float(normal[2] * kLeafCellZ)); // normals transform with the inverse scale
  const cv::Vec3f nn = cv::normalize(n);
  cv::Vec3f axis(unit(hash32(c.id ^ 0x6U)) - 0.5f, unit(hash32(c.id ^ 0x7U)) - 0.5f,
                 unit(hash32(c.id ^ 0x8U)) - 0.5f);
  axis -= nn * axis.dot(nn);
  axis = cv::normalize(axis);
  cv::Vec3f off(c.off[0], c.off[1], c.off[2]);
  off -= nn * off.dot(nn);
  s.along = off.dot(axis);
  s.across = std::sqrt(std::max(0.0f, off.dot(off) - s.along * s.along));
  return s;
}

cv::Vec3f leaf_color(const LeafSample &leaf, const cv::Vec3d &p, const cv::Vec3d &normal,
                     double depth_in_canopy, bool inner, double footprint, std::uint32_t tree_seed)
{
  static const cv::Vec3f palette[5] = {
      {38, 80, 24}, {60, 114, 32}, {100, 146, 44}, {42, 94, 58}, {78, 128, 30}};
  const std::uint32_t h = leaf.id;
  const float m = unit(hash32(h ^ 0x1U));
  cv::Vec3f c = mix(palette[h % 5U], palette[(h >> 3) % 5U], m);
  c *= 0.8f + 0.4f * unit(hash32(h ^ 0x2U));

  // Each leaf has its own orientation: leaf-to-leaf contrast the way a real canopy has it.
  const cv::Vec3d tilt(unit(hash32(h ^ 0x3U)) - 0.5, unit(hash32(h ^ 0x4U)) - 0.5,
                       unit(hash32(h ^ 0x5U)) - 0.5);
  const cv::Vec3d n_leaf = cv::normalize(normal + 1.8 * tilt);
  const float shade = 0.28f + 0.72f * leaf_diffuse(n_leaf);

  // Dark seams between leaves (shadowed gaps), at least ~1.5 px wide so they do not alias.
  const double cell = 0.5 * (kLeafCellX + kLeafCellY);
  const float edge_width = float(std::max(0.08, 1.5 * footprint / cell));
  const float seam = 0.35f + 0.65f * smoothstep(0.0f, edge_width, leaf.f2 - leaf.f1);
  // The leaf blade: an ellipse 1.8 x 1.0 cells; around it the shadowed leaves further in.
  const float a = leaf.along / 0.9f, b = leaf.across / 0.5f;
  const float blade = smoothstep(1.0f + 2.0f * edge_width, 1.0f, std::sqrt(a * a + b * b));
  // The midrib, where it is at least a pixel and a half wide.
  const float rib_fade = octave_weight(0.15 * cell, footprint);
  const float rib = 1.0f - 0.25f * rib_fade * (1.0f - smoothstep(0.0f, 0.06f, leaf.across));
  const float leafness = blade * rib + (1.0f - blade) * 0.5f;

  // Veins and speckles: fine detail for the feature detector at full resolution.
  const float vein = fbm(p[0], p[1], p[2], 9.0, 3, footprint, tree_seed + 11U);
  const float detail = 0.75f + 0.5f * vein;

  // Inside the canopy less light arrives.
  float ao = 1.0f - 0.55f * smoothstep(0.0f, 0.9f, float(depth_in_canopy));
  if (inner)
    ao *= 0.65f;
  return c * (shade * seam * leafness * detail * ao);
}

cv::Vec3f bark_color(double angle_mm, double y, const cv::Vec3d &normal, double footprint,
                     std::uint32_t tree_seed)
{
  const cv::Vec3f brown(108, 80, 70), grey(98, 86, 100);
  // Bark plates: long vertically, narrow around the trunk, with dark furrows.
  const float plates = value_noise2(angle_mm / 9.0, y / 70.0, tree_seed + 21U);
  const float furrow = smoothstep(0.25f, 0.45f, plates);
  const float tone = fbm2(angle_mm, y, 60.0, 2, footprint, tree_seed + 22U);
  const float fine = fbm2(angle_mm, y * 0.5, 6.0, 3, footprint, tree_seed + 23U);
  cv::Vec3f c = mix(brown, grey, tone);
  c *= (0.45f + 0.55f * furrow) * (0.8f + 0.4f * fine);
  return c * (0.3f + 0.7f * lambert(normal));
}

cv::Vec3f soil_color(double x, double z, double footprint, std::uint32_t seed)
{
  const cv::Vec3f brown(138, 98, 74), grey(120, 102, 116), dark(94, 62, 52);
  const float big = fbm2(x, z, 900.0, 2, footprint, seed + 31U);
  const float mid = fbm2(x, z, 110.0, 3, footprint, seed + 32U);
  const float fine = fbm2(x, z, 14.0, 3, footprint, seed + 33U);
  cv::Vec3f c = mix(brown, grey, smoothstep(0.35f, 0.65f, big));
  c = mix(c, dark, smoothstep(0.45f, 0.75f, mid) * 0.8f);
  c *= 0.8f + 0.4f * fine;
  // Pebbles: the peaks of a noise of 30 mm wavelength, with a dark rim.
  const float w = octave_weight(30.0, footprint);
  if (w > 0.0f) {
    const float stone = value_noise2(x / 30.0, z / 30.0, seed + 34U);
    const float rim = w * smoothstep(0.84f, 0.87f, stone);
    const cv::Vec3f pebble = cv::Vec3f(160, 142, 154) * (0.6f + 0.6f * stone);
    c = mix(c * (1.0f - 0.3f * w * smoothstep(0.76f, 0.84f, stone)), pebble, rim);
  }
  return c * (0.3f + 0.7f * lambert(cv::Vec3d(0, -1, 0)));
}

cv::Vec3f grass_color(double x, double z, double footprint, std::uint32_t seed)
{
  // Linear levels: lawn green (ExG about +100), straw (ExG about 0) and bare earth (ExG < 0).
  const cv::Vec3f green(66, 118, 40), lush(48, 104, 34), straw(176, 142, 104), earth(140, 106, 86);
  const float patches = fbm2(x, z, 1400.0, 3, footprint, seed + 51U);
  const float tone = fbm2(x, z, 320.0, 2, footprint, seed + 52U);
  const float clumps = fbm2(x, z, 60.0, 3, footprint, seed + 53U);
  const float blades = fbm2(x * 2.2, z, 9.0, 3, footprint, seed + 54U);
  cv::Vec3f c = mix(green, lush, tone);
  // Dry patches where the slow noise is high; bare earth in the middle of the largest ones.
  const float dry = smoothstep(0.56f, 0.68f, patches);
  cv::Vec3f d = mix(straw, earth, smoothstep(0.72f, 0.85f, patches) * 0.7f);
  c = mix(c, d, dry);
  c *= (0.72f + 0.45f * clumps) * (0.7f + 0.6f * blades);
  return c * (0.3f + 0.7f * lambert(cv::Vec3d(0, -1, 0)));
}

cv::Vec3f wall_color(double x, double height, double footprint, std::uint32_t seed)
{
  // Concrete blocks 400 x 200 mm in a running bond, 12 mm mortar joints.
  const double row = std::floor(height / 200.0);
  const double xs = x + (std::fmod(row, 2.0) != 0.0 ? 200.0 : 0.0);
  const double col = std::floor(xs / 400.0);
  const double u = xs - col * 400.0, v = height - row * 200.0;
  const double joint = std::min(std::min(u, 400.0 - u), std::min(v, 200.0 - v));
  const float in_block = smoothstep(6.0f, 6.0f + float(std::max(2.0, footprint)), float(joint));
  const std::uint32_t h = hash3(std::int64_t(col), std::int64_t(row), 0, seed + 41U);
  const cv::Vec3f block = cv::Vec3f(178, 150, 146) * (0.82f + 0.3f * unit(h));
  const cv::Vec3f mortar(124, 106, 114);
  cv::Vec3f c = mix(mortar, block, in_block);
  const float stains = fbm2(x, height, 350.0, 3, footprint, seed + 42U);
  const float grain = fbm2(x, height, 24.0, 3, footprint, seed + 43U);
  c *= (0.7f + 0.5f * stains) * (0.82f + 0.36f * grain);
  return c * (0.3f + 0.7f * lambert(cv::Vec3d(0, 0, -1)));
}

cv::Vec3f sky_color(double elevation)
{
  const cv::Vec3f horizon(190, 200, 232), zenith(128, 158, 214);
  return mix(horizon, zenith, smoothstep(0.0f, 0.5f, float(-elevation)));
}

} // namespace scene_materials
} // namespace treestereo
