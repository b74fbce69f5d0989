// Where the shared real data (Middlebury, OpenCV's samples, orchard photos; never in the
// repository) is read from: $TREESTEREO_DATA_DIR when set, else the folder the build passed as
// the TREESTEREO_DATA_DIR macro (tests and benches: <source>/../shared/data).
#pragma once

#include <cstdlib>
#include <string>

namespace treestereo {

inline std::string data_dir(const char *built_in)
{
  const char *env = std::getenv("TREESTEREO_DATA_DIR");
  return env && *env ? env : built_in;
}

#ifdef TREESTEREO_DATA_DIR
inline std::string data_dir() { return data_dir(TREESTEREO_DATA_DIR); }
#endif

} // namespace treestereo
