#include "treestereo/json.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <sstream>

using namespace treestereo;

TEST(Json, NestedObjectsAndArrays)
{
  std::ostringstream s;
  JsonWriter w(s);
  w.begin_object()
      .field("frame", 3)
      .field("tree_present", true)
      .field("distance_m", 2.0125)
      .key("centroid_m")
      .array({0.5, -0.25, 2.0})
      .key("bands")
      .begin_array()
      .begin_object()
      .field("width_m", 0.5)
      .end_object()
      .begin_object()
      .end_object()
      .end_array()
      .field("name", std::string("a \"b\"\n"))
      .end_object();
  EXPECT_EQ(s.str(), "{\"frame\":3,\"tree_present\":true,\"distance_m\":2.0125,"
                     "\"centroid_m\":[0.5,-0.25,2],\"bands\":[{\"width_m\":0.5},{}],"
                     "\"name\":\"a \\\"b\\\"\\n\"}");
}

TEST(Json, NonFiniteBecomesNull)
{
  std::ostringstream s;
  JsonWriter w(s);
  w.begin_array()
      .value(std::numeric_limits<double>::quiet_NaN())
      .value(std::numeric_limits<double>::infinity())
      .value(1e-12)
      .end_array();
  EXPECT_EQ(s.str(), "[null,null,1e-12]");
}

TEST(Json, UnbalancedIsAnError)
{
  std::ostringstream s;
  JsonWriter w(s);
  EXPECT_THROW(w.end_object(), std::logic_error);
}
