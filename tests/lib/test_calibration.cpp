#include "treestereo/calibration_file.hpp"

#include "../common/temp_dir.hpp"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>

using namespace treestereo;
namespace fs = std::filesystem;

namespace {

void write_text(const std::string &path, const std::string &text)
{
  std::ofstream(path, std::ios::binary) << text;
}

// A plausible rig built by hand: 640x480, right camera 60 mm to the right, slightly turned.
StereoCalibration make_rig()
{
  StereoCalibration c;
  c.image_size = {640, 480};
  c.M1 = (cv::Mat_<double>(3, 3) << 800, 0, 322, 0, 801, 238, 0, 0, 1);
  c.M2 = (cv::Mat_<double>(3, 3) << 805, 0, 318, 0, 806, 243, 0, 0, 1);
  c.D1 = (cv::Mat_<double>(1, 5) << -0.05, 0.02, 0.001, -0.0005, 0);
  c.D2 = (cv::Mat_<double>(1, 5) << -0.04, 0.015, -0.0007, 0.0003, 0);
  cv::Rodrigues(cv::Vec3d(0.004, -0.012, 0.003), c.R);
  c.T = (cv::Mat_<double>(3, 1) << -60.0, 0.8, -0.5);
  return c;
}

void add_rectification(StereoCalibration &c)
{
  cv::stereoRectify(c.M1, c.D1, c.M2, c.D2, c.image_size, c.R, c.T, c.R1, c.R2, c.P1, c.P2, c.Q,
                    cv::CALIB_ZERO_DISPARITY);
}

// Writes the OpenCV-sample layout with FileStorage directly (independent of save_calibration),
// leaving out `skip` ("image_size": both image_width and image_height).
void write_opencv(const std::string &path, StereoCalibration c, const std::string &skip = "")
{
  cv::FileStorage f(path, cv::FileStorage::WRITE);
  auto put = [&](const char *key, const cv::Mat &m) {
    if (skip != key && !m.empty())
      f << key << m;
  };
  if (skip != "image_width" && skip != "image_size")
    f << "image_width" << c.image_size.width;
  if (skip != "image_height" && skip != "image_size")
    f << "image_height" << c.image_size.height;
  put("M1", c.M1);
  put("D1", c.D1);
  put("M2", c.M2);
  put("D2", c.D2);
  put("R", c.R);
  put("T", c.T);
  put("R1", c.R1);
  put("R2", c.R2);
  put("P1", c.P1);
  put("P2", c.P2);
  put("Q", c.Q);
}

void expect_mat_near(const cv::Mat &a, const cv::Mat &b, double tol, const char *what)
{
  ASSERT_EQ(a.total(), b.total()) << what;
  EXPECT_LE(cv::norm(a.reshape(1, 1), b.reshape(1, 1), cv::NORM_INF), tol) << what;
}

void expect_same(const StereoCalibration &a, const StereoCalibration &b, double tol)
{
  EXPECT_EQ(a.image_size, b.image_size);
  expect_mat_near(a.M1, b.M1, tol, "M1");
  expect_mat_near(a.D1, b.D1, tol, "D1");
  expect_mat_near(a.M2, b.M2, tol, "M2");
  expect_mat_near(a.D2, b.D2, tol, "D2");
  expect_mat_near(a.R, b.R, tol, "R");
  expect_mat_near(a.T, b.T, tol, "T");
}

// Runs f, expects a CalibrationError naming `file` and `key` whose message contains `text`.
void expect_error(const std::function<void()> &f, const std::string &file, const std::string &key,
                  const std::string &text)
{
  try {
    f();
    ADD_FAILURE() << "no CalibrationError; expected one about " << key << ": " << text;
  } catch (const CalibrationError &e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(file), std::string::npos) << msg;
    EXPECT_EQ(e.key(), key) << msg;
    EXPECT_NE(msg.find(text), std::string::npos) << msg;
  }
}

std::string ros_matrix(const char *key, const cv::Mat &m)
{
  std::string s = std::string(key) + ":\n  rows: " + std::to_string(m.rows) +
                  "\n  cols: " + std::to_string(m.cols) + "\n  data: [";
  char buf[64];
  for (int i = 0; i < static_cast<int>(m.total()); ++i) {
    std::snprintf(buf, sizeof buf, "%s%.17g", i ? ", " : "", m.at<double>(i / m.cols, i % m.cols));
    s += buf;
  }
  return s + "]\n";
}

