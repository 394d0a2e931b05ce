// TripleProductRenderer's GPU shading passes (triple_product_impl.h): the shade program's
// uniforms and inputs, the Monte-Carlo baseline's pass, the SG passes (the ground table, the
// ground-lit map, then every sample, the adaptive supersampling's or shading rate 2's), and the
// supersampled layers' resolve.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <glm/gtc/type_ptr.hpp>
#include <string>

#include "core/constants.h"
#include "engine/gl/shader_library.h"
#include "engine/render/triple_product_impl.h"
#include "engine/sphere/healpix.h"

namespace odvr::render {
namespace {

// The traced peaks for the ground's lit fraction (detail::GroundLitFraction): axis and cone
// half-angle, and share of the ground's irradiance; none without peak cones.
void SetGroundPeakUniforms(gl::Program& p, const detail::PreparedLighting& l, bool peak_cones) {
  std::vector<float> axes, shares;
  const std::size_t n = peak_cones ? l.ground_peak_share.size() : 0;
  for (std::size_t k = 0; k < n; ++k) {
    const auto& pk = l.peaks[k];
    axes.insert(axes.end(),
                {static_cast<float>(pk.axis.x), static_cast<float>(pk.axis.y), static_cast<float>(pk.axis.z),
                 static_cast<float>(std::min(detail::HalfValueAngle(pk.lambda), visibility::kMaxConeHalfAngle))});
    shares.push_back(static_cast<float>(l.ground_peak_share[k]));
  }
  p.Set("uGroundPeakCount", static_cast<int>(n));
  if (n > 0) {
    glProgramUniform4fv(p.id(), p.Uniform("uGroundPeakAxis"), static_cast<GLsizei>(n), axes.data());
    glProgramUniform1fv(p.id(), p.Uniform("uGroundPeakShare"), static_cast<GLsizei>(n), shares.data());
  }
}

// The uniforms of cone_trace.glsl, which the SG shader and the Monte-Carlo one both include.
void SetConeTraceUniforms(gl::Program& program, const visibility::VoxelGridSpec& spec, bool has_geometry,
                          const visibility::ConeTraceOptions& trace) {
  program
      .Set("uVoxelOrigin", static_cast<float>(spec.origin.x), static_cast<float>(spec.origin.y),
           static_cast<float>(spec.origin.z))
      .Set("uVoxelSize", static_cast<float>(spec.voxel_size))
      .Set("uVoxelSide", static_cast<float>(spec.side()))
      .Set("uVoxelTopLevel", has_geometry ? spec.levels() - 1 : -1)
      .Set("uConeStartOffset", static_cast<float>(trace.start_offset_voxels))
      .Set("uConeStepScale", static_cast<float>(trace.step_scale))
      .Set("uConeMaxDistance", static_cast<float>(trace.max_distance))
      .Set("uConeOpaque", static_cast<float>(trace.opaque_threshold))
      .Set("uConePartialExponent", static_cast<float>(trace.partial_opacity_exponent));
}

// The ground's unshadowed irradiance from the map's upper half (world up), which the exact ground
// lit fraction divides by (render_mc.comp's groundLitExact).
glm::dvec3 GroundIrradianceFromAbove(const sphere::EquirectImage& env, const glm::dmat3& world_from_env) {
  glm::dvec3 e(0);
  for (int y = 0; y < env.height; ++y) {
    const double lat = 0.5 * kPi - kPi * (y + 0.5) / env.height;
    const double d_omega = (2 * kPi / env.width) * (kPi / env.height) * std::cos(lat);
    for (int x = 0; x < env.width; ++x) {
      const double lon = kPi * (1 - 2 * (x + 0.5) / env.width);
      const glm::dvec3 d =
          world_from_env * glm::dvec3(std::cos(lat) * std::cos(lon), std::sin(lat), -std::cos(lat) * std::sin(lon));
      if (d.y <= 0) continue;
      for (int c = 0; c < 3; ++c) e[c] += env.at(x, y)[c] * d.y * d_omega;
    }
  }
  return e;
}

}  // namespace

gl::Program& TripleProductRenderer::Impl::ShadeProgram(int lanes) {
  gl::Program& p = shade_programs[static_cast<std::size_t>(lanes == 4 ? 2 : lanes == 2 ? 1 : 0)];
  if (!p)
    p = gl::ShaderLibrary::Compute("render_shade.comp", "#define CONE_RINGS " + std::to_string(cone_rings) +
                                                            "\n#define SHADE_LANES " + std::to_string(lanes) + "\n");
  return p;
}

int TripleProductRenderer::Impl::PrepareShading(const RenderOptions& options, const PinholeCamera& camera) {
  const int lanes =
      options.shade_lanes != 0
          ? options.shade_lanes
          : ShadeLanesFor(detail::FirstShadingPassPixels(options, camera.width, camera.height), software_renderer);
  ShadeProgram(lanes);
  return lanes;
}

void TripleProductRenderer::Impl::SetShadeUniforms(const Frame& fr, gl::Program& sp) {
  const RenderOptions& o = fr.options;
  const PinholeCamera& camera = fr.camera;
  const glm::vec3 ground_radiance = lighting.GroundRadiance(o.peak_cones);
  const glm::vec3 ambient = o.ambient_bounce && fr.geometry ? lighting.mean_radiance : glm::vec3(0);
  const glm::mat3 wfc(camera.world_from_camera), efw(lighting.env_from_world);
  glProgramUniform2i(sp.id(), sp.Uniform("uSize"), fr.sw, fr.sh);
  sp.Set("uCameraPosition", static_cast<float>(camera.position.x), static_cast<float>(camera.position.y),
         static_cast<float>(camera.position.z))
      .SetMat3("uWorldFromCamera", glm::value_ptr(wfc))
      .Set("uFocal", static_cast<float>(fr.sf))
      .SetMat3("uEnvFromWorld", glm::value_ptr(efw))
      .Set("uConstant", lighting.constant.x, lighting.constant.y, lighting.constant.z)
      .Set("uPeakCount", static_cast<int>(lighting.peaks.size()))
      .Set("uPeakCones", o.peak_cones ? 1 : 0)
      .Set("uBinLevelCount", lighting.srbfs.empty() ? 0 : static_cast<int>(bins->levels().size()))
      .Set("uSingleConeMaxHalfAngle", static_cast<float>(o.cones.single_cone_max_half_angle))
      .Set("uConeCoverage", static_cast<float>(o.cones.coverage))
      .Set("uMaxConeHalfAngle", static_cast<float>(visibility::kMaxConeHalfAngle))
      .Set("uTermsPerMaterial", kTermsPerMaterial)
      .Set("uMaterialCount", static_cast<int>(materials.size()))
      .Set("uSurfaceOffset", static_cast<float>(o.surface_offset_voxels * spec.voxel_size))
      .Set("uExactTriangles", o.exact_peak_shadows && fr.geometry ? bvh_triangle_count : 0)
      .Set("uExactRayOffset", detail::kExactRayOffset)
      .Set("uBounce", o.specular_bounce && fr.geometry ? 1 : 0)
      .Set("uAmbientBounce", ambient.x, ambient.y, ambient.z)
      .Set("uBounceStep", static_cast<float>(o.bounce_step_voxels * spec.voxel_size))
      .Set("uBounceSteps", o.bounce_steps)
      .Set("uBounceThickness", static_cast<float>(o.bounce_thickness_voxels * spec.voxel_size))
      .Set("uBounceSrbfs", detail::BounceSrbfCount(lighting))
      .Set("uGround", o.ground ? 1 : 0)
      .Set("uWarpSplit", o.lobes.warp == material::WarpMode::kAnisotropicSplit ? 1 : 0)
      .Set("uCosineAsSg", o.lobes.cosine == material::CosineTerm::kAsSg ? 1 : 0)
      .Set("uGroundCenter", static_cast<float>(fr.ground_centre.x), static_cast<float>(fr.ground_centre.y))
      .Set("uGroundHalfSize", static_cast<float>(o.ground_half_size))
      .Set("uGroundShadowsBounce", o.ground && o.ground_shadows_bounce ? 1 : 0)
      .Set("uGroundLitHalfAngle", static_cast<float>(kGroundLitHalfAngle))
      .Set("uGroundRadiance", ground_radiance.x, ground_radiance.y, ground_radiance.z);
  {
    std::array<float, 6> level_lambda;
    level_lambda.fill(3e38f);  // beyond the levels used: never deep enough
    for (int s = 0; s < o.lighting_levels; ++s)
      level_lambda[static_cast<std::size_t>(s)] = static_cast<float>(sphere::Healpix(s).Lambda());
    glProgramUniform1fv(sp.id(), sp.Uniform("uLevelLambda"), 6, level_lambda.data());
    sp.Set("uMinRetention", static_cast<float>(o.overlap_min_retention)).Set("uLobeDepth", o.depth_per_lobe ? 1 : 0);
  }
  SetGroundPeakUniforms(sp, lighting, o.peak_cones);
  SetConeTraceUniforms(sp, spec, fr.geometry, o.trace);
}

void TripleProductRenderer::Impl::BindShadeInputs(const Frame& fr) {
  if (fr.geometry) glBindTextureUnit(0, voxelizer->texture().id());
  g_position.BindImage(0, GL_READ_ONLY);
  g_normal.BindImage(1, GL_READ_ONLY);
  g_base.BindImage(2, GL_READ_ONLY);
  g_emission.BindImage(5, GL_READ_ONLY);
  (fr.k > 1 ? shaded_car : car_layer).BindImage(3, GL_WRITE_ONLY);
  (fr.k > 1 ? shaded_shadow : shadow_layer).BindImage(4, GL_WRITE_ONLY);
  srbf_buffer.BindBase(GL_SHADER_STORAGE_BUFFER, 0);
  peak_buffer.BindBase(GL_SHADER_STORAGE_BUFFER, 1);
  bin_levels.BindBase(GL_SHADER_STORAGE_BUFFER, 2);
  bin_begin.BindBase(GL_SHADER_STORAGE_BUFFER, 3);
  bin_srbfs.BindBase(GL_SHADER_STORAGE_BUFFER, 4);
  terms_buffer.BindBase(GL_SHADER_STORAGE_BUFFER, 5);
  counts.BindBase(GL_SHADER_STORAGE_BUFFER, 6);
  ndf_table.BindBase(GL_SHADER_STORAGE_BUFFER, 7);
  glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_FRAMEBUFFER_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT);
}

