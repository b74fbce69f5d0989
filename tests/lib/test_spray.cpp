// The spray planner on constructed maps: timing, min-gap / min-canopy, speed changes, the
// fail-safe, rates and the section heights.
#include "treestereo/errors.hpp"
#include "treestereo/spray.hpp"
#include "typed_error.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <stdexcept>
#include <vector>

using namespace treestereo;

namespace {

constexpr double kBin = 0.05;
constexpr std::int64_t kMs = 1000000;

// Canopy of one section: [start, end) intervals along the row (m).
using Canopy = std::vector<std::pair<double, double>>;

bool inside(const Canopy &c, double x)
{
  for (const auto &iv : c)
    if (x >= iv.first - 1e-9 && x < iv.second - 1e-9)
      return true;
  return false;
}

struct Emitted {
  SectionCommand c;
  std::int64_t emitted_ns;
};

// Drives the planner: a frame every frame_ns, the position from position(t); each frame the
// bins the rig passed with the next bin's centre become final (as take_final_slices does for a
// map that settles at once),
// present where the canopy is. Runs until t_end_ns, then finish().
std::vector<Emitted> drive(SprayPlanner &planner, const Canopy &canopy,
                           const std::function<double(std::int64_t)> &position,
                           std::int64_t frame_ns, std::int64_t t_end_ns, double fill = 1.0)
{
  std::vector<Emitted> out;
  long next_bin = 0;
  for (std::int64_t t = 0; t <= t_end_ns; t += frame_ns) {
    const double p = position(t);
    std::vector<SpraySlice> slices;
    while ((double(next_bin) + 1.5) * kBin <= p + 1e-12) {
      SpraySlice s;
      s.start_m = double(next_bin) * kBin;
      s.end_m = double(next_bin + 1) * kBin;
      SliceSection sec;
      sec.present = inside(canopy, s.start_m + 0.5 * kBin);
      sec.fill = sec.present ? fill : 0;
      sec.width_share = sec.present ? 1 : 0;
      s.sections.assign(std::size_t(planner.params().n_sections), sec);
      slices.push_back(s);
      ++next_bin;
    }
    for (const SectionCommand &c : planner.update(t, p, slices))
      out.push_back({c, t});
  }
  for (const SectionCommand &c : planner.finish())
    out.push_back({c, t_end_ns});
  return out;
}

SprayParams one_section()
{
  SprayParams p;
  p.n_sections = 1;
  return p;
}

// at_ns where the nozzle, offset behind the camera, reaches x at constant speed v from 0.
std::int64_t expected_at(double x, double offset, double v, std::int64_t latency)
{
  return std::llround((x + offset) / v * 1e9) - latency;
}

} // namespace

TEST(Spray, TimingAtSeveralSpeedsAndLatencies)
{
  for (double v : {0.5, 1.0, 2.0})
    for (std::int64_t latency : {std::int64_t(0), 160 * kMs, 300 * kMs})
      for (double offset : {1.5, 0.8}) {
        SCOPED_TRACE("speed " + std::to_string(v) + " latency " + std::to_string(latency) +
                     " offset " + std::to_string(offset));
        SprayParams p = one_section();
        p.valve_latency_ns = latency;
        p.nozzle_offset_m = offset;
        SprayPlanner planner(p);
        const Canopy canopy = {{2.0, 3.0}};
        const std::int64_t frame = 100 * kMs;
        const std::vector<Emitted> e = drive(
            planner, canopy, [v](std::int64_t t) { return v * double(t) * 1e-9; }, frame,
            std::int64_t((6.0 + offset) / v * 1e9));
        ASSERT_EQ(e.size(), 2u);
        EXPECT_TRUE(e[0].c.on);
        EXPECT_EQ(e[0].c.rate, 1.0);
        EXPECT_DOUBLE_EQ(e[0].c.position_m, 2.0);
        EXPECT_NEAR(double(e[0].c.at_ns), double(expected_at(2.0, offset, v, latency)), 2);
        EXPECT_FALSE(e[1].c.on);
        EXPECT_EQ(e[1].c.rate, 0.0);
        EXPECT_DOUBLE_EQ(e[1].c.position_m, 3.0);
        EXPECT_NEAR(double(e[1].c.at_ns), double(expected_at(3.0, offset, v, latency)), 2);
        // Handed out no later than the switch, within the frame before it.
        for (const Emitted &x : e) {
          EXPECT_LE(x.emitted_ns, x.c.at_ns);
          EXPECT_LE(x.c.at_ns, x.emitted_ns + frame);
        }
      }
}

