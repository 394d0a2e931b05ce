#pragma once
// One headless context per test binary. GL tests FAIL when no context can be made: a machine
// without EGL must not pass silently.
#include <gtest/gtest.h>

#include <memory>

#include "engine/gl/context.h"

namespace odvr::testing {

inline gl::HeadlessContext& SharedGlContext() {
  static std::unique_ptr<gl::HeadlessContext> context = [] {
    try {
      return std::make_unique<gl::HeadlessContext>();
    } catch (const std::exception& e) {
      ADD_FAILURE() << "no headless OpenGL context: " << e.what();
      return std::unique_ptr<gl::HeadlessContext>();
    }
  }();
  if (!context) throw std::runtime_error("no headless OpenGL context");
  context->MakeCurrent();
  return *context;
}

class GlTest : public ::testing::Test {
 protected:
  void SetUp() override { SharedGlContext(); }
};

}  // namespace odvr::testing
