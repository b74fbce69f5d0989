#include "treestereo/json.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace treestereo {

std::string json_quote(const std::string &s)
{
  std::string o = "\"";
  for (unsigned char c : s) {
    switch (c) {
    case '"':
      o += "\\\"";
      break;
    case '\\':
      o += "\\\\";
      break;
    case '\n':
      o += "\\n";
      break;
    case '\t':
      o += "\\t";
      break;
    case '\r':
      o += "\\r";
      break;
    default:
      if (c < 0x20) {
        char buf[8];
        std::snprintf(buf, sizeof buf, "\\u%04x", c);
        o += buf;
      } else {
        o += char(c);
      }
    }
  }
  return o + "\"";
}

void JsonWriter::separator()
{
  if (after_key_) {
    after_key_ = false;
    return;
  }
  if (!first_.empty()) {
    if (!first_.back())
      out_ << ',';
    first_.back() = false;
  }
}

JsonWriter &JsonWriter::begin_object()
{
  separator();
  out_ << '{';
  first_.push_back(true);
  return *this;
}

JsonWriter &JsonWriter::end_object()
{
  if (first_.empty())
    throw std::logic_error("JsonWriter: end_object without begin_object");
  first_.pop_back();
  out_ << '}';
  return *this;
}

JsonWriter &JsonWriter::begin_array()
{
  separator();
  out_ << '[';
  first_.push_back(true);
  return *this;
}

JsonWriter &JsonWriter::end_array()
{
  if (first_.empty())
    throw std::logic_error("JsonWriter: end_array without begin_array");
  first_.pop_back();
  out_ << ']';
  return *this;
}

JsonWriter &JsonWriter::key(const std::string &k)
{
  separator();
  out_ << json_quote(k) << ':';
  after_key_ = true;
  return *this;
}

JsonWriter &JsonWriter::value(double v)
{
  separator();
  if (!std::isfinite(v)) {
    out_ << "null";
    return *this;
  }
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.*g", precision_, v);
  out_ << buf;
  return *this;
}

JsonWriter &JsonWriter::value(long long v)
{
  separator();
  out_ << v;
  return *this;
}

JsonWriter &JsonWriter::value(unsigned long long v)
{
  separator();
  out_ << v;
  return *this;
}

JsonWriter &JsonWriter::value(bool v)
{
  separator();
  out_ << (v ? "true" : "false");
  return *this;
}

JsonWriter &JsonWriter::value(const std::string &v)
{
  separator();
  out_ << json_quote(v);
  return *this;
}

JsonWriter &JsonWriter::null()
{
  separator();
  out_ << "null";
  return *this;
}

JsonWriter &JsonWriter::array(const std::vector<double> &v)
{
  begin_array();
  for (double x : v)
    value(x);
  return end_array();
}

} // namespace treestereo
