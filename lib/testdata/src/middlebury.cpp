#include "treestereo/middlebury.hpp"

#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

namespace treestereo {

namespace {

bool host_is_little_endian()
{
  const std::uint16_t one = 1;
  std::uint8_t b;
  std::memcpy(&b, &one, 1);
  return b == 1;
}

std::runtime_error pfm_error(const std::string &path, const std::string &what)
{
  return std::runtime_error("PFM '" + path + "': " + what);
}

// "[a b c; d e f; g h i]"
cv::Matx33d parse_matrix(const std::string &text, const std::string &key, const std::string &path)
{
  std::string t = text;
  for (char &c : t)
    if (c == '[' || c == ']' || c == ';')
      c = ' ';
  std::istringstream in(t);
  cv::Matx33d m;
  for (int i = 0; i < 9; ++i)
    if (!(in >> m.val[i]))
      throw std::runtime_error("calib '" + path + "': " + key + " needs 9 numbers");
  return m;
}

} // namespace

cv::Mat read_pfm(const std::string &path)
{
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw pfm_error(path, "cannot open the file");
  std::string magic;
  int width = 0, height = 0;
  double scale = 0;
  in >> magic >> width >> height >> scale;
  if (!in || (magic != "Pf" && magic != "PF"))
    throw pfm_error(path, "not a PFM file (expected 'Pf' or 'PF', width, height, scale)");
  if (width <= 0 || height <= 0 || width > 100000 || height > 100000 || scale == 0)
    throw pfm_error(path, "invalid size or scale in the header");
  in.get(); // the single whitespace byte that ends the header
  const int channels = magic == "PF" ? 3 : 1;
  cv::Mat img(height, width, CV_32FC(channels));
  const std::size_t row_bytes = std::size_t(width) * std::size_t(channels) * sizeof(float);
  const bool swap = (scale < 0) != host_is_little_endian();
  for (int y = height - 1; y >= 0; --y) { // stored bottom-to-top
    char *row = img.ptr<char>(y);
    if (!in.read(row, std::streamsize(row_bytes)))
      throw pfm_error(path, "truncated pixel data");
    if (swap)
      for (std::size_t i = 0; i < row_bytes; i += 4) {
        std::swap(row[i], row[i + 3]);
        std::swap(row[i + 1], row[i + 2]);
      }
  }
  return img;
}

StereoGeometry MiddleburyCalib::geometry() const
{
  StereoGeometry g;
  g.view_size = cv::Size(width, height);
  g.fx = cam0(0, 0);
  g.fy = cam0(1, 1);
  g.cx[0] = cam0(0, 2);
  g.cx[1] = cam1(0, 2);
  g.cy = cam0(1, 2);
  g.baseline_mm = baseline_mm;
  // cv::stereoRectify's Q for a horizontal pair with Tx = -baseline.
  g.Q = cv::Matx44d(1, 0, 0, -g.cx[0], 0, 1, 0, -g.cy, 0, 0, 0, g.fx, 0, 0, 1.0 / baseline_mm,
                    -(g.cx[0] - g.cx[1]) / baseline_mm);
  return g;
}

MiddleburyCalib read_middlebury_calib(const std::string &path)
{
  std::ifstream in(path);
  if (!in)
    throw std::runtime_error("calib '" + path + "': cannot open the file");
  std::map<std::string, std::string> kv;
  std::string line;
  while (std::getline(in, line)) {
    const auto eq = line.find('=');
    if (eq != std::string::npos)
      kv[line.substr(0, eq)] = line.substr(eq + 1);
  }
  auto get = [&](const std::string &key) -> const std::string & {
    auto it = kv.find(key);
    if (it == kv.end())
      throw std::runtime_error("calib '" + path + "': missing key '" + key + "'");
    return it->second;
  };
  auto number = [&](const std::string &key) {
    try {
      return std::stod(get(key));
    } catch (const std::logic_error &) {
      throw std::runtime_error("calib '" + path + "': '" + key + "' is not a number");
    }
  };
  MiddleburyCalib c;
  c.cam0 = parse_matrix(get("cam0"), "cam0", path);
  c.cam1 = parse_matrix(get("cam1"), "cam1", path);
  c.doffs = number("doffs");
  c.baseline_mm = number("baseline");
  c.width = int(number("width"));
  c.height = int(number("height"));
  c.ndisp = kv.count("ndisp") ? int(number("ndisp")) : 0;
  if (c.width <= 0 || c.height <= 0 || c.baseline_mm <= 0 || c.cam0(0, 0) <= 0)
    throw std::runtime_error("calib '" + path + "': width, height, baseline and f must be > 0");
  return c;
}

MiddleburyScene load_middlebury_scene(const std::string &dir)
{
  MiddleburyScene s;
  s.left = cv::imread(dir + "/im0.png", cv::IMREAD_COLOR);
  s.right = cv::imread(dir + "/im1.png", cv::IMREAD_COLOR);
  if (s.left.empty() || s.right.empty())
    throw std::runtime_error("Middlebury scene '" + dir + "': cannot read im0.png / im1.png");
  s.calib = read_middlebury_calib(dir + "/calib.txt");
  if (std::ifstream(dir + "/disp0GT.pfm").good()) {
    s.disp_gt = read_pfm(dir + "/disp0GT.pfm");
    if (s.disp_gt.size() != s.left.size() || s.disp_gt.channels() != 1)
      throw std::runtime_error("Middlebury scene '" + dir +
                               "': disp0GT.pfm is not a one-channel map of im0.png's size");
    s.mask_nocc = cv::imread(dir + "/mask0nocc.png", cv::IMREAD_GRAYSCALE);
    if (!s.mask_nocc.empty() && s.mask_nocc.size() != s.left.size())
      throw std::runtime_error("Middlebury scene '" + dir + "': mask0nocc.png has the wrong size");
  }
  return s;
}

MatchAccuracy evaluate_matches(const std::vector<StereoMatch> &matches, const cv::Mat &disp_gt,
                               const cv::Mat &mask_nocc, double tolerance)
{
  if (disp_gt.empty() || disp_gt.type() != CV_32FC1)
    throw std::runtime_error("match evaluation: the ground truth must be a CV_32FC1 disparity");
  if (!mask_nocc.empty() && (mask_nocc.type() != CV_8UC1 || mask_nocc.size() != disp_gt.size()))
    throw std::runtime_error("match evaluation: the mask must be CV_8UC1 of the disparity's size");
  MatchAccuracy acc;
  for (const StereoMatch &m : matches) {
    const int x = int(std::lround(m.xl)), y = int(std::lround(m.yl));
    const bool inside = x >= 0 && y >= 0 && x < disp_gt.cols && y < disp_gt.rows;
    const float gt = inside ? disp_gt.at<float>(y, x) : 0.f;
    if (!inside || !std::isfinite(gt) || (!mask_nocc.empty() && mask_nocc.at<std::uint8_t>(y, x) != 255)) {
      ++acc.unknown;
      continue;
    }
    ++acc.evaluated;
    if (std::abs(double(m.disparity()) - gt) <= tolerance && std::abs(double(m.yr - m.yl)) <= tolerance)
      ++acc.correct;
  }
  return acc;
}

} // namespace treestereo
