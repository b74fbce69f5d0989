// Runs every vegetation index on the real images with hand-marked regions
// (tests/lib/segment_regions.hpp), prints the covered fractions as markdown and writes
// mask overlays (480 px wide, the marked rectangles drawn) to the directory given
// as the first argument (docs/images/ in the repository).
#include "segment_regions.hpp"
#include "treestereo/data_dir.hpp"
#include "treestereo/segment.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdio>
#include <cstdlib>
#include <string>

using namespace treestereo;

namespace {

double mean_cover(const cv::Mat &mask, const std::vector<segment_truth::Region> &regions,
                  double &worst, bool worst_is_min)
{
  double sum = 0;
  worst = worst_is_min ? 1.0 : 0.0;
  for (const auto &r : regions) {
    const double c = segment_truth::covered(mask, r.rect);
    sum += c;
    worst = worst_is_min ? std::min(worst, c) : std::max(worst, c);
  }
  return regions.empty() ? 0 : sum / double(regions.size());
}

// The image in grey with the canopy tinted magenta and the marked rectangles drawn (green:
// foliage, red: other, yellow: hard), 480 px wide: grey compresses well enough in PNG.
cv::Mat figure(const cv::Mat &img, const cv::Mat &mask, const segment_truth::MarkedImage &m)
{
  cv::Mat grey, out;
  cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  cv::cvtColor(grey / 32 * 32, out, cv::COLOR_GRAY2BGR); // 8 grey levels: small PNG
  out.setTo(cv::Scalar(255, 0, 255), mask);
  const int thick = std::max(2, img.cols / 240);
  for (const auto &r : m.foliage)
    cv::rectangle(out, r.rect, cv::Scalar(0, 255, 0), thick);
  for (const auto &r : m.other)
    cv::rectangle(out, r.rect, cv::Scalar(0, 0, 255), thick);
  for (const auto &r : m.hard)
    cv::rectangle(out, r.rect, cv::Scalar(0, 255, 255), thick);
  cv::Mat small;
  cv::resize(out, small, cv::Size(480, out.rows * 480 / out.cols), 0, 0, cv::INTER_NEAREST);
  return small;
}

} // namespace

int main(int argc, char **argv)
{
  const std::string outdir = argc > 1 ? argv[1] : "";
  const std::string dir = data_dir();
  std::printf("| image | index | threshold | foliage covered: mean (min) | other covered: mean "
              "(max) | hard (green cloth) covered |\n|---|---|---|---|---|---|\n");
  for (const auto &m : segment_truth::marked_images()) {
    const cv::Mat img = cv::imread(dir + "/" + m.path);
    if (img.empty()) {
      std::fprintf(stderr, "missing %s/%s: skipped\n", dir.c_str(), m.path);
      continue;
    }
    for (VegIndex index : all_veg_indices()) {
      SegmentParams p;
      p.index = index;
      p.keep = KeepMode::All;
      const Silhouette s = segment_vegetation(img, p);
      double fmin = 0, omax = 0, hmax = 0;
      const double f = mean_cover(s.mask, m.foliage, fmin, true);
      const double o = mean_cover(s.mask, m.other, omax, false);
      const double h = mean_cover(s.mask, m.hard, hmax, false);
      std::printf("| %s | %s | %.3f | %.1f%% (%.1f%%) | %.1f%% (%.1f%%) | %s |\n", m.name,
                  veg_index_name(index), s.threshold, 100 * f, 100 * fmin, 100 * o, 100 * omax,
                  m.hard.empty() ? "-" : (std::to_string(int(std::lround(100 * h))) + "%").c_str());
      if (!outdir.empty())
        cv::imwrite(outdir + "/segment-" + m.name + "-" + veg_index_name(index) + ".png",
                    figure(img, s.mask, m), {cv::IMWRITE_PNG_COMPRESSION, 9});
    }
  }
  return 0;
}
