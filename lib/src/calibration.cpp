// Reading, writing, checking and scaling stereo calibrations.
#include "treestereo/calibration.hpp"

#include <opencv2/core.hpp>

#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace treestereo {

CalibrationError::CalibrationError(std::string file, std::string key, const std::string &problem)
    : std::runtime_error(file + (key.empty() ? std::string() : ": " + key) + ": " + problem),
      file_(std::move(file)), key_(std::move(key))
{
}

double StereoCalibration::baseline_mm() const
{
  return T.empty() ? 0.0 : cv::norm(T);
}

namespace {

// Tolerances for "is a rotation": files written by hand or by MATLAB carry 4-6 digits.
constexpr double kRotationTolerance = 1e-3;
// Below this the rig has no baseline worth the name (mm).
constexpr double kMinBaselineMm = 1e-3;
constexpr int kMaxImageSide = 32768; // larger than any camera sensor: a typo or a corrupt file

std::string lower(std::string s)
{
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

bool ends_with(const std::string &s, const std::string &suffix)
{
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string trim(const std::string &s)
{
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos)
    return {};
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

// Calibration files are a few kB; a larger one (or a gzip bomb) is something else.
constexpr std::size_t kMaxCalibrationBytes = std::size_t(16) << 20;

// Reads the file (decompressed when it ends in .gz). It must exist and be readable, and must not
// be some other kind of file: FileStorage's own error for a PNG ("input file is invalid") would
// not tell the person what went wrong.
std::string read_checked(const std::string &file)
{
  // An ifstream opens a directory without complaint and then reads nothing, which would be
  // reported as "file is empty".
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec))
    throw CalibrationError(file, "", "is a directory, not a calibration file");
  std::string text;
  if (ends_with(lower(file), ".gz")) {
    // Decompressed here (zlib reads an uncompressed file as it is, as OpenCV does), so that a
    // compressed file gets the same checks as a plain one before OpenCV's parser sees it.
    gzFile gz = gzopen(file.c_str(), "rb");
    if (!gz)
      throw CalibrationError(file, "", "file is missing or cannot be read");
    char buf[16384];
    int n = 0;
    while ((n = gzread(gz, buf, sizeof buf)) > 0 && text.size() <= kMaxCalibrationBytes)
      text.append(buf, std::size_t(n));
    int err = Z_OK;
    const std::string zmsg = gzerror(gz, &err); // a truncated stream ends "at EOF" with an error
    gzclose(gz);
    if (n < 0 || (err != Z_OK && err != Z_STREAM_END))
      throw CalibrationError(file, "", "not a valid gzip file (" + zmsg + ")");
  } else {
    std::ifstream in(file, std::ios::binary);
    if (!in)
      throw CalibrationError(file, "", "file is missing or cannot be read");
    std::ostringstream buf;
    buf << in.rdbuf();
    text = buf.str();
  }
  if (text.size() > kMaxCalibrationBytes)
    throw CalibrationError(file, "", "larger than 16 MiB: not a calibration file");
  if (text.empty())
    throw CalibrationError(file, "", "file is empty: expected an OpenCV YAML/XML calibration");
  if (text.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0 || text.compare(0, 3, "\xff\xd8\xff") == 0)
    throw CalibrationError(file, "", "this is an image, not a calibration file (expected OpenCV "
                                     "YAML/XML with M1 D1 M2 D2 R T, or 'left.yaml;right.yaml')");
  if (text.find('\0') != std::string::npos)
    throw CalibrationError(file, "", "binary file, not a calibration (expected OpenCV YAML/XML)");
  return text;
}

// OpenCV's YAML reader insists on its "%YAML:1.0" first line, which ROS camera_info files (and
// YAML written by other tools) do not have: give it one, dropping any other YAML directive.
std::string with_opencv_yaml_header(const std::string &text)
{
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first == std::string::npos || text[first] == '<' || text.compare(first, 6, "%YAML:") == 0)
    return text;
  std::string body = text.substr(first);
  if (body.compare(0, 5, "%YAML") == 0) {
    const auto eol = body.find('\n');
    body = eol == std::string::npos ? std::string() : body.substr(eol + 1);
  }
  return "%YAML:1.0\n" + body;
}

