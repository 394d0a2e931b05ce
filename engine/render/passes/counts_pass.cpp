#include "engine/render/passes/counts_pass.h"

#include <algorithm>

#include "engine/gl/shader_library.h"

namespace odvr::render {

CountsPass::CountsPass() : program_(gl::ShaderLibrary::Compute("render_counts.comp")) {}

detail::CountSums CountsPass::SumOnGpu(const gl::Buffer& counts, const gl::Buffer* pixel_flags,
                                       const gl::Texture& sample_car, int samples_width, int samples_height,
                                       int pixels) {
  constexpr long long kGroup = 256, kMaxGroups = 256;
  // Enough invocations to fill a GPU, few enough that each sums a stride of samples first.
  const long long covered = std::max<long long>(static_cast<long long>(samples_width) * samples_height, pixels);
  const long long groups = std::clamp<long long>((covered + kGroup - 1) / kGroup, 1, kMaxGroups);
  const std::size_t bytes = static_cast<std::size_t>(kMaxGroups * detail::kCountTotals) * sizeof(std::uint32_t);
  if (!group_totals_ || group_totals_.size() < bytes) {
    group_totals_ = gl::Buffer();
    group_totals_.Allocate(bytes);
  }
  gl::Program& program = program_;
  counts.BindBase(GL_SHADER_STORAGE_BUFFER, 0);
  if (pixel_flags) pixel_flags->BindBase(GL_SHADER_STORAGE_BUFFER, 1);
  group_totals_.BindBase(GL_SHADER_STORAGE_BUFFER, 2);
  sample_car.BindImage(0, GL_READ_ONLY);
  glProgramUniform2i(program.id(), program.Uniform("uSamplesSize"), samples_width, samples_height);
  program.Set("uPixels", pixels).Set("uHasFlags", pixel_flags ? 1 : 0);
  program.Use().DispatchCovering(static_cast<unsigned>(groups * kGroup));
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  const std::vector<std::uint32_t> t =
      group_totals_.Read<std::uint32_t>(static_cast<std::size_t>(groups * detail::kCountTotals));
  detail::CountSums s;
  for (long long g = 0; g < groups; ++g) {
    const std::uint32_t* v = &t[static_cast<std::size_t>(g * detail::kCountTotals)];
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

detail::CountSums CountsPass::SumOnCpu(const std::vector<detail::PixelCounts>& counts,
                                       const std::vector<float>& sample_alpha,
                                       const std::vector<std::uint8_t>& sampled_fully) {
  detail::CountSums sums;
  for (std::size_t i = 0; i < counts.size(); ++i) {
    sums.cones_total += counts[i].cones;
    sums.triples_total += counts[i].triples;
    if (sample_alpha[i] > 0) {
      ++sums.car;
      sums.lobes += counts[i].lobes;
      sums.cones += counts[i].cones;
      sums.sgs += counts[i].sgs;
      sums.triples += counts[i].triples;
    } else if (counts[i].lobes > 0) {
      ++sums.ground;
    }
  }
  sums.pixels_sampled_fully = std::count(sampled_fully.begin(), sampled_fully.end(), 1);
  return sums;
}

void CountsPass::Fill(const detail::CountSums& sums, const detail::PreparedLighting& lighting, RenderCounts* c) {
  c->lighting_sgs = lighting.sg_count;
  c->peaks = static_cast<int>(lighting.peaks.size());
  c->car_pixels = static_cast<int>(sums.car);
  c->ground_pixels = static_cast<int>(sums.ground);
  c->pixels_sampled_fully = static_cast<int>(sums.pixels_sampled_fully);
  c->cones_total = sums.cones_total;
  c->triples_total = sums.triples_total;
  if (c->car_pixels > 0) {
    c->lobes_per_car_pixel = static_cast<double>(sums.lobes) / c->car_pixels;
    c->cones_per_car_pixel = static_cast<double>(sums.cones) / c->car_pixels;
    c->sgs_per_car_pixel = static_cast<double>(sums.sgs) / c->car_pixels;
    c->triples_per_car_pixel = static_cast<double>(sums.triples) / c->car_pixels;
  }
}

}  // namespace odvr::render
