// Depth on real data: Middlebury Jadeplant (a potted plant 2.0-3.3 m away, quarter resolution)
// through the project's own chain in lib/: the plant segmented by its colour, SIFT matched with
// the stereo constraints and refined, triangulated. The median depth of the plant's points must
// be within 1% of the ground-truth median over the same pixels (the accuracy target).
#include "treestereo/data_dir.hpp"
#include "treestereo/densify.hpp"
#include "treestereo/depth.hpp"
#include "treestereo/match.hpp"
#include "treestereo/middlebury.hpp"
#include "treestereo/segment.hpp"
#include "treestereo/stats.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iostream>

using namespace treestereo;

namespace {

// The median depth of the valid points on the plant against the ground truth's median over the
// same pixels.
void expect_median_depth_within_one_percent(const DepthResult &d,
                                            const std::vector<StereoMatch> &matches,
                                            const MiddleburyScene &s, const StereoGeometry &g,
                                            const cv::Mat &mask, const char *what)
{
  std::vector<double> measured, truth;
  for (const Point3 &p : d.points) {
    if (!p.valid)
      continue;
    const StereoMatch &m = matches[p.match_index];
    const int x = int(std::lround(m.xl)), y = int(std::lround(m.yl));
    if (x < 0 || y < 0 || x >= s.disp_gt.cols || y >= s.disp_gt.rows || !mask.at<uchar>(y, x))
      continue;
    const float dg = s.disp_gt.at<float>(y, x);
    if (!std::isfinite(dg) || dg <= 0)
      continue;
    measured.push_back(p.z);
    truth.push_back(g.fx * g.baseline_mm / (dg + s.calib.doffs));
  }
  ASSERT_GE(measured.size(), 50u) << what << ": too few plant points with ground truth";
  const double zm = median(measured), zt = median(truth);
  std::cout << "Jadeplant, " << what << ": " << measured.size() << " plant points, median depth "
            << zm << " mm, ground truth " << zt << " mm (" << 100.0 * (zm - zt) / zt << "%)\n";
  EXPECT_NEAR(zm, zt, 0.01 * zt) << what;
}

} // namespace

TEST(Jadeplant, MedianDepthOfThePlantWithinOnePercent)
{
  const std::string dir = data_dir() + "/middlebury2014-quarter/Jadeplant";
  if (!std::ifstream(dir + "/disp0GT.pfm").good())
    GTEST_SKIP() << "Middlebury Jadeplant not found in " << dir
                 << " (set TREESTEREO_DATA_DIR to the shared data directory)";
  const MiddleburyScene s = load_middlebury_scene(dir);
  const StereoGeometry g = s.calib.geometry();

  SegmentParams sp; // defaults (exg-norm, Otsu); the images are BGR
  sp.order = ChannelOrder{2, 1, 0};
  sp.keep = KeepMode::All; // the leaves are many separate regions
  const Silhouette plant = segment_vegetation(s.left, sp);
  ASSERT_TRUE(plant.present);

  // lib's matcher (euclidean, 2 px band, mutual, refine; without siftmatch's two-layer test)
  // with a depth range around the plant, as a sprayer is set up for its row
  MatchParams mp;
  const DisparityRange range = disparity_range_for_depth(g, 1800, 3600);
  mp.matcher.constraints.min_disparity = range.min;
  mp.matcher.constraints.max_disparity = range.max;
  const StereoMatchResult r = StereoMatcher(mp).run(s.left, s.right, plant.mask, cv::Mat());
  const DepthResult d = triangulate_matches(r.matches, g, DepthParams{});

  // and as stereodepth does by default: the matches seed a grid of the plant's pixels
  DensifyParams dp;
  dp.order = sp.order;
  DensifyStats ds;
  std::vector<StereoMatch> all = r.matches;
  const std::vector<StereoMatch> grid =
      densify_matches(s.left, s.right, plant.mask, r.matches, dp, &ds);
  all.insert(all.end(), grid.begin(), grid.end());
  const DepthResult dd = triangulate_matches(all, g, DepthParams{});
  std::cout << "Jadeplant, densified: grid step " << ds.step << " px, " << ds.kept << " of "
            << ds.grid << " grid points kept, disparity window " << ds.min_disparity << ".."
            << ds.max_disparity << "\n";
  EXPECT_GT(ds.kept, 10 * r.matches.size()) << "densification found (nearly) nothing";
  expect_median_depth_within_one_percent(dd, all, s, g, plant.mask, "densified");
  expect_median_depth_within_one_percent(d, r.matches, s, g, plant.mask, "SIFT matches");
}