// OpenCV 4.6's own YAML parser loops forever on some malformed text, so YAML is checked here
// before it reaches the parser, and text with either of these problems is refused (XML and
// JSON are left to OpenCV). Returns what is wrong with the first bad line ("line N ..."), or
// an empty string.
// - Block indentation: a line that dedents must come back to the column of an enclosing level
//   (fuzz-calibration's first find: "%YAML:1.0\n   rows: 1\n A---\nx", a dedent to a column
//   between two levels).
// - The top level: a calibration file's root is a map, so every line at column 0 is a key
//   ("name:" or "name: value"), the document marker "---" or "...", a comment, or the leading
//   %YAML directive (its second find: "%YAML:1.0\n----~\n~\n-"), and the first such line comes
//   before any indented one (a root indented to column k ends at the first line left of k, and
//   the parser's document loop then hangs on what follows, as on "    - 1\na:\n  - a: 1").
// - One document: after a line starting "..." at column 0 (the document's end) only blank lines
//   and comments may follow (its third find: "a: 1\n...\n  - 1", an indented "-" after the end);
//   "---" (the document's start) stands alone on its line, at most once, before the first key
//   (fuzzing's next find: "--- - x\n--- -x\n--- --- d", a "---" with text after it, repeated).
//   This holds for flow-style ({...}) text too, which OpenCV reads with the same parser.
std::string yaml_problem(const std::string &text)
{
  const std::size_t first = text.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && text[first] == '<')
    return "";
  const bool flow = first != std::string::npos && text[first] == '{';
  std::vector<std::size_t> levels{0};
  std::size_t line_no = 0, end_line = 0;
  // seen_content: any line but blanks and comments; seen_body: any but those, the directive
  // and '---'; seen_key: a top-level key
  bool seen_content = false, seen_body = false, seen_key = false, seen_marker = false;
  for (std::size_t pos = 0; pos <= text.size();) {
    const std::size_t end = std::min(text.find('\n', pos), text.size());
    ++line_no;
    std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t'))
      line.pop_back();
    const std::size_t indent = line.find_first_not_of(' ');
    if (indent == std::string::npos || line[indent] == '#')
      continue; // blank or a comment
    if (end_line > 0)
      return "line " + std::to_string(line_no) + " follows the end of the document ('...' on line " +
             std::to_string(end_line) + "): a calibration file holds one YAML document";
    if (line.compare(0, 3, "...") == 0) {
      end_line = line_no;
      const std::size_t rest = line.find_first_not_of(' ', 3);
      if (rest != std::string::npos && line[rest] != '#')
        return "line " + std::to_string(line_no) + " has text after the document's end '...'";
      continue;
    }
    if (line.compare(0, 3, "---") == 0) {
      const std::size_t rest = line.find_first_not_of(' ', 3);
      if (seen_marker || seen_body)
        return "line " + std::to_string(line_no) +
               " starts a second YAML document: a calibration file holds one";
      if (rest != std::string::npos && line[rest] != '#')
        return "line " + std::to_string(line_no) + " has text after the document marker '---'";
      seen_marker = true;
      continue;
    }
    const bool directive = !seen_content && indent == 0 && line[0] == '%';
    seen_content = true;
    if (directive)
      continue;
    seen_body = true;
    if (flow)
      continue; // a flow collection's lines may be indented any way
    if (indent > levels.back()) {
      levels.push_back(indent);
    } else {
      while (levels.back() > indent)
        levels.pop_back();
      if (levels.back() != indent)
        return "line " + std::to_string(line_no) + " is indented to a column no enclosing line has";
    }
    if (indent > 0) {
      if (!seen_key)
        return "line " + std::to_string(line_no) +
               " is indented, but a calibration file's top level starts at column 0";
      continue; // inside a key's value
    }
    const unsigned char c = static_cast<unsigned char>(line[0]);
    const std::size_t colon = line.find(':');
    const bool key = (std::isalpha(c) || c == '_' || c == '"' || c == '\'') &&
                     colon != std::string::npos &&
                     (colon + 1 == line.size() || line[colon + 1] == ' ');
    if (!key)
      return "line " + std::to_string(line_no) +
             " starts at column 0 but is no key: a calibration file's top level is a map of "
             "'name: value' lines";
    seen_key = true;
  }
  return "";
}

