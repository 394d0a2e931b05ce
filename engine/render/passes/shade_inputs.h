#pragma once
// What both shading passes (SG and Monte-Carlo) read besides the G-buffer: the lighting and the
// materials in the buffers render_shade.comp and render_mc.comp bind, and the uniforms they share.
// Internal to engine/render.
#include <memory>
#include <vector>

#include <glm/mat3x3.hpp>

#include "engine/gl/objects.h"
#include "engine/lighting/overlap_bins.h"
#include "engine/lighting/sg_lighting.h"
#include "engine/render/passes/gpu_model.h"
#include "engine/render/passes/render_targets.h"
#include "engine/render/passes/voxelize_pass.h"
#include "engine/render/triple_product_internal.h"
#include "engine/scene/gltf_scene.h"
#include "engine/visibility/voxel_grid.h"

namespace odvr::render {

// The lighting in the world frame (detail::PreparedLighting) and on the GPU: the SRBFs by global
// index, the peaks brightest first, and the overlap bins of the levels used.
class GpuLighting {
 public:
  explicit GpuLighting(const RenderOptions& options);  // the bins; no light until Set
  void Set(const lighting::SgLighting& model, const glm::dmat3& world_from_lighting, int lighting_levels);
  const detail::PreparedLighting& prepared() const { return prepared_; }
  const lighting::OverlapBins& bins() const { return *bins_; }
  int bin_level_count() const { return prepared_.srbfs.empty() ? 0 : static_cast<int>(bins_->levels().size()); }
  // SRBFs at storage binding 0, peaks 1, the bins' levels 2, list starts 3 and SRBF lists 4.
  void Bind() const;

 private:
  detail::PreparedLighting prepared_;
  std::shared_ptr<const lighting::OverlapBins> bins_;
  gl::Buffer srbf_buffer_{gl::NoCreate}, peak_buffer_{gl::NoCreate};
  gl::Buffer bin_levels_{gl::NoCreate}, bin_begin_{gl::NoCreate}, bin_srbfs_{gl::NoCreate};
};

// Per material the BRDF terms the shaders evaluate (brdf_lobes.glsl) and what it emits, with the
// tables their SG forms interpolate: the NDF's fits over α (and the sheen's albedo, once a
// material has a sheen) and the clamped cosine's.
class GpuMaterials {
 public:
  GpuMaterials();  // the NDF's and the clamped cosine's tables
  // The glTF's metallic-roughness (and its sheen) unless an override names the material; an
  // override replaces the whole material, its emission included. Throws odvr::Error for an
  // out-of-range or unshadeable term, leaving the materials as they were.
  void Set(const std::vector<scene::PbrMaterial>& materials, const std::vector<MaterialOverride>& overrides);
  const detail::MaterialTerms& terms() const { return terms_; }
  // Per material: the radiance it emits before its emissive texture (glTF emissive factor ×
  // strength; 0 under an override). The G-buffer multiplies in the texture.
  const std::vector<glm::vec3>& emission() const { return emission_; }
  int count() const { return static_cast<int>(terms_.size()); }
  // The terms at storage binding 5, the NDF (and sheen) table at 7.
  void Bind() const;
  const gl::Buffer& cosine_table() const { return cosine_table_; }

 private:
  void AppendSheenTable();
  detail::MaterialTerms terms_;
  std::vector<glm::vec3> emission_;
  gl::Buffer terms_buffer_{gl::NoCreate}, ndf_table_{gl::NoCreate}, cosine_table_{gl::NoCreate};
  std::vector<glm::vec4> ndf_rows_;  // ndf_table_'s contents
};

// What a shading pass reads besides the G-buffer.
struct ShadeScene {
  const GpuModel& model;
  const VoxelizePass& voxels;
  const GpuLighting& lighting;
  const GpuMaterials& materials;
};

// The inputs both shaders bind alike: the voxels at texture unit 0 (with geometry), the G-buffer
// and the shaded layers at images 0–5, the lighting, materials and counts at storage bindings 0–7.
void BindShadeInputs(const RenderFrame& fr, const ShadeScene& scene, RenderTargets& targets);

// The uniforms of cone_trace.glsl, which the SG shader and the Monte-Carlo one both include.
void SetConeTraceUniforms(gl::Program& program, const visibility::VoxelGridSpec& spec, bool has_geometry,
                          const visibility::ConeTraceOptions& trace);
// The traced peaks for the ground's lit fraction (detail::GroundLitFraction): axis and cone
// half-angle, and share of the ground's irradiance; none without peak cones.
void SetGroundPeakUniforms(gl::Program& program, const detail::PreparedLighting& l, bool peak_cones);

}  // namespace odvr::render
