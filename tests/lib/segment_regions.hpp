// Hand-marked regions of the real images used to check vegetation segmentation
// (docs/segmentation.md shows them). Marked by eye on the images, independently of any mask:
// "foliage" rectangles lie inside leaves, "other" rectangles inside apples, sky, posts, soil,
// pot, boxes, wall. "hard" rectangles are non-foliage that is itself green-yellow (reported,
// not required). Paths are relative to the shared data directory.
#pragma once

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace segment_truth {

struct Region {
  const char *what;
  cv::Rect rect;
};

struct MarkedImage {
  const char *name; // short name for reports and figure files
  const char *path; // under the data directory
  std::vector<Region> foliage, other, hard;
};

inline std::vector<MarkedImage> marked_images()
{
  return {
      {"orchard-1.0m",
       "orchard-photos/1_0m_HIGH_2022_10_12_P2.png",
       {{"leaf, top middle", {822, 30, 45, 55}},
        {"leaf cluster, right", {1580, 120, 50, 50}},
        {"leaves, lower middle", {1370, 590, 50, 40}},
        {"big leaf, lower middle", {1195, 805, 40, 35}}},
       {{"apple, top left", {115, 115, 90, 75}},
        {"apple, top left 2", {265, 125, 85, 85}},
        {"apple, top right", {1460, 50, 100, 85}},
        {"apple, middle right", {1475, 255, 95, 80}},
        {"apple, bottom", {1085, 955, 90, 70}},
        {"wooden post, right", {1828, 700, 20, 250}}},
       {}},
      {"orchard-1.5m",
       "orchard-photos/1_5m_FULL_TREE_2022_06_17_P1.png",
       {{"leaf, upper left", {205, 205, 35, 30}},
        {"leaves, upper right", {880, 140, 50, 50}}},
       {{"sky", {460, 65, 50, 25}},
        {"red-white pole", {614, 60, 14, 400}},
        {"trunk", {260, 300, 18, 180}}},
       {}},
      {"jadeplant",
       "middlebury2014-quarter/Jadeplant/im0.png",
       {{"leaf, middle", {425, 129, 15, 8}},
        {"leaf, right", {478, 110, 12, 10}},
        {"leaf, centre left", {335, 120, 9, 12}},
        {"leaf, left", {245, 141, 12, 7}}},
       {{"black backdrop", {20, 20, 80, 80}},
        {"cardboard box", {70, 280, 100, 120}},
        {"clay pot", {315, 335, 40, 60}},
        {"white table", {120, 445, 150, 35}},
        {"box with stop sign", {180, 75, 40, 40}}},
       {{"yellow-green cloth", {520, 330, 110, 90}}}},
  };
}

// Share of a rectangle's pixels that the mask (255 = canopy) covers.
inline double covered(const cv::Mat &mask, const cv::Rect &r)
{
  return double(cv::countNonZero(mask(r))) / double(r.area());
}

} // namespace segment_truth
