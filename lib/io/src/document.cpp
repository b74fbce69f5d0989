// A strict reader for calibration-sized YAML and XML (document.hpp).
#include "document.hpp"

#include <algorithm>
#include <charconv>
#include <cctype>
#include <cmath>
#include <limits>
#include <unordered_set>

namespace treestereo::detail {

namespace {

// Deeper nesting is no calibration file, and recursion must stay far from the stack's end.
constexpr int kMaxDepth = 64;

[[noreturn]] void fail(int line, const std::string &what)
{
  throw DocError("line " + std::to_string(line) + " " + what);
}

bool is_space(char c)
{
  return c == ' ' || c == '\t';
}

bool is_blank(char c)
{
  return c == ' ' || c == '\t' || c == '\r' || c == '\n';
}

bool is_alpha(char c)
{
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z');
}

bool is_digit(char c)
{
  return c >= '0' && c <= '9';
}

// A character for a message: printable ASCII as it is, anything else as \xNN.
std::string shown(char c)
{
  const auto u = static_cast<unsigned char>(c);
  if (u >= 0x20 && u < 0x7f)
    return std::string(1, c);
  static const char hex[] = "0123456789abcdef";
  return std::string("\\x") + hex[u >> 4] + hex[u & 15];
}

DocNode scalar(std::string text, bool quoted, int line)
{
  DocNode n;
  n.kind = DocNode::Kind::Scalar;
  n.text = std::move(text);
  n.quoted = quoted;
  n.line = line;
  return n;
}

DocNode null_at(int line)
{
  DocNode n;
  n.line = line;
  return n;
}

// Adds a field to a map; `keys` holds the map's keys so far (a set: a file of a million keys
// must not take a million squared steps).
void add_field(DocNode &map, std::unordered_set<std::string> &keys, std::string key, DocNode value,
               int line)
{
  if (!keys.insert(key).second)
    fail(line, "repeats the key '" + key + "'");
  map.fields.emplace_back(std::move(key), std::move(value));
}

// Reads a number as OpenCV writes them: decimal with an optional sign, point and exponent, or
// .nan / .inf / -.inf (any case). `integer`: no point, no exponent.
bool parse_number(std::string_view t, double &v, bool &integer)
{
  bool neg = false;
  if (!t.empty() && (t[0] == '+' || t[0] == '-')) {
    neg = t[0] == '-';
    t.remove_prefix(1);
  }
  if (t.empty())
    return false;
  std::string lower(t);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  integer = false;
  if (lower == ".nan") {
    v = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  if (lower == ".inf") {
    v = neg ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
    return true;
  }
  // Digits, a point and an exponent only: from_chars would also take "inf" and "nan" spelled
  // out, which are words here.
  if (!(is_digit(t[0]) || t[0] == '.') || t.find_first_not_of("0123456789.eE+-") != t.npos)
    return false;
  const char *end = t.data() + t.size();
  const auto [ptr, ec] = std::from_chars(t.data(), end, v);
  if (ptr != end || (ec != std::errc() && ec != std::errc::result_out_of_range))
    return false;
  if (ec == std::errc::result_out_of_range) { // beyond double: infinity or zero, as strtod gives
    const std::size_t e = lower.find('e');
    const std::string_view mantissa = std::string_view(lower).substr(0, e);
    const bool tiny = e != std::string::npos
                          ? lower[e + 1] == '-'
                          : mantissa.substr(0, mantissa.find('.')).find_first_not_of('0') ==
                                std::string_view::npos;
    v = tiny ? 0.0 : std::numeric_limits<double>::infinity();
  }
  integer = t.find_first_of(".eE") == t.npos;
  if (neg)
    v = -v;
  return true;
}

// ---------------------------------------------------------------------------------------------
// YAML

struct Line {
  int no;             // from 1
  std::size_t indent; // the column of its first character
  std::string s;      // from that character, comment and trailing blanks cut
};

// Where a comment starts in a line ('#' first or after a blank, outside quotes), or npos.
std::size_t comment_start(std::string_view s)
{
  char quote = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char c = s[i];
    if (quote) {
      if (c == '\\' && quote == '"')
        ++i;
      else if (c == quote && quote == '\'' && i + 1 < s.size() && s[i + 1] == '\'')
        ++i;
      else if (c == quote)
        quote = 0;
      continue;
    }
    const bool token_start = i == 0 || is_space(s[i - 1]) ||
                             std::string_view("[{,:").find(s[i - 1]) != std::string_view::npos;
    if (c == '#' && (i == 0 || is_space(s[i - 1])))
      return i;
    if ((c == '"' || c == '\'') && token_start)
      quote = c;
  }
  return std::string_view::npos;
}

bool is_item(std::string_view s)
{
  return !s.empty() && s[0] == '-' && (s.size() == 1 || is_space(s[1]));
}

// s[p] is an opening quote: the string it opens, p past its closing quote.
std::string read_quoted(std::string_view s, std::size_t &p, int line)
{
  const char q = s[p++];
  std::string out;
  for (;;) {
    if (p >= s.size())
      fail(line, "has a quoted string that is not closed");
    const char c = s[p++];
    if (c == q) {
      if (q == '\'' && p < s.size() && s[p] == '\'') {
        out += '\'';
        ++p;
        continue;
      }
      return out;
    }
    if (c == '\\' && q == '"') {
      if (p >= s.size())
        fail(line, "has a quoted string that is not closed");
      const char e = s[p++];
      switch (e) {
      case '"':
      case '\\':
      case '/':
        out += e;
        break;
      case 'n':
        out += '\n';
        break;
      case 't':
        out += '\t';
        break;
      case 'r':
        out += '\r';
        break;
      default:
        fail(line, "has an unknown escape '\\" + shown(e) + "' in a quoted string");
      }
      continue;
    }
    out += c;
  }
}

// The ':' that ends a block map's key on this line ("name:" at the end or "name: value"), or
// npos when the line is no key.
std::size_t key_end(std::string_view s)
{
  if (s.empty() || s[0] == '[' || s[0] == '{' || is_item(s))
    return std::string_view::npos;
  std::size_t p = 0;
  if (s[0] == '"' || s[0] == '\'') {
    const char q = s[0];
    for (p = 1; p < s.size() && s[p] != q; ++p)
      if (s[p] == '\\' && q == '"')
        ++p;
    if (p >= s.size())
      return std::string_view::npos;
    p = s.find_first_not_of(" \t", p + 1);
    return p != std::string_view::npos && s[p] == ':' && (p + 1 == s.size() || is_space(s[p + 1]))
               ? p
               : std::string_view::npos;
  }
  for (; p < s.size(); ++p)
    if (s[p] == ':' && (p + 1 == s.size() || is_space(s[p + 1])))
      return p;
  return std::string_view::npos;
}

// Follows brackets and quotes through a flow collection's text, line by line.
struct FlowScan {
  int depth = 0;
  char quote = 0;
  void feed(std::string_view s)
  {
    for (std::size_t i = 0; i < s.size(); ++i) {
      const char c = s[i];
      if (quote) {
        if (c == '\\' && quote == '"')
          ++i;
        else if (c == quote)
          quote = 0;
      } else if (c == '"' || c == '\'') {
        quote = c;
      } else if (c == '[' || c == '{') {
        ++depth;
      } else if (c == ']' || c == '}') {
        --depth;
      }
    }
  }
  bool closed() const { return depth <= 0 && !quote; }
};

class YamlParser
{
public:
  explicit YamlParser(std::string_view text) { split(text); }

