// GlTest: a GoogleTest fixture whose suite shares one EGL headless OpenGL context (real Mesa
// llvmpipe here, no display needed), created once per suite.
#pragma once

#include <memory>

#include <gtest/gtest.h>

#include "render/gl_context.hpp"

namespace augrig::test {

class GlTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    auto ctx = create_gl_context(GlBackend::kEglHeadless);
    ASSERT_TRUE(ctx) << ctx.error().message;
    context() = std::move(*ctx);
  }
  static void TearDownTestSuite() { context().reset(); }
  static std::unique_ptr<GlContext>& context() {
    static std::unique_ptr<GlContext> ctx;
    return ctx;
  }
};

}  // namespace augrig::test
