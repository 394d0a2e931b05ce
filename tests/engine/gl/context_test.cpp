#include "engine/gl/context.h"

#include "tests/engine/gl/gl_test_context.h"

namespace odvr::gl {
namespace {

using ContextGL = odvr::testing::GlTest;

// A CPU rasterizer's times are not a GPU's (bench tables say so), and what pays on a GPU may not
// pay there (RenderOptions::shade_lanes).
TEST(Context, SoftwareRenderersAreToldFromGpus) {
  EXPECT_TRUE(IsSoftwareRenderer("llvmpipe (LLVM 15.0.6, 256 bits)"));
  EXPECT_TRUE(IsSoftwareRenderer("softpipe"));
  EXPECT_TRUE(IsSoftwareRenderer("ANGLE (Google, Vulkan 1.3.0 (SwiftShader Device (Subzero)))"));
  EXPECT_FALSE(IsSoftwareRenderer("NVIDIA H200/PCIe/SSE2"));
  EXPECT_FALSE(IsSoftwareRenderer("AMD Radeon RX 7900 XTX (radeonsi, navi31, LLVM 15.0.6)"));
}

TEST_F(ContextGL, CurrentRendererIsToldAsItsStringIs) {
  EXPECT_EQ(CurrentRendererIsSoftware(), IsSoftwareRenderer(testing::SharedGlContext().Info().renderer));
}

TEST_F(ContextGL, HeadlessContextIsOpenGL45CoreWithCompute) {
  const ContextInfo info = testing::SharedGlContext().Info();
  EXPECT_TRUE(info.platform == "egl-surfaceless" || info.platform == "egl-device") << info.platform;
  EXPECT_GE(info.major * 10 + info.minor, 45) << info.version;
  EXPECT_TRUE(info.core_profile);
  EXPECT_GE(info.max_compute_invocations, 1024);
  EXPECT_GE(info.max_compute_shared_bytes, 32768);
  EXPECT_GE(info.max_compute_group_size[0], 1024);
  EXPECT_GE(info.max_ssbo_bytes, std::int64_t{128} << 20);
  EXPECT_FALSE(info.renderer.empty());
}

TEST_F(ContextGL, PlatformCanBeForcedAndABadChoiceIsAClearError) {
  ::setenv("ODVR_EGL_PLATFORM", "surfaceless", 1);
  {
    HeadlessContext context;  // Mesa is a dependency, so its surfaceless platform must work
    EXPECT_EQ(context.platform(), "egl-surfaceless");
  }
  ::setenv("ODVR_EGL_PLATFORM", "wayland", 1);
  try {
    HeadlessContext context;
    ADD_FAILURE() << "an unknown platform was accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("ODVR_EGL_PLATFORM"), std::string::npos) << e.what();
  }
  ::unsetenv("ODVR_EGL_PLATFORM");
  testing::SharedGlContext();  // the shared context is current again
}

}  // namespace
}  // namespace odvr::gl
