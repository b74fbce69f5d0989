// Command-line lists of the sweep benchmarks: "1.5:2.5:0.1" (from:to:step) or "0.7,1.0,1.3",
// and sizes "1296x972,2592x1944".
#pragma once

#include <opencv2/core.hpp>

#include <cstdio>
#include <sstream>
#include <string>
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

// Takes one of the sweep's options ("--sizes", "--distances", "--seeds", "--lights") with its
// value into `s`; false for any other option.
inline bool sweep_option(const std::string &option, const std::string &value, Sweep &s)
{
  std::string *field = option == "--sizes"       ? &s.sizes
                       : option == "--distances" ? &s.distances
                       : option == "--seeds"     ? &s.seeds
                       : option == "--lights"    ? &s.lights
                                                 : nullptr;
  if (field)
    *field = value;
  return field != nullptr;
}

} // namespace treestereo::bench
