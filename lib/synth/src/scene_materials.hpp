// Surface appearance of the synthetic orchard (internal to the scene renderer): procedural
// colours as functions of the 3D surface point, with Lambert shading. Colours are linear 8-bit
// levels before the light level is applied.
#pragma once

#include <opencv2/core.hpp>

#include <cstdint>

namespace treestereo {
namespace scene_materials {

// Unit vector towards the light: above, left, in front of the row.
cv::Vec3d light_direction();

// The leaf pattern at a canopy surface point: which leaf cell, and whether it is a hole.
struct LeafSample {
  float f1 = 0, f2 = 0;   // cellular distances (cell units)
  std::uint32_t id = 0;   // the leaf
  float along = 0, across = 0; // offset from the leaf's centre along/across its axis (cells)
  bool hole = false;
};
// p_tree: the point relative to the trunk axis (mm); normal: the cluster's unit surface normal
// there; grazing: 1 - |cos| of the angle between the ray and the normal (1 = seen edge-on).
LeafSample leaf_sample(const cv::Vec3d &p_tree, const cv::Vec3d &normal, double grazing,
                       std::uint32_t tree_seed, double gap_fraction);

// Colour of a leaf. normal: unit surface normal facing the camera; depth_in_canopy: 0 at the
// canopy's outer envelope, 1 at its centre; inner: the point is on the inside of a cluster's
// shell (seen through a hole); footprint: mm per pixel at the point.
cv::Vec3f leaf_color(const LeafSample &leaf, const cv::Vec3d &p_tree, const cv::Vec3d &normal,
                     double depth_in_canopy, bool inner, double footprint, std::uint32_t tree_seed);

// Bark at a point of the trunk's surface. angle_mm: arc length around the trunk (mm).
cv::Vec3f bark_color(double angle_mm, double y, const cv::Vec3d &normal, double footprint,
                     std::uint32_t tree_seed);

// Soil at a world point of the ground plane (x, z in mm; world = fixed to the ground).
cv::Vec3f soil_color(double x, double z, double footprint, std::uint32_t seed);

// Mown grass at a world point of the ground plane (x, z in mm): green (excess green 2G-R-B
// clearly positive) with dry yellow-brown patches (excess green about zero or below), clumps
// and blades for the feature detector.
cv::Vec3f grass_color(double x, double z, double footprint, std::uint32_t seed);

// The wall behind the row at a world point (x, height above ground, mm).
cv::Vec3f wall_color(double x, double height, double footprint, std::uint32_t seed);

// Sky along a ray with vertical direction component dy/|d| (negative = up).
cv::Vec3f sky_color(double elevation);

} // namespace scene_materials
} // namespace treestereo
