#include "engine/render/triple_product_renderer.h"

#include <cmath>
#include <glm/gtc/type_ptr.hpp>
#include <glm/matrix.hpp>
#include <string>

#include "core/error.h"
#include "core/timing.h"
#include "engine/gl/context.h"
#include "engine/render/passes/cpu_shade_pass.h"
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

// --- options -------------------------------------------------------------------------

long long detail::FirstShadingPassPixels(const RenderOptions& options, int width, int height) {
  const long long w = width, h = height, k = options.supersample;
  if (options.shading_rate == 2) return ((w + 1) / 2) * ((h + 1) / 2);
  if (k > 1 && options.supersample_contrast > 0 && options.monte_carlo_samples == 0) return w * h;
  return k * w * k * h;
}

int ShadeLanesFor(long long first_pass_pixels, bool software_renderer) {
  return !software_renderer && first_pass_pixels <= kAutoShadeLanesMaxPixels ? 4 : 1;
}

void RenderOptions::Check() const {
  if (lighting_levels < 1 || lighting_levels > 6) throw Error("render levels", "must be in 1..6");
  if (!read_composite && read_layers)
    throw Error("render read_composite", "can be off only with read_layers off (the layers include it)");
  if (cone_rings < 0 || cone_rings > 3) throw Error("render cones", "rings must be in 0..3 (1, 7, 19 or 37 cones)");
  if (shade_lanes != 0 && shade_lanes != 1 && shade_lanes != 2 && shade_lanes != 4)
    throw Error("render shade_lanes", "must be 0 (each render picks), 1, 2 or 4, got " + std::to_string(shade_lanes));
  if (voxel_resolution < 64 || voxel_resolution > 512 || (voxel_resolution & (voxel_resolution - 1)) != 0)
    throw Error("render voxels", "must be a power of two in 64..512, got " + std::to_string(voxel_resolution));
  if (!(ground_half_size > 0)) throw Error("render ground_half_size", "must be positive");
  if (!(surface_offset_voxels >= 0 && surface_offset_voxels <= 8))
    throw Error("render surface_offset_voxels", "must be in [0, 8]");
  if (!(bounce_step_voxels > 0 && bounce_step_voxels <= 16))
    throw Error("render bounce_step_voxels", "must be in (0, 16]");
  if (bounce_steps < 1 || bounce_steps > 1024) throw Error("render bounce_steps", "must be in 1..1024");
  if (!(bounce_thickness_voxels > 0 && bounce_thickness_voxels <= 64))
    throw Error("render bounce_thickness_voxels", "must be in (0, 64]");
  if (!(overlap_min_retention > 0 && overlap_min_retention < 1))
    throw Error("render overlap_min_retention", "must be in (0, 1)");
  if (!(overlap_cutoff > 0 && overlap_cutoff < 1)) throw Error("render overlap_cutoff", "must be in (0, 1)");
  if (ground_lit_map_texels != 0 && (ground_lit_map_texels < 8 || ground_lit_map_texels > 1024))
    throw Error("render ground_lit_map_texels", "must be 0 (trace per cone) or in [8, 1024]");
  for (const auto& m : materials)
    if (m.brdfs.empty() || m.brdfs.size() > static_cast<std::size_t>(TripleProductRenderer::kTermsPerMaterial))
      throw Error("render material override", "needs one or two BRDF terms");
  if (monte_carlo_samples < 0 || monte_carlo_samples > 1 << 20)
    throw Error("render monte_carlo_samples", "must be in 0..2^20");
  if (supersample < 1 || supersample > kMaxSupersample)
    throw Error("render supersample",
                "must be in 1.." + std::to_string(kMaxSupersample) + ", got " + std::to_string(supersample));
  if (!(supersample_contrast >= 0 && supersample_contrast <= 1))
    throw Error("render supersample_contrast", "must be in [0, 1]");
  if (shading_rate != 1 && shading_rate != 2)
    throw Error("render shading_rate", "must be 1 or 2, got " + std::to_string(shading_rate));
  if (shading_rate == 2 && supersample > 1)
    throw Error("render shading_rate", "2 (a pixel per 2x2 block) and supersample > 1 exclude each other");
  if (shading_rate == 2 && monte_carlo_samples > 0)
    throw Error("render shading_rate", "2 is for the SG shader: the Monte-Carlo baseline shades every pixel");
  visibility::ConeSubsampleOptions c = cones;
  c.rings = cone_rings;
  c.Check();
  trace.Check();
}