// Opens a FileStorage for reading; a syntax error becomes a CalibrationError naming the file.
cv::FileStorage open_for_reading(const std::string &file)
{
  const std::string text = read_checked(file);
  if (const std::string bad = yaml_problem(text); !bad.empty())
    throw CalibrationError(file, "", "not a valid OpenCV YAML/XML file (" + bad + ")");
  cv::FileStorage fs;
  try {
    fs.open(with_opencv_yaml_header(text), cv::FileStorage::READ | cv::FileStorage::MEMORY);
  } catch (const cv::Exception &e) {
    throw CalibrationError(file, "", "not a valid OpenCV YAML/XML file (" + trim(e.err) + ")");
  }
  if (!fs.isOpened())
    throw CalibrationError(file, "", "cannot be parsed as an OpenCV YAML/XML file");
  if (fs.root().empty() || !fs.root().isMap())
    throw CalibrationError(file, "", "holds no keys: not a calibration file");
  return fs;
}

// OpenCV's reader allocates rows x cols from the file before it counts the data, so a corrupt
// size asks for gigabytes (found by fuzzing: "cols: `3" read as a huge number). Calibration
// matrices are small: check the header first.
constexpr int kMaxMatrixSide = 16;

void check_matrix_node(const cv::FileNode &node, const std::string &file, const std::string &key)
{
  if (!node.isMap() || !node["rows"].isInt() || !node["cols"].isInt() || !node["data"].isSeq())
    throw CalibrationError(file, key, "is not an opencv-matrix (expected integer rows and cols, "
                                      "dt, and a data list)");
  const int rows = static_cast<int>(node["rows"]), cols = static_cast<int>(node["cols"]);
  if (rows < 1 || cols < 1 || rows > kMaxMatrixSide || cols > kMaxMatrixSide)
    throw CalibrationError(file, key, "is " + std::to_string(rows) + "x" + std::to_string(cols) +
                                          ": a calibration matrix has 1 to " +
                                          std::to_string(kMaxMatrixSide) + " rows and columns");
  const std::size_t n = node["data"].size();
  if (n % (static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols)) != 0 || n == 0)
    throw CalibrationError(file, key, "rows x cols = " + std::to_string(rows) + "x" +
                                          std::to_string(cols) + " but data has " +
                                          std::to_string(n) + " values");
}

// Reads an opencv-matrix node as CV_64F. Missing key: empty Mat when optional, else an error.
cv::Mat read_matrix(const cv::FileStorage &fs, const std::string &file, const std::string &key,
                    bool required)
{
  const cv::FileNode node = fs[key];
  if (node.empty() || node.isNone()) {
    if (required)
      throw CalibrationError(file, key, "missing key");
    return {};
  }
  check_matrix_node(node, file, key);
  cv::Mat m;
  try {
    node >> m;
  } catch (const cv::Exception &e) {
    throw CalibrationError(file, key, "is not a matrix (" + trim(e.err) + ")");
  }
  if (m.empty())
    throw CalibrationError(file, key, "is not an opencv-matrix (expected rows, cols, dt, data)");
  if (m.channels() != 1)
    throw CalibrationError(file, key, "has " + std::to_string(m.channels()) +
                                          " channels, expected a single-channel matrix");
  cv::Mat d;
  m.convertTo(d, CV_64F);
  return d;
}

