// lib's internal YAML/XML reader (lib/io/src/document.hpp), which reads calibration files in place
// of OpenCV's parser: what OpenCV's FileStorage writes reads back as OpenCV itself reads it,
// hand-written YAML and ROS files read as YAML means them, and malformed text is an error that
// names the line, never a crash or a hang (the inputs that crashed or hung OpenCV 4.6 included).
#include "../../lib/io/src/document.hpp"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include <cmath>
#include <string>

using treestereo::detail::DocError;
using treestereo::detail::DocNode;
using treestereo::detail::parse_xml;
using treestereo::detail::parse_yaml;

namespace {

// What FileStorage writes into memory with `fill`, as YAML or XML text.
template <class F> std::string written(const char *ext, F fill)
{
  cv::FileStorage fs(std::string("out") + ext, cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  fill(fs);
  return fs.releaseAndGetString();
}

// Expects our reading of `text` to equal OpenCV's reading of it, node by node.
void expect_same(const DocNode &ours, const cv::FileNode &cv_node, const std::string &where)
{
  SCOPED_TRACE(where);
  if (cv_node.isMap()) {
    ASSERT_TRUE(ours.is_map());
    ASSERT_EQ(ours.fields.size(), cv_node.size());
    for (const auto &[key, value] : ours.fields)
      expect_same(value, cv_node[key], where + "." + key);
  } else if (cv_node.isSeq()) {
    ASSERT_TRUE(ours.is_seq());
    ASSERT_EQ(ours.items.size(), cv_node.size());
    for (std::size_t i = 0; i < ours.items.size(); ++i)
      expect_same(ours.items[i], cv_node[static_cast<int>(i)],
                  where + "[" + std::to_string(i) + "]");
  } else if (cv_node.isInt()) {
    EXPECT_TRUE(ours.is_integer()) << ours.text;
    EXPECT_EQ(ours.number(), static_cast<int>(cv_node));
  } else if (cv_node.isReal()) {
    ASSERT_TRUE(ours.is_number()) << ours.text;
    const double v = cv_node.real();
    if (std::isnan(v))
      EXPECT_TRUE(std::isnan(ours.number()));
    else
      EXPECT_EQ(ours.number(), v) << ours.text; // OpenCV writes 17 digits: exact
  } else if (cv_node.isString()) {
    EXPECT_FALSE(ours.is_number()) << ours.text;
    EXPECT_EQ(ours.text, cv_node.string());
  } else {
    ADD_FAILURE() << "a node OpenCV reads as none of map, list, number, string";
  }
}

// A bit of everything a calibration file holds, and more.
void fill_all(cv::FileStorage &fs)
{
  cv::Mat_<double> m(3, 4);
  for (int i = 0; i < 12; ++i)
    m(i / 4, i % 4) = std::pow(-3.7, i) / 7.0;
  m(1, 1) = std::numeric_limits<double>::quiet_NaN();
  m(2, 3) = -std::numeric_limits<double>::infinity();
  fs << "image_width" << 2592 << "image_height" << -1944;
  fs << "pixel_size_um" << 2.2 << "tiny" << 1e-300 << "huge" << 1.7e308;
  fs << "M" << m;
  fs << "F" << cv::Mat((cv::Mat_<float>(2, 2) << 0.1f, -2.5f, 3e7f, 1e-7f));
  fs << "I" << cv::Mat((cv::Mat_<int>(1, 3) << -7, 0, 2147483647));
  fs << "camera_name"
     << "left camera"
     << "model"
     << "plumb_bob";
  fs << "sizes"
     << "[" << 640 << 480 << 1.5 << "]";
  fs << "nested"
     << "{"
     << "a" << 1 << "b"
     << "{"
     << "c"
     << "[" << 2 << "x y"
     << "]"
     << "}"
     << "}";
}

std::string error_of(const std::string &text, bool xml = false)
{
  try {
    xml ? parse_xml(text) : parse_yaml(text);
  } catch (const DocError &e) {
    return e.what();
  }
  return "(no error)";
}

} // namespace

TEST(Document, ReadsWhatOpenCvWritesAsOpenCvReadsIt)
{
  for (const char *ext : {".yml", ".xml"}) {
    const std::string text = written(ext, fill_all);
    const DocNode ours = std::string(ext) == ".xml" ? parse_xml(text) : parse_yaml(text);
    cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
    expect_same(ours, fs.root(), ext);
  }
}

TEST(Document, ReadsHandWrittenYaml)
{
  const DocNode d = parse_yaml("# a ROS camera_info, by hand\n"
                               "image_width: 640   # px\n"
                               "camera_name: 'it''s left'\n"
                               "quoted: \"a # b\\tc\"\n"
                               "camera_matrix:\n"
                               "  rows: 3\n"
                               "  data: [1, 2.5,\n"
                               "    -3e2, .5]\n"
                               "list:\n"
                               "- 1\n"
                               "- a: 2\n"
                               "  b: [x, {c: 3, d: }]\n"
                               "- - 4\n"
                               "  - 5\n"
                               "empty:\n"
                               "flow: {p: .NaN, q: -.Inf}\n"
                               "...\n"
                               "# the end\n");
  ASSERT_TRUE(d.is_map());
  EXPECT_EQ(d.find("image_width")->number(), 640);
  EXPECT_EQ(d.find("camera_name")->text, "it's left");
  EXPECT_EQ(d.find("quoted")->text, "a # b\tc");
  EXPECT_FALSE(d.find("quoted")->is_number());
  const DocNode *data = d.find("camera_matrix")->find("data");
  ASSERT_TRUE(data && data->is_seq());
  ASSERT_EQ(data->items.size(), 4u);
  EXPECT_EQ(data->items[1].number(), 2.5);
  EXPECT_EQ(data->items[2].number(), -300);
  EXPECT_EQ(data->items[3].number(), 0.5);
  EXPECT_TRUE(data->items[0].is_integer());
  EXPECT_FALSE(data->items[1].is_integer());
  const DocNode *list = d.find("list");
  ASSERT_TRUE(list && list->is_seq());
  ASSERT_EQ(list->items.size(), 3u);
  EXPECT_EQ(list->items[0].number(), 1);
  EXPECT_EQ(list->items[1].find("a")->number(), 2);
  const DocNode *b = list->items[1].find("b");
  ASSERT_TRUE(b && b->is_seq() && b->items.size() == 2);
  EXPECT_EQ(b->items[0].text, "x");
  EXPECT_EQ(b->items[1].find("c")->number(), 3);
  EXPECT_TRUE(b->items[1].find("d")->is_null());
  ASSERT_TRUE(list->items[2].is_seq());
  EXPECT_EQ(list->items[2].items[1].number(), 5);
  EXPECT_TRUE(d.find("empty")->is_null());
  EXPECT_TRUE(std::isnan(d.find("flow")->find("p")->number()));
  EXPECT_EQ(d.find("flow")->find("q")->number(), -HUGE_VAL);
  EXPECT_EQ(d.find("missing"), nullptr);
  // words that strtod would take are no numbers here
  for (const char *word : {"nan", "inf", "infinity", "0x10", "1e", "1.2.3", "-", ".", "+.e1"})
    EXPECT_FALSE(parse_yaml(std::string("a: ") + word).find("a")->is_number()) << word;
  EXPECT_EQ(parse_yaml("a: 1e999").find("a")->number(), HUGE_VAL);
  EXPECT_EQ(parse_yaml("a: -1e-999").find("a")->number(), 0.0);
  EXPECT_TRUE(parse_yaml("\n# nothing\n").is_null());
  // a plain scalar may hold blanks, also in a flow list: "1 2" is one string, not two numbers
  const DocNode blanks = parse_yaml("a: [1 2]");
  const DocNode *one = blanks.find("a");
  ASSERT_TRUE(one && one->is_seq() && one->items.size() == 1);
  EXPECT_FALSE(one->items[0].is_number());
}

TEST(Document, YamlErrorsNameTheLine)
{
  const struct {
    const char *text, *error;
  } cases[] = {
      {"a: [1, 2\nb: 3\n", "line 1 opens '[' but does not close it"},
      {"a: [1, 2}\n", "line 1 expects ',' or ']' in a '[' collection, not '}'"},
      {"a: {b 1}\n", "line 1 expects ':' after the name 'b 1'"},
      {"a: [1, ]]\n", "line 1 has text after the closing ']'"},
      {"a: 'x\n", "line 1 has a quoted string that is not closed"},
      {"a: \"\\q\"\n", "line 1 has an unknown escape '\\q'"},
      {"a: 1\n\tb: 2\n", "line 2 is indented with a tab"},
      {"a: &x 1\n", "line 1 uses a YAML anchor or alias"},
      {"a: 1\na: 2\n", "line 2 repeats the key 'a'"},
      {"a: 1\n  b: 2\n", "line 2 is indented under the key on line 1, which already has a value"},
      {"a:\n  b: 1\n  - 2\n", "line 3 is a list item ('-') among the keys of the map on line 2"},
      {"a:\n  b: 1\n  c\n", "line 3 is no 'name: value' line"},
      {"a:\n  - 1\n - 2\n", "line 3 is indented to a column no enclosing line has"},
      {"[1, 2]\nb: 1\n", "line 2 follows the document's top-level value"},
      {"a: "
       "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[]]]]]]]]]]]]]]]]]]]]]]]"
       "]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]\n",
       "line 1 nests lists and maps deeper than 64 levels"},
  };
  for (const auto &c : cases)
    EXPECT_NE(error_of(c.text).find(c.error), std::string::npos)
        << c.text << " -> " << error_of(c.text);
  // Block nesting is bounded too: a list of lists 5000 deep is an error, not a stack overflow.
  std::string deep = "a:\n";
  for (int i = 0; i < 5000; ++i)
    deep += "- ";
  deep += "1\n";
  EXPECT_NE(error_of(deep).find("deeper than 64 levels"), std::string::npos);
}

TEST(Document, XmlErrorsNameTheLine)
{
  const std::string head = "<?xml version=\"1.0\"?>\n<opencv_storage>\n";
  const struct {
    std::string text;
    const char *error;
  } cases[] = {
      // OpenCV 4.6 dereferences a null pointer on this one (found by fuzz-calibration)
      {head + "<M1 type_id=", "line 3 expects the value of the attribute 'type_id' in quotes"},
      {head + "<M1 type_id", "line 3 expects '=' after the attribute 'type_id' of <M1>"},
      {head + "<M1", "line 3 opens <M1> but the file ends inside the tag"},
      {head + "<M1 a=\"x", "line 3 has the value of the attribute 'a' not closed"},
      {head + "<a>1</a>\n",
       "line 2 opens <opencv_storage> but the file ends before </opencv_storage>"},
      {head + "<a>1</b>\n</opencv_storage>\n", "line 3 closes </b> where <a> (line 3) is open"},
      {head + "<a>1<b>2</b></a>\n</opencv_storage>\n",
       "line 3 has <a> holding both text and elements"},
      {head + "<a><_>1</_><b>2</b></a>\n</opencv_storage>\n",
       "mixing list items <_> and named elements"},
      {head + "<a>1</a><a>2</a>\n</opencv_storage>\n", "line 3 repeats the key 'a'"},
      {head + "<a>&foo;</a>\n</opencv_storage>\n", "line 3 has an unknown entity '&foo;'"},
      {head + "<a>\"x</a>\n</opencv_storage>\n", "line 3 has a quoted text that is not closed"},
      {head + "</opencv_storage>\n<x/>", "line 4 follows </opencv_storage>"},
      {"<?xml version=\"1.0\"?>\n<storage/>", "line 2 has the root element <storage>"},
      {head + "<!-- open", "line 3 opens a comment '<!--' that is not closed"},
      {head + "<", "line 3 ends where a name was expected"},
  };
  for (const auto &c : cases)
    EXPECT_NE(error_of(c.text, true).find(c.error), std::string::npos)
        << c.text << " -> " << error_of(c.text, true);
  std::string deep = head;
  for (int i = 0; i < 5000; ++i)
    deep += "<a>";
  EXPECT_NE(error_of(deep, true).find("deeper than 64 levels"), std::string::npos);
  // Entities, comments, quoted literals and <_> lists read as OpenCV means them.
  const DocNode d =
      parse_xml(head + "<!-- c -->\n<s>\"a &lt;b&gt;\" x&amp;y &#65;&#x42;</s>\n"
                       "<l><_>1</_><_>2.5</_></l><e/><one> 7 </one>\n</opencv_storage>\n");
  ASSERT_TRUE(d.is_map());
  const DocNode *s = d.find("s");
  ASSERT_TRUE(s && s->is_seq() && s->items.size() == 3);
  EXPECT_EQ(s->items[0].text, "a <b>");
  EXPECT_TRUE(s->items[0].quoted);
  EXPECT_EQ(s->items[1].text, "x&y");
  EXPECT_EQ(s->items[2].text, "AB");
  const DocNode *l = d.find("l");
  ASSERT_TRUE(l && l->is_seq() && l->items.size() == 2);
  EXPECT_EQ(l->items[1].number(), 2.5);
  EXPECT_TRUE(d.find("e")->is_null());
  EXPECT_TRUE(d.find("one")->is_integer());
  EXPECT_EQ(d.find("one")->line, 5);
}