// A ROS camera_info file as camera_calibration writes it (no %YAML header). P in metres.
std::string ros_camera(const char *name, cv::Size size, const cv::Mat &K, const cv::Mat &D,
                       const cv::Mat &R, const cv::Mat &P_mm)
{
  cv::Mat P = P_mm.clone();
  P.at<double>(0, 3) /= 1000.0;
  P.at<double>(1, 3) /= 1000.0;
  return "image_width: " + std::to_string(size.width) + "\nimage_height: " +
         std::to_string(size.height) + "\ncamera_name: " + name + "\n" + ros_matrix("camera_matrix", K) +
         "distortion_model: plumb_bob\n" + ros_matrix("distortion_coefficients", D) +
         ros_matrix("rectification_matrix", R) + ros_matrix("projection_matrix", P);
}

} // namespace

TEST(Calibration, ExampleMer500Loads)
{
  const std::string path = std::string(TREESTEREO_SOURCE_DIR) + "/docs/examples/calibration-mer500.yml";
  const StereoCalibration c = load_calibration(path);
  EXPECT_EQ(c.image_size, cv::Size(2592, 1944));
  EXPECT_DOUBLE_EQ(c.M1.at<double>(0, 0), 3503.12);
  EXPECT_DOUBLE_EQ(c.M1.at<double>(1, 1), 3504.61);
  EXPECT_DOUBLE_EQ(c.M1.at<double>(0, 2), 1207.31);
  EXPECT_DOUBLE_EQ(c.M1.at<double>(1, 2), 967.84);
  EXPECT_DOUBLE_EQ(c.M2.at<double>(0, 0), 3511.25);
  EXPECT_DOUBLE_EQ(c.M2.at<double>(1, 1), 3511.71);
  EXPECT_DOUBLE_EQ(c.M2.at<double>(0, 2), 1198.93);
  EXPECT_DOUBLE_EQ(c.M2.at<double>(1, 2), 960.13);
  EXPECT_NEAR(c.baseline_mm(), 50.0, 1e-9);
  EXPECT_LT(c.T.at<double>(0), 0); // right camera to the right
  EXPECT_DOUBLE_EQ(c.pixel_size_um, 2.2);
  // The paper: f = fx * dx = 7.706 mm (left) for its 8 mm lens.
  EXPECT_NEAR(c.M1.at<double>(0, 0) * c.pixel_size_um / 1000.0, 7.706, 0.001);
  EXPECT_FALSE(c.has_rectification());
}

TEST(Calibration, ReadsOpenCvLayoutYamlAndXml)
{
  TempDir dir("treestereo-calib");
  StereoCalibration rig = make_rig();
  add_rectification(rig);
  for (const char *name : {"stereo.yml", "stereo.xml", "stereo.yaml.gz", "stereo.xml.gz"}) {
    write_opencv(dir.file(name), rig);
    const StereoCalibration c = load_calibration(dir.file(name));
    expect_same(c, rig, 1e-12);
    ASSERT_TRUE(c.has_rectification()) << name;
    expect_mat_near(c.P2, rig.P2, 1e-9, "P2");
    expect_mat_near(c.Q, rig.Q, 1e-12, "Q");
    EXPECT_NEAR(c.baseline_mm(), cv::norm(rig.T), 1e-12);
  }
}

TEST(Calibration, RoundTripsThroughSave)
{
  TempDir dir("treestereo-calib");
  StereoCalibration rig = make_rig();
  add_rectification(rig);
  rig.pixel_size_um = 3.45;
  for (const char *name : {"out.yml", "out.xml"}) {
    save_calibration(rig, dir.file(name));
    const StereoCalibration c = load_calibration(dir.file(name));
    expect_same(c, rig, 0.0);
    expect_mat_near(c.P1, rig.P1, 0.0, "P1");
    expect_mat_near(c.Q, rig.Q, 0.0, "Q");
    EXPECT_EQ(c.pixel_size_um, 3.45);
  }
  expect_error([&] { save_calibration(rig, dir.file("out.txt")); }, "out.txt", "", "extension");
  StereoCalibration bad = rig;
  bad.T = cv::Mat::zeros(3, 1, CV_64F);
  expect_error([&] { save_calibration(bad, dir.file("bad.yml")); }, "bad.yml", "T", "zero baseline");
  EXPECT_FALSE(fs::exists(dir.file("bad.yml")));
}

