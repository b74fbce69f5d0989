#include "treestereo/canopy.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace treestereo {

const char *canopy_mode_name(CanopyMode mode)
{
  return mode == CanopyMode::Row ? "row" : "tree";
}

CanopyMode canopy_mode_from_name(const std::string &name)
{
  if (name == "tree")
    return CanopyMode::Tree;
  if (name == "row")
    return CanopyMode::Row;
  throw std::runtime_error("unknown canopy mode '" + name + "' (valid: tree, row)");
}

const char *ground_model_name(GroundModel model)
{
  switch (model) {
  case GroundModel::Off: return "off";
  case GroundModel::Rig: return "rig";
  default: return "fit";
  }
}

GroundModel ground_model_from_name(const std::string &name)
{
  if (name == "off")
    return GroundModel::Off;
  if (name == "fit")
    return GroundModel::Fit;
  if (name == "rig")
    return GroundModel::Rig;
  throw std::runtime_error("unknown ground model '" + name + "' (valid: off, fit, rig)");
}

double depth_support(const cv::Mat &mask, const std::vector<cv::Point2f> &px, double radius_px)
{
  CV_Assert(mask.type() == CV_8U);
  const int total = cv::countNonZero(mask);
  if (total == 0)
    return 0.0;
  cv::Mat seen(mask.size(), CV_8U, cv::Scalar(0));
  const int r = std::max(0, int(std::lround(radius_px)));
  for (const cv::Point2f &p : px) {
    const cv::Point c(int(std::lround(p.x)), int(std::lround(p.y)));
    if (c.x < -r || c.y < -r || c.x >= mask.cols + r || c.y >= mask.rows + r)
      continue;
    cv::circle(seen, c, r, cv::Scalar(255), cv::FILLED);
  }
  cv::bitwise_and(seen, mask, seen);
  return double(cv::countNonZero(seen)) / double(total);
}

} // namespace treestereo