// A count or size read as a double: converting an out-of-range or NaN double to int is
// undefined behaviour, so such values are refused first (found by fuzzing).
int checked_int(double v, const std::string &file, const std::string &key)
{
  if (!(v >= -1e9 && v <= 1e9))
    throw CalibrationError(file, key, "value out of range (|value| must be below 1e9)");
  return static_cast<int>(v);
}

int read_int(const cv::FileStorage &fs, const std::string &file, const std::string &key)
{
  const cv::FileNode node = fs[key];
  if (node.empty() || node.isNone())
    return 0;
  if (!node.isInt() && !node.isReal())
    throw CalibrationError(file, key, "must be a number");
  return checked_int(node.real(), file, key);
}

// image_width/image_height, or an empty size when both are absent.
cv::Size read_image_size(const cv::FileStorage &fs, const std::string &file)
{
  return {read_int(fs, file, "image_width"), read_int(fs, file, "image_height")};
}

bool has_key(const cv::FileStorage &fs, const std::string &key)
{
  const cv::FileNode n = fs[key];
  return !n.empty() && !n.isNone();
}

void read_intrinsics(const cv::FileStorage &fs, const std::string &file, StereoCalibration &c)
{
  c.M1 = read_matrix(fs, file, "M1", true);
  c.D1 = read_matrix(fs, file, "D1", true);
  c.M2 = read_matrix(fs, file, "M2", true);
  c.D2 = read_matrix(fs, file, "D2", true);
}

void read_extrinsics(const cv::FileStorage &fs, const std::string &file, StereoCalibration &c)
{
  c.R = read_matrix(fs, file, "R", true);
  c.T = read_matrix(fs, file, "T", true);
  c.R1 = read_matrix(fs, file, "R1", false);
  c.R2 = read_matrix(fs, file, "R2", false);
  c.P1 = read_matrix(fs, file, "P1", false);
  c.P2 = read_matrix(fs, file, "P2", false);
  c.Q = read_matrix(fs, file, "Q", false);
}

void read_pixel_size(const cv::FileStorage &fs, const std::string &file, StereoCalibration &c)
{
  const cv::FileNode n = fs["pixel_size_um"];
  if (n.empty() || n.isNone())
    return;
  if (!n.isReal() && !n.isInt())
    throw CalibrationError(file, "pixel_size_um", "must be a number (micrometres)");
  c.pixel_size_um = n.real();
}

StereoCalibration load_opencv(const std::string &file)
{
  cv::FileStorage fs = open_for_reading(file);
  StereoCalibration c;
  read_intrinsics(fs, file, c);
  read_extrinsics(fs, file, c);
  read_pixel_size(fs, file, c);
  c.image_size = read_image_size(fs, file);
  validate_calibration(c, file);
  return c;
}

// OpenCV's stereo_calib sample writes intrinsics.yml (M1 D1 M2 D2) and extrinsics.yml
// (R T R1 R2 P1 P2 Q), neither with the image size: take it from whichever file has it.
StereoCalibration load_opencv_split(const std::string &intr_file, const std::string &extr_file)
{
  cv::FileStorage fi = open_for_reading(intr_file);
  cv::FileStorage fe = open_for_reading(extr_file);
  StereoCalibration c;
  read_intrinsics(fi, intr_file, c);
  read_extrinsics(fe, extr_file, c);
  read_pixel_size(fi, intr_file, c);
  c.image_size = read_image_size(fi, intr_file);
  if ((c.image_size.width == 0 || c.image_size.height == 0) &&
      (has_key(fe, "image_width") || has_key(fe, "image_height")))
    c.image_size = read_image_size(fe, extr_file);
  validate_calibration(c, intr_file + ";" + extr_file);
  return c;
}