// --- the renderer ---------------------------------------------------------------------------------

TripleProductRenderer::Impl::Impl(const scene::GltfScene& source, const glm::dmat4& world_from_model,
                                  const RenderOptions& options)
    : model(source, world_from_model),
      voxelize(model, source, options.voxel_resolution),
      lighting(options),
      sg_shade(options) {
  if (options.monte_carlo_samples > 0) monte_carlo.emplace();
  if (options.supersample > 1) resolve.emplace();
  if (!options.read_layers) counts.emplace();
  if ((options.monte_carlo_samples > 0 && options.monte_carlo_exact_visibility) || options.exact_peak_shadows)
    model.BuildBvh();
}

TripleProductRenderer::Impl::~Impl() {
  if (stage_queries[0] != 0) glDeleteQueries(static_cast<GLsizei>(stage_queries.size()), stage_queries.data());
}

TripleProductRenderer::TripleProductRenderer(const scene::GltfScene& model, const glm::dmat4& world_from_model,
                                             RenderOptions options)
    : options_(std::move(options)) {
  options_.Check();
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      if (!std::isfinite(world_from_model[i][j])) throw Error("world_from_model", "must be finite");
  const glm::dmat3 linear(world_from_model);
  if (!(std::abs(glm::determinant(linear)) > 1e-12)) throw Error("world_from_model", "is singular");
  gl::RequireCurrentGl45("triple-product renderer");
  impl_ = std::make_unique<Impl>(model, world_from_model, options_);
  SetMaterials(options_.materials);
  SetLighting(lighting::SgLighting{});
}

TripleProductRenderer::~TripleProductRenderer() = default;

const std::vector<glm::vec3>& TripleProductRenderer::world_triangles() const { return impl_->model.triangles(); }
const visibility::VoxelGridSpec& TripleProductRenderer::voxel_spec() const { return impl_->voxelize.spec(); }
const gl::Texture& TripleProductRenderer::composite_texture() const { return impl_->targets.composite_layer; }

int TripleProductRenderer::peaks_without_cone() const {
  return std::max(0, static_cast<int>(impl_->lighting.prepared().peaks.size()) - kMaxPeakCones);
}

int TripleProductRenderer::PrepareShading(const PinholeCamera& camera) {
  return impl_->sg_shade.PrepareLanes(options_, camera);
}

void TripleProductRenderer::SetMaterials(std::vector<MaterialOverride> overrides) {
  impl_->materials.Set(impl_->model.materials(), overrides);
  options_.materials = std::move(overrides);
}

void TripleProductRenderer::SetLighting(const lighting::SgLighting& model, const glm::dmat3& world_from_lighting) {
  impl_->lighting.Set(model, world_from_lighting, options_.lighting_levels);
}

void TripleProductRenderer::SetBackgroundEquirect(const sphere::EquirectImage& equirect) {
  impl_->composite.SetEquirect(equirect);
}

void TripleProductRenderer::SetBackgroundRotation(const glm::dmat3& world_from_background) {
  impl_->composite.SetRotation(glm::transpose(world_from_background));
}

void TripleProductRenderer::SetEnvironment(const sphere::EquirectImage& equirect) {
  impl_->composite.SetEquirect(equirect);
  impl_->composite.SetRotation(std::nullopt);
  if (impl_->monte_carlo) impl_->monte_carlo->SetEnvironment(equirect);
}