void TripleProductRenderer::Impl::ShadeMonteCarlo(const Frame& fr) {
  const RenderOptions& o = fr.options;
  const PinholeCamera& camera = fr.camera;
  const glm::mat3 wfc(camera.world_from_camera), efw(lighting.env_from_world);
  gl::Program& mp = mc_program;
  glProgramUniform2i(mp.id(), mp.Uniform("uSize"), fr.sw, fr.sh);
  glProgramUniform1ui(mp.id(), mp.Uniform("uSeed"), o.monte_carlo_seed);
  mp.Set("uCameraPosition", static_cast<float>(camera.position.x), static_cast<float>(camera.position.y),
         static_cast<float>(camera.position.z))
      .SetMat3("uWorldFromCamera", glm::value_ptr(wfc))
      .Set("uFocal", static_cast<float>(fr.sf))
      .SetMat3("uEnvFromWorld", glm::value_ptr(efw))
      .Set("uTermsPerMaterial", kTermsPerMaterial)
      .Set("uMaterialCount", static_cast<int>(materials.size()))
      .Set("uSurfaceOffset", static_cast<float>(o.surface_offset_voxels * spec.voxel_size))
      .Set("uGround", o.ground ? 1 : 0)
      .Set("uGroundCenter", static_cast<float>(fr.ground_centre.x), static_cast<float>(fr.ground_centre.y))
      .Set("uGroundHalfSize", static_cast<float>(o.ground_half_size))
      .Set("uGroundShadowsBounce", o.ground && o.ground_shadows_bounce ? 1 : 0)
      .Set("uGroundLitHalfAngle", static_cast<float>(kGroundLitHalfAngle))
      .Set("uSamples", o.monte_carlo_samples)
      // A ray of a voxel's width: level 0 all along (cone_trace.glsl clamps the diameter).
      .Set("uShadowRayHalfAngle", 1e-4f)
      .Set("uExactTriangles", fr.geometry ? bvh_triangle_count : 0)
      // Off the surface by a millimetre: the G-buffer's positions are interpolated in float.
      .Set("uExactRayOffset", detail::kExactRayOffset)
      .Set("uExactVisibility", o.monte_carlo_exact_visibility ? 1 : 0);
  if (o.monte_carlo_exact_visibility) {
    const glm::dvec3 e = GroundIrradianceFromAbove(environment, glm::transpose(lighting.env_from_world));
    mp.Set("uGroundIrradiance", static_cast<float>(e.x), static_cast<float>(e.y), static_cast<float>(e.z));
  }
  SetGroundPeakUniforms(mp, lighting, o.peak_cones);
  SetConeTraceUniforms(mp, spec, fr.geometry, o.trace);
  mc_environment.BindUnit(1);
  env_row_cdf.BindBase(GL_SHADER_STORAGE_BUFFER, 8);
  env_col_cdf.BindBase(GL_SHADER_STORAGE_BUFFER, 9);
  env_texel_prob.BindBase(GL_SHADER_STORAGE_BUFFER, 10);
  if (bvh_triangle_count > 0) {
    bvh_nodes.BindBase(GL_SHADER_STORAGE_BUFFER, 11);
    bvh_triangles.BindBase(GL_SHADER_STORAGE_BUFFER, 12);
  }
  mp.Use().DispatchCovering(static_cast<unsigned>(fr.sw), static_cast<unsigned>(fr.sh));
}