// ROS camera_info stores matrices as {rows, cols, data: [...]}.
cv::Mat read_ros_matrix(const cv::FileStorage &fs, const std::string &file, const std::string &key,
                        int rows, int cols)
{
  const cv::FileNode node = fs[key];
  if (node.empty() || node.isNone())
    throw CalibrationError(file, key, "missing key");
  if (!node.isMap() || node["data"].empty())
    throw CalibrationError(file, key, "expected a ROS matrix {rows, cols, data}");
  const int r = node["rows"].empty() ? rows : checked_int(node["rows"].real(), file, key + ".rows");
  const int k = node["cols"].empty() ? cols : checked_int(node["cols"].real(), file, key + ".cols");
  const cv::FileNode data = node["data"];
  if (!data.isSeq())
    throw CalibrationError(file, key, "data must be a list of numbers");
  std::vector<double> v;
  for (const cv::FileNode &e : data) {
    if (!e.isReal() && !e.isInt())
      throw CalibrationError(file, key, "data must hold numbers only");
    v.push_back(e.real());
  }
  if (r <= 0 || k <= 0 || static_cast<std::size_t>(r) * static_cast<std::size_t>(k) != v.size())
    throw CalibrationError(file, key, "rows x cols = " + std::to_string(r) + "x" +
                                          std::to_string(k) + " but data has " +
                                          std::to_string(v.size()) + " values");
  // The distortion vector's length varies; every other shape is fixed.
  if (rows > 0 && (r != rows || k != cols))
    throw CalibrationError(file, key, "is " + std::to_string(r) + "x" + std::to_string(k) +
                                          ", expected " + std::to_string(rows) + "x" +
                                          std::to_string(cols));
  return cv::Mat(v, true).reshape(1, r);
}

struct RosCamera {
  cv::Size size;
  cv::Mat K, D, R, P;
};

RosCamera read_ros_camera(const std::string &file)
{
  cv::FileStorage fs = open_for_reading(file);
  RosCamera cam;
  cam.size = read_image_size(fs, file);
  if (cam.size.width <= 0 || cam.size.height <= 0)
    throw CalibrationError(file, "image_width", "image size missing or not positive "
                                                "(image_width, image_height)");
  cam.K = read_ros_matrix(fs, file, "camera_matrix", 3, 3);
  cam.D = read_ros_matrix(fs, file, "distortion_coefficients", 0, 0).reshape(1, 1);
  cam.R = read_ros_matrix(fs, file, "rectification_matrix", 3, 3);
  cam.P = read_ros_matrix(fs, file, "projection_matrix", 3, 4);
  return cam;
}

