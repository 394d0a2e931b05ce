// TripleProductRenderer's GPU path in order (triple_product_impl.h): the shading passes
// (triple_product_shade_gpu.cpp), the composite, the stages' times by the GPU's clock and the
// readback; and the counts summed on the GPU.
#include <algorithm>
#include <array>
#include <glm/gtc/type_ptr.hpp>

#include "core/timing.h"
#include "engine/render/triple_product_impl.h"

namespace odvr::render {
namespace {

// A layer read back as RGBA, split into RGB and (where `alpha` is given) its alpha.
sphere::EquirectImage ToRgb(const float* v, int w, int h, std::vector<float>* alpha) {
  const std::size_t pixels = static_cast<std::size_t>(w) * h;
  sphere::EquirectImage img(w, h);
  if (alpha) alpha->resize(pixels);
  for (std::size_t i = 0; i < pixels; ++i) {
    for (int c = 0; c < 3; ++c) img.rgb[3 * i + c] = v[4 * i + c];
    if (alpha) (*alpha)[i] = v[4 * i + 3];
  }
  return img;
}

}  // namespace

namespace detail {

CountSums SumCountsOnGpu(gl::Program& program, gl::Buffer& counts, gl::Buffer* pixel_flags, gl::Buffer& group_totals,
                         gl::Texture& sample_car, int samples_width, int samples_height, int pixels) {
  constexpr long long kGroup = 256, kMaxGroups = 256;
  // Enough invocations to fill a GPU, few enough that each sums a stride of samples first.
  const long long covered = std::max<long long>(static_cast<long long>(samples_width) * samples_height, pixels);
  const long long groups = std::clamp<long long>((covered + kGroup - 1) / kGroup, 1, kMaxGroups);
  const std::size_t bytes = static_cast<std::size_t>(kMaxGroups * kCountTotals) * sizeof(std::uint32_t);
  if (!group_totals || group_totals.size() < bytes) {
    group_totals = gl::Buffer();
    group_totals.Allocate(bytes);
  }
  counts.BindBase(GL_SHADER_STORAGE_BUFFER, 0);
  if (pixel_flags) pixel_flags->BindBase(GL_SHADER_STORAGE_BUFFER, 1);
  group_totals.BindBase(GL_SHADER_STORAGE_BUFFER, 2);
  sample_car.BindImage(0, GL_READ_ONLY);
  glProgramUniform2i(program.id(), program.Uniform("uSamplesSize"), samples_width, samples_height);
  program.Set("uPixels", pixels).Set("uHasFlags", pixel_flags ? 1 : 0);
  program.Use().DispatchCovering(static_cast<unsigned>(groups * kGroup));
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  const std::vector<std::uint32_t> t =
      group_totals.Read<std::uint32_t>(static_cast<std::size_t>(groups * kCountTotals));
  CountSums s;
  for (long long g = 0; g < groups; ++g) {
    const std::uint32_t* v = &t[static_cast<std::size_t>(g * kCountTotals)];
    const auto pair = [&](int i) {
      return static_cast<long long>(v[3 + 2 * i] | (static_cast<std::uint64_t>(v[4 + 2 * i]) << 32));
    };
    s.car += v[0];
    s.ground += v[1];
    s.pixels_sampled_fully += v[2];
    s.lobes += pair(0);
    s.cones += pair(1);
    s.sgs += pair(2);
    s.triples += pair(3);
    s.cones_total += pair(4);
    s.triples_total += pair(5);
  }
  return s;
}

}  // namespace detail

void TripleProductRenderer::Impl::RenderOnGpu(const Frame& fr, RenderResult* out, Tally* tally) {
  auto t0 = SteadyClock::now();
  const int lanes = PrepareShading(fr.options, fr.camera);
  out->counts.shade_lanes = lanes;
  gl::Program& sp = ShadeProgram(lanes);
  SetShadeUniforms(fr, sp);
  BindShadeInputs(fr);
  if (fr.monte_carlo) {
    ShadeMonteCarlo(fr);
  } else {
    ShadeSg(fr, sp, lanes);
  }
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  if (fr.k > 1) Resolve(fr);
  gl::Finish();
  out->ms.shade = MsSince(t0);
  Stamp(fr, 3);
  const long long half_rate_shaded = fr.half_rate ? HalfRateShadedPixels(fr) : 0;
  CompositeOnGpu(fr, &out->ms);
  Stamp(fr, 4);
  ReadStageTimes(&out->ms);
  t0 = SteadyClock::now();
  ReadBack(fr, half_rate_shaded, out, tally);
  out->ms.readback = MsSince(t0);
}

long long TripleProductRenderer::Impl::HalfRateShadedPixels(const Frame& fr) {
  // Every block once, three more pixels of each flagged whole block, and every pixel of the
  // blocks an odd edge cuts (all flagged); the count read now that the GPU is done.
  const int w = fr.w, h = fr.h;
  std::uint32_t listed = 0;
  block_list.Read(0, 4, &listed);
  const long long blocks = static_cast<long long>(fr.bw) * fr.bh, whole = static_cast<long long>(w / 2) * (h / 2);
  return whole + 3LL * (listed - (blocks - whole)) + (static_cast<long long>(fr.pixels) - 4 * whole);
}

void TripleProductRenderer::Impl::CompositeOnGpu(const Frame& fr, RenderTimings* ms) {
  const auto t0 = SteadyClock::now();
  const PinholeCamera& camera = fr.camera;
  const glm::mat3 wfc(camera.world_from_camera);
  gl::Program& cp = composite_program;
  const glm::mat3 background_efw(background_from_world.value_or(lighting.env_from_world));
  cp.Set("uBackgroundIsImage", background_is_image ? 1 : 0)
      .Set("uCameraPosition", static_cast<float>(camera.position.x), static_cast<float>(camera.position.y),
           static_cast<float>(camera.position.z))
      .SetMat3("uWorldFromCamera", glm::value_ptr(wfc))
      .Set("uFocal", static_cast<float>(fr.f))
      .SetMat3("uEnvFromWorld", glm::value_ptr(background_efw));
  glProgramUniform2i(cp.id(), cp.Uniform("uSize"), fr.w, fr.h);
  if (environment_texture) {
    environment_texture.BindUnit(0);
  } else {
    static const float black[3] = {0, 0, 0};
    environment_texture = gl::Texture::Create2D(GL_RGB32F, 1, 1);
    environment_texture.Upload2D(GL_RGB, GL_FLOAT, black);
    environment_texture.BindUnit(0);
  }
  car_layer.BindImage(0, GL_READ_ONLY);
  shadow_layer.BindImage(1, GL_READ_ONLY);
  composite_layer.BindImage(2, GL_WRITE_ONLY);
  background_layer.BindImage(3, GL_WRITE_ONLY);
  cp.Use().DispatchCovering(static_cast<unsigned>(fr.w), static_cast<unsigned>(fr.h));
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  gl::Finish();
  ms->composite = MsSince(t0);
}

void TripleProductRenderer::Impl::ReadStageTimes(RenderTimings* ms) {
  std::array<GLuint64, 5> ns{};
  for (std::size_t i = 0; i < ns.size(); ++i) glGetQueryObjectui64v(stage_queries[i], GL_QUERY_RESULT, &ns[i]);
  const auto between = [&](int a, int b) {
    return static_cast<double>(ns[static_cast<std::size_t>(b)] - ns[static_cast<std::size_t>(a)]) * 1e-6;
  };
  ms->gpu_voxelize = between(0, 1);
  ms->gpu_gbuffer = between(1, 2);
  ms->gpu_shade = between(2, 3);
  ms->gpu_composite = between(3, 4);
}

void TripleProductRenderer::Impl::ReadBack(const Frame& fr, long long half_rate_shaded, RenderResult* out,
                                           Tally* tally) {
  const int w = fr.w, h = fr.h, k = fr.k;
  const std::size_t pixels = fr.pixels, samples = fr.samples;
  // Each layer through the mapped staging buffer, split into RGB and alpha as it is read.
  const auto rgba = [&](const gl::Texture& t) {
    const std::size_t texels = static_cast<std::size_t>(t.width()) * t.height();
    return reinterpret_cast<const float*>(readback.Read(t, GL_RGBA, GL_FLOAT, texels * 4 * sizeof(float)));
  };
  if (fr.options.read_composite) out->composite = ToRgb(rgba(composite_layer), w, h, nullptr);
  if (!fr.options.read_layers) {
    tally->gpu_sums = detail::SumCountsOnGpu(counts_program, counts, fr.adaptive ? &pixel_flags : nullptr, count_totals,
                                             k > 1 ? shaded_car : car_layer, fr.sw, fr.sh, static_cast<int>(pixels));
    if (k > 1 && !fr.adaptive) tally->gpu_sums->pixels_sampled_fully = static_cast<long long>(pixels);
    if (fr.half_rate) tally->gpu_sums->pixels_sampled_fully = half_rate_shaded;
    return;
  }
  out->car = ToRgb(rgba(car_layer), w, h, &out->car_alpha);
  out->shadow = ToRgb(rgba(shadow_layer), w, h, &out->ground_mask);
  out->background = ToRgb(rgba(background_layer), w, h, nullptr);
  const auto* raw =
      reinterpret_cast<const std::uint32_t*>(readback.Read(counts, 0, samples * 4 * sizeof(std::uint32_t)));
  tally->counts.resize(samples);
  for (std::size_t i = 0; i < samples; ++i)
    tally->counts[i] = {raw[4 * i], raw[4 * i + 1], raw[4 * i + 2], raw[4 * i + 3]};
  if (fr.adaptive) {
    const auto flags = pixel_flags.Read<std::uint32_t>(pixels);
    out->sampled_fully.assign(flags.begin(), flags.end());
  } else if (fr.half_rate) {
    const auto flags = block_flags.Read<std::uint32_t>(static_cast<std::size_t>(fr.bw) * fr.bh);
    std::vector<std::uint8_t> block(flags.begin(), flags.end());
    out->sampled_fully = detail::HalfRateShaded(block, w, h);
  } else if (k > 1) {
    out->sampled_fully.assign(pixels, 1);
  }
  if (k > 1) {
    const float* car = rgba(shaded_car);
    tally->sample_alpha.resize(samples);
    for (std::size_t i = 0; i < samples; ++i) tally->sample_alpha[i] = car[4 * i + 3];
  }
}

}  // namespace odvr::render