TEST(Spray, ShortGapStaysSprayedTenCentimetreGapCloses)
{
  const auto drive_gap = [](double gap) {
    SprayPlanner planner(one_section());
    const Canopy canopy = {{2.0, 2.5}, {2.5 + gap, 3.0}};
    return drive(planner, canopy, [](std::int64_t t) { return double(t) * 1e-9; }, 100 * kMs,
                 6000 * kMs);
  };
  const std::vector<Emitted> short_gap = drive_gap(0.05);
  ASSERT_EQ(short_gap.size(), 2u);
  EXPECT_TRUE(short_gap[0].c.on);
  EXPECT_DOUBLE_EQ(short_gap[1].c.position_m, 3.0);

  const std::vector<Emitted> gap = drive_gap(0.10);
  ASSERT_EQ(gap.size(), 4u);
  EXPECT_TRUE(gap[0].c.on);
  EXPECT_FALSE(gap[1].c.on);
  EXPECT_NEAR(gap[1].c.position_m, 2.5, 1e-9);
  EXPECT_TRUE(gap[2].c.on);
  EXPECT_NEAR(gap[2].c.position_m, 2.6, 1e-9);
  EXPECT_FALSE(gap[3].c.on);
  // The valve is closed for the gap's travel time: 0.1 m at 1 m/s.
  EXPECT_NEAR(double(gap[2].c.at_ns - gap[1].c.at_ns), 100e6, 2);
}

TEST(Spray, ShortCanopyIsNotSprayed)
{
  const auto count = [](double len, double min_canopy) {
    SprayParams p = one_section();
    p.min_canopy_m = min_canopy;
    SprayPlanner planner(p);
    return drive(planner, {{1.0, 1.0 + len}}, [](std::int64_t t) { return double(t) * 1e-9; },
                 100 * kMs, 4000 * kMs)
        .size();
  };
  EXPECT_EQ(count(0.05, 0.10), 0u);
  EXPECT_EQ(count(0.10, 0.10), 2u);
  EXPECT_EQ(count(0.15, 0.20), 0u);
  EXPECT_EQ(count(0.20, 0.20), 2u);
  // Pieces of canopy joined by a short gap count as one run.
  SprayPlanner planner(one_section());
  EXPECT_EQ(drive(planner, {{1.0, 1.05}, {1.10, 1.15}},
                  [](std::int64_t t) { return double(t) * 1e-9; }, 100 * kMs, 4000 * kMs)
                .size(),
            2u);
}

TEST(Spray, CanopyWhereTheDataBeginsIsSprayedAtAnyLength)
{
  // The first frame's view cut a neighbour's crown: 50 mm of it where the data begins (x = 0).
  // How far it goes on before is not known; it is sprayed, under min_canopy as it is.
  SprayPlanner planner(one_section());
  const auto at_start = drive(planner, {{0.0, 0.05}, {1.0, 1.05}},
                              [](std::int64_t t) { return double(t) * 1e-9; }, 100 * kMs,
                              4000 * kMs);
  ASSERT_EQ(at_start.size(), 2u); // the piece at 1.0 m is a speck: not sprayed
  EXPECT_TRUE(at_start[0].c.on);
  EXPECT_NEAR(at_start[0].c.position_m, 0.0, 1e-9);
  EXPECT_FALSE(at_start[1].c.on);
  EXPECT_NEAR(at_start[1].c.position_m, 0.05, 1e-9);
  // Canopy that begins a bin after the data does: its start was seen, min_canopy holds.
  SprayPlanner later(one_section());
  EXPECT_EQ(drive(later, {{0.05, 0.10}}, [](std::int64_t t) { return double(t) * 1e-9; },
                  100 * kMs, 4000 * kMs)
                .size(),
            0u);
}

