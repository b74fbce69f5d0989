// Stereo calibration from chessboard image pairs, and a check of a calibration's rectification.
#pragma once

#include "treestereo/calibration.hpp"

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace treestereo {

// One stereo pair of chessboard images; `name` labels it in reports (e.g. the file names).
struct ChessboardPair {
  cv::Mat left, right; // CV_8U, 1, 3 or 4 channels
  std::string name;
};

struct RejectedPair {
  std::size_t index = 0; // position in the input
  std::string name;
  std::string reason;    // "board not found in left image", ...
};

struct ChessboardCalibration {
  StereoCalibration calib;      // with R1 R2 P1 P2 Q from cv::stereoRectify (alpha -1)
  double rms_left = 0, rms_right = 0; // per-camera reprojection RMS (px), calibrateCamera
  double rms_stereo = 0;        // joint reprojection RMS (px), stereoCalibrate
  std::vector<std::size_t> used; // indices of the pairs the calibration rests on
  std::vector<RejectedPair> rejected;
};

// Finds the inner corners of a board with `board` inner corners (e.g. 9x6) to subpixel
// accuracy. Returns false when the board is not found.
bool find_chessboard(const cv::Mat &image, cv::Size board, std::vector<cv::Point2f> &corners);

// Calibrates a stereo rig from chessboard pairs. `square` is the square's side in mm (T then
// comes out in mm). Pairs whose board is not found in either view, or whose views differ in
// size (from each other or from the first usable pair), are rejected with the reason.
// Each camera is calibrated alone (calibrateCamera, k3 fixed), then stereoCalibrate refines
// intrinsics and extrinsics together starting from those (CALIB_USE_INTRINSIC_GUESS).
// Throws BadInput when fewer than 3 pairs are usable or an image is not 8-bit grey/colour,
// BadSettings on a board under 2x2 inner corners or a square size not above 0.
ChessboardCalibration calibrate_chessboard(const std::vector<ChessboardPair> &pairs,
                                           cv::Size board, double square);

struct RectificationCheck {
  double mean_abs_dy = 0, max_abs_dy = 0; // px, over all matching corners
  std::size_t corners = 0;                // how many corner pairs were measured
  std::vector<std::size_t> used;
  std::vector<double> pair_mean_abs_dy;   // per used pair (same order as `used`), px
  std::vector<double> pair_max_abs_dy;
  std::vector<RejectedPair> rejected;
};

// Rectifies the corners of each pair (no image remapping: cv::undistortPoints with the R1/P1 and
// R2/P2 of cv::stereoRectify as compute_rectification calls it) and measures the row difference of matching corners. A good
// calibration gives a mean |dy| well under a pixel. Throws BadInput when no pair has
// the board in both views.
RectificationCheck check_rectification(const StereoCalibration &calib,
                                       const std::vector<ChessboardPair> &pairs, cv::Size board);

// Reads an OpenCV image list (the format of OpenCV's stereo_calib.xml: a sequence "imagelist" of
// file names, left and right alternating). Relative names are taken relative to the list's
// folder. Throws FileError on a missing/invalid file or an odd count.
std::vector<std::string> read_image_list(const std::string &path);

} // namespace treestereo
