// Speed of vegetation segmentation per view, for each index, at three view sizes.
// The view is the left half (a ROI with the real stride) of a side-by-side frame, as in the
// pipeline. Content: the first orchard photo when the shared data is there, else a synthetic
// scene (a textured green crown on soil and sky). Prints a markdown table.
#include "treestereo/data_dir.hpp"
#include "treestereo/segment.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <ctime>

using namespace treestereo;

namespace {

cv::Mat source_image(std::string &what)
{
  const std::string dir = data_dir();
  cv::Mat img = cv::imread(dir + "/orchard-photos/1_5m_FULL_TREE_2022_06_17_P1.png");
  if (!img.empty()) {
    what = "orchard photo 1_5m_FULL_TREE (resized)";
    return img;
  }
  what = "synthetic crown (no shared data found)";
  img.create(1080, 1440, CV_8UC3);
  img.rowRange(0, 400).setTo(cv::Scalar(200, 170, 150));
  img.rowRange(400, 1080).setTo(cv::Scalar(60, 100, 140));
  cv::circle(img, {720, 540}, 400, cv::Scalar(40, 130, 60), cv::FILLED);
  cv::Mat noise(img.size(), CV_8UC3);
  cv::randn(noise, cv::Scalar::all(0), cv::Scalar::all(20));
  cv::add(img, noise, img);
  return img;
}

double time_ms(VegetationSegmenter &seg, const cv::Mat &view, Silhouette &out, int runs)
{
  std::vector<double> ms;
  seg.run(view, out); // warm-up: allocations, thread pool
  for (int i = 0; i < runs; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    seg.run(view, out);
    const auto t1 = std::chrono::steady_clock::now();
    ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
  }
  return median(ms);
}

double thread_cpu_ms()
{
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

// CPU time of one run on the calling thread (after a warm-up run).
double cpu_ms(VegetationSegmenter &seg, const cv::Mat &view, Silhouette &out)
{
  seg.run(view, out);
  const double t0 = thread_cpu_ms();
  seg.run(view, out);
  return thread_cpu_ms() - t0;
}

} // namespace

int main(int argc, char **argv)
{
  const int runs = argc > 1 ? std::max(10, std::atoi(argv[1])) : 15;
  std::string what;
  const cv::Mat src = source_image(what);
  const cv::Size sizes[] = {{640, 480}, {1296, 972}, {2592, 1944}};

  std::printf("Vegetation segmentation, ms per view (median of %d runs), %d OpenCV threads\n",
              runs, cv::getNumThreads());
  std::printf("Content: %s; view = left half of a side-by-side frame (ROI, real stride);\n"
              "defaults: Otsu, morph_size 5, keep largest.\n\n", what.c_str());
  std::printf("| index | 640x480 | 1296x972 | 2592x1944 |\n|---|---|---|---|\n");
  for (VegIndex index : all_veg_indices()) {
    std::printf("| %s |", veg_index_name(index));
    for (const cv::Size &s : sizes) {
      cv::Mat frame(s.height, 2 * s.width, CV_8UC3);
      cv::resize(src, frame(cv::Rect(0, 0, s.width, s.height)), s, 0, 0, cv::INTER_AREA);
      cv::resize(src, frame(cv::Rect(s.width, 0, s.width, s.height)), s, 0, 0, cv::INTER_AREA);
      SegmentParams p;
      p.index = index;
      VegetationSegmenter seg(p);
      Silhouette out;
      std::printf(" %.2f |", time_ms(seg, frame(cv::Rect(0, 0, s.width, s.height)), out, runs));
    }
    std::printf("\n");
  }

  // The opening by reconstruction's cost: both settings interleaved on the same view, on one
  // thread, timed by the thread's CPU clock: on the shared machine, wall time mostly measures
  // when the scheduler lets the thread run (steps of 4-5 ms), not the work.
  cv::setNumThreads(1);
  std::printf("\nexg-norm, opening by reconstruction off/on: CPU ms per view on one thread "
              "(median of %d runs, interleaved)\n\n| size | reconstruct=false | "
              "reconstruct=true |\n|---|---|---|\n",
              runs);
  for (const cv::Size &s : sizes) {
    cv::Mat view;
    cv::resize(src, view, s, 0, 0, cv::INTER_AREA);
    SegmentParams p;
    p.reconstruct = false;
    VegetationSegmenter plain(p);
    p.reconstruct = true;
    VegetationSegmenter rec(p);
    Silhouette out;
    std::vector<double> ms[2];
    for (int i = 0; i < runs; ++i) {
      ms[0].push_back(cpu_ms(plain, view, out));
      ms[1].push_back(cpu_ms(rec, view, out));
    }
    std::printf("| %dx%d | %.2f | %.2f |\n", s.width, s.height, median(ms[0]), median(ms[1]));
  }
  return 0;
}
