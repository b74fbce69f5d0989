// Rectified SceneRenderer (treetestsrc) pairs and their truth in the rectified frame, for the
// benchmarks. Header-only: shared by bench-siftmatch, bench-match-scene, bench-extent,
// bench-densify and bench-sampling.
#pragma once

#include "treestereo/rectify.hpp"
#include "treestereo/scene.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdint>
#include <limits>

namespace treestereo::bench {

// Both views of `r` rendered (RGB -> BGR) and rectified with the rig's own calibration; the
// left view's truth, per-pixel maps unrectified (truth_in_frame(truth, rect.geometry.R1) gives
// its figures in the rectified frame).
struct RectifiedRender {
  StereoRectification rect;
  cv::Mat view[2]; // BGR, rectified
  GroundTruth truth_left;
};

inline RectifiedRender render_rectified(const SceneRenderer &r, cv::Size size)
{
  RectifiedRender out;
  out.rect = compute_rectification(r.calibration(), size);
  for (int v = 0; v < 2; ++v) {
    cv::Mat rgb;
    r.render(v, 0, rgb, v == LEFT ? &out.truth_left : nullptr);
    cv::cvtColor(rgb, rgb, cv::COLOR_RGB2BGR);
    rectify_view(out.rect, v, rgb, out.view[v]);
  }
  return out;
}

// The renderer's visible canopy depth (mm) splatted into the rectified left view, nearest
// surface kept (0 = none): truth `t` of the left view of `r`, geometry of its rectification.
inline cv::Mat truth_depth_rectified(const SceneRenderer &r, const GroundTruth &t,
                                     const StereoGeometry &g)
{
  cv::Mat zt(t.depth.size(), CV_32F, cv::Scalar(0));
  const cv::Mat &rays = r.normalized_rays(0);
  for (int y = 0; y < t.depth.rows; y++)
    for (int x = 0; x < t.depth.cols; x++) {
      const float z = t.depth.at<float>(y, x);
      if (z <= 0 || !t.canopy_mask.at<uchar>(y, x))
        continue;
      const cv::Vec2f n = rays.at<cv::Vec2f>(y, x); // CV_32FC2 (scene.cpp)
      const cv::Vec3d X = g.R1 * cv::Vec3d(n[0] * z, n[1] * z, z);
      const int u = int(std::lround(g.fx * X[0] / X[2] + g.cx[0]));
      const int v = int(std::lround(g.fy * X[1] / X[2] + g.cy));
      if (u < 0 || v < 0 || u >= zt.cols || v >= zt.rows)
        continue;
      float &c = zt.at<float>(v, u);
      if (c == 0 || X[2] < c)
        c = float(X[2]);
    }
  return zt;
}

// The true disparity of every rectified left pixel: the rendered depth made a 3D point along the
// pixel's ray, carried to the rectified grid by the rectification's own map (nearest: no mixing of
// foreground and background at edges), rotated into the rectified frame, d = fx b / Z + doffs.
// NaN where the ray hits nothing.
inline cv::Mat rectified_truth_disparity(const SceneRenderer &r, const StereoRectification &rect,
                                         const GroundTruth &t)
{
  const cv::Mat &rays = r.normalized_rays(LEFT);
  cv::Mat pts(t.depth.size(), CV_32FC3);
  for (int y = 0; y < pts.rows; ++y)
    for (int x = 0; x < pts.cols; ++x) {
      const float z = t.depth.at<float>(y, x);
      const cv::Vec2f n = rays.at<cv::Vec2f>(y, x);
      pts.at<cv::Vec3f>(y, x) = z > 0 ? cv::Vec3f(float(n[0] * z), float(n[1] * z), z)
                                      : cv::Vec3f(0, 0, 0);
    }
  cv::Mat rp;
  cv::remap(pts, rp, rect.map1[LEFT], rect.map2[LEFT], cv::INTER_NEAREST, cv::BORDER_CONSTANT);
  const StereoGeometry &g = rect.geometry;
  cv::Mat d(rp.size(), CV_32F);
  for (int y = 0; y < rp.rows; ++y)
    for (int x = 0; x < rp.cols; ++x) {
      const cv::Vec3f p = rp.at<cv::Vec3f>(y, x);
      const cv::Vec3d q = g.R1 * cv::Vec3d(p[0], p[1], p[2]);
      d.at<float>(y, x) = p[2] > 0 ? float(g.fx * g.baseline_mm / q[2] + g.doffs())
                                   : std::numeric_limits<float>::quiet_NaN();
    }
  return d;
}

// One rendered, rectified pair (BGR views, canopy masks) and its left truth.
struct ScenePair {
  cv::Mat view[2], mask[2];
  cv::Mat d_true; // CV_32F, NaN = no surface
  StereoGeometry geometry;
};

inline ScenePair render_pair(const SceneParams &sp)
{
  const SceneRenderer renderer(sp);
  const StereoRectification rect =
      compute_rectification(renderer.calibration(), sp.image_size, -1, true);
  ScenePair p;
  GroundTruth truth[2];
  for (int v = 0; v < 2; ++v) {
    cv::Mat rgb, bgr;
    renderer.render(v, 0, rgb, &truth[v]);
    cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
    rectify_view(rect, v, bgr, p.view[v]);
    cv::remap(truth[v].canopy_mask, p.mask[v], rect.map1[v], rect.map2[v], cv::INTER_NEAREST);
  }
  p.d_true = rectified_truth_disparity(renderer, rect, truth[LEFT]);
  p.geometry = rect.geometry;
  return p;
}

} // namespace treestereo::bench
