// Renders docs/images/treeoverlay-example.png: a synthetic spherical canopy seen by a stereo pair
// (640x480 views, f 800 px, baseline 50 mm, sphere of radius 0.6 m at 2.2 m), its silhouette,
// matches and 3D points constructed exactly, tree metrics computed by lib/, and treeoverlay's
// drawing on top. Usage: overlay-figure OUT.png
#include "treestereo/metrics.hpp"
#include "treestereo/overlay.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdio>
#include <random>

using namespace treestereo;

namespace {

const cv::Point3d kCentre(-0.05, 0.05, 2.2); // m, left camera frame
const double kRadius = 0.6, kBaseline = 0.05;

// Depth of the sphere's front along the ray through pixel (x, y) of a camera at x = cam_x; 0: miss.
double hit(const StereoGeometry &g, double x, double y, double cam_x)
{
  const cv::Point3d d((x - g.cx[0]) / g.fx, (y - g.cy) / g.fy, 1.0);
  const cv::Point3d o(cam_x, 0, 0), oc = o - kCentre;
  const double a = d.dot(d), b = 2 * d.dot(oc), c = oc.dot(oc) - kRadius * kRadius;
  const double disc = b * b - 4 * a * c;
  return disc < 0 ? 0.0 : (-b - std::sqrt(disc)) / (2 * a);
}

cv::Mat render(const StereoGeometry &g, double cam_x)
{
  cv::Mat img(g.view_size, CV_8UC3);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const double z = hit(g, x, y, cam_x);
      cv::Vec3b &p = img.at<cv::Vec3b>(y, x); // RGB
      if (z > 0) {
        // shaded by depth, with a coarse leaf pattern (per-pixel noise would bloat the PNG)
        const double leaf = ((x / 6 + y / 6 + int(z * 40)) % 3) * 0.06;
        const double shade = 0.5 + leaf + 0.4 * (1.0 - (z - 1.6) / 0.6);
        p = cv::Vec3b(cv::saturate_cast<uchar>(40 * shade),
                      cv::saturate_cast<uchar>(140 * shade),
                      cv::saturate_cast<uchar>(45 * shade));
      } else {
        const bool ground = y > 380;
        p = ground ? cv::Vec3b(120, 100, 80) : cv::Vec3b(170, 195, 220);
      }
    }
  return img;
}

} // namespace

int main(int argc, char **argv)
{
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT.png\n", argv[0]);
    return 2;
  }
  StereoGeometry g;
  g.view_size = {640, 480};
  g.fx = g.fy = 800;
  g.cx[0] = g.cx[1] = 320;
  g.cy = 240;
  g.baseline_mm = kBaseline * 1000;
  std::mt19937 rng(7);

  cv::Mat frame(480, 1280, CV_8UC3);
  render(g, 0.0).copyTo(frame(cv::Rect(0, 0, 640, 480)));
  render(g, kBaseline).copyTo(frame(cv::Rect(640, 0, 640, 480)));

  OverlayScene scene;
  for (int v = 0; v < 2; ++v) {
    Silhouette &s = scene.views[v];
    s.mask = cv::Mat::zeros(480, 640, CV_8U);
    for (int y = 0; y < 480; ++y)
      for (int x = 0; x < 640; ++x)
        if (hit(g, x, y, v * kBaseline) > 0)
          s.mask.at<uchar>(y, x) = 255;
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(s.mask.clone(), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
    s.present = !contours.empty();
    s.contour = contours.at(0);
    s.bbox = cv::boundingRect(s.mask);
    s.area_px = cv::countNonZero(s.mask);
  }
  std::vector<Point3> points;
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < 4000 && scene.matches.size() < 160; ++i) {
    const double x = 640 * u(rng), y = 480 * u(rng), z = hit(g, x, y, 0.0);
    if (z <= 0)
      continue;
    const double xr = x - g.fx * kBaseline / z;
    scene.matches.push_back({float(x), float(y), float(xr), float(y), 0});
    scene.match_depth_m.push_back(z);
    points.push_back({float((x - g.cx[0]) / g.fx * z * 1000), float((y - g.cy) / g.fy * z * 1000),
                      float(z * 1000), std::uint32_t(points.size()), true});
  }
  const TreeMetrics m = compute_tree_metrics(scene.views[LEFT], points, g, MetricsParams());
  scene.text = metrics_text(m, nullptr);
  scene.bands = m.bands;
  scene.geometry = g;
  scene.band_depth_m = m.centroid_m.z;
  draw_overlay(frame, ChannelOrder{0, 1, 2, 3}, scene, OverlayStyle());

  cv::Mat bgr;
  cv::cvtColor(frame, bgr, cv::COLOR_RGB2BGR);
  if (!cv::imwrite(argv[1], bgr, {cv::IMWRITE_PNG_COMPRESSION, 9})) {
    std::fprintf(stderr, "could not write %s\n", argv[1]);
    return 1;
  }
  std::printf("distance %.3f m, height %.3f m, width %.3f m (true 1.200), thickness %.3f m\n",
              m.distance_m, m.height_m, m.width_m, m.thickness_m);
  return 0;
}