  DocNode parse()
  {
    if (lines_.empty())
      return {};
    const Line &first = lines_[0];
    if (first.indent > 0)
      fail(first.no, "is indented, but a calibration file's top level starts at column 0");
    DocNode root;
    if (first.s[0] == '[' || first.s[0] == '{') {
      const std::string s = first.s;
      const int no = first.no;
      ++i_;
      root = parse_inline(s, -1, no, 0);
    } else {
      root = parse_map(0, 0);
    }
    if (i_ < lines_.size())
      fail(lines_[i_].no, "follows the document's top-level value");
    return root;
  }

private:
  std::vector<Line> lines_;
  std::size_t i_ = 0;

  // The lines that hold content, with the file-level rules: a %YAML directive only first, the
  // marker '---' alone on its line at most once before the content, nothing but comments after
  // the end '...', no tabs in the indentation.
  void split(std::string_view text)
  {
    int no = 0, end_line = 0;
    bool seen_content = false, seen_body = false, seen_marker = false;
    for (std::size_t pos = 0; pos <= text.size();) {
      const std::size_t end = std::min(text.find('\n', pos), text.size());
      const std::string_view raw = text.substr(pos, end - pos);
      pos = end + 1;
      ++no;
      const std::size_t indent = raw.find_first_not_of(' ');
      if (indent == std::string_view::npos)
        continue;
      std::string s(raw.substr(indent));
      s.resize(std::min(s.size(), comment_start(s)));
      s = std::string(trim(s));
      if (s.empty())
        continue;
      if (raw[indent] == '\t')
        fail(no, "is indented with a tab: YAML indents with spaces");
      if (end_line > 0)
        fail(no, "follows the end of the document ('...' on line " + std::to_string(end_line) +
                     "): a calibration file holds one YAML document");
      if (indent == 0 && s.compare(0, 3, "...") == 0) {
        if (s.size() > 3)
          fail(no, "has text after the document's end '...'");
        end_line = no;
        continue;
      }
      if (indent == 0 && s.compare(0, 3, "---") == 0) {
        if (seen_marker || seen_body)
          fail(no, "starts a second YAML document: a calibration file holds one");
        if (s.size() > 3)
          fail(no, "has text after the document marker '---'");
        seen_marker = true;
        continue;
      }
      const bool directive = !seen_content && indent == 0 && s[0] == '%';
      seen_content = true;
      if (directive)
        continue;
      seen_body = true;
      lines_.push_back({no, indent, std::move(s)});
    }
  }

