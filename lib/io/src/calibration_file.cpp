// Reading and writing stereo calibration files: OpenCV FileStorage (YAML/XML, optionally .gz),
// OpenCV's stereo_calib pair and ROS camera_info pairs, read with document.cpp's strict reader.
#include "treestereo/calibration_file.hpp"

#include "document.hpp"

#include <opencv2/core.hpp>

#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace treestereo {

namespace {

using detail::DocNode;

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

// Calibration files are a few kB; a larger one (or a gzip bomb) is something else.
constexpr std::size_t kMaxCalibrationBytes = std::size_t(16) << 20;

// Reads the file (decompressed when it ends in .gz). It must exist and be readable, and must not
// be some other kind of file: a syntax error about a PNG's first line would not tell the person
// what went wrong.
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
      throw CalibrationError(file, "", "file is missing or cannot be read", FileAccess::Read);
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
      throw CalibrationError(file, "", "file is missing or cannot be read", FileAccess::Read);
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

// The file's document: XML when it starts with '<', else YAML. Read by lib's own strict reader
// (document.hpp), never by OpenCV's parser, which hangs or crashes on some malformed text.
DocNode open_document(const std::string &file)
{
  const std::string content = read_checked(file);
  std::string_view text = content;
  if (text.compare(0, 3, "\xef\xbb\xbf") == 0) // a UTF-8 byte order mark
    text.remove_prefix(3);
  DocNode root;
  try {
    const auto first = text.find_first_not_of(" \t\r\n");
    root = first != text.npos && text[first] == '<' ? detail::parse_xml(text)
                                                    : detail::parse_yaml(text);
  } catch (const detail::DocError &e) {
    throw CalibrationError(file, "",
                           std::string("not a valid OpenCV YAML/XML file (") + e.what() + ")");
  }
  if (!root.is_map() || root.fields.empty())
    throw CalibrationError(file, "", "holds no keys: not a calibration file");
  return root;
}

// The key's node, or nullptr when it is absent or has no value.
const DocNode *value_of(const DocNode &map, const std::string &key)
{
  const DocNode *n = map.find(key);
  return n && !n->is_null() ? n : nullptr;
}

// A count or size read as a double: converting an out-of-range or NaN double to int is
// undefined behaviour, so such values are refused first (found by fuzzing).
int checked_int(double v, const std::string &file, const std::string &key)
{
  if (!(v >= -1e9 && v <= 1e9))
    throw CalibrationError(file, key, "value out of range (|value| must be below 1e9)");
  return static_cast<int>(v);
}

double number_of(const DocNode &n, const std::string &file, const std::string &key)
{
  if (!n.is_number())
    throw CalibrationError(file, key, "must be a number");
  return n.number();
}

// A matrix's data: a list of numbers (in XML a single value stands alone).
std::vector<double> read_numbers(const DocNode &data, const std::string &file,
                                 const std::string &key)
{
  if (!data.is_seq() && data.kind != DocNode::Kind::Scalar)
    throw CalibrationError(file, key, "data must be a list of numbers");
  std::vector<double> v;
  const auto add = [&](const DocNode &e) {
    if (!e.is_number())
      throw CalibrationError(file, key, "data must hold numbers only");
    v.push_back(e.number());
  };
  if (data.is_seq())
    std::for_each(data.items.begin(), data.items.end(), add);
  else
    add(data);
  return v;
}

void check_count(std::size_t n, int rows, int cols, const std::string &file, const std::string &key)
{
  if (rows <= 0 || cols <= 0 ||
      n != static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols))
    throw CalibrationError(file, key, "rows x cols = " + std::to_string(rows) + "x" +
                                          std::to_string(cols) + " but data has " +
                                          std::to_string(n) + " values");
}

// Calibration matrices are small: a larger side is a corrupt file (fuzzing found "cols: `3"
// read as a huge number, for which OpenCV's reader allocated gigabytes).
constexpr int kMaxMatrixSide = 16;

// Reads an opencv-matrix {rows, cols, dt, data} as CV_64F. Missing key: an empty Mat when
// optional, else an error.
cv::Mat read_matrix(const DocNode &root, const std::string &file, const std::string &key,
                    bool required)
{
  const DocNode *node = value_of(root, key);
  if (!node) {
    if (required)
      throw CalibrationError(file, key, "missing key");
    return {};
  }
  const DocNode *rows = node->find("rows"), *cols = node->find("cols"), *dt = node->find("dt"),
                *data = node->find("data");
  if (!node->is_map() || !rows || !rows->is_integer() || !cols || !cols->is_integer() || !dt ||
      dt->kind != DocNode::Kind::Scalar || !data)
    throw CalibrationError(file, key, "is not an opencv-matrix (expected integer rows and cols, "
                                      "dt, and a data list)");
  const int r = checked_int(rows->number(), file, key), c = checked_int(cols->number(), file, key);
  if (r < 1 || c < 1 || r > kMaxMatrixSide || c > kMaxMatrixSide)
    throw CalibrationError(file, key, "is " + std::to_string(r) + "x" + std::to_string(c) +
                                          ": a calibration matrix has 1 to " +
                                          std::to_string(kMaxMatrixSide) + " rows and columns");
  // dt: OpenCV's element type, an optional channel count and one of u c w s i f d h.
  const std::string &type = dt->text;
  const std::size_t letter = type.find_first_not_of("0123456789");
  if (letter == std::string::npos || letter + 1 != type.size() || letter > 3 ||
      std::string_view("ucwsifdh").find(type[letter]) == std::string_view::npos)
    throw CalibrationError(file, key,
                           "has dt '" + type + "': expected an element type such as d or f");
  const int channels = letter == 0 ? 1 : std::stoi(type.substr(0, letter));
  if (channels != 1)
    throw CalibrationError(file, key, "has " + std::to_string(channels) +
                                          " channels, expected a single-channel matrix");
  const std::vector<double> v = read_numbers(*data, file, key);
  check_count(v.size(), r, c, file, key);
  return cv::Mat(v, true).reshape(1, r);
}

