// FramePresenter draws a linear picture as 8-bit sRGB: from a CPU image (upload, table encode,
// blit) or from a GPU texture (a shader encodes): the two agree within one step and keep the
// picture's top row at the top.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "app/player/window_input.h"
#include "core/error.h"
#include "core/srgb.h"
#include "engine/gl/context.h"
#include "engine/gl/objects.h"
#include "engine/image/image_io.h"

namespace odvr::app {
namespace {

std::vector<unsigned char> Draw(const std::function<void(GLuint)>& show, int w, int h) {
  gl::Texture target = gl::Texture::Create2D(GL_RGBA8, w, h);
  gl::Framebuffer fbo;
  fbo.AttachColor(target).CheckComplete();
  show(fbo.id());
  gl::Finish();
  return fbo.ReadRgba8(0, 0, w, h);  // rows bottom-up
}

TEST(FramePresenterGL, TextureAndImagePathsAgreeWithinOneStep) {
  gl::HeadlessContext context;
  const int w = 64, h = 40;
  const float exposure = 1.5f;
  sphere::EquirectImage linear(w, h), exposed(w, h);
  std::vector<float> rgba(static_cast<std::size_t>(w) * h * 4);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      // Dark to past white along x, a different ramp per channel, rows distinct.
      const float v[3] = {0.9f * x / (w - 1), 0.7f * y / (h - 1), 0.001f * static_cast<float>(x + y)};
      for (int c = 0; c < 3; ++c) {
        linear.rgb[3 * i + c] = v[c];
        exposed.rgb[3 * i + c] = v[c] * exposure;
        rgba[4 * i + c] = v[c];
      }
      rgba[4 * i + 3] = 1;
    }
  gl::Texture texture = gl::Texture::Create2D(GL_RGBA32F, w, h);
  texture.Upload2D(GL_RGBA, GL_FLOAT, rgba.data());
  FramePresenter presenter;
  const auto from_image = Draw([&](GLuint fbo) { presenter.Show(exposed, w, h, fbo); }, w, h);
  const auto from_texture = Draw([&](GLuint fbo) { presenter.Show(texture, exposure, w, h, fbo); }, w, h);
  ASSERT_EQ(from_image.size(), from_texture.size());
  int worst = 0;
  for (std::size_t i = 0; i < from_image.size(); ++i)
    worst = std::max(worst, std::abs(static_cast<int>(from_image[i]) - static_cast<int>(from_texture[i])));
  EXPECT_LE(worst, 1);
  // The picture's top row (y = 0) is the framebuffer's last row: its green is 0 there, its most
  // at the bottom.
  const auto at = [&](const std::vector<unsigned char>& px, int x, int gl_row, int c) {
    return static_cast<int>(px[(static_cast<std::size_t>(gl_row) * w + x) * 4 + c]);
  };
  EXPECT_EQ(at(from_texture, 10, h - 1, 1), 0);
  const int bottom_green = static_cast<int>(std::lround(255 * LinearToSrgb(0.7f * exposure)));
  EXPECT_NEAR(at(from_texture, 10, 0, 1), bottom_green, 1);
  // The exposure is applied: red at x = 40 is encoded from 0.9·40/63·1.5.
  EXPECT_NEAR(at(from_texture, 40, 5, 0), std::lround(255 * LinearToSrgb(0.9f * 40 / 63 * exposure)), 1);
  gl::Texture none{gl::NoCreate};
  EXPECT_THROW(presenter.Show(none, 1.f, w, h, 0), Error);
}

}  // namespace
}  // namespace odvr::app