void TripleProductRenderer::Impl::ShadeSg(const Frame& fr, gl::Program& sp, int lanes) {
  const RenderOptions& o = fr.options;
  cosine_table.BindBase(GL_SHADER_STORAGE_BUFFER, 8);
  ground_table.BindBase(GL_SHADER_STORAGE_BUFFER, 11);
  if (o.exact_peak_shadows && bvh_triangle_count > 0) {
    bvh_nodes.BindBase(GL_SHADER_STORAGE_BUFFER, 14);
    bvh_triangles.BindBase(GL_SHADER_STORAGE_BUFFER, 15);
  }
  if (o.ground) {
    sp.Set("uGroundTablePass", 1).Use();
    glDispatchCompute(1, 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  }
  DispatchGroundLitMap(fr, sp, lanes);
  sp.Set("uGroundTablePass", 0).Set("uOutWidth", fr.w).Set("uFactor", fr.k).Set("uAdaptivePass", 0);
  if (fr.half_rate) {
    ShadeHalfRate(fr, sp, lanes);
  } else if (fr.adaptive) {
    ShadeAdaptive(fr, sp, lanes);
  } else {
    sp.Set("uSampleStride", 1)
        .Set("uSamplePhase", 0)
        .Use()
        .DispatchCovering(static_cast<unsigned>(fr.sw), static_cast<unsigned>(fr.sh), static_cast<unsigned>(lanes));
  }
}

void TripleProductRenderer::Impl::DispatchGroundLitMap(const Frame& fr, gl::Program& sp, int lanes) {
  const RenderOptions& o = fr.options;
  const detail::GroundLitMapLayout map =
      o.ground && o.ground_shadows_bounce && fr.geometry
          ? detail::GroundLitMapLayoutFor(spec, lighting, o.peak_cones, fr.ground_centre, o.ground_half_size,
                                          o.ground_lit_map_texels)
          : detail::GroundLitMapLayout{};
  const std::size_t map_bytes = std::max<std::size_t>(map.texels(), 1) * sizeof(float);
  if (!ground_lit_map || ground_lit_map.size() < map_bytes) {
    ground_lit_map = gl::Buffer();
    ground_lit_map.Allocate(map_bytes);
  }
  ground_lit_map.BindBase(GL_SHADER_STORAGE_BUFFER, 12);
  glProgramUniform2i(sp.id(), sp.Uniform("uGroundLitMapSize"), map.width, map.height);
  sp.Set("uGroundLitMapOrigin", static_cast<float>(map.origin.x), static_cast<float>(map.origin.y))
      .Set("uGroundLitMapSpacing", static_cast<float>(map.spacing));
  if (map.width > 0) {
    spdlog::debug("render: the ground's lit fraction on {}x{} texels {:.3f} m apart", map.width, map.height,
                  map.spacing);
    sp.Set("uGroundTablePass", 2)
        .Use()
        .DispatchCovering(static_cast<unsigned>(map.width), static_cast<unsigned>(map.height),
                          static_cast<unsigned>(lanes));
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  }
}

void TripleProductRenderer::Impl::ShadeHalfRate(const Frame& fr, gl::Program& sp, int lanes) {
  const int w = fr.w, h = fr.h, bw = fr.bw, bh = fr.bh;
  const std::size_t blocks = static_cast<std::size_t>(bw) * static_cast<std::size_t>(bh);
  if (!block_flags || block_flags.size() < blocks * 4) {
    block_flags = gl::Buffer();
    block_flags.Allocate(blocks * 4);
    block_list = gl::Buffer();
    block_list.Allocate(4 + blocks * 4);
  }
  // The pixels the passes leave unshaded read as empty in the counts until they are filled.
  glClearNamedBufferData(counts.id(), GL_RGBA32UI, GL_RGBA_INTEGER, GL_UNSIGNED_INT, nullptr);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  sp.Set("uOutWidth", bw)
      .Set("uFactor", 2)
      .Set("uSampleStride", 2)
      .Set("uSamplePhase", 1)
      .Use()
      .DispatchCovering(static_cast<unsigned>(bw), static_cast<unsigned>(bh), static_cast<unsigned>(lanes));
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  FlagAndShadeListed(fr, sp, block_flags, block_list, bw, bh, 2, car_layer, shadow_layer, true);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  gl::Program& fill = fill_program;
  glProgramUniform2i(fill.id(), fill.Uniform("uBlocks"), bw, bh);
  glProgramUniform2i(fill.id(), fill.Uniform("uSize"), w, h);
  car_layer.BindImage(0, GL_READ_WRITE);
  shadow_layer.BindImage(1, GL_READ_WRITE);
  block_flags.BindBase(GL_SHADER_STORAGE_BUFFER, 9);
  fill.Use().DispatchCovering(static_cast<unsigned>(w), static_cast<unsigned>(h));
}

void TripleProductRenderer::Impl::ShadeAdaptive(const Frame& fr, gl::Program& sp, int lanes) {
  const int k = fr.k;
  // The samples a pass leaves unshaded must read as empty in the counts and the coverage.
  glClearNamedBufferData(counts.id(), GL_RGBA32UI, GL_RGBA_INTEGER, GL_UNSIGNED_INT, nullptr);
  glClearTexImage(shaded_car.id(), 0, GL_RGBA, GL_FLOAT, nullptr);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  flagged_list.BindBase(GL_SHADER_STORAGE_BUFFER, 10);
  sp.Set("uSampleStride", k)
      .Set("uSamplePhase", k / 2)
      .Use()
      .DispatchCovering(static_cast<unsigned>(fr.w), static_cast<unsigned>(fr.h), static_cast<unsigned>(lanes));
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  FlagAndShadeListed(fr, sp, pixel_flags, flagged_list, fr.w, fr.h, k, shaded_car, shaded_shadow, false);
}

void TripleProductRenderer::Impl::FlagAndShadeListed(const Frame& fr, gl::Program& sp, gl::Buffer& flags,
                                                     gl::Buffer& list, int flag_w, int flag_h, int factor,
                                                     gl::Texture& car, gl::Texture& shadow, bool neighbour_reps) {
  gl::Program& fp = flag_program;
  glProgramUniform2i(fp.id(), fp.Uniform("uSize"), flag_w, flag_h);
  fp.Set("uFactor", factor)
      .Set("uContrast", static_cast<float>(fr.options.supersample_contrast))
      .Set("uNormalCos", detail::kSupersampleNormalCos)
      .Set("uNeighbourReps", neighbour_reps ? 1 : 0);
  g_position.BindImage(0, GL_READ_ONLY);
  g_normal.BindImage(1, GL_READ_ONLY);
  car.BindImage(2, GL_READ_ONLY);
  shadow.BindImage(3, GL_READ_ONLY);
  flags.BindBase(GL_SHADER_STORAGE_BUFFER, 9);
  list.BindBase(GL_SHADER_STORAGE_BUFFER, 10);
  const std::uint32_t zero = 0;
  list.SubData(0, 4, &zero);
  fp.Use().DispatchCovering(static_cast<unsigned>(flag_w), static_cast<unsigned>(flag_h));
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  // The second pass sized on the GPU from the list's count: no wait for the flags here.
  constexpr int kListPitch = 256;
  gl::Program& ap = list_args_program;
  ap.Set("uFactor", factor).Set("uListPitch", kListPitch);
  list_args.BindBase(GL_SHADER_STORAGE_BUFFER, 13);
  ap.Use();
  glDispatchCompute(1, 1, 1);
  glMemoryBarrier(GL_COMMAND_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT);
  g_position.BindImage(0, GL_READ_ONLY);
  g_normal.BindImage(1, GL_READ_ONLY);
  g_base.BindImage(2, GL_READ_ONLY);
  g_emission.BindImage(5, GL_READ_ONLY);
  car.BindImage(3, GL_WRITE_ONLY);
  shadow.BindImage(4, GL_WRITE_ONLY);
  sp.Set("uAdaptivePass", 1).Set("uListPitch", kListPitch).Set("uSampleStride", 1).Set("uSamplePhase", 0).Use();
  glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, list_args.id());
  glDispatchComputeIndirect(0);
  glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, 0);
}

void TripleProductRenderer::Impl::Resolve(const Frame& fr) {
  const int w = fr.w, h = fr.h, k = fr.k;
  gl::Program& rp = resolve_program;
  const std::vector<float> weights = detail::SupersampleWeights(k);
  glProgramUniform2i(rp.id(), rp.Uniform("uSize"), w, h);
  glProgramUniform2i(rp.id(), rp.Uniform("uShadedSize"), fr.sw, fr.sh);
  rp.Set("uFactor", k).Set("uAdaptive", fr.adaptive ? 1 : 0);
  if (fr.adaptive) pixel_flags.BindBase(GL_SHADER_STORAGE_BUFFER, 9);
  glProgramUniform1fv(rp.id(), rp.Uniform("uWeights"), static_cast<GLsizei>(weights.size()), weights.data());
  shaded_car.BindImage(0, GL_READ_ONLY);
  shaded_shadow.BindImage(1, GL_READ_ONLY);
  car_layer.BindImage(2, GL_WRITE_ONLY);
  shadow_layer.BindImage(3, GL_WRITE_ONLY);
  rp.Use().DispatchCovering(static_cast<unsigned>(w), static_cast<unsigned>(h));
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
}

}  // namespace odvr::render
