// treestereo-calibrate: stereo calibration from chessboard image pairs, and a check of an
// existing calibration's rectification on such pairs.
#include "treestereo/calibration_file.hpp"
#include "treestereo/chessboard.hpp"
#include "treestereo/errors.hpp"

#include <opencv2/imgcodecs.hpp>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

const char *kUsage =
    "Usage:\n"
    "  treestereo-calibrate --board WxH --square MM [-o calib.yml] LEFT1 RIGHT1 [LEFT2 RIGHT2 ...]\n"
    "  treestereo-calibrate --board WxH --square MM [-o calib.yml] --list stereo_calib.xml\n"
    "  treestereo-calibrate --board WxH --check calib.yml (LEFT RIGHT ... | --list FILE)\n"
    "\n"
    "Calibrates a stereo rig from chessboard image pairs (left, right alternating) and prints\n"
    "the per-camera and stereo reprojection RMS, the baseline and the rejected pairs.\n"
    "\n"
    "  --board WxH    inner corners of the chessboard, e.g. 9x6 (not the number of squares)\n"
    "  --square MM    side of one square in mm; the baseline comes out in the same unit\n"
    "  -o, --output F write the calibration (OpenCV YAML/XML by extension: .yml .yaml .xml)\n"
    "  --list F       OpenCV image list (as samples/data/stereo_calib.xml), names relative to it\n"
    "  --check F      do not calibrate: load calibration F, rectify the pairs' corners and\n"
    "                 report the row difference |dy| of matching corners (px)\n"
    "  -h, --help     this text\n"
    "Exit status: 0 on success, 1 on an error, 2 on a usage error.\n";

struct Options {
  cv::Size board;
  double square = 0;
  std::string output, list, check;
  std::vector<std::string> images;
};

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

cv::Size parse_board(const std::string &s)
{
  int w = 0, h = 0;
  char x = 0, extra = 0;
  if (std::sscanf(s.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X') ||
      w < 2 || h < 2)
    throw UsageError("--board expects inner corners as WxH (e.g. 9x6), got '" + s + "'");
  return {w, h};
}

double parse_square(const std::string &s)
{
  char *end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (end == s.c_str() || *end != '\0' || !(v > 0))
    throw UsageError("--square expects a positive length in mm, got '" + s + "'");
  return v;
}

// Returns false when --help was asked for.
bool parse(int argc, char **argv, Options &o)
{
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc)
        throw UsageError(a + " needs a value");
      return argv[++i];
    };
    if (a == "-h" || a == "--help")
      return false;
    if (a == "--board")
      o.board = parse_board(value());
    else if (a == "--square")
      o.square = parse_square(value());
    else if (a == "-o" || a == "--output")
      o.output = value();
    else if (a == "--list")
      o.list = value();
    else if (a == "--check")
      o.check = value();
    else if (a.size() > 1 && a[0] == '-')
      throw UsageError("unknown option " + a);
    else
      o.images.push_back(a);
  }
  if (o.board.area() == 0)
    throw UsageError("--board WxH is required (inner corners, e.g. 9x6)");
  if (o.check.empty() && o.square <= 0)
    throw UsageError("--square MM is required to calibrate");
  if (!o.check.empty() && !o.output.empty())
    throw UsageError("--check does not write a calibration: drop -o");
  if (!o.list.empty() && !o.images.empty())
    throw UsageError("give either --list or image files, not both");
  if (o.list.empty() && (o.images.empty() || o.images.size() % 2 != 0))
    throw UsageError("give the images as pairs: LEFT1 RIGHT1 LEFT2 RIGHT2 ... (got " +
                     std::to_string(o.images.size()) + " files)");
  return true;
}