TEST(Calibration, ReadsOpenCvSampleSplitFiles)
{
  TempDir dir("treestereo-calib");
  StereoCalibration rig = make_rig();
  add_rectification(rig);
  {
    // As the stereo_calib sample writes them, plus the image size it leaves out.
    cv::FileStorage fi(dir.file("intrinsics.yml"), cv::FileStorage::WRITE);
    fi << "M1" << rig.M1 << "D1" << rig.D1 << "M2" << rig.M2 << "D2" << rig.D2;
    fi << "image_width" << 640 << "image_height" << 480;
    cv::FileStorage fe(dir.file("extrinsics.yml"), cv::FileStorage::WRITE);
    fe << "R" << rig.R << "T" << rig.T << "R1" << rig.R1 << "R2" << rig.R2 << "P1" << rig.P1
       << "P2" << rig.P2 << "Q" << rig.Q;
  }
  const StereoCalibration c = load_calibration(dir.file("intrinsics.yml") + ";" + dir.file("extrinsics.yml"));
  expect_same(c, rig, 1e-12);
  EXPECT_TRUE(c.has_rectification());

  {
    cv::FileStorage fi(dir.file("intrinsics-nosize.yml"), cv::FileStorage::WRITE);
    fi << "M1" << rig.M1 << "D1" << rig.D1 << "M2" << rig.M2 << "D2" << rig.D2;
  }
  expect_error([&] { load_calibration(dir.file("intrinsics-nosize.yml") + ";" + dir.file("extrinsics.yml")); },
               "intrinsics-nosize.yml", "image_width", "image size missing");
}

TEST(Calibration, ReadsRosCameraInfoPair)
{
  TempDir dir("treestereo-calib");
  StereoCalibration rig = make_rig();
  add_rectification(rig);
  write_text(dir.file("left.yaml"), ros_camera("left", rig.image_size, rig.M1, rig.D1, rig.R1, rig.P1));
  write_text(dir.file("right.yaml"), ros_camera("right", rig.image_size, rig.M2, rig.D2, rig.R2, rig.P2));
  const StereoCalibration c = load_calibration(dir.file("left.yaml") + ";" + dir.file("right.yaml"));
  // R and T are rebuilt from R1, R2 and P2 only: they must be the rig's, sign included.
  expect_same(c, rig, 1e-9);
  EXPECT_LT(c.T.at<double>(0), 0);
  expect_mat_near(c.P1, rig.P1, 1e-9, "P1");
  expect_mat_near(c.P2, rig.P2, 1e-9, "P2");
  expect_mat_near(c.Q, rig.Q, 1e-12, "Q");

  // The convention X_right = R X_left + T on a point: its rectified rows agree.
  const cv::Mat X = (cv::Mat_<double>(3, 1) << 150, -80, 2000);
  const cv::Mat Xr = c.R * X + c.T;
  const cv::Mat ul = c.P1.colRange(0, 3) * (c.R1 * X);
  const cv::Mat ur = c.P2.colRange(0, 3) * (c.R2 * Xr);
  EXPECT_NEAR(ul.at<double>(1) / ul.at<double>(2), ur.at<double>(1) / ur.at<double>(2), 1e-9);
  // ... and its disparity is f * B / Z in the rectified frame.
  const double z = cv::Mat(c.R1 * X).at<double>(2);
  const double d = ul.at<double>(0) / ul.at<double>(2) - ur.at<double>(0) / ur.at<double>(2);
  EXPECT_NEAR(d, c.P1.at<double>(0, 0) * cv::norm(rig.T) / z, 1e-6);

  // Zero Tx, swapped files and a wrong data count, each named.
  cv::Mat p0 = rig.P2.clone();
  p0.at<double>(0, 3) = 0;
  write_text(dir.file("right0.yaml"), ros_camera("right", rig.image_size, rig.M2, rig.D2, rig.R2, p0));
  expect_error([&] { load_calibration(dir.file("left.yaml") + ";" + dir.file("right0.yaml")); },
               "right0.yaml", "projection_matrix", "zero");
  expect_error([&] { load_calibration(dir.file("right.yaml") + ";" + dir.file("left.yaml")); },
               "right.yaml", "projection_matrix", "swapped");
  write_text(dir.file("short.yaml"), "image_width: 640\nimage_height: 480\n"
                                     "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 320, 0, 1, 240]\n");
  expect_error([&] { load_calibration(dir.file("short.yaml") + ";" + dir.file("right.yaml")); },
               "short.yaml", "camera_matrix", "data has 6 values");
  write_text(dir.file("nop.yaml"), ros_camera("left", rig.image_size, rig.M1, rig.D1, rig.R1, rig.P1)
                                       .substr(0, ros_camera("left", rig.image_size, rig.M1, rig.D1, rig.R1, rig.P1)
                                                      .find("projection_matrix")));
  expect_error([&] { load_calibration(dir.file("nop.yaml") + ";" + dir.file("right.yaml")); },
               "nop.yaml", "projection_matrix", "missing key");
}