TEST(Spray, SpeedChangeHalfwayIsFollowed)
{
  // 1 m/s up to 2 s, then 2 m/s. The canopy at 4.0-5.0 m reaches the nozzles (1.5 m behind)
  // at p = 5.5 m and 6.5 m: t = 3.75 s and 4.25 s.
  SprayPlanner planner(one_section());
  const auto pos = [](std::int64_t t) {
    const double s = double(t) * 1e-9;
    return s <= 2.0 ? s : 2.0 + 2.0 * (s - 2.0);
  };
  const std::vector<Emitted> e = drive(planner, {{4.0, 5.0}}, pos, 50 * kMs, 6000 * kMs);
  ASSERT_EQ(e.size(), 2u);
  EXPECT_NEAR(double(e[0].c.at_ns), 3750e6 - 160e6, 2);
  EXPECT_NEAR(double(e[1].c.at_ns), 4250e6 - 160e6, 2);
  // At the old speed the on command would have been 1.75 s later.
  EXPECT_GT(std::abs(double(e[0].c.at_ns) - (5500e6 - 160e6)), 1e9);
}

TEST(Spray, SprayedLengthEqualsCanopyLength)
{
  SprayParams p;
  p.n_sections = 3;
  SprayPlanner planner(p);
  const Canopy canopy = {{1.0, 1.8}, {2.3, 2.45}, {3.0, 4.25}};
  const double v = 1.5;
  const std::vector<Emitted> e = drive(
      planner, canopy, [v](std::int64_t t) { return v * double(t) * 1e-9; }, 80 * kMs,
      5000 * kMs);
  for (int k = 0; k < 3; ++k) {
    double on_x = 0, sprayed_m = 0, sprayed_time_m = 0;
    std::int64_t on_t = 0;
    bool on = false;
    int switches = 0;
    for (const Emitted &x : e) {
      if (x.c.section != k)
        continue;
      ++switches;
      ASSERT_NE(x.c.on, on) << "a repeated state";
      if (x.c.on) {
        on_x = x.c.position_m;
        on_t = x.c.at_ns;
      } else {
        sprayed_m += x.c.position_m - on_x;
        sprayed_time_m += v * double(x.c.at_ns - on_t) * 1e-9;
      }
      on = x.c.on;
    }
    EXPECT_FALSE(on);
    EXPECT_EQ(switches, 6);
    EXPECT_NEAR(sprayed_m, 0.8 + 0.15 + 1.25, 1e-9);
    EXPECT_NEAR(sprayed_time_m, 0.8 + 0.15 + 1.25, 1e-8);
  }
}

TEST(Spray, FailSafeAfterHoldTime)
{
  for (SprayFallback fb : {SprayFallback::On, SprayFallback::Off, SprayFallback::Hold}) {
    SprayParams p;
    p.n_sections = 2;
    p.fallback = fb;
    SprayPlanner planner(p);
    // Sprayed canopy under both sections, then the frames stop at 1 s (position 1 m).
    std::vector<SpraySlice> slices;
    for (int b = 0; b < 20; ++b) {
      SpraySlice s;
      s.start_m = b * kBin;
      s.end_m = (b + 1) * kBin;
      SliceSection on;
      on.present = true;
      on.fill = on.width_share = 1;
      s.sections = {on, on};
      slices.push_back(s);
    }
    std::vector<SectionCommand> c = planner.update(0, 0.0, {});
    c = planner.update(900 * kMs, 0.9, {});
    c = planner.update(1000 * kMs, 1.0, slices);
    EXPECT_TRUE(c.empty()); // the canopy is 1.5 m ahead of the nozzles
    const std::int64_t last = 1000 * kMs;
    EXPECT_TRUE(planner.tick(last + 499 * kMs).empty());
    EXPECT_FALSE(planner.in_fallback());
    c = planner.tick(last + 500 * kMs);
    EXPECT_TRUE(planner.in_fallback());
    if (fb == SprayFallback::Hold) {
      EXPECT_TRUE(c.empty());
    } else {
      ASSERT_EQ(c.size(), 2u);
      for (int k = 0; k < 2; ++k) {
        EXPECT_EQ(c[std::size_t(k)].section, k);
        EXPECT_EQ(c[std::size_t(k)].on, fb == SprayFallback::On);
        EXPECT_EQ(c[std::size_t(k)].rate, fb == SprayFallback::On ? 1.0 : 0.0);
        EXPECT_EQ(c[std::size_t(k)].at_ns, last + 500 * kMs);
        EXPECT_NEAR(c[std::size_t(k)].position_m, 1.5 - 1.5, 1e-9);
      }
    }
    EXPECT_TRUE(planner.tick(last + 2000 * kMs).empty()); // once
    // Data again: bare ground. With the fallback on the sections close after min_gap; off or
    // holding (nothing was handed out: off) they stay closed.
    std::vector<SpraySlice> ground;
    for (int b = 40; b < 44; ++b) {
      SpraySlice s;
      s.start_m = b * kBin;
      s.end_m = (b + 1) * kBin;
      s.sections = {SliceSection(), SliceSection()};
      ground.push_back(s);
    }
    c = planner.update(last + 2100 * kMs, 2.2, ground);
    EXPECT_FALSE(planner.in_fallback());
    const std::vector<SectionCommand> rest = planner.finish();
    c.insert(c.end(), rest.begin(), rest.end());
    if (fb == SprayFallback::On) {
      ASSERT_EQ(c.size(), 2u);
      EXPECT_FALSE(c[0].on);
      EXPECT_NEAR(c[0].position_m, 2.0, 1e-9);
    } else {
      EXPECT_TRUE(c.empty());
    }
  }
}

