#include "treestereo/segment.hpp"

#include <gtest/gtest.h>

using namespace treestereo;

TEST(Segment, Placeholder) { EXPECT_EQ(std::string(veg_index_name(VegIndex::Exg)), "exg"); }
