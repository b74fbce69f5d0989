// libFuzzer target: the calibration reader (lib/calibration.cpp) on arbitrary files.
//
// Input layout: the first byte picks the form, the rest is the file content; for the forms
// made of two files the content is split at the first "\n%%\n".
//   0  one OpenCV file, calib.yml        3  one OpenCV file, calib.yaml
//   1  one OpenCV file, calib.xml        4  OpenCV sample pair intrinsics.yml;extrinsics.yml
//   2  ROS pair left.yaml;right.yaml     5  a gzip-named file calib.yml.gz
// A CalibrationError (or any std::exception) is a fine answer; a crash, a leak, undefined
// behaviour or a calibration that does not survive save + load again is a bug.
#include "treestereo/calibration_file.hpp"

#include "../common/temp_dir.hpp"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

using treestereo::StereoCalibration;

namespace {

const std::filesystem::path &work_dir()
{
  static const TempDir dir("treestereo-fuzz-calib");
  static const std::filesystem::path path(dir.path());
  return path;
}

std::string write(const std::string &name, const std::string &content)
{
  const std::string path = (work_dir() / name).string();
  std::ofstream(path, std::ios::binary | std::ios::trunc) << content;
  return path;
}

bool near(const cv::Mat &a, const cv::Mat &b)
{
  if (a.total() != b.total())
    return false;
  const double scale = std::max(1.0, cv::norm(a, cv::NORM_INF));
  return cv::norm(a.reshape(1, 1), b.reshape(1, 1), cv::NORM_INF) <= 1e-9 * scale;
}

// What load_calibration accepted must be written and read back as the same rig.
void check_round_trip(const StereoCalibration &c)
{
  const std::string path = (work_dir() / "roundtrip.yml").string();
  treestereo::save_calibration(c, path);
  const StereoCalibration back = treestereo::load_calibration(path);
  if (back.image_size != c.image_size || !near(back.M1, c.M1) || !near(back.M2, c.M2) ||
      !near(back.D1, c.D1) || !near(back.D2, c.D2) || !near(back.R, c.R) || !near(back.T, c.T)) {
    std::fprintf(stderr, "calibration changed through save + load\n");
    std::abort();
  }
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
  if (size < 1)
    return 0;
  const int form = data[0] % 6;
  std::string content(reinterpret_cast<const char *>(data + 1), size - 1);
  std::string second;
  const auto cut = content.find("\n%%\n");
  if (cut != std::string::npos) {
    second = content.substr(cut + 4);
    content.resize(cut + 1);
  }
  std::string spec;
  switch (form) {
  case 0: spec = write("calib.yml", content); break;
  case 1: spec = write("calib.xml", content); break;
  case 2: spec = write("left.yaml", content) + ";" + write("right.yaml", second); break;
  case 3: spec = write("calib.yaml", content); break;
  case 4: spec = write("intrinsics.yml", content) + ";" + write("extrinsics.yml", second); break;
  default: spec = write("calib.yml.gz", content); break;
  }
  StereoCalibration c;
  try {
    c = treestereo::load_calibration(spec);
  } catch (const treestereo::CalibrationError &) {
    return 0; // the expected answer to a bad file
  } catch (const std::exception &e) {
    // Acceptable (no crash), but a person gets a less helpful message than a CalibrationError
    // would give: TREESTEREO_FUZZ_STRICT=1 stops on it so it can be found and fixed.
    if (std::getenv("TREESTEREO_FUZZ_STRICT")) {
      std::fprintf(stderr, "not a CalibrationError: %s\n", e.what());
      std::abort();
    }
    return 0;
  }
  try {
    check_round_trip(c);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "an accepted calibration fails save + load: %s\n", e.what());
    std::abort();
  }
  return 0;
}
