#include "treestereo/data_dir.hpp"
#include "treestereo/errors.hpp"
#include "treestereo/chessboard.hpp"
#include "typed_error.hpp"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdlib>
#include <filesystem>

using namespace treestereo;

namespace {

std::string samples_list()
{
  return data_dir() + "/opencv-samples/stereo_calib.xml";
}

std::vector<ChessboardPair> load_samples(const std::vector<std::string> &files)
{
  std::vector<ChessboardPair> pairs;
  for (std::size_t i = 0; i + 1 < files.size(); i += 2)
    pairs.push_back({cv::imread(files[i], cv::IMREAD_GRAYSCALE),
                     cv::imread(files[i + 1], cv::IMREAD_GRAYSCALE), files[i]});
  return pairs;
}

// A rendered, axis-aligned board: corners are known exactly.
cv::Mat render_board(cv::Size inner, int square, cv::Point origin, cv::Size image)
{
  cv::Mat img(image, CV_8UC1, cv::Scalar(255));
  for (int y = 0; y <= inner.height; ++y)
    for (int x = 0; x <= inner.width; ++x)
      if ((x + y) % 2 == 0)
        cv::rectangle(img, cv::Rect(origin.x + x * square, origin.y + y * square, square, square),
                      cv::Scalar(0), cv::FILLED);
  return img;
}

} // namespace

TEST(Chessboard, FindsCornersOfARenderedBoard)
{
  const cv::Size inner(7, 5);
  const cv::Mat img = render_board(inner, 30, {60, 50}, {400, 300});
  std::vector<cv::Point2f> corners;
  ASSERT_TRUE(find_chessboard(img, inner, corners));
  ASSERT_EQ(corners.size(), 35u);
  // Inner corners sit at origin + (k+1) * square, minus half a pixel (pixel-centre convention).
  for (const auto &c : corners) {
    const double fx = (c.x + 0.5 - 60) / 30.0, fy = (c.y + 0.5 - 50) / 30.0;
    EXPECT_NEAR(fx, std::round(fx), 0.1 / 30.0) << c;
    EXPECT_NEAR(fy, std::round(fy), 0.1 / 30.0) << c;
  }
  cv::Mat blank(300, 400, CV_8UC3, cv::Scalar::all(128));
  EXPECT_FALSE(find_chessboard(blank, inner, corners));
}

TEST(Chessboard, RejectsPairsAndExplainsWhy)
{
  const cv::Size inner(7, 5);
  const cv::Mat board = render_board(inner, 30, {60, 50}, {400, 300});
  const cv::Mat blank(300, 400, CV_8UC1, cv::Scalar(200));
  const cv::Mat other = render_board(inner, 30, {60, 50}, {500, 300});
  const std::vector<ChessboardPair> pairs{
      {blank, board, "a"}, {board, blank, "b"}, {board, other, "c"}, {blank, blank, "d"}};
  try {
    calibrate_chessboard(pairs, inner, 25.0);
    ADD_FAILURE() << "calibrated from no usable pair";
  } catch (const BadInput &e) {
    EXPECT_NE(std::string(e.what()).find("only 0 of 4 pairs"), std::string::npos) << e.what();
  }
  // The check reports the same reasons before giving up.
  StereoCalibration dummy;
  EXPECT_THROW(check_rectification(dummy, pairs, inner), BadInput);
  EXPECT_THROW(calibrate_chessboard(pairs, inner, 0.0), BadSettings);
  EXPECT_THROW(calibrate_chessboard(pairs, {1, 5}, 25.0), BadSettings);
}

TEST(Chessboard, ErrorsAreTypedAndNameTheProblem)
{
  std::vector<cv::Point2f> corners;
  expect_typed_error<BadInput>(
      [&] { find_chessboard(cv::Mat(40, 40, CV_32F), cv::Size(7, 5), corners); }, "8-bit");
  expect_typed_error<BadSettings>(
      [&] { find_chessboard(cv::Mat(40, 40, CV_8U), cv::Size(1, 5), corners); }, "board");
  try {
    read_image_list("/nonexistent-treestereo-dir/list.xml");
    ADD_FAILURE() << "a missing list was read";
  } catch (const FileError &e) {
    EXPECT_EQ(e.access(), FileAccess::Read);
    EXPECT_EQ(e.path(), "/nonexistent-treestereo-dir/list.xml");
  }
}

