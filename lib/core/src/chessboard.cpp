// Chessboard stereo calibration and the rectification check.
#include "treestereo/chessboard.hpp"

#include "treestereo/errors.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <stdexcept>

namespace treestereo {

namespace {

constexpr std::size_t kMinPairs = 3;

cv::Mat to_gray(const cv::Mat &image)
{
  if (image.depth() != CV_8U)
    throw BadInput("A chessboard image is not 8-bit: give 8-bit grey or colour images.",
                   "chessboard: image depth " + std::to_string(image.depth()));
  cv::Mat gray;
  switch (image.channels()) {
  case 1: gray = image; break;
  case 3: cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY); break;
  case 4: cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY); break;
  default:
    throw BadInput("A chessboard image has an unusable number of channels: give grey, BGR or "
                   "BGRA images.",
                   "chessboard: image of " + std::to_string(image.channels()) + " channels");
  }
  return gray;
}

std::vector<cv::Point3f> board_points(cv::Size board, double square)
{
  std::vector<cv::Point3f> pts;
  for (int y = 0; y < board.height; ++y)
    for (int x = 0; x < board.width; ++x)
      pts.emplace_back(static_cast<float>(x * square), static_cast<float>(y * square), 0.0f);
  return pts;
}

// Both views' corners of every pair that has the board in both views of `size` (the first
// usable pair's size when `size` is empty).
struct Detections {
  std::vector<std::vector<cv::Point2f>> left, right;
  std::vector<std::size_t> used;
  std::vector<RejectedPair> rejected;
  cv::Size size;
};

Detections detect_pairs(const std::vector<ChessboardPair> &pairs, cv::Size board, cv::Size size)
{
  Detections d;
  d.size = size;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const ChessboardPair &p = pairs[i];
    auto reject = [&](const std::string &why) { d.rejected.push_back({i, p.name, why}); };
    if (p.left.empty() || p.right.empty()) {
      reject(p.left.empty() ? "left image is empty" : "right image is empty");
      continue;
    }
    if (p.left.size() != p.right.size()) {
      reject("size mismatch: left " + std::to_string(p.left.cols) + "x" +
             std::to_string(p.left.rows) + ", right " + std::to_string(p.right.cols) + "x" +
             std::to_string(p.right.rows));
      continue;
    }
    if (d.size.area() > 0 && p.left.size() != d.size) {
      reject("size mismatch: " + std::to_string(p.left.cols) + "x" + std::to_string(p.left.rows) +
             " while the other pairs are " + std::to_string(d.size.width) + "x" +
             std::to_string(d.size.height));
      continue;
    }
    std::vector<cv::Point2f> cl, cr;
    const bool found_l = find_chessboard(p.left, board, cl);
    const bool found_r = find_chessboard(p.right, board, cr);
    if (!found_l || !found_r) {
      reject(!found_l && !found_r ? "board not found in either image"
             : !found_l           ? "board not found in left image"
                                  : "board not found in right image");
      continue;
    }
    d.size = p.left.size();
    d.left.push_back(std::move(cl));
    d.right.push_back(std::move(cr));
    d.used.push_back(i);
  }
  return d;
}

// The rejected pairs and why, for an error's detail: "a: board not found in left image; ...".
std::string rejections(const std::vector<RejectedPair> &rejected)
{
  std::string out;
  for (const RejectedPair &r : rejected)
    out += (out.empty() ? "" : "; ") + r.name + ": " + r.reason;
  return out;
}

void check_board(cv::Size board)
{
  if (board.width < 2 || board.height < 2)
    throw BadSettings("The board is too small: give its inner corners, at least 2x2.",
                      "chessboard: board " + std::to_string(board.width) + "x" +
                          std::to_string(board.height) + " inner corners");
}

} // namespace

bool find_chessboard(const cv::Mat &image, cv::Size board, std::vector<cv::Point2f> &corners)
{
  check_board(board);
  const cv::Mat gray = to_gray(image);
  corners.clear();
  const int flags = static_cast<int>(cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
  if (!cv::findChessboardCorners(gray, board, corners, flags))
    return false;
  // The search window must not reach the neighbouring corners, or on a small or oblique board
  // cornerSubPix drifts towards them: at most ~40% of the closest corner spacing, at most 11.
  double spacing = 1e9;
  for (int y = 0; y < board.height; ++y)
    for (int x = 0; x < board.width; ++x) {
      const cv::Point2f p = corners[static_cast<std::size_t>(y * board.width + x)];
      if (x + 1 < board.width)
        spacing = std::min(spacing, cv::norm(p - corners[static_cast<std::size_t>(y * board.width + x + 1)]));
      if (y + 1 < board.height)
        spacing = std::min(spacing, cv::norm(p - corners[static_cast<std::size_t>((y + 1) * board.width + x)]));
    }
  const int half = std::clamp(static_cast<int>(spacing * 0.4), 2, 11);
  cv::cornerSubPix(gray, corners, cv::Size(half, half), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01));
  return true;
}

