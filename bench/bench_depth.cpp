// Speed of stereodepth's algorithms: triangulating matches and dense SGBM on a canopy box.
// Prints a markdown table of median wall times. Never run by the test suite.
#include "treestereo/depth.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cstdio>
#include <functional>
#include <random>
#include <string>
#include <vector>

using namespace treestereo;

namespace {

double median_ms(int runs, const std::function<void()> &fn)
{
  std::vector<double> ms;
  for (int i = 0; i < runs; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    fn();
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                     .count());
  }
  return median(ms);
}

// The paper's cameras at full resolution (2592x1944), 50 mm baseline.
StereoGeometry paper_rig()
{
  StereoGeometry g;
  g.view_size = cv::Size(2592, 1944);
  g.fx = g.fy = 2400;
  g.cx[LEFT] = g.cx[RIGHT] = 1296;
  g.cy = 972;
  g.baseline_mm = 50;
  return g;
}

std::vector<StereoMatch> random_matches(const StereoGeometry &g, int n)
{
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> ux(0, float(g.view_size.width)),
      uy(0, float(g.view_size.height)), uz(1500, 2500);
  std::vector<StereoMatch> m(static_cast<std::size_t>(n));
  for (StereoMatch &s : m) {
    s.xl = ux(rng);
    s.yl = s.yr = uy(rng);
    s.xr = s.xl - float(g.fx * g.baseline_mm / uz(rng));
  }
  return m;
}

} // namespace

int main()
{
  const StereoGeometry g = paper_rig();
  std::printf("| case | size | median ms | notes |\n|---|---|---|---|\n");
  for (int n : {1000, 10000}) {
    const std::vector<StereoMatch> m = random_matches(g, n);
    DepthResult r;
    const double ms = median_ms(21, [&] { r = triangulate_matches(m, g, DepthParams{}); });
    std::printf("| triangulate + filter | %d matches | %.3f | %zu kept |\n", n, ms, r.stats.n_valid);
  }

  // A textured scene at 2 m (disparity 60 px), matched over a 1-5 m depth range.
  cv::Mat noise(g.view_size, CV_8U), left, right;
  cv::RNG rng(3);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(noise, left, cv::Size(0, 0), 1.2);
  const double d = g.fx * g.baseline_mm / 2000.0;
  cv::warpAffine(left, right, cv::Matx23d(1, 0, d, 0, 1, 0), g.view_size,
                 cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REFLECT);
  const cv::Mat mask(g.view_size, CV_8U, cv::Scalar(255));
  DenseParams p;
  p.filter.min_depth_mm = 1000;
  p.filter.max_depth_mm = 5000;
  for (cv::Size box : {cv::Size(640, 480), cv::Size(1296, 972)}) {
    const cv::Rect r((g.view_size.width - box.width) / 2, (g.view_size.height - box.height) / 2,
                     box.width, box.height);
    DenseResult res;
    const double ms = median_ms(5, [&] { res = dense_depth(left, right, mask, r, g, p); });
    std::printf("| dense SGBM 3-way | %dx%d box | %.1f | disparities %d..%d, %zu points, "
                "median %.0f mm (true 2000) |\n",
                box.width, box.height, ms, res.min_disparity,
                res.min_disparity + res.num_disparities - 1, res.stats.n_valid,
                res.stats.median_mm);
  }
  return 0;
}
