// A small streaming JSON writer for the tools' outputs (JSON lines, ground-truth files).
// Numbers are written with enough digits to round-trip; non-finite numbers become null, so a
// file never holds NaN.
#pragma once

#include <ostream>
#include <string>
#include <vector>

namespace treestereo {

class JsonWriter {
public:
  explicit JsonWriter(std::ostream &out, int precision = 9) : out_(out), precision_(precision) {}

  JsonWriter &begin_object();
  JsonWriter &end_object();
  JsonWriter &begin_array();
  JsonWriter &end_array();
  JsonWriter &key(const std::string &k);
  JsonWriter &value(double v);
  JsonWriter &value(long long v);
  JsonWriter &value(unsigned long long v);
  JsonWriter &value(int v) { return value(static_cast<long long>(v)); }
  JsonWriter &value(unsigned v) { return value(static_cast<unsigned long long>(v)); }
  JsonWriter &value(bool v);
  JsonWriter &value(const std::string &v);
  JsonWriter &value(const char *v) { return value(std::string(v)); }
  JsonWriter &null();
  // Shorthand: key then value.
  template <typename T> JsonWriter &field(const std::string &k, const T &v)
  {
    key(k);
    return value(v);
  }
  JsonWriter &array(const std::vector<double> &v);

private:
  void separator();
  std::ostream &out_;
  int precision_;
  std::vector<bool> first_; // per open container: nothing written in it yet
  bool after_key_ = false;
};

// JSON string literal of s (quotes and escapes).
std::string json_quote(const std::string &s);

} // namespace treestereo
