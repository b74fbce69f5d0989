// Nozzle sections from the row map: valve commands timed for the travel (DESIGN.md
// "In an orchard": section command fields section, on, rate, at_ns, position_m).
//
// The nozzles sit nozzle_offset_m behind the camera along the travel. A canopy slice at world
// x (m along the row) reaches them when the rig's position p(t) = x + nozzle_offset_m. p(t) is
// extrapolated from the latest position and the recent speed (position over running time);
// the valve is told to switch valve_latency earlier, so it is open when the slice arrives:
//
//   at_ns = t_now + (x + nozzle_offset_m - p_now) / speed * 1e9 - valve_latency_ns
//
// Commands wait in the planner, re-timed on every update with the latest speed, and are handed
// out once they fall due before the next frame is expected (or when late), so a speed change is
// followed up to the last frame before the valve switches.
//
// Per section, runs along the row: a gap shorter than min_gap_m between canopy stays sprayed;
// canopy (gaps closed) shorter than min_canopy_m is not sprayed, unless it begins where the data
// begins or resumes after the fail-safe (that slice's start): the view cut it there, and how far
// it goes on before is not known. Missing bins count as gaps.
// Within a bin the canopy runs from its cells' leftmost to their rightmost canopy pixel
// (SliceSection::lo_m / hi_m): a valve switches at the canopy's edge, not at the bin's, so the
// bin's length (50 mm) does not add to the switch's error.
//
// Fail-safe: without data for hold_time_ns the last state is kept; then every section goes to
// the fallback state with one command each (Fallback::Hold: none); the next data resumes control.
#pragma once

#include "treestereo/rowmap.hpp"

#include <cstdint>
#include <deque>
#include <string>
#include <vector>

namespace treestereo {

enum class RateModel { OnOff, Proportional };
enum class SprayFallback { On, Off, Hold };

struct SprayParams {
  int n_sections = 4;              // >= 1
  double nozzle_offset_m = 1.5;    // nozzles behind the camera along the travel, >= 0
  std::int64_t valve_latency_ns = 160000000; // valve response, >= 0
  double min_gap_m = 0.075;        // shorter gaps stay sprayed, >= 0
  double min_canopy_m = 0.10;      // shorter canopy is not sprayed, >= 0
  RateModel rate_model = RateModel::OnOff;
  double rate_step = 0.1;          // proportional rates are rounded to this step, (0, 1]
  std::int64_t hold_time_ns = 500000000; // > 0
  SprayFallback fallback = SprayFallback::On;
  // Speed from the oldest sample of this window (at least the previous one), > 0.
  std::int64_t speed_window_ns = 250000000;
};

// Throws BadSettings naming the field when a value is out of range.
void validate(const SprayParams &p);

// A section's height range above the ground (m).
struct SectionRange {
  double lo_m = 0, hi_m = 0;
};

// "0.4:0.7,0.7:1.0" -> ranges (m). Empty text: none. Throws BadSettings naming the text
// and what is wrong (not lo:hi, not a number, lo >= hi, negative).
std::vector<SectionRange> parse_section_heights(const std::string &text);

// One section over one travel bin.
struct SliceSection {
  bool present = false;
  double fill = 0;        // mean fill of the present cells it overlaps (0..1)
  double width_share = 0; // share of the section's height covered by present cells (0..1)
  // Where along the row its canopy lies within the bin (world x, m; lo_m < hi_m), when present:
  // the cells' RowMapCell::lo_m / hi_m. Both 0: unknown, the whole bin.
  double lo_m = 0, hi_m = 0;
};

// A travel bin newly final in the map: its world extent along the row and each section.
struct SpraySlice {
  double start_m = 0, end_m = 0;
  std::vector<SliceSection> sections;
};

// A bin's cells (one per band, band edges in mm) as sections: with `ranges` empty one section
// per band, else each range overlapping the bands (height-weighted).
std::vector<SliceSection> sections_of(const std::vector<RowMapCell> &cells,
                                      const std::vector<double> &band_edges_mm,
                                      const std::vector<SectionRange> &ranges);

// The bins of `map` final at position_mm and not yet taken (`next_bin`: the first bin not yet
// taken, updated; start it at LONG_MIN) as slices. A bin is final once the rig has passed the
// next bin's centre by the map's settle distance (RowMap::settle_mm(): the frames that may still
// vote for a band), as a cell's presence may depend on its neighbours (RowMap::cell()). Taken
// sooner, a band that the frames after the nearest see present would be planned empty, and the
// valve would close where the map (treemetrics' row-map-location) shows canopy.
std::vector<SpraySlice> take_final_slices(const RowMap &map, double position_mm, long &next_bin,
                                          const std::vector<SectionRange> &ranges);

struct SectionCommand {
  int section = 0;
  bool on = false;
  double rate = 0;         // 0..1 (on/off model: 1 or 0)
  std::int64_t at_ns = 0;  // running time at which the valve must switch
  double position_m = 0;   // world position of the canopy slice it is for
};

// The stretches each section sprays, from its commands in time order: from an opening's
// position_m to the next closing's (a section left open at the end: end_m = +infinity). Rate
// changes of an open valve continue the stretch; fail-safe commands (no canopy position) are
// left out by the caller.
std::vector<SprayedStretch> sprayed_stretches(const std::vector<SectionCommand> &commands);

class SprayPlanner {
public:
  explicit SprayPlanner(const SprayParams &p); // validates