TEST(Chessboard, ReadsOpenCvImageList)
{
  const std::string list = samples_list();
  if (!std::filesystem::exists(list))
    GTEST_SKIP() << "no OpenCV sample images at " << list << " (set TREESTEREO_DATA_DIR)";
  const std::vector<std::string> files = read_image_list(list);
  ASSERT_EQ(files.size(), 26u);
  EXPECT_EQ(files[0], data_dir() + "/opencv-samples/left01.jpg");
  EXPECT_EQ(files[1], data_dir() + "/opencv-samples/right01.jpg");
  EXPECT_THROW(read_image_list(data_dir() + "/opencv-samples/nothere.xml"), FileError);
}

TEST(Chessboard, CalibratesOpenCvSamplePairs)
{
  const std::string list = samples_list();
  if (!std::filesystem::exists(list))
    GTEST_SKIP() << "no OpenCV sample images at " << list << " (set TREESTEREO_DATA_DIR)";
  std::vector<ChessboardPair> pairs = load_samples(read_image_list(list));
  ASSERT_EQ(pairs.size(), 13u);
  // One bad pair on top: the board is not in the right view.
  pairs.push_back({pairs[0].left, cv::Mat(480, 640, CV_8UC1, cv::Scalar(90)), "extra"});

  const ChessboardCalibration r = calibrate_chessboard(pairs, {9, 6}, 1.0);
  std::printf("RMS left %.3f right %.3f stereo %.3f px; |T| %.4f squares; T = [%.4f %.4f %.4f]\n",
              r.rms_left, r.rms_right, r.rms_stereo, r.calib.baseline_mm(), r.calib.T.at<double>(0),
              r.calib.T.at<double>(1), r.calib.T.at<double>(2));
  EXPECT_EQ(r.used.size(), 13u);
  ASSERT_EQ(r.rejected.size(), 1u);
  EXPECT_EQ(r.rejected[0].index, 13u);
  EXPECT_EQ(r.rejected[0].reason, "board not found in right image");
  EXPECT_LT(r.rms_stereo, 1.0);
  EXPECT_LT(r.rms_left, 1.0);
  EXPECT_LT(r.rms_right, 1.0);
  // The README's reference (OpenCV's own sample): T about [-3.34, 0.05, 0.00] squares.
  EXPECT_NEAR(r.calib.baseline_mm(), 3.34, 0.02 * 3.34);
  EXPECT_LT(r.calib.T.at<double>(0), 0);
  EXPECT_EQ(r.calib.image_size, cv::Size(640, 480));
  EXPECT_TRUE(r.calib.has_rectification());

  const RectificationCheck c = check_rectification(r.calib, pairs, {9, 6});
  std::printf("rectified |dy|: mean %.3f px, max %.3f px over %zu corners\n", c.mean_abs_dy,
              c.max_abs_dy, c.corners);
  EXPECT_EQ(c.corners, 13u * 54u);
  EXPECT_LT(c.mean_abs_dy, 0.25);
  ASSERT_EQ(c.rejected.size(), 1u);

  // A wrong calibration shows: the same one with the right camera turned by 1 degree.
  StereoCalibration bent = r.calib;
  cv::Mat turn;
  cv::Rodrigues(cv::Vec3d(0.0175, 0, 0), turn);
  bent.R = turn * bent.R;
  bent.R1.release();
  bent.R2.release();
  bent.P1.release();
  bent.P2.release();
  bent.Q.release();
  const RectificationCheck worse = check_rectification(bent, pairs, {9, 6});
  EXPECT_GT(worse.mean_abs_dy, 5.0);
}
