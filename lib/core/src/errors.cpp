#include "treestereo/errors.hpp"
#include "treestereo/types.hpp"

#include <cmath>
#include <utility>

namespace treestereo {

void require_valid(const StereoGeometry &g, const char *needs, const char *where)
{
  if (g.valid() && std::isfinite(g.fx) && std::isfinite(g.baseline_mm))
    return;
  throw BadInput(std::string("The stereo geometry is not valid: ") + needs +
                     " needs a calibrated, rectified pair (fx and baseline above 0, a view "
                     "size): rectify the pair with a calibration first.",
                 std::string(where) + ": " + describe(g));
}

FileError::FileError(std::string path, FileAccess access, const std::string &message)
    : Error(message), path_(std::move(path)), access_(access)
{
}

} // namespace treestereo
