// The panorama seen through a camera must show what the equirect convention says lies in each
// direction: the test paints each longitude/latitude band and looks around.
#include "engine/render/panorama_renderer.h"

#include <glm/gtc/matrix_transform.hpp>

#include "engine/sphere/equirect.h"
#include "tests/engine/gl/gl_test_context.h"

namespace odvr::render {
namespace {

class PanoramaRendererGL : public odvr::testing::GlTest {
 protected:
  // Colour of a direction: red = forward (+X), green = up (+Y), blue = right (+Z), each the
  // positive part of the direction's component.
  static std::vector<float> DirectionPanorama(int w, int h) {
    std::vector<float> rgb(static_cast<std::size_t>(w) * h * 3);
    for (int row = 0; row < h; ++row)
      for (int col = 0; col < w; ++col) {
        const auto d = sphere::EquirectPixelDirection(col, row, w, h);
        float* p = &rgb[3 * (static_cast<std::size_t>(row) * w + col)];
        p[0] = static_cast<float>(std::max(0.0, d.x));
        p[1] = static_cast<float>(std::max(0.0, d.y));
        p[2] = static_cast<float>(std::max(0.0, d.z));
      }
    return rgb;
  }

  // Renders a 33×33 view looking along `forward` and returns the centre pixel (linear, 0..255).
  std::array<int, 3> CentreLooking(PanoramaRenderer& r, glm::vec3 forward, glm::vec3 up) {
    constexpr int kSize = 33;
    gl::Texture target = gl::Texture::Create2D(GL_RGBA8, kSize, kSize);
    gl::Framebuffer fbo;
    fbo.AttachColor(target).CheckComplete().Bind();
    glViewport(0, 0, kSize, kSize);
    const glm::mat4 view = glm::lookAt(glm::vec3(0), forward, up);
    r.Draw(view, glm::perspective(glm::radians(60.0f), 1.0f, 0.1f, 10.0f), 1.0f, false);
    const auto px = fbo.ReadRgba8(kSize / 2, kSize / 2, 1, 1);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    return {px[0], px[1], px[2]};
  }
};

TEST_F(PanoramaRendererGL, ShowsEachDirectionWhereTheConventionPutsIt) {
  PanoramaRenderer renderer;
  const int w = 256, h = 128;
  const auto pano = DirectionPanorama(w, h);
  renderer.UploadLinear(w, h, pano.data());

  const auto forward = CentreLooking(renderer, {1, 0, 0}, {0, 1, 0});
  EXPECT_GT(forward[0], 245);
  EXPECT_LT(forward[1], 10);
  EXPECT_LT(forward[2], 10);
  const auto right = CentreLooking(renderer, {0, 0, 1}, {0, 1, 0});
  EXPECT_GT(right[2], 245);
  EXPECT_LT(right[0], 10);
  const auto up = CentreLooking(renderer, {0, 1, 0}, {-1, 0, 0});  // the pole
  EXPECT_GT(up[1], 245);
  const auto back = CentreLooking(renderer, {-1, 0, 0}, {0, 1, 0});  // the seam
  EXPECT_LT(back[0] + back[1] + back[2], 10);
}

TEST_F(PanoramaRendererGL, Srgb8FramesAreLinearizedAndReEncoded) {
  PanoramaRenderer renderer;
  std::vector<std::uint8_t> grey(16 * 8 * 3, 128);
  renderer.UploadSrgb8(16, 8, grey.data());
  constexpr int kSize = 8;
  gl::Texture target = gl::Texture::Create2D(GL_RGBA8, kSize, kSize);
  gl::Framebuffer fbo;
  fbo.AttachColor(target).CheckComplete().Bind();
  glViewport(0, 0, kSize, kSize);
  renderer.Draw(glm::mat4(1), glm::perspective(1.0f, 1.0f, 0.1f, 10.0f), 1.0f, true);
  const auto px = fbo.ReadRgba8(4, 4, 1, 1);
  EXPECT_NEAR(px[0], 128, 1);  // sRGB in, sRGB out: unchanged
  renderer.Draw(glm::mat4(1), glm::perspective(1.0f, 1.0f, 0.1f, 10.0f), 1.0f, false);
  const auto linear = fbo.ReadRgba8(4, 4, 1, 1);
  EXPECT_NEAR(linear[0], 55, 2);  // sRGB 128 is 0.216 linear
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

}  // namespace
}  // namespace odvr::render