TEST(Spray, ProportionalRate)
{
  SprayParams p = one_section();
  p.rate_model = RateModel::Proportional;
  SprayPlanner planner(p);
  const std::vector<Emitted> e = drive(
      planner, {{1.0, 2.0}}, [](std::int64_t t) { return double(t) * 1e-9; }, 100 * kMs,
      4000 * kMs, 0.44);
  ASSERT_EQ(e.size(), 2u);
  EXPECT_TRUE(e[0].c.on);
  EXPECT_NEAR(e[0].c.rate, 0.4, 1e-12);
  EXPECT_FALSE(e[1].c.on);
}

TEST(Spray, SectionHeights)
{
  const std::vector<SectionRange> r = parse_section_heights("0.4:0.7,0.7:1.3");
  ASSERT_EQ(r.size(), 2u);
  EXPECT_DOUBLE_EQ(r[1].lo_m, 0.7);
  EXPECT_DOUBLE_EQ(r[1].hi_m, 1.3);
  EXPECT_TRUE(parse_section_heights("").empty());
  for (const char *bad : {"0.4-0.7", "0.4:", "x:1", "0.7:0.4", "-0.1:0.3", "0.4:0.7,"}) {
    try {
      parse_section_heights(bad);
      ADD_FAILURE() << bad << " accepted";
    } catch (const BadSettings &e) {
      EXPECT_NE(std::string(e.what()).find(std::string("\"") + bad + "\""), std::string::npos)
          << e.what();
    }
  }
  // Bands 0.4-0.7-1.0-1.3 m: the upper section covers the top two, one of them present.
  std::vector<RowMapCell> cells(3);
  cells[1].seen = cells[1].present = true;
  cells[1].fill = 0.5;
  const std::vector<SliceSection> s = sections_of(cells, {400, 700, 1000, 1300}, r);
  EXPECT_FALSE(s[0].present);
  EXPECT_TRUE(s[1].present);
  EXPECT_NEAR(s[1].width_share, 0.5, 1e-12);
  EXPECT_NEAR(s[1].fill, 0.5, 1e-12);
  EXPECT_EQ(sections_of(cells, {400, 700, 1000, 1300}, {}).size(), 3u);
}

TEST(Spray, RepeatedTimestampKeepsItsSlices)
{
  // A frame with the previous one's running time: no speed sample, but its slices are planned.
  SprayPlanner planner(one_section());
  planner.update(0, 0.0, {});
  planner.update(100 * kMs, 0.1, {});
  std::vector<SpraySlice> slices;
  for (int b = 0; b < 4; ++b) {
    SpraySlice s;
    s.start_m = b * kBin;
    s.end_m = (b + 1) * kBin;
    SliceSection on;
    on.present = true;
    on.fill = on.width_share = 1;
    s.sections = {on};
    slices.push_back(s);
  }
  EXPECT_TRUE(planner.update(100 * kMs, 0.1, slices).empty());
  EXPECT_DOUBLE_EQ(planner.speed_m_s(), 1.0);
  const std::vector<SectionCommand> c = planner.finish();
  ASSERT_EQ(c.size(), 1u);
  EXPECT_TRUE(c[0].on);
  EXPECT_NEAR(double(c[0].at_ns), 100e6 + (0.0 + 1.5 - 0.1) * 1e9 - 160e6, 2);
}