  // One frame: its running time, the rig's position (m) and the slices newly final (ascending,
  // not before earlier ones). Returns the commands now due.
  std::vector<SectionCommand> update(std::int64_t running_ns, double position_m,
                                     const std::vector<SpraySlice> &slices);
  // No frame: at running_ns past the last data by hold_time_ns the fallback commands (once).
  std::vector<SectionCommand> tick(std::int64_t running_ns);
  // End of data: every planned command, timed with the last speed; `rest` first: the map's bins
  // not final yet (take_final_slices() at an infinite position), which no later frame will
  // change.
  std::vector<SectionCommand> finish(const std::vector<SpraySlice> &rest = {});

  bool in_fallback() const { return fallback_; }
  bool has_data() const { return !samples_.empty(); }
  std::int64_t last_data_ns() const { return samples_.empty() ? 0 : samples_.back().t; }
  double speed_m_s() const; // the latest estimate; 0 without two samples
  const SprayParams &params() const { return p_; }

private:
  struct Sample {
    std::int64_t t;
    double x;
  };
  struct Planned {
    int section;
    bool on;
    double rate;
    double x;
  };
  struct Section {
    bool on = false;       // state after the planned commands
    double rate = 0;       // rate after the planned commands
    bool cand = false;     // off: a canopy run not yet min_canopy long
    bool cand_open = false; // the run begins where the data begins: sprayed at any length
    double cand_start = 0, cand_end = 0;
    std::vector<Planned> cand_rates; // rate changes inside the candidate run
    bool in_gap = false;   // on: a gap not yet min_gap long
    double gap_start = 0;
  };
  double rate_of(const SliceSection &s) const;
  void check(const std::vector<SpraySlice> &slices) const; // throws BadInput
  void plan(const std::vector<SpraySlice> &slices);
  void absent(int k, double x_start, double x_end);
  void present(int k, double x_start, double x_end, double rate);
  std::vector<SectionCommand> due(std::int64_t horizon_ns, bool all);
  std::int64_t time_at(double x) const;

  SprayParams p_;
  std::vector<Section> sections_;
  std::deque<Planned> planned_;
  std::deque<Sample> samples_;
  bool have_frontier_ = false;
  double frontier_ = 0;
  double data_start_ = 0; // the first slice's start (valid with have_frontier_)
  std::int64_t frame_ns_ = 0; // the last frame interval
  bool fallback_ = false;
  struct Valve {
    bool on = false;
    double rate = 0;
  };
  std::vector<Valve> valve_; // the state after the commands handed out
};

} // namespace treestereo