TEST(CalibrationErrors, MissingKey)
{
  TempDir dir("treestereo-calib");
  write_opencv(dir.file("c.yml"), make_rig(), "R");
  expect_error([&] { load_calibration(dir.file("c.yml")); }, "c.yml", "R", "missing key");
}

TEST(CalibrationErrors, WrongMatrixShape)
{
  TempDir dir("treestereo-calib");
  StereoCalibration rig = make_rig();
  rig.M2 = cv::Mat::eye(2, 3, CV_64F);
  write_opencv(dir.file("c.yml"), rig);
  expect_error([&] { load_calibration(dir.file("c.yml")); }, "c.yml", "M2", "wrong shape 2x3, expected 3x3");
  rig = make_rig();
  rig.D1 = cv::Mat::zeros(1, 6, CV_64F);
  write_opencv(dir.file("d.yml"), rig);
  expect_error([&] { load_calibration(dir.file("d.yml")); }, "d.yml", "D1", "wrong shape 1x6");
}

TEST(CalibrationErrors, NonFiniteValues)
{
  TempDir dir("treestereo-calib");
  StereoCalibration rig = make_rig();
  rig.T.at<double>(1) = std::numeric_limits<double>::quiet_NaN();
  write_opencv(dir.file("nan.yml"), rig);
  expect_error([&] { load_calibration(dir.file("nan.yml")); }, "nan.yml", "T", "non-finite");
  rig = make_rig();
  rig.M1.at<double>(0, 2) = std::numeric_limits<double>::infinity();
  write_opencv(dir.file("inf.xml"), rig);
  expect_error([&] { load_calibration(dir.file("inf.xml")); }, "inf.xml", "M1", "non-finite");
}

TEST(CalibrationErrors, NotARotation)
{
  TempDir dir("treestereo-calib");
  StereoCalibration rig = make_rig();
  rig.R = rig.R * 1.01; // scaled
  write_opencv(dir.file("scaled.yml"), rig);
  expect_error([&] { load_calibration(dir.file("scaled.yml")); }, "scaled.yml", "R", "not a rotation");
  rig = make_rig();
  rig.R.row(2) *= -1; // orthogonal but a reflection: det = -1
  write_opencv(dir.file("mirror.yml"), rig);
  expect_error([&] { load_calibration(dir.file("mirror.yml")); }, "mirror.yml", "R", "det = -1");
}

TEST(CalibrationErrors, ZeroBaseline)
{
  TempDir dir("treestereo-calib");
  StereoCalibration rig = make_rig();
  rig.T = cv::Mat::zeros(3, 1, CV_64F);
  write_opencv(dir.file("c.yml"), rig);
  expect_error([&] { load_calibration(dir.file("c.yml")); }, "c.yml", "T", "zero baseline");
}

