#pragma once
// The message of the odvr::Error that `f` throws, for tests of error paths; a test failure
// (and "") when it throws none.
#include <gtest/gtest.h>

#include <string>

#include "core/error.h"

namespace odvr::testing {

template <class F>
std::string ErrorMessageOf(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "no odvr::Error thrown";
  return "";
}

}  // namespace odvr::testing
