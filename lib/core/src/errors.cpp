#include "treestereo/errors.hpp"

#include <utility>

namespace treestereo {

FileError::FileError(std::string path, FileAccess access, const std::string &message)
    : Error(message), path_(std::move(path)), access_(access)
{
}

} // namespace treestereo
