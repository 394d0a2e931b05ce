// TripleProductRenderer's CPU path (triple_product_impl.h): the CPU reference shades the
// read-back G-buffer (with supersampling's resolve and flags, or shading rate 2's flags and fill,
// as the GPU passes do them), then the composite on the CPU.
#include <algorithm>
#include <cmath>
#include <glm/vec2.hpp>

#include "core/timing.h"
#include "engine/render/triple_product_impl.h"
#include "engine/sphere/equirect.h"

namespace odvr::render {
namespace {

// Bilinear look-up with GL's rules (texel centres at +0.5), longitude wrapping, latitude clamped.
glm::vec3 SampleEquirect(const sphere::EquirectImage& img, const glm::dvec3& d) {
  const glm::dvec2 px = sphere::EquirectPixel(d, img.width, img.height);
  const double x = px.x - 0.5, y = std::clamp(px.y - 0.5, 0.0, img.height - 1.0);
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const double fx = x - x0, fy = y - y0;
  const auto at = [&](int c, int r) {
    c = ((c % img.width) + img.width) % img.width;
    r = std::clamp(r, 0, img.height - 1);
    const float* v = img.at(c, r);
    return glm::dvec3(v[0], v[1], v[2]);
  };
  return glm::vec3((1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x0 + 1, y0)) +
                   fy * ((1 - fx) * at(x0, y0 + 1) + fx * at(x0 + 1, y0 + 1)));
}

}  // namespace

namespace detail {

std::vector<std::uint8_t> HalfRateShaded(const std::vector<std::uint8_t>& block_flags, int w, int h) {
  std::vector<std::uint8_t> shaded(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      shaded[static_cast<std::size_t>(y) * w + x] =
          block_flags[static_cast<std::size_t>(y / 2) * ((w + 1) / 2) + x / 2] || (x % 2 == 1 && y % 2 == 1) ? 1 : 0;
  return shaded;
}

}  // namespace detail

void TripleProductRenderer::Impl::RenderOnCpu(const Frame& fr, RenderResult* out, Tally* tally) {
  detail::GBuffer g;
  g.width = fr.sw;
  g.height = fr.sh;
  g.position = g_position.Read<float>(GL_RGBA, GL_FLOAT, 4);
  g.normal = g_normal.Read<float>(GL_RGBA, GL_FLOAT, 4);
  g.base = g_base.Read<float>(GL_RGBA, GL_FLOAT, 4);
  g.emission = g_emission.Read<float>(GL_RGBA, GL_FLOAT, 4);
  auto t0 = SteadyClock::now();  // the shading stage alone, as on the GPU
  ShadeOnCpu(fr, g, out, tally);
  out->ms.shade = MsSince(t0);
  t0 = SteadyClock::now();
  CompositeOnCpu(fr, out);
  out->ms.composite = MsSince(t0);
}

void TripleProductRenderer::Impl::ShadeOnCpu(const Frame& fr, const detail::GBuffer& g, RenderResult* out,
                                             Tally* tally) {
  const RenderOptions& o = fr.options;
  const int w = fr.w, h = fr.h, k = fr.k, sw = fr.sw, sh = fr.sh;
  std::vector<detail::PixelCounts>& sample_counts = tally->counts;
  detail::ReferenceInputs in;
  in.gbuffer = &g;
  in.camera = fr.shaded_camera;
  in.materials = &material_terms;
  in.lighting = &lighting;
  in.bins = bins.get();
  in.grid = fr.geometry ? cpu_grid.get() : nullptr;
  in.bvh = fr.geometry && o.exact_peak_shadows ? bvh.get() : nullptr;
  in.options = o;
  in.ground_centre = fr.ground_centre;
  if (k > 1) {
    RenderResult shaded;
    detail::ShadeReference(in, &shaded, &sample_counts);
    if (fr.adaptive) {
      // Every sample is shaded here; the ones the GPU would not shade are left out of the
      // result, the counts and the coverage alike.
      out->sampled_fully = detail::FlagPixels(g, shaded, k, w, h, static_cast<float>(o.supersample_contrast));
      for (int y = 0; y < sh; ++y)
        for (int x = 0; x < sw; ++x) {
          const std::size_t s = static_cast<std::size_t>(y) * sw + x;
          if (!out->sampled_fully[static_cast<std::size_t>(y / k) * w + x / k] && (x % k != k / 2 || y % k != k / 2)) {
            sample_counts[s] = {};
            shaded.car_alpha[s] = 0;
          }
        }
      detail::ResolveSupersampled(shaded, k, w, h, out, &out->sampled_fully);
    } else {
      out->sampled_fully.assign(fr.pixels, 1);
      detail::ResolveSupersampled(shaded, k, w, h, out);
    }
    tally->sample_alpha = std::move(shaded.car_alpha);
  } else if (fr.half_rate) {
    // Every pixel is shaded here; the flags pick the blocks the GPU shades whole, and the other
    // blocks' pixels are filled as render_fill.comp fills them, out of the counts.
    detail::ShadeReference(in, out, &sample_counts);
    const std::vector<std::uint8_t> block =
        detail::FlagPixels(g, *out, 2, fr.bw, fr.bh, static_cast<float>(o.supersample_contrast), true);
    detail::FillHalfRate(block, out);
    out->sampled_fully = detail::HalfRateShaded(block, w, h);
    for (std::size_t i = 0; i < fr.pixels; ++i)
      if (!out->sampled_fully[i]) sample_counts[i] = {};
  } else {
    detail::ShadeReference(in, out, &sample_counts);
  }
}

void TripleProductRenderer::Impl::CompositeOnCpu(const Frame& fr, RenderResult* out) const {
  const int w = fr.w, h = fr.h;
  out->background = sphere::EquirectImage(w, h, 0.f);
  out->composite = sphere::EquirectImage(w, h, 0.f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      glm::vec3 bg(0);
      if (background_is_image) {
        const float* b = background_image.at(x, y);
        bg = glm::vec3(b[0], b[1], b[2]);
      } else if (!environment.empty()) {
        bg = SampleEquirect(environment,
                            background_from_world.value_or(lighting.env_from_world) * fr.camera.Ray(x + 0.5, y + 0.5));
      }
      const float a = out->car_alpha[i];
      for (int c = 0; c < 3; ++c) {
        out->background.rgb[3 * i + c] = bg[c];
        out->composite.rgb[3 * i + c] = (1 - a) * bg[c] * out->shadow.rgb[3 * i + c] + a * out->car.rgb[3 * i + c];
      }
    }
}

}  // namespace odvr::render
