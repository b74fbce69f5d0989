// Checks of lib's typed errors (lib/include/treestereo/errors.hpp) in the unit tests.
#pragma once

#include "treestereo/errors.hpp"

#include <gtest/gtest.h>

#include <cctype>
#include <string>

// Expects @call to throw an @E whose message is a sentence (a capital first, a full stop last)
// holding @part, the name of what is wrong, with the technical side in its detail.
template <class E, class Call>
void expect_typed_error(Call &&call, const std::string &part)
{
  try {
    call();
    ADD_FAILURE() << "no error naming " << part;
  } catch (const E &e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(part), std::string::npos) << message;
    EXPECT_TRUE(!message.empty() && std::isupper(static_cast<unsigned char>(message.front())) &&
                message.back() == '.')
        << message;
    EXPECT_FALSE(e.detail().empty()) << message;
  }
}
