// Nozzle sections from the row map (spray.hpp).
#include "treestereo/spray.hpp"

#include "treestereo/errors.hpp"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <stdexcept>

namespace treestereo {

namespace {
// Lengths are sums of bin widths: a run of exactly min_canopy_m must count as min_canopy_m.
constexpr double kEps = 1e-9;

[[noreturn]] void bad_param(const char *field, const char *range, const std::string &value)
{
  throw BadSettings(std::string("The spray setting ") + field + " is out of range: set it to " +
                        range + ".",
                    std::string("SprayParams.") + field + " = " + value);
}
} // namespace

void validate(const SprayParams &p)
{
  if (p.n_sections < 1 || p.n_sections > 256)
    bad_param("n_sections", "1 to 256", std::to_string(p.n_sections));
  if (!std::isfinite(p.nozzle_offset_m) || p.nozzle_offset_m < 0 || p.nozzle_offset_m > 100)
    bad_param("nozzle_offset_m", "0 to 100 m", std::to_string(p.nozzle_offset_m));
  if (p.valve_latency_ns < 0 || p.valve_latency_ns > 10000000000LL)
    bad_param("valve_latency_ns", "0 to 10 s", std::to_string(p.valve_latency_ns));
  if (!std::isfinite(p.min_gap_m) || p.min_gap_m < 0 || p.min_gap_m > 100)
    bad_param("min_gap_m", "0 to 100 m", std::to_string(p.min_gap_m));
  if (!std::isfinite(p.min_canopy_m) || p.min_canopy_m < 0 || p.min_canopy_m > 100)
    bad_param("min_canopy_m", "0 to 100 m", std::to_string(p.min_canopy_m));
  if (!(p.rate_step > 0) || !(p.rate_step <= 1))
    bad_param("rate_step", "above 0, at most 1", std::to_string(p.rate_step));
  if (p.hold_time_ns <= 0)
    bad_param("hold_time_ns", "above 0", std::to_string(p.hold_time_ns));
  if (p.speed_window_ns <= 0)
    bad_param("speed_window_ns", "above 0", std::to_string(p.speed_window_ns));
}

std::vector<SectionRange> parse_section_heights(const std::string &text)
{
  std::vector<SectionRange> out;
  if (text.empty())
    return out;
  std::size_t start = 0;
  while (start <= text.size()) {
    std::size_t comma = text.find(',', start);
    if (comma == std::string::npos)
      comma = text.size();
    const std::string item = text.substr(start, comma - start);
    const std::string where = "Section heights \"" + text + "\": item \"" + item + "\" ";
    const std::string detail = "parse_section_heights: item at character " + std::to_string(start);
    const std::string fix = "; write each item as lo:hi, heights in m above the ground with lo "
                            "below hi, items comma separated (e.g. 0.4:0.7,0.7:1.0).";
    const std::size_t colon = item.find(':');
    if (colon == std::string::npos)
      throw BadSettings(where + "is not lo:hi (heights in m above the ground)" + fix, detail);
    const std::string a = item.substr(0, colon), b = item.substr(colon + 1);
    char *end = nullptr;
    SectionRange r;
    r.lo_m = std::strtod(a.c_str(), &end);
    if (a.empty() || *end != '\0' || !std::isfinite(r.lo_m))
      throw BadSettings(where + "has no number before ':'" + fix, detail);
    r.hi_m = std::strtod(b.c_str(), &end);
    if (b.empty() || *end != '\0' || !std::isfinite(r.hi_m))
      throw BadSettings(where + "has no number after ':'" + fix, detail);
    if (r.lo_m < 0)
      throw BadSettings(where + "starts below the ground (negative height)" + fix, detail);
    if (!(r.lo_m < r.hi_m))
      throw BadSettings(where + "is empty: lo must be below hi" + fix, detail);
    out.push_back(r);
    start = comma + 1;
  }
  return out;
}

std::vector<SliceSection> sections_of(const std::vector<RowMapCell> &cells,
                                      const std::vector<double> &band_edges_mm,
                                      const std::vector<SectionRange> &ranges)
{
  if (band_edges_mm.size() != cells.size() + 1)
    throw BadInput("The row map's cells and band edges do not agree: give one band edge more "
                   "than cells.",
                   "sections_of: " + std::to_string(cells.size()) + " cells for " +
                       std::to_string(band_edges_mm.size()) + " band edges");
  std::vector<SliceSection> out;
  if (ranges.empty()) {
    for (const RowMapCell &c : cells) {
      SliceSection s;
      s.present = c.present;
      s.fill = c.present ? c.fill : 0;
      s.width_share = c.present ? 1 : 0;
      if (c.present) {
        s.lo_m = c.lo_m;
        s.hi_m = c.hi_m;
      }
      out.push_back(s);
    }
    return out;
  }
  for (const SectionRange &r : ranges) {
    double covered = 0, fill = 0;
    double x_lo = std::numeric_limits<double>::infinity(), x_hi = -x_lo;
    for (std::size_t k = 0; k < cells.size(); ++k) {
      const double lo = band_edges_mm[k] / 1000.0, hi = band_edges_mm[k + 1] / 1000.0;
      const double o = std::min(r.hi_m, hi) - std::max(r.lo_m, lo);
      if (o > 0 && cells[k].present) {
        covered += o;
        fill += cells[k].fill * o;
        if (cells[k].hi_m > cells[k].lo_m) {
          x_lo = std::min(x_lo, cells[k].lo_m);
          x_hi = std::max(x_hi, cells[k].hi_m);
        }
      }
    }
    SliceSection s;
    s.present = covered > 0;
    if (s.present && x_hi > x_lo) {
      s.lo_m = x_lo;
      s.hi_m = x_hi;
    }
    s.fill = s.present ? fill / covered : 0;
    s.width_share = std::min(1.0, covered / (r.hi_m - r.lo_m));
    out.push_back(s);
  }
  return out;
}

std::vector<SpraySlice> take_final_slices(const RowMap &map, double position_mm, long &next_bin,
                                          const std::vector<SectionRange> &ranges)
{
  std::vector<SpraySlice> out;
  if (map.empty())
    return out;
  const double bin = map.params().bin_mm;
  const int nb = map.n_bands();
  for (long b = std::max(next_bin, map.first_bin()); b <= map.last_bin(); ++b) {
    // final once the rig has passed the next bin's centre too, by the map's settle distance
    // (see the header)
    if ((double(b) + 1.5) * bin + map.settle_mm() > position_mm)
      break;
    next_bin = b + 1;
    std::vector<RowMapCell> cells(static_cast<std::size_t>(nb));
    bool seen = false;
    for (int k = 0; k < nb; ++k) {
      cells[std::size_t(k)] = map.cell(b, k);
      seen = seen || cells[std::size_t(k)].seen;
    }
    if (!seen)
      continue; // no frame held the bin whole: a gap to the planner
    SpraySlice s;
    s.start_m = double(b) * bin / 1000.0;
    s.end_m = double(b + 1) * bin / 1000.0;
    s.sections = sections_of(cells, map.band_edges_mm(), ranges);
    out.push_back(std::move(s));
  }
  return out;
}

SprayPlanner::SprayPlanner(const SprayParams &p) : p_(p)
{
  validate(p_);
  sections_.resize(std::size_t(p_.n_sections));
  valve_.resize(std::size_t(p_.n_sections));
}

double SprayPlanner::rate_of(const SliceSection &s) const
{
  if (p_.rate_model == RateModel::OnOff)
    return 1.0;
  const double r = std::clamp(s.fill * s.width_share, 0.0, 1.0);
  // Present canopy always gets some spray: at least one step.
  return std::clamp(std::round(r / p_.rate_step) * p_.rate_step, p_.rate_step, 1.0);
}

void SprayPlanner::present(int k, double x_start, double x_end, double rate)
{
  Section &s = sections_[std::size_t(k)];
  if (s.on) {
    s.in_gap = false; // shorter than min_gap: absent() closes longer ones first
    if (rate != s.rate) {
      planned_.push_back({k, true, rate, x_start});
      s.rate = rate;
    }
    return;
  }
  if (!s.cand) {
    s.cand = true;
    s.cand_open = x_start <= data_start_ + kEps;
    s.cand_start = x_start;
    s.cand_rates.clear();
    s.cand_rates.push_back({k, true, rate, x_start});
  } else if (rate != s.cand_rates.back().rate) {
    s.cand_rates.push_back({k, true, rate, x_start});
  }
  s.cand_end = x_end;
  if (s.cand_open || s.cand_end - s.cand_start >= p_.min_canopy_m - kEps) {
    planned_.insert(planned_.end(), s.cand_rates.begin(), s.cand_rates.end());
    s.on = true;
    s.rate = s.cand_rates.back().rate;
    s.cand = false;
    s.cand_rates.clear();
  }
}

void SprayPlanner::absent(int k, double x_start, double x_end)
{
  Section &s = sections_[std::size_t(k)];
  if (s.on) {
    if (!s.in_gap) {
      s.in_gap = true;
      s.gap_start = x_start;
    }
    if (x_end - s.gap_start >= p_.min_gap_m - kEps) {
      planned_.push_back({k, false, 0.0, s.gap_start});
      s.on = false;
      s.rate = 0;
      s.in_gap = false;
    }
  } else if (s.cand && x_end - s.cand_end >= p_.min_gap_m - kEps) {
    s.cand = false; // the run ended shorter than min_canopy: not sprayed
    s.cand_rates.clear();
  }
}

double SprayPlanner::speed_m_s() const
{
  if (samples_.size() < 2)
    return 0;
  const Sample &last = samples_.back();
  std::size_t i = samples_.size() - 2; // at least the previous sample
  while (i > 0 && last.t - samples_[i - 1].t <= p_.speed_window_ns)
    --i;
  const Sample &old = samples_[i];
  if (last.t <= old.t)
    return 0;
  return (last.x - old.x) / (double(last.t - old.t) * 1e-9);
}

std::int64_t SprayPlanner::time_at(double x) const
{
  const Sample &last = samples_.back();
  const double v = speed_m_s();
  return last.t + std::llround((x + p_.nozzle_offset_m - last.x) / v * 1e9) -
         p_.valve_latency_ns;
}

std::vector<SectionCommand> SprayPlanner::due(std::int64_t horizon_ns, bool all)
{
  std::vector<SectionCommand> out;
  if (planned_.empty() || samples_.empty())
    return out;
  std::stable_sort(planned_.begin(), planned_.end(),
                   [](const Planned &a, const Planned &b) { return a.x < b.x; });
  const bool timed = speed_m_s() > 0;
  if (!timed && !all)
    return out; // standing still: no slice comes nearer the nozzles
  while (!planned_.empty()) {
    const Planned &p = planned_.front();
    const std::int64_t at = timed ? time_at(p.x) : samples_.back().t;
    if (!all && at > horizon_ns)
      break;
    out.push_back({p.section, p.on, p.rate, at, p.x});
    valve_[std::size_t(p.section)] = {p.on, p.rate};
    planned_.pop_front();
  }
  return out;
}

void SprayPlanner::check(const std::vector<SpraySlice> &slices) const
{
  for (const SpraySlice &sl : slices)
    if (int(sl.sections.size()) != p_.n_sections)
      throw BadInput("A row map slice does not have the spray planner's section count: give "
                     "slices with one entry per nozzle section.",
                     "SprayPlanner: a slice with " + std::to_string(sl.sections.size()) +
                         " sections, the planner has " + std::to_string(p_.n_sections));
}

void SprayPlanner::plan(const std::vector<SpraySlice> &slices)
{
  for (const SpraySlice &sl : slices) {
    if (have_frontier_ && sl.end_m <= frontier_ + kEps)
      continue; // already planned
    const double start = have_frontier_ ? std::max(sl.start_m, frontier_) : sl.start_m;
    if (!have_frontier_)
      data_start_ = start;
    if (have_frontier_ && start > frontier_ + kEps)
      for (int k = 0; k < p_.n_sections; ++k)
        absent(k, frontier_, start); // bins no frame held: no canopy known there
    for (int k = 0; k < p_.n_sections; ++k) {
      const SliceSection &s = sl.sections[std::size_t(k)];
      if (!s.present) {
        absent(k, start, sl.end_m);
        continue;
      }
      // The canopy's own extent within the bin, the rest of the bin a gap.
      double lo = start, hi = sl.end_m;
      if (s.hi_m > s.lo_m) {
        lo = std::clamp(s.lo_m, start, sl.end_m);
        hi = std::clamp(s.hi_m, lo, sl.end_m);
      }
      if (lo > start + kEps)
        absent(k, start, lo);
      present(k, lo, std::max(hi, lo + kEps), rate_of(s));
      if (hi < sl.end_m - kEps)
        absent(k, hi, sl.end_m);
    }
    frontier_ = sl.end_m;
    have_frontier_ = true;
  }
}

std::vector<SectionCommand> SprayPlanner::update(std::int64_t running_ns, double position_m,
                                                 const std::vector<SpraySlice> &slices)
{
  if (!std::isfinite(position_m))
    throw BadInput("The rig's position is not finite: the spray planner needs a finite "
                   "position along the row.",
                   "SprayPlanner::update: position_m = " + std::to_string(position_m));
  check(slices);
  if (fallback_) {
    // Data again: control resumes from the state the fallback left the valves in.
    fallback_ = false;
    for (std::size_t k = 0; k < sections_.size(); ++k) {
      Section fresh;
      fresh.on = valve_[k].on;
      fresh.rate = valve_[k].rate;
      sections_[k] = fresh;
    }
    have_frontier_ = false;
  }
  // A frame not later than the last adds no speed sample (its slices still count).
  if (samples_.empty() || running_ns > samples_.back().t) {
    frame_ns_ = samples_.empty() ? 0 : running_ns - samples_.back().t;
    samples_.push_back({running_ns, position_m});
    while (samples_.size() > 2 && running_ns - samples_[1].t > p_.speed_window_ns)
      samples_.pop_front();
  }

  plan(slices);
  return due(running_ns + frame_ns_, false);
}

std::vector<SectionCommand> SprayPlanner::tick(std::int64_t running_ns)
{
  std::vector<SectionCommand> out;
  if (fallback_ || samples_.empty() || running_ns - samples_.back().t < p_.hold_time_ns)
    return out;
  fallback_ = true;
  planned_.clear();
  for (std::size_t k = 0; k < sections_.size(); ++k) {
    Section s;
    if (p_.fallback == SprayFallback::Hold) {
      s.on = valve_[k].on;
      s.rate = valve_[k].rate;
    } else {
      s.on = p_.fallback == SprayFallback::On;
      s.rate = s.on ? 1.0 : 0.0;
      valve_[k] = {s.on, s.rate};
      // Where the rig is believed to be now: the slice under the nozzles.
      const double v = speed_m_s();
      const double x = samples_.back().x + v * double(running_ns - samples_.back().t) * 1e-9 -
                       p_.nozzle_offset_m;
      out.push_back({int(k), s.on, s.rate, running_ns, x});
    }
    sections_[k] = s;
  }
  return out;
}

std::vector<SectionCommand> SprayPlanner::finish(const std::vector<SpraySlice> &rest)
{
  check(rest);
  if (!fallback_)
    plan(rest);
  return due(0, true);
}

std::vector<SprayedStretch> sprayed_stretches(const std::vector<SectionCommand> &commands)
{
  std::map<int, std::vector<const SectionCommand *>> by_section;
  for (const SectionCommand &c : commands)
    by_section[c.section].push_back(&c);
  std::vector<SprayedStretch> out;
  for (auto &[section, cmds] : by_section) {
    std::stable_sort(cmds.begin(), cmds.end(), [](const SectionCommand *a, const SectionCommand *b) {
      return a->at_ns < b->at_ns;
    });
    bool open = false;
    double from = 0;
    for (const SectionCommand *c : cmds) {
      if (c->on && !open)
        from = c->position_m;
      else if (!c->on && open)
        out.push_back({section, std::min(from, c->position_m), std::max(from, c->position_m)});
      open = c->on;
    }
    if (open)
      out.push_back({section, from, std::numeric_limits<double>::infinity()});
  }
  return out;
}

} // namespace treestereo
