// Runs every vegetation index on the real images with hand-marked regions
// (tests/lib/segment_regions.hpp), prints the covered fractions as markdown and writes
// mask overlays (480 px wide, the marked rectangles drawn) to the directory given
// as the first argument (docs/images/ in the repository).
//
//   segment-figures [--keep] [OUTDIR]
//
// --keep: instead, the orchard photos with the default settings (exg-norm, Otsu) and
// keep=largest beside keep=all: a table of the share of pixels marked vegetation and one
// figure per photo, segment-<name>-keep.png (two 480 px panels, no rectangles).
// Images missing from the shared data directory are skipped with a message (exit 0).
#include "segment_regions.hpp"
#include "treestereo/data_dir.hpp"
#include "treestereo/segment.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

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

// The image in grey (8 levels: small PNG) with the mask tinted magenta, full size.
cv::Mat tinted(const cv::Mat &img, const cv::Mat &mask)
{
  cv::Mat grey, out;
  cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  cv::cvtColor(grey / 32 * 32, out, cv::COLOR_GRAY2BGR);
  out.setTo(cv::Scalar(255, 0, 255), mask);
  return out;
}

cv::Mat to_width(const cv::Mat &img, int width)
{
  cv::Mat small;
  cv::resize(img, small, cv::Size(width, img.rows * width / img.cols), 0, 0, cv::INTER_NEAREST);
  return small;
}

// The image in grey with the canopy tinted magenta and the marked rectangles drawn (green:
// foliage, red: other, yellow: hard), 480 px wide: grey compresses well enough in PNG.
cv::Mat figure(const cv::Mat &img, const cv::Mat &mask, const segment_truth::MarkedImage &m)
{
  cv::Mat out = tinted(img, mask);
  const int thick = std::max(2, img.cols / 240);
  for (const auto &r : m.foliage)
    cv::rectangle(out, r.rect, cv::Scalar(0, 255, 0), thick);
  for (const auto &r : m.other)
    cv::rectangle(out, r.rect, cv::Scalar(0, 0, 255), thick);
  for (const auto &r : m.hard)
    cv::rectangle(out, r.rect, cv::Scalar(0, 255, 255), thick);
  return to_width(out, 480);
}

double share(const cv::Mat &mask)
{
  return double(cv::countNonZero(mask)) / double(mask.total());
}

// Two 480 px panels side by side, each with its caption in a white strip above it.
cv::Mat keep_figure(const cv::Mat &img, const std::vector<Silhouette> &panels,
                    const std::vector<std::string> &captions)
{
  std::vector<cv::Mat> cols;
  for (std::size_t i = 0; i < panels.size(); ++i) {
    const cv::Mat body = to_width(tinted(img, panels[i].mask), 480);
    cv::Mat panel(body.rows + 24, body.cols, CV_8UC3, cv::Scalar::all(255));
    body.copyTo(panel(cv::Rect(0, 24, body.cols, body.rows)));
    cv::putText(panel, captions[i], {6, 17}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar::all(0), 1,
                cv::LINE_AA);
    if (i > 0)
      cols.emplace_back(panel.rows, 4, CV_8UC3, cv::Scalar::all(255));
    cols.push_back(panel);
  }
  cv::Mat out;
  cv::hconcat(cols, out);
  return out;
}

// --keep: the orchard photos, keep=largest beside keep=all (default settings otherwise).
void keep_figures(const std::string &dir, const std::string &outdir)
{
  std::printf("| image | keep | threshold | regions | pixels marked vegetation |\n"
              "|---|---|---|---|---|\n");
  for (const auto &m : segment_truth::marked_images()) {
    if (std::string(m.path).rfind("orchard-photos/", 0) != 0)
      continue;
    const cv::Mat img = cv::imread(dir + "/" + m.path);
    if (img.empty()) {
      std::fprintf(stderr, "missing %s/%s (no shared data here): skipped\n", dir.c_str(), m.path);
      continue;
    }
    std::vector<Silhouette> panels;
    std::vector<std::string> captions;
    for (KeepMode keep : {KeepMode::Largest, KeepMode::All}) {
      SegmentParams p;
      p.keep = keep;
      panels.push_back(segment_vegetation(img, p));
      const Silhouette &s = panels.back();
      std::printf("| %s | %s | %.3f | %d | %.1f%% |\n", m.name, keep_mode_name(keep), s.threshold,
                  s.n_regions, 100 * share(s.mask));
      char caption[96];
      std::snprintf(caption, sizeof caption, "keep=%s: %.1f%% of pixels, %d region%s",
                    keep_mode_name(keep), 100 * share(s.mask), s.n_regions,
                    s.n_regions == 1 ? "" : "s");
      captions.emplace_back(caption);
    }
    if (!outdir.empty())
      cv::imwrite(outdir + "/segment-" + m.name + "-keep.png", keep_figure(img, panels, captions),
                  {cv::IMWRITE_PNG_COMPRESSION, 9});
  }
}

} // namespace

int main(int argc, char **argv)
{
  const bool keep = argc > 1 && std::string(argv[1]) == "--keep";
  const std::string outdir = argc > 1 + int(keep) ? argv[1 + int(keep)] : "";
  const std::string dir = data_dir();
  if (keep) {
    keep_figures(dir, outdir);
    return 0;
  }
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