TEST(CalibrationErrors, ImageSizeMissingOrNotPositive)
{
  TempDir dir("treestereo-calib");
  write_opencv(dir.file("nosize.yml"), make_rig(), "image_width");
  expect_error([&] { load_calibration(dir.file("nosize.yml")); }, "nosize.yml", "image_width", "not positive");
  write_opencv(dir.file("none.yml"), make_rig(), "image_size");
  expect_error([&] { load_calibration(dir.file("none.yml")); }, "none.yml", "image_width", "image size missing");
  StereoCalibration rig = make_rig();
  rig.image_size = {640, -480};
  write_opencv(dir.file("neg.yml"), rig);
  expect_error([&] { load_calibration(dir.file("neg.yml")); }, "neg.yml", "image_width", "640x-480 is not positive");
  // Found by fuzzing: 2592 x 2591944 overflowed int in a size's area (undefined behaviour) and
  // would have asked stereorectify for maps of 27 GB.
  rig.image_size = {2592, 2591944};
  write_opencv(dir.file("huge.yml"), rig);
  expect_error([&] { load_calibration(dir.file("huge.yml")); }, "huge.yml", "image_width",
               "2592x2591944 is larger than 32768 px on a side");
  {
    // The split files' path to the same check (the size is read where it is found).
    cv::FileStorage fi(dir.file("intr.yml"), cv::FileStorage::WRITE);
    fi << "M1" << rig.M1 << "D1" << rig.D1 << "M2" << rig.M2 << "D2" << rig.D2;
    fi << "image_width" << rig.image_size.width << "image_height" << rig.image_size.height;
    cv::FileStorage fe(dir.file("extr.yml"), cv::FileStorage::WRITE);
    fe << "R" << rig.R << "T" << rig.T;
  }
  expect_error([&] { load_calibration(dir.file("intr.yml") + ";" + dir.file("extr.yml")); },
               "intr.yml", "image_width", "larger than 32768 px");
}

TEST(CalibrationErrors, FileMissing)
{
  TempDir dir("treestereo-calib");
  expect_error([&] { load_calibration(dir.file("nothere.yml")); }, "nothere.yml", "", "missing");
  expect_error([&] { load_calibration(dir.file("a.yaml") + ";" + dir.file("b.yaml")); }, "a.yaml", "", "missing");
  // A directory opens as a stream that reads nothing: it must not be called "empty".
  fs::create_directories(dir.file("calib.yml"));
  expect_error([&] { load_calibration(dir.file("calib.yml")); }, "calib.yml", "", "is a directory");
}

// The element layer maps the error's type and access to a GStreamer code: a file that cannot be
// read or written says so, a file that was read but cannot be used is a setting's error.
TEST(CalibrationErrors, TypeAndAccess)
{
  TempDir dir("treestereo-calib");
  auto access_of = [](const std::function<void()> &f) {
    try {
      f();
    } catch (const BadSettings &e) {
      const auto *c = dynamic_cast<const CalibrationError *>(&e);
      EXPECT_NE(c, nullptr) << e.what();
      return c ? c->access() : FileAccess::None;
    }
    ADD_FAILURE() << "no error";
    return FileAccess::None;
  };
  EXPECT_EQ(access_of([&] { load_calibration(dir.file("nothere.yml")); }), FileAccess::Read);
  EXPECT_EQ(access_of([&] { save_calibration(make_rig(), dir.file("no/such/dir.yml")); }),
            FileAccess::Write);
  std::ofstream(dir.file("words.yml")) << "just some words\n";
  EXPECT_EQ(access_of([&] { load_calibration(dir.file("words.yml")); }), FileAccess::None);
}

TEST(CalibrationErrors, WrongFormat)
{
  TempDir dir("treestereo-calib");
  cv::Mat img(8, 8, CV_8UC1, cv::Scalar(7));
  std::vector<uchar> png;
  cv::imencode(".png", img, png);
  std::ofstream(dir.file("board.png"), std::ios::binary).write(reinterpret_cast<const char *>(png.data()),
                                                               static_cast<std::streamsize>(png.size()));
  expect_error([&] { load_calibration(dir.file("board.png")); }, "board.png", "", "image");
  // Plain prose saved as .yml: FileStorage accepts it as one string, there are no keys.
  write_text(dir.file("notes.yml"), "these are my notes about the cameras\n");
  EXPECT_THROW(load_calibration(dir.file("notes.yml")), CalibrationError);
  write_text(dir.file("empty.yml"), "");
  expect_error([&] { load_calibration(dir.file("empty.yml")); }, "empty.yml", "", "empty");
}