// ROS conventions (sensor_msgs/CameraInfo): R_i rotates camera i's frame into the rectified
// frame i; both rectified frames are parallel and the rectified right origin sits at (B,0,0) in
// the rectified-left frame; P_right[0,3] = Tx = -fx' * B with B in metres. Hence
//   X_right = R2^T (R1 X_left - (B,0,0))  =>  R = R2^T R1,  T = R2^T (-B, 0, 0).
// P1/P2 keep their pixels; the Tx column is turned into px*mm like OpenCV's stereoRectify.
StereoCalibration load_ros_pair(const std::string &left_file, const std::string &right_file)
{
  const RosCamera l = read_ros_camera(left_file);
  const RosCamera r = read_ros_camera(right_file);
  if (l.size != r.size)
    throw CalibrationError(right_file, "image_width",
                           "image size " + std::to_string(r.size.width) + "x" +
                               std::to_string(r.size.height) + " differs from the left's " +
                               std::to_string(l.size.width) + "x" + std::to_string(l.size.height));
  if (l.P.at<double>(0, 3) != 0.0)
    throw CalibrationError(left_file, "projection_matrix",
                           "P[0,3] (Tx) is not zero, so this is not the left camera; "
                           "are the files swapped? give 'left.yaml;right.yaml'");
  const double fx_rect = r.P.at<double>(0, 0);
  const double tx = r.P.at<double>(0, 3);
  if (!(std::abs(fx_rect) > 0) || !std::isfinite(tx))
    throw CalibrationError(right_file, "projection_matrix", "P[0,0] must be a non-zero focal length");
  if (tx > 0)
    throw CalibrationError(right_file, "projection_matrix",
                           "P[0,3] (Tx) is positive: this camera is left of the other one; "
                           "are the files swapped? give 'left.yaml;right.yaml'");
  const double baseline_mm = -tx / fx_rect * 1000.0;
  if (!(baseline_mm >= kMinBaselineMm))
    throw CalibrationError(right_file, "projection_matrix",
                           "P[0,3] (Tx) is zero: this file holds no baseline; the right "
                           "camera's camera_info must carry Tx = -fx * baseline");

  StereoCalibration c;
  c.image_size = l.size;
  c.M1 = l.K;
  c.D1 = l.D;
  c.M2 = r.K;
  c.D2 = r.D;
  c.R1 = l.R;
  c.R2 = r.R;
  c.R = r.R.t() * l.R;
  c.T = r.R.t() * (cv::Mat_<double>(3, 1) << -baseline_mm, 0.0, 0.0);
  c.P1 = l.P.clone();
  c.P2 = r.P.clone();
  c.P1.at<double>(0, 3) *= 1000.0;
  c.P1.at<double>(1, 3) *= 1000.0;
  c.P2.at<double>(0, 3) *= 1000.0;
  c.P2.at<double>(1, 3) *= 1000.0;
  c.Q = cv::Mat(disparity_to_depth(c.P1, c.P2));
  validate_calibration(c, left_file + ";" + right_file);
  return c;
}

void check_shape(const cv::Mat &m, const std::string &source, const std::string &key, int rows,
                 int cols)
{
  if (m.rows != rows || m.cols != cols)
    throw CalibrationError(source, key, "wrong shape " + std::to_string(m.rows) + "x" +
                                            std::to_string(m.cols) + ", expected " +
                                            std::to_string(rows) + "x" + std::to_string(cols));
}

void check_finite(const cv::Mat &m, const std::string &source, const std::string &key)
{
  if (!cv::checkRange(m))
    throw CalibrationError(source, key, "holds a non-finite value (NaN or inf)");
}

void check_distortion(const cv::Mat &d, const std::string &source, const std::string &key)
{
  const int n = static_cast<int>(d.total());
  const bool vector = d.rows == 1 || d.cols == 1;
  if (!vector || (n != 4 && n != 5 && n != 8 && n != 12 && n != 14))
    throw CalibrationError(source, key, "wrong shape " + std::to_string(d.rows) + "x" +
                                            std::to_string(d.cols) +
                                            ", expected 1xN with N = 4, 5, 8, 12 or 14");
  check_finite(d, source, key);
}

void check_camera_matrix(const cv::Mat &m, const std::string &source, const std::string &key)
{
  check_shape(m, source, key, 3, 3);
  check_finite(m, source, key);
  if (!(m.at<double>(0, 0) > 0 && m.at<double>(1, 1) > 0))
    throw CalibrationError(source, key, "focal lengths fx, fy must be positive");
}

void check_rotation(const cv::Mat &r, const std::string &source, const std::string &key)
{
  check_shape(r, source, key, 3, 3);
  check_finite(r, source, key);
  const double orth = cv::norm(r.t() * r - cv::Mat::eye(3, 3, CV_64F), cv::NORM_INF);
  const double det = cv::determinant(r);
  if (orth > kRotationTolerance || std::abs(det - 1.0) > kRotationTolerance) {
    std::ostringstream s;
    s << "is not a rotation matrix (max |R^T R - I| = " << orth << ", det = " << det
      << "; expected R^T R = I and det = +1)";
    throw CalibrationError(source, key, s.str());
  }
}

cv::Mat as_column(const cv::Mat &t)
{
  return t.total() == 3 ? t.reshape(1, 3) : t;
}

std::string size_str(cv::Size s)
{
  return std::to_string(s.width) + "x" + std::to_string(s.height);
}