  bool more_indented(std::size_t indent) const
  {
    return i_ < lines_.size() && lines_[i_].indent > indent;
  }

  // The node that starts at the current line, whatever its column.
  DocNode parse_block(int depth)
  {
    Line &l = lines_[i_];
    if (depth > kMaxDepth)
      fail(l.no, "nests lists and maps deeper than " + std::to_string(kMaxDepth) + " levels");
    if (is_item(l.s))
      return parse_list(l.indent, depth);
    if (key_end(l.s) != std::string::npos)
      return parse_map(l.indent, depth);
    const std::string s = l.s;
    const long owner = static_cast<long>(l.indent) - 1;
    const int no = l.no;
    ++i_;
    return parse_inline(s, owner, no, depth);
  }

  DocNode parse_map(std::size_t indent, int depth)
  {
    DocNode map;
    map.kind = DocNode::Kind::Map;
    std::unordered_set<std::string> keys;
    map.line = lines_[i_].no;
    while (i_ < lines_.size() && lines_[i_].indent == indent) {
      const Line &l = lines_[i_];
      const std::size_t colon = key_end(l.s);
      if (colon == std::string::npos) {
        if (indent == 0)
          fail(l.no, "starts at column 0 but is no key: a calibration file's top level is a map "
                     "of 'name: value' lines");
        if (is_item(l.s))
          fail(l.no, "is a list item ('-') among the keys of the map on line " +
                         std::to_string(map.line));
        fail(l.no, "is no 'name: value' line, but the lines above it at this column are keys");
      }
      const int no = l.no;
      std::string key = key_text(std::string_view(l.s).substr(0, colon), no);
      const std::string rest(trim(std::string_view(l.s).substr(colon + 1)));
      ++i_;
      DocNode value = parse_value(rest, indent, no, depth + 1);
      const bool leaf = value.kind == DocNode::Kind::Scalar || !rest.empty();
      add_field(map, keys, std::move(key), std::move(value), no);
      if (more_indented(indent))
        fail(lines_[i_].no, leaf ? "is indented under the key on line " + std::to_string(no) +
                                       ", which already has a value"
                                 : std::string("is indented to a column no enclosing line has"));
    }
    return map;
  }