TEST(CalibrationErrors, SyntaxErrorNamesTheFile)
{
  TempDir dir("treestereo-calib");
  write_text(dir.file("broken.yml"), "%YAML:1.0\n---\nM1: !!opencv-matrix\n   rows: 3\n  cols: [3\n");
  expect_error([&] { load_calibration(dir.file("broken.yml")); }, "broken.yml", "", "not a valid OpenCV");
  write_text(dir.file("broken.xml"), "<?xml version=\"1.0\"?>\n<opencv_storage>\n<M1 type_id=\"opencv-matrix\">\n");
  expect_error([&] { load_calibration(dir.file("broken.xml")); }, "broken.xml", "", "not a valid OpenCV");
  // fuzz-calibration's finds and the classes they stand for: OpenCV 4.6's YAML parser loops
  // forever on each of these (and its XML parser crashed on the last), so lib reads the files
  // itself (lib/io/src/document.cpp) and refuses these with the line named.
  const struct {
    const char *name, *text, *why;
  } hangs[] = {
      // a root indented to column 3, ended by a line at column 1
      {"hang.yml", "%YAML:1.0\n   rows: 1\n A---\nx",
       "line 2 is indented, but a calibration file's top level starts at column 0"},
      {"hang7.yml", "    - - 1\na:\n  - a: 1\n    a: {\n",
       "line 1 is indented, but a calibration file's top level starts at column 0"},
      // a dedent between two levels inside a value (refused, not known to hang)
      {"dedent.yml", "%YAML:1.0\nM1:\n   rows: 1\n A: 2\n",
       "line 4 is indented to a column no enclosing line has"},
      // column-0 lines that are no keys ("----~" counts as a '---' with text after it)
      {"hang2.yaml", "----~\n~\n-", "line 1 has text after the document marker '---'"},
      {"hang3.yml", "%YAML:1.0\n---\nimage_width: 640\n~\n-",
       "line 4 starts at column 0 but is no key"},
      // the first again in a file named .gz (zlib reads plain text as it is), which went to
      // OpenCV unchecked: compressed files are decompressed and checked like plain ones
      {"hang4.yml.gz", "%YAML:1.0\n   rows: 1\n A---\nx",
       "line 2 is indented, but a calibration file's top level starts at column 0"},
      // an indented "-" after the document's end "..." (the class of a fuzz-calibration
      // timeout in CI)
      {"hang5.yml", "%YAML:1.0\na: 1\n...\n  - 1\n",
       "line 4 follows the end of the document ('...' on line 3)"},
      {"hang6.yml", "%YAML:1.0\na: {b: 1}\n... \n -\n",
       "line 4 follows the end of the document ('...' on line 3)"},
      // "---" with text after it, repeated (found by fuzzing); a second document is
      // refused by the same rule
      {"hang8.yml", "--- - \xc3\n--- -\xc3\n--- \xc3\n--- --- d",
       "line 1 has text after the document marker '---'"},
      {"twodocs.yml", "%YAML:1.0\n---\na: 1\n---\n -\n",
       "line 4 starts a second YAML document: a calibration file holds one"},
      // the file ends after an attribute's '=' (a null pointer read in OpenCV's parser)
      {"cut.xml", "<?xml version=\"1.0\"?>\n<opencv_storage>\n<M1 type_id=",
       "line 3 expects the value of the attribute 'type_id' in quotes"},
  };
  for (const auto &h : hangs) {
    write_text(dir.file(h.name), h.text);
    expect_error([&] { load_calibration(dir.file(h.name)); }, h.name, "", h.why);
  }
  // The end marker itself, with only comments after it, is fine.
  const std::string good = dir.file("good.yml");
  save_calibration(make_rig(), good);
  {
    std::ofstream(good, std::ios::app) << "...\n# written by hand\n\n";
  }
  EXPECT_NO_THROW(load_calibration(good));
  write_text(dir.file("cut.yml.gz"), std::string("\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\x03\xcb", 11));
  expect_error([&] { load_calibration(dir.file("cut.yml.gz")); }, "cut.yml.gz", "",
               "not a valid gzip file");
}