// Resampling maps an old pixel centre u to (u + 0.5) * s - 0.5, i.e. pixels' = A * pixels with
// A = [sx 0 ox; 0 sy oy; 0 0 1]; applied to a camera or projection matrix: M' = A * M.
void scale_projection(cv::Mat &m, double sx, double sy)
{
  if (m.empty())
    return;
  const double ox = 0.5 * sx - 0.5, oy = 0.5 * sy - 0.5;
  const cv::Mat a = (cv::Mat_<double>(3, 3) << sx, 0, ox, 0, sy, oy, 0, 0, 1);
  // A new buffer: assigning the product to m would write into data shared with the input.
  m = cv::Mat(a * m).clone();
}

} // namespace

cv::Matx44d disparity_to_depth(const cv::Mat &P1, const cv::Mat &P2)
{
  cv::Mat p1, p2;
  P1.convertTo(p1, CV_64F);
  P2.convertTo(p2, CV_64F);
  const double f = p1.at<double>(0, 0);
  const double tx = p2.at<double>(0, 3) / p2.at<double>(0, 0); // -baseline
  const double cx1 = p1.at<double>(0, 2), cx2 = p2.at<double>(0, 2), cy = p1.at<double>(1, 2);
  return cv::Matx44d(1, 0, 0, -cx1,
                     0, 1, 0, -cy,
                     0, 0, 0, f,
                     0, 0, -1.0 / tx, (cx1 - cx2) / tx);
}

void validate_calibration(const StereoCalibration &c, const std::string &source)
{
  if (c.image_size.width == 0 && c.image_size.height == 0)
    throw CalibrationError(source, "image_width", "image size missing: add image_width and "
                                                  "image_height (the calibration images' size)");
  if (c.image_size.width <= 0 || c.image_size.height <= 0)
    throw CalibrationError(source, "image_width",
                           "image size " + size_str(c.image_size) + " is not positive");
  if (c.image_size.width > kMaxImageSide || c.image_size.height > kMaxImageSide)
    throw CalibrationError(source, "image_width",
                           "image size " + size_str(c.image_size) + " is larger than " +
                               std::to_string(kMaxImageSide) +
                               " px on a side: no camera's (check image_width and image_height)");
  check_camera_matrix(c.M1, source, "M1");
  check_distortion(c.D1, source, "D1");
  check_camera_matrix(c.M2, source, "M2");
  check_distortion(c.D2, source, "D2");
  check_rotation(c.R, source, "R");
  if (c.T.total() != 3 || (c.T.rows != 1 && c.T.cols != 1))
    throw CalibrationError(source, "T", "wrong shape " + std::to_string(c.T.rows) + "x" +
                                            std::to_string(c.T.cols) + ", expected 3x1");
  check_finite(c.T, source, "T");
  if (!(c.baseline_mm() >= kMinBaselineMm))
    throw CalibrationError(source, "T", "zero baseline: the two cameras are at the same place");
  if (!c.R1.empty())
    check_rotation(c.R1, source, "R1");
  if (!c.R2.empty())
    check_rotation(c.R2, source, "R2");
  for (const auto &[m, key] : {std::pair<const cv::Mat &, const char *>{c.P1, "P1"},
                               std::pair<const cv::Mat &, const char *>{c.P2, "P2"}}) {
    if (m.empty())
      continue;
    check_shape(m, source, key, 3, 4);
    check_finite(m, source, key);
  }
  if (!c.Q.empty()) {
    check_shape(c.Q, source, "Q", 4, 4);
    check_finite(c.Q, source, "Q");
  }
  if (c.R1.empty() != c.P1.empty() || c.R2.empty() != c.P2.empty() || c.P1.empty() != c.P2.empty())
    throw CalibrationError(source, c.P1.empty() ? "P1" : "P2",
                           "rectification is incomplete: give all of R1 R2 P1 P2 or none");
  if (!c.P2.empty() && !(std::abs(c.P2.at<double>(0, 3)) > 0))
    throw CalibrationError(source, "P2", "P2[0,3] is zero: the rectified pair has no baseline");
  if (!std::isfinite(c.pixel_size_um) || c.pixel_size_um < 0)
    throw CalibrationError(source, "pixel_size_um", "must be a positive number (or absent)");
}