int read_int(const DocNode &root, const std::string &file, const std::string &key)
{
  const DocNode *node = value_of(root, key);
  return node ? checked_int(number_of(*node, file, key), file, key) : 0;
}

// image_width/image_height, or an empty size when both are absent.
cv::Size read_image_size(const DocNode &root, const std::string &file)
{
  return {read_int(root, file, "image_width"), read_int(root, file, "image_height")};
}

bool has_key(const DocNode &root, const std::string &key)
{
  return value_of(root, key) != nullptr;
}

void read_intrinsics(const DocNode &root, const std::string &file, StereoCalibration &c)
{
  c.M1 = read_matrix(root, file, "M1", true);
  c.D1 = read_matrix(root, file, "D1", true);
  c.M2 = read_matrix(root, file, "M2", true);
  c.D2 = read_matrix(root, file, "D2", true);
}

void read_extrinsics(const DocNode &root, const std::string &file, StereoCalibration &c)
{
  c.R = read_matrix(root, file, "R", true);
  c.T = read_matrix(root, file, "T", true);
  c.R1 = read_matrix(root, file, "R1", false);
  c.R2 = read_matrix(root, file, "R2", false);
  c.P1 = read_matrix(root, file, "P1", false);
  c.P2 = read_matrix(root, file, "P2", false);
  c.Q = read_matrix(root, file, "Q", false);
}

void read_pixel_size(const DocNode &root, const std::string &file, StereoCalibration &c)
{
  if (const DocNode *n = value_of(root, "pixel_size_um")) {
    if (!n->is_number())
      throw CalibrationError(file, "pixel_size_um", "must be a number (micrometres)");
    c.pixel_size_um = n->number();
  }
}

StereoCalibration load_opencv(const std::string &file)
{
  const DocNode doc = open_document(file);
  StereoCalibration c;
  read_intrinsics(doc, file, c);
  read_extrinsics(doc, file, c);
  read_pixel_size(doc, file, c);
  c.image_size = read_image_size(doc, file);
  validate_calibration(c, file);
  return c;
}

// OpenCV's stereo_calib sample writes intrinsics.yml (M1 D1 M2 D2) and extrinsics.yml
// (R T R1 R2 P1 P2 Q), neither with the image size: take it from whichever file has it.
StereoCalibration load_opencv_split(const std::string &intr_file, const std::string &extr_file)
{
  const DocNode fi = open_document(intr_file);
  const DocNode fe = open_document(extr_file);
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
cv::Mat read_ros_matrix(const DocNode &root, const std::string &file, const std::string &key,
                        int rows, int cols)
{
  const DocNode *node = value_of(root, key);
  if (!node)
    throw CalibrationError(file, key, "missing key");
  const DocNode *data = node->find("data");
  if (!node->is_map() || !data || data->is_null())
    throw CalibrationError(file, key, "expected a ROS matrix {rows, cols, data}");
  const auto count = [&](const char *name, int otherwise) {
    const DocNode *n = value_of(*node, name);
    return n ? checked_int(number_of(*n, file, key + "." + name), file, key + "." + name)
             : otherwise;
  };
  const int r = count("rows", rows), k = count("cols", cols);
  if (!data->is_seq())
    throw CalibrationError(file, key, "data must be a list of numbers");
  const std::vector<double> v = read_numbers(*data, file, key);
  check_count(v.size(), r, k, file, key);
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
  const DocNode doc = open_document(file);
  RosCamera cam;
  cam.size = read_image_size(doc, file);
  if (cam.size.width <= 0 || cam.size.height <= 0)
    throw CalibrationError(file, "image_width", "image size missing or not positive "
                                                "(image_width, image_height)");
  cam.K = read_ros_matrix(doc, file, "camera_matrix", 3, 3);
  cam.D = read_ros_matrix(doc, file, "distortion_coefficients", 0, 0).reshape(1, 1);
  cam.R = read_ros_matrix(doc, file, "rectification_matrix", 3, 3);
  cam.P = read_ros_matrix(doc, file, "projection_matrix", 3, 4);
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

cv::Mat as_column(const cv::Mat &t)
{
  return t.total() == 3 ? t.reshape(1, 3) : t;
}

} // namespace

StereoCalibration load_calibration(const std::string &spec)
{
  const auto semi = spec.find(';');
  if (semi == std::string::npos)
    return load_opencv(std::string(detail::trim(spec)));
  const std::string first(detail::trim(std::string_view(spec).substr(0, semi)));
  const std::string second(detail::trim(std::string_view(spec).substr(semi + 1)));
  if (first.empty() || second.empty() || second.find(';') != std::string::npos)
    throw CalibrationError(spec, "", "expected two files separated by one ';' "
                                     "(\"left.yaml;right.yaml\" or \"intrinsics.yml;extrinsics.yml\")");
  const bool opencv_split = has_key(open_document(first), "M1");
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
    throw CalibrationError(path, "",
                           "cannot be written (" + std::string(detail::trim(e.err)) + ")",
                           FileAccess::Write);
  }
  if (!fs.isOpened())
    throw CalibrationError(path, "", "cannot be opened for writing", FileAccess::Write);
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

} // namespace treestereo
