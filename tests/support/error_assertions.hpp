// Assertions shared by the tests: substring checks and "this throws E; what does it say".
#pragma once

#include <gtest/gtest.h>

#include <exception>
#include <functional>
#include <string>

namespace stampede::testing {

inline ::testing::AssertionResult Contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << text << "' does not contain '" << part << "'";
}

// Runs `body`, expecting an E; returns its message ("" and a test failure otherwise).
template <class E>
std::string error_of(const std::function<void()>& body) {
  try {
    body();
  } catch (const E& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected another exception type, got: " << e.what();
    return "";
  }
  ADD_FAILURE() << "expected an exception, nothing was thrown";
  return "";
}

}  // namespace stampede::testing