  DocNode parse_list(std::size_t indent, int depth)
  {
    DocNode list;
    list.kind = DocNode::Kind::Seq;
    list.line = lines_[i_].no;
    while (i_ < lines_.size() && lines_[i_].indent == indent && is_item(lines_[i_].s)) {
      Line &l = lines_[i_];
      const std::size_t off = l.s.find_first_not_of(" \t", 1);
      if (off == std::string::npos) { // "-" alone: the item is on the lines below, or null
        const int no = l.no;
        ++i_;
        list.items.push_back(more_indented(indent) ? parse_block(depth + 1) : null_at(no));
      } else { // the item's content, as if it stood alone at its own column
        l.indent += off;
        l.s.erase(0, off);
        list.items.push_back(parse_block(depth + 1));
      }
      if (more_indented(indent))
        fail(lines_[i_].no, "is indented to a column no enclosing line has");
    }
    return list;
  }

  std::string key_text(std::string_view raw, int line)
  {
    raw = trim(raw);
    std::string key(raw);
    if (!raw.empty() && (raw[0] == '"' || raw[0] == '\'')) {
      std::size_t p = 0;
      key = read_quoted(raw, p, line);
    }
    if (key.empty())
      fail(line, "has an empty key");
    return key;
  }

  // What follows "key:" on its line (`rest`), or the block below it.
  DocNode parse_value(std::string rest, std::size_t indent, int line, int depth)
  {
    if (!rest.empty() && rest[0] == '!') { // a tag (!!opencv-matrix): the value is what follows
      const std::size_t sp = rest.find_first_of(" \t");
      rest = sp == std::string::npos ? std::string() : std::string(trim(rest.substr(sp)));
    }
    if (rest.empty()) {
      if (more_indented(indent))
        return parse_block(depth);
      if (i_ < lines_.size() && lines_[i_].indent == indent && is_item(lines_[i_].s))
        return parse_list(indent, depth);
      return null_at(line);
    }
    return parse_inline(rest, static_cast<long>(indent), line, depth);
  }

  // A value written on one line, or a flow collection that goes on over the lines below (each
  // indented more than `owner`).
  DocNode parse_inline(const std::string &rest, long owner, int line, int depth)
  {
    const char c = rest[0];
    if (c == '&' || c == '*')
      fail(line, "uses a YAML anchor or alias ('&', '*'): write the value itself");
    if (c == '[' || c == '{') {
      std::string flow = rest;
      FlowScan scan;
      scan.feed(flow);
      while (!scan.closed()) {
        if (i_ >= lines_.size() || static_cast<long>(lines_[i_].indent) <= owner)
          fail(line, "opens '" + std::string(1, c) + "' but does not close it");
        flow += ' ';
        flow += lines_[i_].s;
        scan.feed(lines_[i_].s);
        ++i_;
      }
      std::size_t p = 0;
      DocNode v = parse_flow(flow, p, line, depth);
      if (!trim(std::string_view(flow).substr(p)).empty())
        fail(line, "has text after the closing '" + std::string(1, c == '[' ? ']' : '}') + "'");
      return v;
    }
    if (c == '"' || c == '\'') {
      std::size_t p = 0;
      std::string text = read_quoted(rest, p, line);
      if (!trim(std::string_view(rest).substr(p)).empty())
        fail(line, "has text after a quoted string");
      return scalar(std::move(text), true, line);
    }
    return scalar(rest, false, line);
  }

  static void skip_spaces(std::string_view s, std::size_t &p)
  {
    while (p < s.size() && is_space(s[p]))
      ++p;
  }

