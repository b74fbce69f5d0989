// Speed of the synthetic orchard renderer: milliseconds per view (median of several runs) at
// the sizes treetestsrc is used with, and the one-off set-up (ray tables, tile cones).
// Usage: bench-render [runs per size, default 5]
#include "treestereo/scene.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/core/utility.hpp>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

using namespace treestereo;

namespace {

double ms_since(std::chrono::steady_clock::time_point t0)
{
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

} // namespace

int main(int argc, char **argv)
{
  const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 5;
  const cv::Size sizes[] = {{640, 480}, {1296, 972}, {2592, 1944}};
  std::printf("Renderer speed, %d threads, median of %d runs per view\n\n", cv::getNumThreads(), runs);
  std::printf("| size | set-up (ms) | left view (ms) | right view (ms) | with ground truth (ms) |\n");
  std::printf("|---|---|---|---|---|\n");
  for (const cv::Size &size : sizes) {
    SceneParams p;
    p.image_size = size;
    const auto t0 = std::chrono::steady_clock::now();
    SceneRenderer r(p);
    const double setup = ms_since(t0);
    std::vector<double> left, right, truth;
    cv::Mat rgb;
    GroundTruth g;
    for (int i = 0; i < runs; ++i) {
      auto t = std::chrono::steady_clock::now();
      r.render(0, std::uint64_t(i), rgb);
      left.push_back(ms_since(t));
      t = std::chrono::steady_clock::now();
      r.render(1, std::uint64_t(i), rgb);
      right.push_back(ms_since(t));
      t = std::chrono::steady_clock::now();
      r.render(0, std::uint64_t(i), rgb, &g);
      truth.push_back(ms_since(t));
    }
    std::printf("| %dx%d | %.0f | %.1f | %.1f | %.1f |\n", size.width, size.height, setup,
                median(left), median(right), median(truth));
  }
  return 0;
}
