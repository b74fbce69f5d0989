// libFuzzer target: spraycontrol's section-heights text (parse_section_heights) and the planner
// fed from it (lib/spray.cpp).
//
// Input layout: the text up to the first '\n' is the section-heights property; the bytes after it
// drive the planner, 4 per frame: the travel this frame (0..25.5 cm), the time step (0..255 ms),
// and two bytes of canopy bits (which of the map's 4 bands hold canopy, and where in the bin it
// starts and ends).
// A std::runtime_error from the parser is a fine answer. A crash, a leak, undefined behaviour, a
// range the parser accepts that is not finite, negative or empty, one that does not read back
// the same, or a command out of range (section, rate, time, position) is a bug.
#include "treestereo/spray.hpp"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

using namespace treestereo;

namespace {

void check(bool ok, const char *what)
{
  if (!ok) {
    std::fprintf(stderr, "fuzz-sections: %s\n", what);
    std::abort();
  }
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size)
{
  const std::string all(reinterpret_cast<const char *>(data), size);
  const std::size_t nl = all.find('\n');
  const std::string text = all.substr(0, nl);
  std::vector<SectionRange> ranges;
  try {
    ranges = parse_section_heights(text);
  } catch (const std::runtime_error &) {
    return 0;
  }
  std::string again;
  for (const SectionRange &r : ranges) {
    check(std::isfinite(r.lo_m) && std::isfinite(r.hi_m), "a range is not finite");
    check(r.lo_m >= 0 && r.lo_m < r.hi_m, "a range is negative or empty");
    char b[80];
    std::snprintf(b, sizeof b, "%s%.17g:%.17g", again.empty() ? "" : ",", r.lo_m, r.hi_m);
    again += b;
  }
  const std::vector<SectionRange> back = parse_section_heights(again);
  check(back.size() == ranges.size(), "the ranges do not read back");
  for (std::size_t i = 0; i < back.size(); ++i)
    check(back[i].lo_m == ranges[i].lo_m && back[i].hi_m == ranges[i].hi_m,
          "a range does not read back the same");
  if (ranges.size() > 64 || nl == std::string::npos)
    return 0;

  // The planner over bins of 50 mm, the map's 4 default bands 0.4-1.6 m.
  const std::vector<double> edges = {400, 700, 1000, 1300, 1600};
  SprayParams p;
  p.n_sections = ranges.empty() ? 4 : int(ranges.size());
  SprayPlanner planner(p);
  std::int64_t t = 0;
  double pos = 0, next_bin = 0;
  const std::uint8_t *d = data + nl + 1;
  const std::size_t n = size - nl - 1;
  std::vector<SectionCommand> cmds;
  for (std::size_t i = 0; i + 4 <= n; i += 4) {
    pos += d[i] / 1000.0;
    t += std::int64_t(d[i + 1]) * 1000000;
    std::vector<SpraySlice> slices;
    while (next_bin + 0.05 <= pos) {
      std::vector<RowMapCell> cells(4);
      for (int k = 0; k < 4; ++k) {
        RowMapCell &c = cells[std::size_t(k)];
        c.seen = true;
        c.present = (d[i + 2] >> k) & 1;
        c.fill = c.present ? 0.5 : 0;
        if (c.present) {
          // Somewhere in the bin: from a sixteenth-step start to a sixteenth-step share of the
          // rest.
          c.lo_m = next_bin + 0.05 * (d[i + 3] & 15) / 16.0;
          c.hi_m = c.lo_m + (next_bin + 0.05 - c.lo_m) * ((d[i + 3] >> 4) + 1) / 16.0;
        }
      }
      SpraySlice s;
      s.start_m = next_bin;
      s.end_m = next_bin + 0.05;
      s.sections = sections_of(cells, edges, ranges);
      slices.push_back(s);
      next_bin += 0.05;
    }
    const auto got = planner.update(t, pos, slices);
    cmds.insert(cmds.end(), got.begin(), got.end());
  }
  const auto rest = planner.finish();
  cmds.insert(cmds.end(), rest.begin(), rest.end());
  for (const SectionCommand &c : cmds) {
    check(c.section >= 0 && c.section < p.n_sections, "a command for no section");
    check(c.rate >= 0 && c.rate <= 1, "a rate out of 0..1");
    check(std::isfinite(c.position_m) && c.position_m >= 0 && c.position_m <= next_bin + 1e-9,
          "a command's position off the slices");
    check(c.on == (c.rate > 0), "on and rate disagree");
  }
  return 0;
}
