// Speed of the synthetic orchard renderer: milliseconds per view (median of several runs) at
// the sizes treetestsrc is used with, and the one-off set-up (ray tables, tile cones).
// Wall-clock time depends on what else the machine runs; the CPU time summed over all threads
// (std::clock) does much less, so both are printed.
// Usage: bench-render [runs per size, default 5]
#include "treestereo/scene.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/core/utility.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <functional>
#include <memory>
#include <vector>

using namespace treestereo;

namespace {

struct Timing {
  std::vector<double> wall_ms, cpu_ms;
  void measure(const std::function<void()> &f)
  {
    const auto t0 = std::chrono::steady_clock::now();
    const std::clock_t c0 = std::clock();
    f();
    cpu_ms.push_back(1000.0 * double(std::clock() - c0) / CLOCKS_PER_SEC);
    wall_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
};

} // namespace

int main(int argc, char **argv)
{
  const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 5;
  const cv::Size sizes[] = {{640, 480}, {1296, 972}, {2592, 1944}};
  std::printf("Renderer speed, %d threads, median of %d runs; wall-clock ms (CPU ms over all threads)\n\n",
              cv::getNumThreads(), runs);
  std::printf("| size | set-up | left view | right view | left view + ground truth |\n");
  std::printf("|---|---|---|---|---|\n");
  for (const cv::Size &size : sizes) {
    SceneParams p;
    p.image_size = size;
    Timing setup, left, right, truth;
    std::unique_ptr<SceneRenderer> r;
    setup.measure([&] { r = std::make_unique<SceneRenderer>(p); });
    cv::Mat rgb;
    GroundTruth g;
    for (int i = 0; i < runs; ++i) {
      const auto frame = std::uint64_t(i);
      left.measure([&] { r->render(0, frame, rgb); });
      right.measure([&] { r->render(1, frame, rgb); });
      truth.measure([&] { r->render(0, frame, rgb, &g); });
    }
    auto cell = [](Timing &t) {
      return cv::format("%.1f (%.1f)", median(t.wall_ms), median(t.cpu_ms));
    };
    std::printf("| %dx%d | %s | %s | %s | %s |\n", size.width, size.height, cell(setup).c_str(),
                cell(left).c_str(), cell(right).c_str(), cell(truth).c_str());
  }
  return 0;
}