void TripleProductRenderer::SetBackgroundImage(const sphere::EquirectImage& image) { impl_->composite.SetImage(image); }

RenderResult TripleProductRenderer::Render(const PinholeCamera& camera, ShadeDevice device, bool draw_model) {
  Impl& im = *impl_;
  const RenderFrame fr = im.MakeFrame(options_, camera, device, draw_model);
  RenderResult out;
  const auto t_total = SteadyClock::now();
  gl::Finish();

  // Voxelize. GL timestamps around the GPU path's stages, read once the composite is done.
  im.Stamp(fr, 0);
  auto t0 = SteadyClock::now();
  if (fr.geometry) im.voxelize.Run(im.model, device);
  out.ms.voxelize = MsSince(t0);
  im.Stamp(fr, 1);

  // G-buffer, at the shaded size (RenderOptions::supersample).
  t0 = SteadyClock::now();
  im.targets.Ensure(fr);
  im.gbuffer.Run(fr, im.model, im.materials, im.targets);
  out.ms.gbuffer = MsSince(t0);
  im.Stamp(fr, 2);

  // Shade, resolve and composite; on the GPU, read back.
  Impl::Tally tally;
  if (device == ShadeDevice::kGpu) {
    im.RenderOnGpu(fr, &out, &tally);
  } else {
    im.RenderOnCpu(fr, &out, &tally);
  }

  im.SumCounts(fr, tally, &out);
  out.ms.total = MsSince(t_total);
  return out;
}

RenderFrame TripleProductRenderer::Impl::MakeFrame(const RenderOptions& options, const PinholeCamera& camera,
                                                   ShadeDevice device, bool draw_model) const {
  const scene::Bounds& bounds = model.bounds();
  const glm::dvec2 ground_centre(bounds.empty() ? 0.0 : bounds.center().x, bounds.empty() ? 0.0 : bounds.center().z);
  RenderFrame fr = RenderFrame::Make(options, camera, device, model.has_geometry() && draw_model, ground_centre);
  composite.CheckOutputSize(fr.w, fr.h);
  if (fr.monte_carlo && device != ShadeDevice::kGpu)
    throw Error("render", "the Monte-Carlo baseline runs on the GPU only");
  if (fr.monte_carlo && !(monte_carlo && monte_carlo->has_environment()))
    throw Error("render", "the Monte-Carlo baseline needs SetEnvironment");
  return fr;
}

