// Command-line lists of the sweep benchmarks: "1.5:2.5:0.1" (from:to:step) or "0.7,1.0,1.3",
// and sizes "1296x972,2592x1944".
#pragma once

#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace treestereo::bench {

inline std::vector<double> parse_list(const std::string &s)
{
  std::vector<double> v;
  if (s.find(':') != std::string::npos) {
    double a, b, step;
    if (std::sscanf(s.c_str(), "%lf:%lf:%lf", &a, &b, &step) == 3 && step > 0)
      for (int i = 0; a + i * step <= b + 1e-9; i++)
        v.push_back(a + i * step);
    return v;
  }
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    v.push_back(std::stod(item));
  return v;
}

inline std::vector<cv::Size> parse_sizes(const std::string &s)
{
  std::vector<cv::Size> v;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    int w, h;
    if (std::sscanf(item.c_str(), "%dx%d", &w, &h) == 2)
      v.emplace_back(w, h);
  }
  return v;
}

// The sweep's lists as given on the command line, parsed by the functions above.
struct Sweep {
  std::string sizes, distances, seeds, lights;
};

// Stores `value` into the field `fields` names for `option`; false when it names none.
inline bool take_option(const std::string &option, const std::string &value,
                        std::initializer_list<std::pair<const char *, std::string *>> fields)
{
  for (const auto &[name, field] : fields)
    if (option == name) {
      *field = value;
      return true;
    }
  return false;
}

// Takes one of the sweep's options ("--sizes", "--distances", "--seeds", "--lights") with its
// value into `s`; false for any other option.
inline bool sweep_option(const std::string &option, const std::string &value, Sweep &s)
{
  return take_option(option, value,
                     {{"--sizes", &s.sizes},
                      {"--distances", &s.distances},
                      {"--seeds", &s.seeds},
                      {"--lights", &s.lights}});
}

// Mean and worst of the absolute errors of a set of frames (or bands).
struct AbsErrors {
  std::vector<double> abs;
  void add(double error) { abs.push_back(std::abs(error)); }
  std::size_t n() const { return abs.size(); }
  double mean() const
  {
    double s = 0;
    for (double a : abs)
      s += a;
    return abs.empty() ? 0.0 : s / double(abs.size());
  }
  double worst() const { return abs.empty() ? 0.0 : *std::max_element(abs.begin(), abs.end()); }
  // "mean / worst" with `scale` (100 for %) and `decimals`; "-" when empty.
  std::string cell(double scale = 100.0, int decimals = 2) const
  {
    if (abs.empty())
      return "-";
    char b[64];
    std::snprintf(b, sizeof b, "%.*f / %.*f", decimals, scale * mean(), decimals, scale * worst());
    return b;
  }
};

} // namespace treestereo::bench
