/* A fresh directory under the system's temporary folder, removed with all it holds when the
 * object goes: the tests' one way to hold files they write. A function-local static one lives
 * until the process exits (a gstcheck test's forked child, or a fuzzer's run). */
#pragma once

#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>

class TempDir {
public:
  /* @prefix names the directory ("<prefix>-XXXXXX"), so a leftover says whose it is. */
  explicit TempDir(const std::string &prefix)
  {
    std::string tmpl = (std::filesystem::temp_directory_path() / (prefix + "-XXXXXX")).string();
    if (!mkdtemp(tmpl.data()))
      throw std::runtime_error("cannot make a directory like " + tmpl);
    path_ = tmpl;
  }
  ~TempDir()
  {
    std::error_code ec; // a destructor does not throw: what cannot be removed stays
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir &) = delete;
  TempDir &operator=(const TempDir &) = delete;

  const std::string &path() const { return path_; }
  std::string file(const std::string &name) const { return path_ + "/" + name; }

private:
  std::string path_;
};