void TripleProductRenderer::Impl::Stamp(const RenderFrame& fr, int stage) {
  if (fr.device != ShadeDevice::kGpu) return;
  if (stage_queries[0] == 0)
    glCreateQueries(GL_TIMESTAMP, static_cast<GLsizei>(stage_queries.size()), stage_queries.data());
  glQueryCounter(stage_queries[static_cast<std::size_t>(stage)], GL_TIMESTAMP);
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

void TripleProductRenderer::Impl::RenderOnGpu(const RenderFrame& fr, RenderResult* out, Tally* tally) {
  auto t0 = SteadyClock::now();
  const int lanes = sg_shade.PrepareLanes(fr.options, fr.camera);
  out->counts.shade_lanes = lanes;
  if (fr.monte_carlo) {
    monte_carlo->Run(fr, scene(), targets);
  } else {
    sg_shade.Run(fr, scene(), targets, lanes);
  }
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  if (fr.k > 1) resolve->Run(fr, targets);
  gl::Finish();
  out->ms.shade = MsSince(t0);
  Stamp(fr, 3);
  const long long half_rate_shaded = fr.half_rate ? sg_shade.HalfRateShadedPixels(fr) : 0;
  t0 = SteadyClock::now();
  composite.RunOnGpu(fr, lighting.prepared().env_from_world, targets);
  out->ms.composite = MsSince(t0);
  Stamp(fr, 4);
  ReadStageTimes(&out->ms);
  t0 = SteadyClock::now();
  ReadBack(fr, half_rate_shaded, out, tally);
  out->ms.readback = MsSince(t0);
}

void TripleProductRenderer::Impl::ReadBack(const RenderFrame& fr, long long half_rate_shaded, RenderResult* out,
                                           Tally* tally) {
  const int w = fr.w, h = fr.h, k = fr.k;
  const std::size_t pixels = fr.pixels, samples = fr.samples;
  // Each layer through the mapped staging buffer, split into RGB and alpha as it is read.
  const auto rgba = [&](const gl::Texture& t) {
    const std::size_t texels = static_cast<std::size_t>(t.width()) * t.height();
    return reinterpret_cast<const float*>(readback.Read(t, GL_RGBA, GL_FLOAT, texels * 4 * sizeof(float)));
  };
  if (fr.options.read_composite) out->composite = ToRgb(rgba(targets.composite_layer), w, h, nullptr);
  if (!fr.options.read_layers) {
    tally->gpu_sums = counts->SumOnGpu(targets.counts, fr.adaptive ? &targets.pixel_flags : nullptr,
                                       targets.ShadedCar(fr), fr.sw, fr.sh, static_cast<int>(pixels));
    if (k > 1 && !fr.adaptive) tally->gpu_sums->pixels_sampled_fully = static_cast<long long>(pixels);
    if (fr.half_rate) tally->gpu_sums->pixels_sampled_fully = half_rate_shaded;
    return;
  }
  out->car = ToRgb(rgba(targets.car_layer), w, h, &out->car_alpha);
  out->shadow = ToRgb(rgba(targets.shadow_layer), w, h, &out->ground_mask);
  out->background = ToRgb(rgba(targets.background_layer), w, h, nullptr);
  const auto* raw =
      reinterpret_cast<const std::uint32_t*>(readback.Read(targets.counts, 0, samples * 4 * sizeof(std::uint32_t)));
  tally->counts.resize(samples);
  for (std::size_t i = 0; i < samples; ++i)
    tally->counts[i] = {raw[4 * i], raw[4 * i + 1], raw[4 * i + 2], raw[4 * i + 3]};
  if (fr.adaptive) {
    const auto flags = targets.pixel_flags.Read<std::uint32_t>(pixels);
    out->sampled_fully.assign(flags.begin(), flags.end());
  } else if (fr.half_rate) {
    out->sampled_fully = detail::HalfRateShaded(sg_shade.ReadBlockFlags(fr), w, h);
  } else if (k > 1) {
    out->sampled_fully.assign(pixels, 1);
  }
  if (k > 1) {
    const float* car = rgba(targets.shaded_car);
    tally->sample_alpha.resize(samples);
    for (std::size_t i = 0; i < samples; ++i) tally->sample_alpha[i] = car[4 * i + 3];
  }
}

void TripleProductRenderer::Impl::RenderOnCpu(const RenderFrame& fr, RenderResult* out, Tally* tally) {
  const detail::GBuffer g = targets.ReadGBuffer();
  auto t0 = SteadyClock::now();  // the shading stage alone, as on the GPU
  ShadeOnCpu(fr, scene(), g, out, &tally->counts, &tally->sample_alpha);
  out->ms.shade = MsSince(t0);
  t0 = SteadyClock::now();
  composite.RunOnCpu(fr, lighting.prepared().env_from_world, out);
  out->ms.composite = MsSince(t0);
}

void TripleProductRenderer::Impl::SumCounts(const RenderFrame& fr, const Tally& tally, RenderResult* out) const {
  const detail::CountSums sums =
      tally.gpu_sums
          ? *tally.gpu_sums
          : CountsPass::SumOnCpu(tally.counts, fr.k > 1 ? tally.sample_alpha : out->car_alpha, out->sampled_fully);
  CountsPass::Fill(sums, lighting.prepared(), &out->counts);
}

}  // namespace odvr::render
