// The errors lib/ throws, by who can fix them. Each is a std::runtime_error (catch sites for that
// keep working) whose what() says what is wrong; the element layer maps the type to a GStreamer
// error domain and code.
#pragma once

#include <stdexcept>
#include <string>
#include <utility>

namespace treestereo {

// The base of the typed errors below. what() is the message; detail(), when given, is the
// technical side (the values at odds, the buffer) and what() is then a sentence for a person,
// which the element layer posts as it is.
class Error : public std::runtime_error {
public:
  explicit Error(const std::string &message, std::string detail = std::string())
      : std::runtime_error(message), detail_(std::move(detail))
  {
  }
  const std::string &detail() const { return detail_; }

private:
  std::string detail_;
};

// Data handed in that cannot be used: a frame, a mask or a geometry of the wrong shape or kind.
// Upstream has to change.
class BadInput : public Error {
public:
  using Error::Error;
};

// A parameter value that cannot be used: out of range, malformed, or at odds with another one.
// The settings have to change.
class BadSettings : public Error {
public:
  using Error::Error;
};

// What a file error stopped: reading, writing, or neither (the file was read but its content is
// not usable).
enum class FileAccess { None, Read, Write };

// A file that cannot be opened, read or written; @message names the file and the cause.
class FileError : public Error {
public:
  FileError(std::string path, FileAccess access, const std::string &message);
  const std::string &path() const { return path_; }
  FileAccess access() const { return access_; }

private:
  std::string path_;
  FileAccess access_;
};

} // namespace treestereo