  DocNode parse_flow(std::string_view s, std::size_t &p, int line, int depth)
  {
    if (depth > kMaxDepth)
      fail(line, "nests lists and maps deeper than " + std::to_string(kMaxDepth) + " levels");
    skip_spaces(s, p);
    if (p >= s.size())
      fail(line, "ends where a value was expected");
    const char c = s[p];
    if (c == '[' || c == '{') {
      const bool is_list = c == '[';
      const char close = is_list ? ']' : '}';
      DocNode n;
      n.kind = is_list ? DocNode::Kind::Seq : DocNode::Kind::Map;
      std::unordered_set<std::string> keys;
      n.line = line;
      ++p;
      for (;;) {
        skip_spaces(s, p);
        if (p >= s.size())
          fail(line, "opens '" + std::string(1, c) + "' but does not close it");
        if (s[p] == close) {
          ++p;
          return n;
        }
        if (is_list) {
          n.items.push_back(parse_flow(s, p, line, depth + 1));
        } else {
          std::string key;
          if (s[p] == '"' || s[p] == '\'') {
            key = read_quoted(s, p, line);
          } else {
            const std::size_t b = p;
            while (p < s.size() && std::string_view(":,[]{}").find(s[p]) == std::string_view::npos)
              ++p;
            key = std::string(trim(s.substr(b, p - b)));
          }
          if (key.empty())
            fail(line, "has an entry without a name in a '{' map");
          skip_spaces(s, p);
          if (p >= s.size() || s[p] != ':')
            fail(line, "expects ':' after the name '" + key + "' in a '{' map");
          ++p;
          skip_spaces(s, p);
          DocNode v = p < s.size() && (s[p] == ',' || s[p] == '}')
                          ? null_at(line)
                          : parse_flow(s, p, line, depth + 1);
          add_field(n, keys, std::move(key), std::move(v), line);
        }
        skip_spaces(s, p);
        if (p < s.size() && s[p] == ',')
          ++p;
        else if (p < s.size() && s[p] != close)
          fail(line, "expects ',' or '" + std::string(1, close) + "' in a '" + std::string(1, c) +
                         "' collection, not '" + shown(s[p]) + "'");
      }
    }
    if (c == '"' || c == '\'') {
      std::string text = read_quoted(s, p, line);
      return scalar(std::move(text), true, line);
    }
    if (c == '&' || c == '*')
      fail(line, "uses a YAML anchor or alias ('&', '*'): write the value itself");
    if (c == '!') { // a tag on an item: skip it
      while (p < s.size() && !is_space(s[p]) && s[p] != ',' && s[p] != ']' && s[p] != '}')
        ++p;
      return parse_flow(s, p, line, depth + 1);
    }
    const std::size_t b = p;
    while (p < s.size() && std::string_view(",[]{}").find(s[p]) == std::string_view::npos)
      ++p;
    const std::string_view text = trim(s.substr(b, p - b));
    if (text.empty())
      fail(line, "has '" + shown(c) + "' where a value was expected");
    return scalar(std::string(text), false, line);
  }
};

// ---------------------------------------------------------------------------------------------
// XML

class XmlParser
{
public:
  explicit XmlParser(std::string_view s) : s_(s) {}

  DocNode parse()
  {
    skip_misc(true);
    if (p_ >= s_.size())
      return {};
    if (s_[p_] != '<')
      fail_at(p_, "has text where the root element <opencv_storage> was expected");
    const std::size_t at = p_++;
    const std::string root = read_name();
    if (root != "opencv_storage")
      fail_at(at, "has the root element <" + root + ">, expected <opencv_storage>");
    DocNode doc = element(root, at, 1);
    skip_misc(false);
    if (p_ < s_.size())
      fail_at(p_, "follows </opencv_storage>: an XML calibration file has one root element");
    return doc;
  }

private:
  std::string_view s_;
  std::size_t p_ = 0;

  std::size_t counted_ = 0; // line_at's count of newlines before counted_, kept as it moves on
  int newlines_ = 0;

