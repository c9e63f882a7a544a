// Real OpenGL through EGL surfaceless (Mesa llvmpipe here): no display needed.
#include "render/gl_context.hpp"

#include <cstdlib>

#include <epoxy/gl.h>
#include <gtest/gtest.h>

namespace augrig {
namespace {

TEST(GlContext, EglHeadlessGivesCoreProfile33OrLater) {
  auto ctx = create_gl_context(GlBackend::kEglHeadless);
  ASSERT_TRUE(ctx) << ctx.error().message;
  EXPECT_NE(std::string((*ctx)->backend_name()).find("egl"), std::string::npos);
  EXPECT_GE(epoxy_gl_version(), 33);
  EXPECT_FALSE((*ctx)->renderer().empty());
  // Clear a renderbuffer and read it back: the context really renders.
  GLuint fbo = 0, rb = 0;
  glGenFramebuffers(1, &fbo);
  glGenRenderbuffers(1, &rb);
  glBindRenderbuffer(GL_RENDERBUFFER, rb);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, 4, 4);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb);
  ASSERT_EQ(glCheckFramebufferStatus(GL_FRAMEBUFFER), static_cast<GLenum>(GL_FRAMEBUFFER_COMPLETE));
  glClearColor(1.0f, 0.5f, 0.0f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  unsigned char px[4] = {};
  glReadPixels(1, 1, 1, 1, GL_RGBA, GL_UNSIGNED_BYTE, px);
  EXPECT_EQ(px[0], 255);
  EXPECT_NEAR(px[1], 128, 1);
  EXPECT_EQ(px[2], 0);
  glDeleteRenderbuffers(1, &rb);
  glDeleteFramebuffers(1, &fbo);
}

TEST(GlContext, GlfwWithoutDisplayFailsWithAClearMessage) {
  if (std::getenv("DISPLAY") || std::getenv("WAYLAND_DISPLAY")) GTEST_SKIP() << "a display is present";
  auto ctx = create_gl_context(GlBackend::kGlfwWindow);
  ASSERT_FALSE(ctx);
  EXPECT_NE(ctx.error().message.find("create_glfw_context"), std::string::npos) << ctx.error().message;
}

}  // namespace
}  // namespace augrig

namespace augrig {
namespace {

// Runs under `xvfb-run` (a CTest entry of its own, see tests/CMakeLists.txt): a real window.
TEST(GlContext, GlfwWindowWhenADisplayIsPresent) {
  if (!std::getenv("DISPLAY")) GTEST_SKIP() << "no display; CTest runs this under xvfb-run";
  GlContextOptions opt;
  opt.window_width = 320;
  opt.window_height = 240;
  auto ctx = create_gl_context(GlBackend::kGlfwWindow, opt);
  ASSERT_TRUE(ctx) << ctx.error().message;
  EXPECT_STREQ((*ctx)->backend_name(), "glfw");
  ASSERT_NE((*ctx)->window(), nullptr);
  EXPECT_GE(epoxy_gl_version(), 33);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glClearColor(0.0f, 1.0f, 0.0f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  unsigned char px[4] = {};
  glReadPixels(10, 10, 1, 1, GL_RGBA, GL_UNSIGNED_BYTE, px);
  EXPECT_EQ(px[1], 255);
  EXPECT_EQ(px[0], 0);
}

}  // namespace
}  // namespace augrig
