// Renders one triangle into a framebuffer and checks pixels inside and outside it.
#include "engine/gl/objects.h"
#include "engine/gl/shader_library.h"
#include "tests/engine/gl/gl_test_context.h"

namespace odvr::gl {
namespace {

using TriangleGL = odvr::testing::GlTest;

TEST_F(TriangleGL, RendersIntoFramebuffer) {
  constexpr int kSize = 64;
  Texture color = Texture::Create2D(GL_RGBA8, kSize, kSize);
  Framebuffer fbo;
  fbo.AttachColor(color).CheckComplete().Bind();
  glViewport(0, 0, kSize, kSize);
  glClearColor(0, 0, 1, 1);
  glClear(GL_COLOR_BUFFER_BIT);

  // Lower-left half of the viewport, red.
  const std::vector<float> vertices = {-1, -1, 0, 1, 0, 0,  //
                                       1,  -1, 0, 1, 0, 0,  //
                                       -1, 1,  0, 1, 0, 0};
  Buffer vbo;
  vbo.SetData(vertices);
  VertexArray vao;
  vao.AddFloatAttribute(0, vbo, 0, 3, 0, 6 * sizeof(float))
      .AddFloatAttribute(1, vbo, 0, 3, 3 * sizeof(float), 6 * sizeof(float));
  Program program = ShaderLibrary::Graphics("flat_color.vert", "flat_color.frag");
  program.Use();
  vao.Bind();
  glDrawArrays(GL_TRIANGLES, 0, 3);

  const auto pixels = fbo.ReadRgba8(0, 0, kSize, kSize);
  auto at = [&](int x, int y) { return &pixels[4 * (y * kSize + x)]; };
  // Inside (near the lower-left corner, rows are bottom-up): red.
  EXPECT_EQ(at(4, 4)[0], 255);
  EXPECT_EQ(at(4, 4)[2], 0);
  // Outside (upper right): the clear colour.
  EXPECT_EQ(at(60, 60)[0], 0);
  EXPECT_EQ(at(60, 60)[2], 255);
  // Count: half the pixels minus the diagonal, within a row's worth.
  int red = 0;
  for (int i = 0; i < kSize * kSize; ++i) red += pixels[4 * i] == 255;
  EXPECT_NEAR(red, kSize * kSize / 2, kSize);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

}  // namespace
}  // namespace odvr::gl
