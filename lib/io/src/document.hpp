// Internal (not installed): a strict reader for the YAML and XML that calibration files are
// written in (OpenCV FileStorage's output, ROS camera_info, hand-written files), used by
// calibration.cpp instead of OpenCV's own parser.
//
// Why not cv::FileStorage: OpenCV 4.6's parsers trust their input. Fuzzing found its YAML parser
// looping forever on malformed text (five classes of input) and its XML parser dereferencing a
// null pointer when a file ends inside a tag ("<a b=" at the end of the file). A calibration
// file comes from a person or another tool, so it is read here, where every path checks where it
// is; OpenCV still writes the files (save_calibration).
//
// What is read: YAML block maps and lists (indentation), flow lists and maps over several lines
// ([ ... ], { ... }), plain and quoted scalars, tags (!!opencv-matrix, skipped), comments, the
// %YAML directive and the document markers --- and ...; OpenCV's XML (<opencv_storage>,
// elements, attributes (skipped), comments, entities, text split into literals). Not read:
// anchors and aliases, multi-line scalars, several documents: each is an error naming the line.
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace treestereo::detail {

// A node of a parsed document: nothing (a key without a value), a scalar, a list or a map.
struct DocNode {
  enum class Kind { Null, Scalar, Seq, Map };
  Kind kind = Kind::Null;
  int line = 0;               // where it starts, from 1
  std::string text;           // a scalar's text, quotes and escapes resolved
  bool quoted = false;        // a quoted scalar is a string, never a number
  std::vector<DocNode> items; // a list's
  std::vector<std::pair<std::string, DocNode>> fields; // a map's, in the file's order

  bool is_null() const { return kind == Kind::Null; }
  bool is_map() const { return kind == Kind::Map; }
  bool is_seq() const { return kind == Kind::Seq; }
  // A map's field of that name, or nullptr (also when this is no map).
  const DocNode *find(std::string_view key) const;
  // An unquoted scalar that reads whole as a number: decimal, with a point or an exponent, or
  // YAML's .nan, .inf and -.inf (as OpenCV writes NaN and infinity).
  bool is_number() const;
  // ... and as a whole number: digits with an optional sign, no point, no exponent.
  bool is_integer() const;
  // The number; NaN when this is not one.
  double number() const;
};

// A syntax error; what() names the line ("line 4 ...").
class DocError : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

// `s` without its leading and trailing blanks (space, tab, CR, LF).
std::string_view trim(std::string_view s);

// The document's root. Throws DocError. A text holding only blanks and comments gives a null root.
DocNode parse_yaml(std::string_view text);
DocNode parse_xml(std::string_view text);

} // namespace treestereo::detail