TEST(Calibration, ScalesOnlyByAPureScale)
{
  StereoCalibration rig = make_rig();
  add_rectification(rig);
  const StereoCalibration half = scale_calibration(rig, {320, 240});
  // A 3D point lands, in the half-size image, where the full-size pixel centre maps to.
  const std::vector<cv::Point3d> X{{120, -40, 1500}};
  std::vector<cv::Point2d> full, small;
  cv::projectPoints(X, cv::Vec3d(), cv::Vec3d(), rig.M1, rig.D1, full);
  cv::projectPoints(X, cv::Vec3d(), cv::Vec3d(), half.M1, half.D1, small);
  EXPECT_NEAR(small[0].x, (full[0].x + 0.5) * 0.5 - 0.5, 1e-9);
  EXPECT_NEAR(small[0].y, (full[0].y + 0.5) * 0.5 - 0.5, 1e-9);
  EXPECT_NEAR(half.baseline_mm(), rig.baseline_mm(), 1e-12);
  EXPECT_NEAR(half.P2.at<double>(0, 3), rig.P2.at<double>(0, 3) * 0.5, 1e-9);
  EXPECT_NEAR(half.Q.at<double>(3, 2), rig.Q.at<double>(3, 2), 1e-12); // 1/B does not scale
  EXPECT_NEAR(half.Q.at<double>(2, 3), rig.Q.at<double>(2, 3) * 0.5, 1e-9);

  StereoCalibration big = rig;
  big.image_size = {2592, 1944};
  try {
    scale_calibration(big, {1000, 1000});
    ADD_FAILURE() << "no error for a non-uniform scale";
  } catch (const CalibrationError &e) {
    EXPECT_NE(std::string(e.what()).find("calibration is for 2592x1944 but the stream is 1000x1000: not a pure scale"),
              std::string::npos) << e.what();
  }
  // 2592x1944 binned 3x: exactly 864x648; rounding to 865x649 is still within half a pixel.
  EXPECT_NO_THROW(scale_calibration(big, {864, 648}));
  EXPECT_NO_THROW(scale_calibration(big, {865, 649}));
}

// Found by fuzzing: sizes and matrix dimensions far outside int were cast to int (undefined
// behaviour). They are refused with the key named.
TEST(CalibrationErrors, NumbersBeyondIntRange)
{
  TempDir dir("treestereo-calib");
  StereoCalibration rig = make_rig();
  add_rectification(rig);
  std::string left = ros_camera("left", rig.image_size, rig.M1, rig.D1, rig.R1, rig.P1);
  write_text(dir.file("right.yaml"), ros_camera("right", rig.image_size, rig.M2, rig.D2, rig.R2, rig.P2));
  const std::string rows = "camera_matrix:\n  rows: 3";
  write_text(dir.file("left.yaml"), std::string(left).replace(left.find(rows), rows.size(),
                                                             "camera_matrix:\n  rows: 1e300"));
  expect_error([&] { load_calibration(dir.file("left.yaml") + ";" + dir.file("right.yaml")); },
               "left.yaml", "camera_matrix.rows", "out of range");
  write_opencv(dir.file("good.yml"), rig);
  std::ifstream in(dir.file("good.yml"));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string width = "image_width: 640";
  ASSERT_NE(text.find(width), std::string::npos);
  write_text(dir.file("big.yml"), text.replace(text.find(width), width.size(), "image_width: 1e20"));
  expect_error([&] { load_calibration(dir.file("big.yml")); }, "big.yml", "image_width", "out of range");
}

// Found by fuzzing: OpenCV allocates rows x cols before reading the data, so a corrupt size
// asked for 48 GB. The header is checked first.
TEST(CalibrationErrors, MatrixSizeFromTheFileIsBounded)
{
  TempDir dir("treestereo-calib");
  write_opencv(dir.file("good.yml"), make_rig());
  std::ifstream in(dir.file("good.yml"));
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto m2 = text.find("M2:");
  const auto cols = text.find("cols: 3", m2);
  ASSERT_NE(cols, std::string::npos);
  write_text(dir.file("huge.yml"), std::string(text).replace(cols, 7, "cols: 400000000"));
  expect_error([&] { load_calibration(dir.file("huge.yml")); }, "huge.yml", "M2", "rows and columns");
  write_text(dir.file("word.yml"), std::string(text).replace(cols, 7, "cols: three"));
  expect_error([&] { load_calibration(dir.file("word.yml")); }, "word.yml", "M2", "integer rows and cols");
  write_text(dir.file("short.yml"), std::string(text).replace(cols, 7, "cols: 4"));
  expect_error([&] { load_calibration(dir.file("short.yml")); }, "short.yml", "M2", "data has 9 values");
}