std::vector<treestereo::ChessboardPair> load_pairs(const std::vector<std::string> &files)
{
  std::vector<treestereo::ChessboardPair> pairs;
  for (std::size_t i = 0; i + 1 < files.size(); i += 2) {
    treestereo::ChessboardPair p;
    p.left = cv::imread(files[i], cv::IMREAD_GRAYSCALE);
    p.right = cv::imread(files[i + 1], cv::IMREAD_GRAYSCALE);
    for (std::size_t k : {i, i + 1})
      if ((k == i ? p.left : p.right).empty())
        throw std::runtime_error(files[k] + ": missing or not an image");
    p.name = files[i] + " + " + files[i + 1];
    pairs.push_back(std::move(p));
  }
  return pairs;
}

void print_rejected(const std::vector<treestereo::RejectedPair> &rejected)
{
  std::printf("rejected pairs: %zu\n", rejected.size());
  for (const auto &r : rejected)
    std::printf("  pair %zu (%s): %s\n", r.index + 1, r.name.c_str(), r.reason.c_str());
}

int run_check(const Options &o, const std::vector<treestereo::ChessboardPair> &pairs)
{
  const treestereo::StereoCalibration calib = treestereo::load_calibration(o.check);
  const treestereo::RectificationCheck c = treestereo::check_rectification(calib, pairs, o.board);
  std::printf("pairs used: %zu of %zu, corners: %zu\n", c.used.size(), pairs.size(), c.corners);
  std::printf("rectified row difference |dy|: mean %.3f px, max %.3f px\n", c.mean_abs_dy,
              c.max_abs_dy);
  for (std::size_t k = 0; k < c.used.size(); ++k)
    std::printf("  pair %zu (%s): mean %.3f px, max %.3f px\n", c.used[k] + 1,
                pairs[c.used[k]].name.c_str(), c.pair_mean_abs_dy[k], c.pair_max_abs_dy[k]);
  print_rejected(c.rejected);
  return 0;
}

int run_calibrate(const Options &o, const std::vector<treestereo::ChessboardPair> &pairs)
{
  const treestereo::ChessboardCalibration r =
      treestereo::calibrate_chessboard(pairs, o.board, o.square);
  const treestereo::StereoCalibration &c = r.calib;
  std::printf("pairs used: %zu of %zu, image size %dx%d\n", r.used.size(), pairs.size(),
              c.image_size.width, c.image_size.height);
  std::printf("RMS reprojection error: left %.3f px, right %.3f px, stereo %.3f px\n", r.rms_left,
              r.rms_right, r.rms_stereo);
  std::printf("baseline |T|: %.4f mm  T = [%.4f, %.4f, %.4f] mm\n", c.baseline_mm(),
              c.T.at<double>(0), c.T.at<double>(1), c.T.at<double>(2));
  std::printf("focal length: left %.2f px, right %.2f px\n", c.M1.at<double>(0, 0),
              c.M2.at<double>(0, 0));
  print_rejected(r.rejected);
  if (!o.output.empty()) {
    treestereo::save_calibration(c, o.output);
    std::printf("written: %s\n", o.output.c_str());
  }
  return 0;
}

} // namespace

int main(int argc, char **argv)
{
  Options o;
  try {
    if (!parse(argc, argv, o)) {
      std::fputs(kUsage, stdout);
      return 0;
    }
  } catch (const UsageError &e) {
    std::fprintf(stderr, "treestereo-calibrate: %s\n\n%s", e.what(), kUsage);
    return 2;
  }
  try {
    const std::vector<std::string> files = o.list.empty() ? o.images : treestereo::read_image_list(o.list);
    const std::vector<treestereo::ChessboardPair> pairs = load_pairs(files);
    return o.check.empty() ? run_calibrate(o, pairs) : run_check(o, pairs);
  } catch (const std::exception &e) {
    // a typed error's detail (the values at odds) after its sentence
    const auto *typed = dynamic_cast<const treestereo::Error *>(&e);
    if (typed && !typed->detail().empty())
      std::fprintf(stderr, "treestereo-calibrate: error: %s (%s)\n", e.what(),
                   typed->detail().c_str());
    else
      std::fprintf(stderr, "treestereo-calibrate: error: %s\n", e.what());
    return 1;
  }
}