  int line_at(std::size_t pos)
  {
    pos = std::min(pos, s_.size());
    if (pos < counted_) // an error's earlier position: count again
      return 1 + static_cast<int>(std::count(s_.begin(), s_.begin() + pos, '\n'));
    newlines_ += static_cast<int>(std::count(s_.begin() + counted_, s_.begin() + pos, '\n'));
    counted_ = pos;
    return 1 + newlines_;
  }
  [[noreturn]] void fail_at(std::size_t pos, const std::string &what) { fail(line_at(pos), what); }
  bool starts(std::string_view t) const { return s_.substr(p_).substr(0, t.size()) == t; }
  bool skip_blanks()
  {
    const std::size_t b = p_;
    while (p_ < s_.size() && is_blank(s_[p_]))
      ++p_;
    return p_ > b;
  }
  void skip_past(std::string_view end, const std::string &what)
  {
    const std::size_t at = p_;
    const std::size_t e = s_.find(end, p_);
    if (e == std::string_view::npos)
      fail_at(at, "opens " + what + " that is not closed with '" + std::string(end) + "'");
    p_ = e + end.size();
  }
  // Blanks and comments; before the root also the <?xml ...?> declaration and <!DOCTYPE ...>.
  void skip_misc(bool prolog)
  {
    for (;;) {
      skip_blanks();
      if (starts("<!--"))
        skip_past("-->", "a comment '<!--'");
      else if (prolog && starts("<?"))
        skip_past("?>", "a declaration '<?'");
      else if (prolog && starts("<!"))
        skip_past(">", "a declaration '<!'");
      else
        return;
    }
  }
  std::string read_name()
  {
    const std::size_t b = p_;
    if (p_ < s_.size() && (is_alpha(s_[p_]) || s_[p_] == '_')) {
      ++p_;
      while (p_ < s_.size() && (is_alpha(s_[p_]) || is_digit(s_[p_]) || s_[p_] == '_' ||
                                s_[p_] == '-' || s_[p_] == '.' || s_[p_] == ':'))
        ++p_;
    }
    if (p_ == b)
      fail_at(b, p_ < s_.size() ? "has '" + shown(s_[p_]) + "' where a name was expected"
                                : std::string("ends where a name was expected"));
    return std::string(s_.substr(b, p_ - b));
  }
  // At '&': the character the entity stands for.
  char entity()
  {
    const std::size_t at = p_;
    const std::size_t semi = s_.find(';', p_);
    if (semi == std::string_view::npos || semi - p_ > 8)
      fail_at(at, "has an '&' that starts no entity (write &amp; for '&')");
    const std::string_view e = s_.substr(p_ + 1, semi - p_ - 1);
    p_ = semi + 1;
    if (e == "lt")
      return '<';
    if (e == "gt")
      return '>';
    if (e == "amp")
      return '&';
    if (e == "apos")
      return '\'';
    if (e == "quot")
      return '"';
    if (e.size() > 1 && e[0] == '#') {
      const bool hex = e[1] == 'x';
      const std::string_view digits = e.substr(hex ? 2 : 1);
      unsigned v = 0;
      const auto [ptr, ec] =
          std::from_chars(digits.data(), digits.data() + digits.size(), v, hex ? 16 : 10);
      if (ec == std::errc() && ptr == digits.data() + digits.size() && !digits.empty() && v >= 1 &&
          v <= 255)
        return static_cast<char>(v);
    }
    std::string name;
    for (char c : e)
      name += shown(c);
    fail_at(at, "has an unknown entity '&" + name + ";'");
  }
  // One literal of an element's text: a quoted string or a run without blanks.
  DocNode literal()
  {
    DocNode lit = scalar({}, false, line_at(p_));
    if (s_[p_] == '"') {
      const std::size_t at = p_++;
      lit.quoted = true;
      for (;;) {
        if (p_ >= s_.size() || s_[p_] == '<')
          fail_at(at, "has a quoted text that is not closed");
        if (s_[p_] == '"') {
          ++p_;
          break;
        }
        lit.text += s_[p_] == '&' ? entity() : s_[p_++];
      }
      if (p_ < s_.size() && !is_blank(s_[p_]) && s_[p_] != '<')
        fail_at(p_, "has text right after a quoted text: put a blank between literals");
      return lit;
    }
    while (p_ < s_.size() && !is_blank(s_[p_]) && s_[p_] != '<')
      lit.text += s_[p_] == '&' ? entity() : s_[p_++];
    return lit;
  }
  // After "<name": the attributes, the content and the closing tag.
  DocNode element(const std::string &name, std::size_t at, int depth)
  {
    if (depth > kMaxDepth)
      fail_at(at, "nests elements deeper than " + std::to_string(kMaxDepth) + " levels");
    const int line = line_at(at);
    const std::string tag = "<" + name + ">";
    for (;;) { // attributes (type_id="opencv-matrix" and the like): checked, not kept
      const bool spaced = skip_blanks();
      if (p_ >= s_.size())
        fail_at(at, "opens " + tag + " but the file ends inside the tag");
      if (starts("/>")) {
        p_ += 2;
        return null_at(line);
      }
      if (s_[p_] == '>') {
        ++p_;
        break;
      }
      if (!spaced)
        fail_at(p_, "expects a blank before an attribute of " + tag);
      const std::string attr = read_name();
      skip_blanks();
      if (p_ >= s_.size() || s_[p_] != '=')
        fail_at(p_, "expects '=' after the attribute '" + attr + "' of " + tag);
      ++p_;
      skip_blanks();
      if (p_ >= s_.size() || (s_[p_] != '"' && s_[p_] != '\''))
        fail_at(p_, "expects the value of the attribute '" + attr + "' in quotes");
      const std::size_t e = s_.find(s_[p_], p_ + 1);
      if (e == std::string_view::npos || s_.substr(p_, e - p_).find('<') != std::string_view::npos)
        fail_at(p_, "has the value of the attribute '" + attr + "' not closed");
      p_ = e + 1;
    }
    std::vector<std::pair<std::string, DocNode>> children;
    std::vector<DocNode> literals;
    for (;;) {
      skip_blanks();
      if (p_ >= s_.size())
        fail_at(at, "opens " + tag + " but the file ends before </" + name + ">");
      if (starts("<!--")) {
        skip_past("-->", "a comment '<!--'");
      } else if (starts("</")) {
        const std::size_t close_at = p_;
        p_ += 2;
        const std::string closing = read_name();
        skip_blanks();
        if (p_ >= s_.size() || s_[p_] != '>')
          fail_at(close_at, "has the closing tag </" + closing + " without '>'");
        ++p_;
        if (closing != name)
          fail_at(close_at, "closes </" + closing + "> where " + tag + " (line " +
                                std::to_string(line) + ") is open");
        break;
      } else if (s_[p_] == '<') {
        const std::size_t child_at = p_++;
        std::string child = read_name();
        DocNode node = element(child, child_at, depth + 1);
        children.emplace_back(std::move(child), std::move(node));
      } else {
        literals.push_back(literal());
      }
    }
    if (!children.empty() && !literals.empty())
      fail_at(at, "has " + tag + " holding both text and elements");
    DocNode node = null_at(line);
    if (literals.size() == 1)
      return std::move(literals[0]);
    if (literals.size() > 1) {
      node.kind = DocNode::Kind::Seq;
      node.items = std::move(literals);
      return node;
    }
    if (children.empty())
      return node;
    const auto items = std::count_if(children.begin(), children.end(),
                                     [](const auto &c) { return c.first == "_"; });
    if (items == static_cast<long>(children.size())) { // OpenCV writes list items as <_>
      node.kind = DocNode::Kind::Seq;
      for (auto &c : children)
        node.items.push_back(std::move(c.second));
    } else if (items == 0) {
      node.kind = DocNode::Kind::Map;
      std::unordered_set<std::string> keys;
      for (auto &c : children) {
        const int line = c.second.line;
        add_field(node, keys, std::move(c.first), std::move(c.second), line);
      }
    } else {
      fail_at(at, "has " + tag + " mixing list items <_> and named elements");
    }
    return node;
  }
};

} // namespace

std::string_view trim(std::string_view s)
{
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string_view::npos)
    return {};
  return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

const DocNode *DocNode::find(std::string_view key) const
{
  for (const auto &[k, v] : fields)
    if (k == key)
      return &v;
  return nullptr;
}

bool DocNode::is_number() const
{
  double v = 0;
  bool integer = false;
  return kind == Kind::Scalar && !quoted && parse_number(text, v, integer);
}

bool DocNode::is_integer() const
{
  double v = 0;
  bool integer = false;
  return kind == Kind::Scalar && !quoted && parse_number(text, v, integer) && integer;
}

double DocNode::number() const
{
  double v = 0;
  bool integer = false;
  if (kind == Kind::Scalar && !quoted && parse_number(text, v, integer))
    return v;
  return std::numeric_limits<double>::quiet_NaN();
}

DocNode parse_yaml(std::string_view text)
{
  return YamlParser(text).parse();
}

DocNode parse_xml(std::string_view text)
{
  return XmlParser(text).parse();
}

} // namespace treestereo::detail