ChessboardCalibration calibrate_chessboard(const std::vector<ChessboardPair> &pairs,
                                           cv::Size board, double square)
{
  check_board(board);
  if (!(square > 0) || !std::isfinite(square))
    throw BadSettings("The square size cannot be used: give the side of a square as a length "
                      "above 0 (mm).",
                      "calibrate_chessboard: square " + std::to_string(square));
  Detections d = detect_pairs(pairs, board, cv::Size());
  if (d.used.size() < kMinPairs)
    throw BadInput("Too few image pairs show the board: only " + std::to_string(d.used.size()) +
                       " of " + std::to_string(pairs.size()) + " pairs show the whole " +
                       std::to_string(board.width) + "x" + std::to_string(board.height) +
                       " board in both views and at least " + std::to_string(kMinPairs) +
                       " are needed; check the board size (inner corners, not squares) or take "
                       "more pairs.",
                   "rejected: " + rejections(d.rejected));
  const std::vector<std::vector<cv::Point3f>> objects(d.used.size(), board_points(board, square));

  ChessboardCalibration out;
  StereoCalibration &c = out.calib;
  c.image_size = d.size;
  // k3 is poorly constrained by a dozen flat-board views and trades off against k1/k2.
  const int mono_flags = static_cast<int>(cv::CALIB_FIX_K3);
  std::vector<cv::Mat> rvecs, tvecs;
  out.rms_left = cv::calibrateCamera(objects, d.left, d.size, c.M1, c.D1, rvecs, tvecs, mono_flags);
  out.rms_right = cv::calibrateCamera(objects, d.right, d.size, c.M2, c.D2, rvecs, tvecs, mono_flags);
  // Joint refinement: the rigid link between the views constrains the intrinsics further, and
  // starting from the per-camera solutions keeps the optimisation from wandering off.
  cv::Mat E, F;
  const int stereo_flags = static_cast<int>(cv::CALIB_USE_INTRINSIC_GUESS | cv::CALIB_FIX_K3);
  out.rms_stereo = cv::stereoCalibrate(
      objects, d.left, d.right, c.M1, c.D1, c.M2, c.D2, d.size, c.R, c.T, E, F, stereo_flags,
      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-6));
  cv::stereoRectify(c.M1, c.D1, c.M2, c.D2, d.size, c.R, c.T, c.R1, c.R2, c.P1, c.P2, c.Q,
                    cv::CALIB_ZERO_DISPARITY, -1, d.size);
  for (cv::Mat *m : {&c.M1, &c.D1, &c.M2, &c.D2, &c.R, &c.T})
    m->convertTo(*m, CV_64F);
  validate_calibration(c, "chessboard calibration");
  out.used = std::move(d.used);
  out.rejected = std::move(d.rejected);
  return out;
}

RectificationCheck check_rectification(const StereoCalibration &calib,
                                       const std::vector<ChessboardPair> &pairs, cv::Size board)
{
  check_board(board);
  const Detections d = detect_pairs(pairs, board, cv::Size());
  RectificationCheck out;
  out.used = d.used;
  out.rejected = d.rejected;
  if (d.used.empty())
    throw BadInput("No image pair shows the whole " + std::to_string(board.width) + "x" +
                       std::to_string(board.height) +
                       " board in both views: check the board size (inner corners, not squares) "
                       "or take pairs that show it.",
                   "rejected: " + rejections(d.rejected));
  // Same stereoRectify as the pipeline, but on points: exact, and no map quantisation.
  cv::Mat R1, R2, P1, P2, Q;
  const StereoCalibration c = scale_calibration(calib, d.size);
  cv::stereoRectify(c.M1, c.D1, c.M2, c.D2, d.size, c.R, c.T, R1, R2, P1, P2, Q,
                    cv::CALIB_ZERO_DISPARITY, -1, d.size);
  const cv::TermCriteria crit(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-10);
  double sum = 0;
  for (std::size_t k = 0; k < d.used.size(); ++k) {
    std::vector<cv::Point2f> rl, rr;
    cv::undistortPoints(d.left[k], rl, c.M1, c.D1, R1, P1, crit);
    cv::undistortPoints(d.right[k], rr, c.M2, c.D2, R2, P2, crit);
    double pair_sum = 0, pair_max = 0;
    for (std::size_t j = 0; j < rl.size(); ++j) {
      const double dy = std::abs(static_cast<double>(rl[j].y) - rr[j].y);
      pair_sum += dy;
      pair_max = std::max(pair_max, dy);
    }
    sum += pair_sum;
    out.corners += rl.size();
    out.max_abs_dy = std::max(out.max_abs_dy, pair_max);
    out.pair_mean_abs_dy.push_back(pair_sum / static_cast<double>(rl.size()));
    out.pair_max_abs_dy.push_back(pair_max);
  }
  out.mean_abs_dy = sum / static_cast<double>(out.corners);
  return out;
}

std::vector<std::string> read_image_list(const std::string &path)
{
  if (!std::ifstream(path))
    throw FileError(path, FileAccess::Read,
                    path + ": image list is missing or cannot be read");
  cv::FileStorage fs;
  try {
    fs.open(path, cv::FileStorage::READ);
  } catch (const cv::Exception &e) {
    throw FileError(path, FileAccess::None,
                    path + ": not a valid OpenCV image list (" + e.err + ")");
  }
  if (!fs.isOpened())
    throw FileError(path, FileAccess::Read,
                    path + ": image list is missing or cannot be read");
  cv::FileNode list = fs["imagelist"];
  if (list.empty() && fs.root().isSeq())
    list = fs.root();
  if (!list.isSeq())
    throw FileError(path, FileAccess::None, path + ": no 'imagelist' sequence of file names");
  const auto slash = path.find_last_of('/');
  const std::string folder = slash == std::string::npos ? std::string() : path.substr(0, slash + 1);
  std::vector<std::string> out;
  for (const cv::FileNode &n : list) {
    if (!n.isString())
      throw FileError(path, FileAccess::None, path + ": 'imagelist' must hold file names only");
    const std::string name = n.string();
    out.push_back(!name.empty() && name[0] == '/' ? name : folder + name);
  }
  if (out.empty() || out.size() % 2 != 0)
    throw FileError(path, FileAccess::None,
                    path + ": the list holds " + std::to_string(out.size()) +
                        " names; expected left and right alternating (an even count)");
  return out;
}

} // namespace treestereo