TEST(Spray, SprayedStretchesFromCommands)
{
  // Section 1 opens at 1.0, changes rate, closes at 1.5, opens at 2.0 and is left open;
  // section 0 opens at 0.5 and closes at 0.9 (posted out of time order).
  const std::vector<SectionCommand> cmds = {
      {1, true, 1.0, 100, 1.0}, {0, false, 0.0, 90, 0.9}, {1, true, 0.5, 120, 1.2},
      {1, false, 0.0, 150, 1.5}, {0, true, 1.0, 50, 0.5}, {1, true, 1.0, 200, 2.0}};
  const std::vector<SprayedStretch> s = sprayed_stretches(cmds);
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(s[0].section, 0);
  EXPECT_DOUBLE_EQ(s[0].start_m, 0.5);
  EXPECT_DOUBLE_EQ(s[0].end_m, 0.9);
  EXPECT_EQ(s[1].section, 1);
  EXPECT_DOUBLE_EQ(s[1].start_m, 1.0);
  EXPECT_DOUBLE_EQ(s[1].end_m, 1.5);
  EXPECT_DOUBLE_EQ(s[2].start_m, 2.0);
  EXPECT_TRUE(std::isinf(s[2].end_m));
  EXPECT_TRUE(sprayed_stretches({}).empty());
}

TEST(Spray, ParamsValidated)
{
  SprayParams p;
  p.n_sections = 0;
  EXPECT_THROW(SprayPlanner{p}, BadSettings);
  p = SprayParams();
  p.hold_time_ns = 0;
  EXPECT_THROW(SprayPlanner{p}, BadSettings);
  p = SprayParams();
  p.nozzle_offset_m = -1;
  EXPECT_THROW(SprayPlanner{p}, BadSettings);
}

TEST(Spray, TheEndOfDataPlansTheBinsNotPassed)
{
  // The rig stops at 0.3 m: canopy from 0.2 to 0.5 m is in the map, its bins from 0.25 m on not
  // final yet. finish() with them plans it whole, timed with the last speed (1 m/s).
  SprayPlanner planner(one_section());
  const auto bins = [](int from, int to) {
    std::vector<SpraySlice> out;
    for (int b = from; b < to; ++b) {
      SpraySlice s;
      s.start_m = b * kBin;
      s.end_m = (b + 1) * kBin;
      SliceSection c;
      c.present = b >= 4 && b < 10;
      c.fill = c.width_share = c.present ? 1 : 0;
      s.sections = {c};
      out.push_back(s);
    }
    return out;
  };
  planner.update(0, 0.0, {});
  planner.update(300 * kMs, 0.3, bins(0, 5));
  const std::vector<SectionCommand> c = planner.finish(bins(5, 12));
  ASSERT_EQ(c.size(), 2u);
  EXPECT_TRUE(c[0].on);
  EXPECT_NEAR(c[0].position_m, 0.2, 1e-9);
  EXPECT_FALSE(c[1].on);
  EXPECT_NEAR(c[1].position_m, 0.5, 1e-9);
  EXPECT_NEAR(double(c[1].at_ns), 300e6 + (0.5 + 1.5 - 0.3) * 1e9 - 160e6, 2);
  // without them the canopy known is 50 mm, under min_canopy: none of it would be sprayed
  SprayPlanner cut(one_section());
  cut.update(0, 0.0, {});
  cut.update(300 * kMs, 0.3, bins(0, 5));
  EXPECT_TRUE(cut.finish().empty());
  expect_typed_error<BadInput>([&] { planner.finish({SpraySlice()}); }, "section count");
}

TEST(Spray, ErrorsAreTypedAndNameTheProblem)
{
  SprayParams p;
  p.rate_step = 0;
  expect_typed_error<BadSettings>([&] { SprayPlanner planner{p}; }, "rate_step");
  expect_typed_error<BadSettings>([] { parse_section_heights("0.7:0.4"); }, "lo below hi");
  SprayPlanner planner{SprayParams()};
  expect_typed_error<BadInput>([&] { planner.update(0, std::nan(""), {}); }, "rig's position");
}
