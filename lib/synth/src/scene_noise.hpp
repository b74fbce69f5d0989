// Deterministic hashing and procedural 3D noise for the scene renderer (internal).
// Everything is a pure function of integer lattice coordinates and a seed, so results are the
// same on every platform and thread (no <random> distributions, whose output is unspecified).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace treestereo {
namespace scene_noise {

inline std::uint32_t hash32(std::uint32_t x)
{
  // A low-bias integer finaliser (Wellons' "lowbias32").
  x ^= x >> 16;
  x *= 0x7feb352dU;
  x ^= x >> 15;
  x *= 0x846ca68bU;
  x ^= x >> 16;
  return x;
}

inline std::uint64_t hash64(std::uint64_t x)
{
  // splitmix64's finaliser.
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// Lattice hashing in stages (z, then y, then x) so neighbouring lattice points share work.
inline std::uint32_t hash_z(std::int64_t z, std::uint32_t seed) { return hash32(std::uint32_t(z) * 0xcb1ab31fU ^ seed); }
inline std::uint32_t hash_y(std::int64_t y, std::uint32_t hz) { return hash32(std::uint32_t(y) * 0xd8163841U ^ hz); }
inline std::uint32_t hash_x(std::int64_t x, std::uint32_t hyz) { return hash32(std::uint32_t(x) * 0x8da6b343U ^ hyz); }

inline std::uint32_t hash3(std::int64_t x, std::int64_t y, std::int64_t z, std::uint32_t seed)
{
  return hash_x(x, hash_y(y, hash_z(z, seed)));
}

// Uniform in [0, 1) from the top 24 bits.
inline float unit(std::uint32_t h) { return float(h >> 8) * (1.0f / 16777216.0f); }

// A stream of uniform numbers from a 64-bit state (for building the scene).
class Rng {
public:
  explicit Rng(std::uint64_t seed) : state_(hash64(seed)) {}
  double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  std::uint64_t next() { return state_ = hash64(state_); }

private:
  std::uint64_t state_;
};

inline float smooth5(float t) { return t * t * t * (t * (t * 6.0f - 15.0f) + 10.0f); }
inline float lerp(float a, float b, float t) { return a + (b - a) * t; }
inline float clamp01(float v) { return std::min(1.0f, std::max(0.0f, v)); }
inline float smoothstep(float e0, float e1, float x)
{
  const float t = clamp01((x - e0) / (e1 - e0));
  return t * t * (3.0f - 2.0f * t);
}

// Value noise in [0, 1) with unit lattice spacing. Coordinates are doubles so the lattice index
// stays exact far from the origin (a rig that has driven kilometres).
inline float value_noise(double x, double y, double z, std::uint32_t seed)
{
  const double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  const auto ix = std::int64_t(fx), iy = std::int64_t(fy), iz = std::int64_t(fz);
  const float tx = smooth5(float(x - fx)), ty = smooth5(float(y - fy)), tz = smooth5(float(z - fz));
  float plane[2];
  for (int dz = 0; dz < 2; ++dz) {
    const std::uint32_t hz = hash_z(iz + dz, seed);
    const std::uint32_t h0 = hash_y(iy, hz), h1 = hash_y(iy + 1, hz);
    const float a = lerp(unit(hash_x(ix, h0)), unit(hash_x(ix + 1, h0)), tx);
    const float b = lerp(unit(hash_x(ix, h1)), unit(hash_x(ix + 1, h1)), tx);
    plane[dz] = lerp(a, b, ty);
  }
  return lerp(plane[0], plane[1], tz);
}

// Two-dimensional value noise in [0, 1) (for flat surfaces: half the work of the 3D one).
inline float value_noise2(double x, double y, std::uint32_t seed)
{
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = std::int64_t(fx), iy = std::int64_t(fy);
  const float tx = smooth5(float(x - fx)), ty = smooth5(float(y - fy));
  const std::uint32_t h0 = hash_y(iy, seed), h1 = hash_y(iy + 1, seed);
  const float a = lerp(unit(hash_x(ix, h0)), unit(hash_x(ix + 1, h0)), tx);
  const float b = lerp(unit(hash_x(ix, h1)), unit(hash_x(ix + 1, h1)), tx);
  return lerp(a, b, ty);
}

// Weight of a noise octave of the given wavelength (mm) at a footprint (mm per pixel): octaves
// finer than about 3 pixels fade to their mean, since a pinhole sample of finer detail would
// alias, differently in the two views.
inline float octave_weight(double wavelength, double footprint)
{
  return smoothstep(2.0f, 4.0f, float(wavelength / footprint));
}

// Fractal sum of value noise, octaves halving the wavelength from `wavelength` (mm), in [0, 1).
inline float fbm(double x, double y, double z, double wavelength, int octaves, double footprint,
                 std::uint32_t seed)
{
  float sum = 0.0f, norm = 0.0f, amp = 1.0f;
  for (int i = 0; i < octaves; ++i) {
    const float w = octave_weight(wavelength, footprint);
    const double k = 1.0 / wavelength;
    const float n = w > 0.0f ? value_noise(x * k, y * k, z * k, seed + std::uint32_t(i) * 101U) : 0.5f;
    sum += amp * (w * n + (1.0f - w) * 0.5f);
    norm += amp;
    amp *= 0.55f;
    wavelength *= 0.5;
  }
  return sum / norm;
}

// The same in two dimensions.
inline float fbm2(double x, double y, double wavelength, int octaves, double footprint,
                  std::uint32_t seed)
{
  float sum = 0.0f, norm = 0.0f, amp = 1.0f;
  for (int i = 0; i < octaves; ++i) {
    const float w = octave_weight(wavelength, footprint);
    const double k = 1.0 / wavelength;
    const float n = w > 0.0f ? value_noise2(x * k, y * k, seed + std::uint32_t(i) * 101U) : 0.5f;
    sum += amp * (w * n + (1.0f - w) * 0.5f);
    norm += amp;
    amp *= 0.55f;
    wavelength *= 0.5;
  }
  return sum / norm;
}

// Cellular (Worley) noise with one jittered feature point per unit cell.
struct Cell {
  float f1 = 1e9f, f2 = 1e9f; // distances to the nearest and second-nearest feature points
  std::uint32_t id = 0;       // hash of the nearest feature's cell
  float off[3] = {0, 0, 0};   // from the point to the nearest feature
};

inline Cell worley(double x, double y, double z, std::uint32_t seed)
{
  const double bx = std::floor(x), by = std::floor(y), bz = std::floor(z);
  const auto ix = std::int64_t(bx), iy = std::int64_t(by), iz = std::int64_t(bz);
  const float px = float(x - bx), py = float(y - by), pz = float(z - bz);
  // Squared distance from the point to the neighbour cell's box, per axis and offset.
  const float gx[3] = {px * px, 0.0f, (1 - px) * (1 - px)};
  const float gy[3] = {py * py, 0.0f, (1 - py) * (1 - py)};
  const float gz[3] = {pz * pz, 0.0f, (1 - pz) * (1 - pz)};
  std::uint32_t hyz[3][3];
  for (int dz = 0; dz < 3; ++dz) {
    const std::uint32_t hz = hash_z(iz + dz - 1, seed);
    for (int dy = 0; dy < 3; ++dy)
      hyz[dz][dy] = hash_y(iy + dy - 1, hz);
  }
  float d1 = 1e9f, d2 = 1e9f, off[3] = {0, 0, 0};
  std::uint32_t id = 0;
  // The own cell first, then face, edge and corner neighbours, so pruning bites early.
  static constexpr signed char order[27][3] = {
      {0, 0, 0},   {-1, 0, 0},  {1, 0, 0},   {0, -1, 0}, {0, 1, 0},   {0, 0, -1},  {0, 0, 1},
      {-1, -1, 0}, {1, -1, 0},  {-1, 1, 0},  {1, 1, 0},  {-1, 0, -1}, {1, 0, -1},  {-1, 0, 1},
      {1, 0, 1},   {0, -1, -1}, {0, 1, -1},  {0, -1, 1}, {0, 1, 1},   {-1, -1, -1}, {1, -1, -1},
      {-1, 1, -1}, {1, 1, -1},  {-1, -1, 1}, {1, -1, 1}, {-1, 1, 1},  {1, 1, 1}};
  constexpr float kJitter = 1.0f / 1024.0f;
  for (const auto &o : order) {
    const int dx = o[0], dy = o[1], dz = o[2];
    if (gx[dx + 1] + gy[dy + 1] + gz[dz + 1] >= d2)
      continue;
    // One hash gives the cell's identity and its feature point (10 bits per axis).
    const std::uint32_t h = hash_x(ix + dx, hyz[dz + 1][dy + 1]);
    const float fx = float(dx) + float(h & 1023U) * kJitter - px;
    const float fy = float(dy) + float((h >> 10) & 1023U) * kJitter - py;
    const float fz = float(dz) + float((h >> 20) & 1023U) * kJitter - pz;
    const float d = fx * fx + fy * fy + fz * fz;
    if (d < d1) {
      d2 = d1;
      d1 = d;
      id = h;
      off[0] = fx;
      off[1] = fy;
      off[2] = fz;
    } else if (d < d2) {
      d2 = d;
    }
  }
  Cell c;
  c.f1 = std::sqrt(d1);
  c.f2 = std::sqrt(d2);
  c.id = id;
  std::copy(off, off + 3, c.off);
  return c;
}

} // namespace scene_noise
} // namespace treestereo
