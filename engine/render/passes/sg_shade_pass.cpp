#include "engine/render/passes/sg_shade_pass.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <glm/gtc/type_ptr.hpp>
#include <string>

#include "engine/gl/context.h"
#include "engine/gl/shader_library.h"
#include "engine/sphere/healpix.h"

namespace odvr::render {

namespace detail {

GroundLitMapLayout GroundLitMapLayoutFor(const visibility::VoxelGridSpec& spec, const PreparedLighting& l,
                                         bool peak_cones, const glm::dvec2& ground_centre, double ground_half_size,
                                         int max_texels) {
  GroundLitMapLayout layout;
  if (max_texels <= 0) return layout;
  const glm::dvec2 square_lo = ground_centre - ground_half_size, square_hi = ground_centre + ground_half_size;
  const glm::dvec3 lo = spec.origin, hi = spec.origin + spec.side();
  // The up cone: the cube's footprint.
  glm::dvec2 r_lo(lo.x, lo.z), r_hi(hi.x, hi.z);
  for (std::size_t k = 0; peak_cones && k < l.ground_peak_share.size(); ++k) {
    if (l.ground_peak_share[k] <= 0) continue;
    const glm::dvec3 a = glm::normalize(l.peaks[k].axis);
    if (!(a.y > 1e-6)) {  // along or under the horizon: its shadow may reach anywhere
      r_lo = square_lo;
      r_hi = square_hi;
      break;
    }
    // The cube's shadow along the axis: its corners moved down the axis to the ground (a corner
    // under the ground lands on the sun's side, which only widens the rectangle).
    for (int c = 0; c < 8; ++c) {
      const glm::dvec3 corner((c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z);
      const glm::dvec3 q = corner - (corner.y / a.y) * a;
      r_lo = glm::min(r_lo, glm::dvec2(q.x, q.z));
      r_hi = glm::max(r_hi, glm::dvec2(q.x, q.z));
    }
  }
  r_lo = glm::max(r_lo, square_lo);
  r_hi = glm::min(r_hi, square_hi);
  if (!(r_hi.x > r_lo.x && r_hi.y > r_lo.y)) return layout;  // the cube's shadows miss the catcher
  const glm::dvec2 extent = r_hi - r_lo;
  // Two texels beyond the rectangle's interior span: one on each side.
  layout.spacing = std::max(spec.voxel_size, std::max(extent.x, extent.y) / std::max(1, max_texels - 3));
  // The quotient may land a rounding above an integer: not one more texel for it.
  layout.width = static_cast<int>(std::ceil(extent.x / layout.spacing - 1e-9)) + 3;
  layout.height = static_cast<int>(std::ceil(extent.y / layout.spacing - 1e-9)) + 3;
  layout.origin = r_lo - layout.spacing;
  return layout;
}

double SampleGroundLitMap(const GroundLitMapLayout& layout, const std::vector<float>& texels, double x, double z) {
  if (layout.width <= 0) return 1.0;
  const double fx = (x - layout.origin.x) / layout.spacing, fz = (z - layout.origin.y) / layout.spacing;
  if (!(fx >= 0 && fz >= 0 && fx < layout.width - 1 && fz < layout.height - 1)) return 1.0;
  const int i = static_cast<int>(fx), j = static_cast<int>(fz);
  const double tx = fx - i, tz = fz - j;
  const auto at = [&](int di, int dj) {
    return static_cast<double>(texels[static_cast<std::size_t>(j + dj) * static_cast<std::size_t>(layout.width) +
                                      static_cast<std::size_t>(i + di)]);
  };
  return (1 - tz) * ((1 - tx) * at(0, 0) + tx * at(1, 0)) + tz * ((1 - tx) * at(0, 1) + tx * at(1, 1));
}

}  // namespace detail

SgShadePass::SgShadePass(const RenderOptions& options)
    : cone_rings_(options.cone_rings), software_renderer_(gl::CurrentRendererIsSoftware()) {
  if (options.shade_lanes != 0) Program(options.shade_lanes);
  const int cones = 1 + 3 * options.cone_rings * (options.cone_rings + 1);  // render_shade.comp's kMaxCones
  ground_table_ = gl::Buffer();
  ground_table_.Allocate(static_cast<std::size_t>(cones + 1 + TripleProductRenderer::kMaxPeakCones) * 4 *
                         sizeof(float));
  if (options.supersample > 1 || options.shading_rate == 2) {
    flag_program_ = gl::ShaderLibrary::Compute("render_flag.comp");
    list_args_program_ = gl::ShaderLibrary::Compute("render_list_args.comp");
    list_args_ = gl::Buffer();
    list_args_.Allocate(3 * sizeof(std::uint32_t));
  }
  if (options.shading_rate == 2) fill_program_ = gl::ShaderLibrary::Compute("render_fill.comp");
}

gl::Program& SgShadePass::Program(int lanes) {
  gl::Program& p = programs_[static_cast<std::size_t>(lanes == 4 ? 2 : lanes == 2 ? 1 : 0)];
  if (!p)
    p = gl::ShaderLibrary::Compute("render_shade.comp", "#define CONE_RINGS " + std::to_string(cone_rings_) +
                                                            "\n#define SHADE_LANES " + std::to_string(lanes) + "\n");
  return p;
}

int SgShadePass::PrepareLanes(const RenderOptions& options, const PinholeCamera& camera) {
  const int lanes =
      options.shade_lanes != 0
          ? options.shade_lanes
          : ShadeLanesFor(detail::FirstShadingPassPixels(options, camera.width, camera.height), software_renderer_);
  Program(lanes);
  return lanes;
}

void SgShadePass::SetUniforms(const RenderFrame& fr, const ShadeScene& scene, gl::Program& sp) {
  const RenderOptions& o = fr.options;
  const PinholeCamera& camera = fr.camera;
  const detail::PreparedLighting& lighting = scene.lighting.prepared();
  const visibility::VoxelGridSpec& spec = scene.voxels.spec();
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
      .Set("uBinLevelCount", scene.lighting.bin_level_count())
      .Set("uSingleConeMaxHalfAngle", static_cast<float>(o.cones.single_cone_max_half_angle))
      .Set("uConeCoverage", static_cast<float>(o.cones.coverage))
      .Set("uMaxConeHalfAngle", static_cast<float>(visibility::kMaxConeHalfAngle))
      .Set("uTermsPerMaterial", TripleProductRenderer::kTermsPerMaterial)
      .Set("uMaterialCount", scene.materials.count())
      .Set("uSurfaceOffset", static_cast<float>(o.surface_offset_voxels * spec.voxel_size))
      .Set("uExactTriangles", o.exact_peak_shadows && fr.geometry ? scene.model.bvh_triangle_count() : 0)
      .Set("uExactRayOffset", detail::ExactRayOffset(spec.voxel_size))
      .Set("uBvhShadingMaterials", scene.model.bvh_shading_first_triangle_row())
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

void SgShadePass::Run(const RenderFrame& fr, const ShadeScene& scene, RenderTargets& targets, int lanes) {
  const RenderOptions& o = fr.options;
  gl::Program& sp = Program(lanes);
  SetUniforms(fr, scene, sp);
  BindShadeInputs(fr, scene, targets);
  scene.materials.cosine_table().BindBase(GL_SHADER_STORAGE_BUFFER, 8);
  ground_table_.BindBase(GL_SHADER_STORAGE_BUFFER, 11);
  if (o.exact_peak_shadows && scene.model.bvh_triangle_count() > 0) {
    scene.model.bvh_nodes().BindBase(GL_SHADER_STORAGE_BUFFER, 14);
    scene.model.bvh_triangles().BindBase(GL_SHADER_STORAGE_BUFFER, 15);
    scene.model.bvh_shading_buffer().BindBase(GL_SHADER_STORAGE_BUFFER, 16);
  }
  if (o.ground) {
    sp.Set("uGroundTablePass", 1).Use();
    glDispatchCompute(1, 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  }
  DispatchGroundLitMap(fr, scene, sp, lanes);
  sp.Set("uGroundTablePass", 0).Set("uOutWidth", fr.w).Set("uFactor", fr.k).Set("uAdaptivePass", 0);
  if (fr.half_rate) {
    ShadeHalfRate(fr, targets, sp, lanes);
  } else if (fr.adaptive) {
    ShadeAdaptive(fr, targets, sp, lanes);
  } else {
    sp.Set("uSampleStride", 1)
        .Set("uSamplePhase", 0)
        .Use()
        .DispatchCovering(static_cast<unsigned>(fr.sw), static_cast<unsigned>(fr.sh), static_cast<unsigned>(lanes));
  }
}

void SgShadePass::DispatchGroundLitMap(const RenderFrame& fr, const ShadeScene& scene, gl::Program& sp, int lanes) {
  const RenderOptions& o = fr.options;
  const detail::GroundLitMapLayout map =
      o.ground && o.ground_shadows_bounce && fr.geometry
          ? detail::GroundLitMapLayoutFor(scene.voxels.spec(), scene.lighting.prepared(), o.peak_cones,
                                          fr.ground_centre, o.ground_half_size, o.ground_lit_map_texels)
          : detail::GroundLitMapLayout{};
  const std::size_t map_bytes = std::max<std::size_t>(map.texels(), 1) * sizeof(float);
  if (!ground_lit_map_ || ground_lit_map_.size() < map_bytes) {
    ground_lit_map_ = gl::Buffer();
    ground_lit_map_.Allocate(map_bytes);
  }
  ground_lit_map_.BindBase(GL_SHADER_STORAGE_BUFFER, 12);
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

void SgShadePass::ShadeHalfRate(const RenderFrame& fr, RenderTargets& targets, gl::Program& sp, int lanes) {
  const int w = fr.w, h = fr.h, bw = fr.bw, bh = fr.bh;
  const std::size_t blocks = static_cast<std::size_t>(bw) * static_cast<std::size_t>(bh);
  if (!block_flags_ || block_flags_.size() < blocks * 4) {
    block_flags_ = gl::Buffer();
    block_flags_.Allocate(blocks * 4);
    block_list_ = gl::Buffer();
    block_list_.Allocate(4 + blocks * 4);
  }
  // The pixels the passes leave unshaded read as empty in the counts until they are filled.
  glClearNamedBufferData(targets.counts.id(), GL_RGBA32UI, GL_RGBA_INTEGER, GL_UNSIGNED_INT, nullptr);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  sp.Set("uOutWidth", bw)
      .Set("uFactor", 2)
      .Set("uSampleStride", 2)
      .Set("uSamplePhase", 1)
      .Use()
      .DispatchCovering(static_cast<unsigned>(bw), static_cast<unsigned>(bh), static_cast<unsigned>(lanes));
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  FlagAndShadeListed(fr, targets, sp, block_flags_, block_list_, bw, bh, 2, targets.car_layer, targets.shadow_layer,
                     true);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  gl::Program& fill = fill_program_;
  glProgramUniform2i(fill.id(), fill.Uniform("uBlocks"), bw, bh);
  glProgramUniform2i(fill.id(), fill.Uniform("uSize"), w, h);
  targets.car_layer.BindImage(0, GL_READ_WRITE);
  targets.shadow_layer.BindImage(1, GL_READ_WRITE);
  block_flags_.BindBase(GL_SHADER_STORAGE_BUFFER, 9);
  fill.Use().DispatchCovering(static_cast<unsigned>(w), static_cast<unsigned>(h));
}

void SgShadePass::ShadeAdaptive(const RenderFrame& fr, RenderTargets& targets, gl::Program& sp, int lanes) {
  const int k = fr.k;
  // The samples a pass leaves unshaded must read as empty in the counts and the coverage.
  glClearNamedBufferData(targets.counts.id(), GL_RGBA32UI, GL_RGBA_INTEGER, GL_UNSIGNED_INT, nullptr);
  glClearTexImage(targets.shaded_car.id(), 0, GL_RGBA, GL_FLOAT, nullptr);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  targets.flagged_list.BindBase(GL_SHADER_STORAGE_BUFFER, 10);
  sp.Set("uSampleStride", k)
      .Set("uSamplePhase", k / 2)
      .Use()
      .DispatchCovering(static_cast<unsigned>(fr.w), static_cast<unsigned>(fr.h), static_cast<unsigned>(lanes));
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  FlagAndShadeListed(fr, targets, sp, targets.pixel_flags, targets.flagged_list, fr.w, fr.h, k, targets.shaded_car,
                     targets.shaded_shadow, false);
}

void SgShadePass::FlagAndShadeListed(const RenderFrame& fr, RenderTargets& targets, gl::Program& sp, gl::Buffer& flags,
                                     gl::Buffer& list, int flag_w, int flag_h, int factor, gl::Texture& car,
                                     gl::Texture& shadow, bool neighbour_reps) {
  gl::Program& fp = flag_program_;
  glProgramUniform2i(fp.id(), fp.Uniform("uSize"), flag_w, flag_h);
  fp.Set("uFactor", factor)
      .Set("uContrast", static_cast<float>(fr.options.supersample_contrast))
      .Set("uNormalCos", detail::kSupersampleNormalCos)
      .Set("uNeighbourReps", neighbour_reps ? 1 : 0);
  targets.g_position.BindImage(0, GL_READ_ONLY);
  targets.g_normal.BindImage(1, GL_READ_ONLY);
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
  gl::Program& ap = list_args_program_;
  ap.Set("uFactor", factor).Set("uListPitch", kListPitch);
  list_args_.BindBase(GL_SHADER_STORAGE_BUFFER, 13);
  ap.Use();
  glDispatchCompute(1, 1, 1);
  glMemoryBarrier(GL_COMMAND_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT);
  targets.g_position.BindImage(0, GL_READ_ONLY);
  targets.g_normal.BindImage(1, GL_READ_ONLY);
  targets.g_base.BindImage(2, GL_READ_ONLY);
  targets.g_emission.BindImage(5, GL_READ_ONLY);
  car.BindImage(3, GL_WRITE_ONLY);
  shadow.BindImage(4, GL_WRITE_ONLY);
  sp.Set("uAdaptivePass", 1).Set("uListPitch", kListPitch).Set("uSampleStride", 1).Set("uSamplePhase", 0).Use();
  glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, list_args_.id());
  glDispatchComputeIndirect(0);
  glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, 0);
}

long long SgShadePass::HalfRateShadedPixels(const RenderFrame& fr) const {
  // Every block once, three more pixels of each flagged whole block, and every pixel of the
  // blocks an odd edge cuts (all flagged); the count read now that the GPU is done.
  const int w = fr.w, h = fr.h;
  std::uint32_t listed = 0;
  block_list_.Read(0, 4, &listed);
  const long long blocks = static_cast<long long>(fr.bw) * fr.bh, whole = static_cast<long long>(w / 2) * (h / 2);
  return whole + 3LL * (listed - (blocks - whole)) + (static_cast<long long>(fr.pixels) - 4 * whole);
}

std::vector<std::uint8_t> SgShadePass::ReadBlockFlags(const RenderFrame& fr) const {
  const auto flags = block_flags_.Read<std::uint32_t>(static_cast<std::size_t>(fr.bw) * fr.bh);
  return std::vector<std::uint8_t>(flags.begin(), flags.end());
}

}  // namespace odvr::render