StereoCalibration load_calibration(const std::string &spec)
{
  const auto semi = spec.find(';');
  if (semi == std::string::npos)
    return load_opencv(trim(spec));
  const std::string first = trim(spec.substr(0, semi));
  const std::string second = trim(spec.substr(semi + 1));
  if (first.empty() || second.empty() || second.find(';') != std::string::npos)
    throw CalibrationError(spec, "", "expected two files separated by one ';' "
                                     "(\"left.yaml;right.yaml\" or \"intrinsics.yml;extrinsics.yml\")");
  cv::FileStorage probe = open_for_reading(first);
  const bool opencv_split = has_key(probe, "M1");
  probe.release();
  return opencv_split ? load_opencv_split(first, second) : load_ros_pair(first, second);
}

void save_calibration(const StereoCalibration &c, const std::string &path)
{
  std::string ext = lower(path);
  if (ends_with(ext, ".gz"))
    ext.resize(ext.size() - 3);
  if (!ends_with(ext, ".yml") && !ends_with(ext, ".yaml") && !ends_with(ext, ".xml"))
    throw CalibrationError(path, "", "unknown extension: use .yml, .yaml or .xml");
  validate_calibration(c, path);
  cv::FileStorage fs;
  try {
    fs.open(path, cv::FileStorage::WRITE);
  } catch (const cv::Exception &e) {
    throw CalibrationError(path, "", "cannot be written (" + trim(e.err) + ")");
  }
  if (!fs.isOpened())
    throw CalibrationError(path, "", "cannot be opened for writing");
  fs << "image_width" << c.image_size.width << "image_height" << c.image_size.height;
  fs << "M1" << c.M1 << "D1" << c.D1 << "M2" << c.M2 << "D2" << c.D2;
  fs << "R" << c.R << "T" << as_column(c.T);
  if (!c.R1.empty())
    fs << "R1" << c.R1 << "R2" << c.R2 << "P1" << c.P1 << "P2" << c.P2;
  if (!c.Q.empty())
    fs << "Q" << c.Q;
  if (c.pixel_size_um > 0)
    fs << "pixel_size_um" << c.pixel_size_um;
  fs.release();
}

StereoCalibration scale_calibration(const StereoCalibration &calib, cv::Size new_size,
                                    const std::string &source)
{
  const cv::Size old = calib.image_size;
  if (new_size == old)
    return calib;
  if (old.width <= 0 || old.height <= 0 || new_size.width <= 0 || new_size.height <= 0)
    throw CalibrationError(source, "image_width",
                           "cannot scale a calibration for " + size_str(old) + " to " +
                               size_str(new_size));
  const double sx = static_cast<double>(new_size.width) / old.width;
  const double sy = static_cast<double>(new_size.height) / old.height;
  // Same factor within half a pixel on each axis: a crop or a different aspect is not the rig.
  if (std::abs(old.height * sx - new_size.height) > 0.5 ||
      std::abs(old.width * sy - new_size.width) > 0.5)
    throw CalibrationError(source, "image_width",
                           "calibration is for " + size_str(old) + " but the stream is " +
                               size_str(new_size) + ": not a pure scale");
  StereoCalibration c = calib;
  c.image_size = new_size;
  for (cv::Mat *m : {&c.M1, &c.M2, &c.P1, &c.P2}) {
    scale_projection(*m, sx, sy);
  }
  if (!c.P1.empty())
    c.Q = cv::Mat(disparity_to_depth(c.P1, c.P2));
  if (c.pixel_size_um > 0)
    c.pixel_size_um /= sx; // a binned pixel is larger
  return c;
}

} // namespace treestereo
