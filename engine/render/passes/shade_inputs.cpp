#include "engine/render/passes/shade_inputs.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <string>
#include <variant>

#include "core/constants.h"
#include "core/error.h"
#include "engine/material/brdf.h"
#include "engine/render/passes/gpu_model.h"
#include "engine/sphere/healpix.h"

namespace odvr::render {
namespace {

// render_shade.comp's material-term types (brdf_lobes.glsl).
enum TermType : int {
  kNone = 0,
  kGltf = 1,
  kLambertian = 2,
  kPhong = 3,
  kBlinnPhong = 4,
  kWard = 5,
  kCookTorrance = 6,
  kMetallicRoughness = 7,
  kSheen = 8
};

struct GpuTerm {
  glm::ivec4 type{0};
  glm::vec4 color{0};
  glm::vec4 params{0};
};

GpuTerm ToGpuTerm(const material::Brdf& brdf) {
  GpuTerm t;
  std::visit(
      [&](const auto& m) {
        using T = std::decay_t<decltype(m)>;
        if constexpr (std::is_same_v<T, material::Lambertian>) {
          t.type.x = kLambertian;
          t.color = glm::vec4(glm::vec3(m.albedo), 0);
        } else if constexpr (std::is_same_v<T, material::Phong>) {
          t.type.x = kPhong;
          t.color = glm::vec4(glm::vec3(m.ks), 0);
          t.params.x = static_cast<float>(m.exponent);
        } else if constexpr (std::is_same_v<T, material::BlinnPhong>) {
          t.type.x = kBlinnPhong;
          t.color = glm::vec4(glm::vec3(m.ks), 0);
          t.params.x = static_cast<float>(m.exponent);
        } else if constexpr (std::is_same_v<T, material::Ward>) {
          if (std::abs(m.alpha_x - m.alpha_y) > 1e-9 * std::max(m.alpha_x, m.alpha_y))
            throw Error("material override", "the renderer shades isotropic Ward only (alpha_x = alpha_y)");
          t.type.x = kWard;
          t.color = glm::vec4(glm::vec3(m.rho_s), 0);
          t.params.x = static_cast<float>(m.alpha_x);
        } else if constexpr (std::is_same_v<T, material::CookTorrance>) {
          t.type.x = kCookTorrance;
          t.color = glm::vec4(glm::vec3(m.f0), 0);
          t.params.x = static_cast<float>(m.alpha);
          t.params.y = m.ndf == material::Ndf::kBeckmann ? 1.f : 0.f;
        } else if constexpr (std::is_same_v<T, material::Sheen>) {
          t.type.x = kSheen;
          t.color = glm::vec4(glm::vec3(m.color), 0);
          t.params.x = static_cast<float>(m.roughness);
        } else {
          t.type.x = kMetallicRoughness;
          t.color = glm::vec4(glm::vec3(m.base_color), 0);
          t.params.x = static_cast<float>(m.metallic);
          t.params.y = static_cast<float>(m.roughness);
        }
      },
      brdf);
  return t;
}

std::string Lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Everything of the lighting that the shading stage reads, in the world frame.
detail::PreparedLighting Prepare(const lighting::SgLighting& model, const glm::dmat3& world_from_lighting,
                                 int max_levels) {
  detail::PreparedLighting p;
  p.env_from_world = glm::transpose(world_from_lighting);
  p.constant = model.constant;
  p.sg_count = model.constant != glm::vec3(0) ? 1 : 0;
  int deepest = -1;
  for (const auto& l : model.levels)
    if (l.level < max_levels) deepest = std::max(deepest, l.level);
  if (deepest >= 0) {
    p.srbfs.assign(static_cast<std::size_t>(lighting::GlobalSrbfIndex(max_levels, 0)), {});
    for (const auto& l : model.levels) {
      if (l.level >= max_levels) continue;
      const auto& hp = sphere::Healpix(l.level);
      for (std::size_t i = 0; i < l.indices.size(); ++i) {
        auto& s = p.srbfs[static_cast<std::size_t>(lighting::GlobalSrbfIndex(l.level, l.indices[i]))];
        s.axis = world_from_lighting * hp.centre(l.indices[i]);
        s.lambda = l.lambda;
        s.amplitude += l.amplitudes[i];
        ++p.sg_count;
      }
    }
  }
  std::vector<lighting::RgbSg> peaks = model.peaks;
  // Brightest first: ∫G μ summed over the channels.
  std::stable_sort(peaks.begin(), peaks.end(), [](const auto& a, const auto& b) {
    return lighting::Integral({a.axis, a.lambda, 1.0}) * (a.amplitude.x + a.amplitude.y + a.amplitude.z) >
           lighting::Integral({b.axis, b.lambda, 1.0}) * (b.amplitude.x + b.amplitude.y + b.amplitude.z);
  });
  for (auto& pk : peaks) {
    pk.axis = glm::normalize(world_from_lighting * pk.axis);
    p.peaks.push_back(pk);
  }
  p.sg_count += static_cast<int>(p.peaks.size());
  // One pass over the lights for the ground: its irradiance from above (channels summed), of
  // which the traced peaks' shares, and the lighting's cosine-weighted mean radiance below the
  // horizon (E from below / π), the traced peaks' part apart.
  const glm::dvec3 up(0, 1, 0), down(0, -1, 0);
  double total = 0;
  glm::dvec3 e_down(0), e_traced(0), sphere_sum(0);
  std::vector<double> peak_e;
  const auto add = [&](const glm::vec3& amplitude, const glm::dvec3& axis, double lambda, bool traced) {
    sphere_sum += glm::dvec3(amplitude) * lighting::Integral({axis, lambda, 1.0});
    const double e_up = material::ClampedCosineIntegral(up, {axis, lambda, 1.0}) *
                        static_cast<double>(amplitude.x + amplitude.y + amplitude.z);
    total += e_up;
    if (traced) peak_e.push_back(e_up);
    (traced ? e_traced : e_down) += glm::dvec3(amplitude) * material::ClampedCosineIntegral(down, {axis, lambda, 1.0});
  };
  add(p.constant, up, 0.0, false);
  for (const auto& s : p.srbfs)
    if (s.amplitude != glm::vec3(0)) add(s.amplitude, s.axis, s.lambda, false);
  for (std::size_t k = 0; k < p.peaks.size(); ++k)
    add(p.peaks[k].amplitude, p.peaks[k].axis, p.peaks[k].lambda, k < TripleProductRenderer::kMaxPeakCones);
  for (double e : peak_e) p.ground_peak_share.push_back(total > 0 ? e / total : 0.0);
  p.ground_radiance = glm::vec3(e_down / kPi);
  p.ground_radiance_traced_peaks = glm::vec3(e_traced / kPi);
  p.mean_radiance = glm::vec3(glm::max(sphere_sum, glm::dvec3(0)) / (4 * kPi));
  return p;
}

glm::vec4 LightVec(const glm::dvec3& a, double l) { return glm::vec4(glm::vec3(a), static_cast<float>(l)); }

// The NDF table's nodes over α (brdf_lobes.glsl's kNdfTableNodes, which must equal it).
constexpr int kNdfTableNodes = 512;

}  // namespace

// material::SheenAlbedoTable after the NDF's rows, four values a vec4 (brdf_lobes.glsl's
// sheenTableAt); made (a fraction of a second) and uploaded only once a material has a sheen.
void GpuMaterials::AppendSheenTable() {
  if (ndf_rows_.size() > 2 * static_cast<std::size_t>(kNdfTableNodes)) return;
  const std::vector<double>& sheen = material::SheenAlbedoTable();
  std::vector<float> packed(sheen.begin(), sheen.end());
  packed.resize((packed.size() + 3) / 4 * 4, 0.f);
  for (std::size_t k = 0; k < packed.size(); k += 4)
    ndf_rows_.emplace_back(packed[k], packed[k + 1], packed[k + 2], packed[k + 3]);
  ndf_table_ = MakeBuffer(ndf_rows_);
}

GpuMaterials::GpuMaterials() {
  // Per α ∈ [kMinAlpha, 1]: λα² of the NDF's one-SG fit, then GGX's two SGs (λ_k α², μ_k π α²);
  // brdf_lobes.glsl interpolates them.
  std::vector<glm::vec4> table(2 * static_cast<std::size_t>(kNdfTableNodes));
  for (std::size_t i = 0; i < table.size() / 2; ++i) {
    const double a =
        material::kMinAlpha + (1.0 - material::kMinAlpha) * static_cast<double>(i) / (table.size() / 2 - 1);
    const double a2 = a * a;
    const material::GgxSgFit fit = material::GgxSg(a);
    table[2 * i] = glm::vec4(static_cast<float>(material::NdfSgLambda(a) * a2), 0, 0, 0);
    table[2 * i + 1] =
        glm::vec4(static_cast<float>(fit.lambda[0] * a2), static_cast<float>(fit.lambda[1] * a2),
                  static_cast<float>(fit.amplitude[0] * kPi * a2), static_cast<float>(fit.amplitude[1] * kPi * a2));
  }
  ndf_table_ = MakeBuffer(table);
  ndf_rows_ = std::move(table);
  // The clamped cosine's two tables interleaved, so that the shader reads both with one vec2.
  const std::vector<double>& cosine = material::ClampedCosineTable();
  const std::size_t block = cosine.size() / 2;
  std::vector<glm::vec2> interleaved(block);
  for (std::size_t i = 0; i < block; ++i)
    interleaved[i] = glm::vec2(static_cast<float>(cosine[i]), static_cast<float>(cosine[block + i]));
  cosine_table_ = MakeBuffer(interleaved);
}

void GpuMaterials::Set(const std::vector<scene::PbrMaterial>& materials,
                       const std::vector<MaterialOverride>& overrides) {
  for (const auto& o : overrides)
    for (const auto& brdf : o.brdfs) material::CheckBrdf(brdf);
  std::vector<GpuTerm> gpu_terms;
  detail::MaterialTerms material_terms;
  bool sheen = false;
  std::vector<glm::vec3> emission;
  for (const auto& mat : materials) {
    std::vector<material::Brdf> terms;
    for (const auto& o : overrides)
      if (o.material.empty() || Lower(mat.name).find(Lower(o.material)) != std::string::npos) terms = o.brdfs;
    if (terms.size() > static_cast<std::size_t>(TripleProductRenderer::kTermsPerMaterial))
      throw Error("material override",
                  "at most " + std::to_string(TripleProductRenderer::kTermsPerMaterial) + " BRDF terms");
    std::vector<GpuTerm> row(TripleProductRenderer::kTermsPerMaterial);
    detail::MaterialTermList list;
    list.from_gbuffer = terms.empty();
    if (list.from_gbuffer) {
      row[0].type.x = kGltf;
      if (mat.sheen_color != glm::vec3(0)) {
        list.terms.push_back(material::Sheen{glm::dvec3(mat.sheen_color), mat.sheen_roughness});
        row[1] = ToGpuTerm(list.terms.back());
      }
    } else {
      for (std::size_t k = 0; k < terms.size(); ++k) row[k] = ToGpuTerm(terms[k]);
      list.terms = std::move(terms);
    }
    emission.push_back(list.from_gbuffer ? mat.emission() : glm::vec3(0));
    gpu_terms.insert(gpu_terms.end(), row.begin(), row.end());
    for (const auto& brdf : list.terms) sheen = sheen || std::holds_alternative<material::Sheen>(brdf);
    material_terms.push_back(std::move(list));
  }
  if (sheen) AppendSheenTable();
  terms_buffer_ = MakeBuffer(gpu_terms);
  terms_ = std::move(material_terms);
  emission_ = std::move(emission);
}

void GpuMaterials::Bind() const {
  terms_buffer_.BindBase(GL_SHADER_STORAGE_BUFFER, 5);
  ndf_table_.BindBase(GL_SHADER_STORAGE_BUFFER, 7);
}

GpuLighting::GpuLighting(const RenderOptions& options) {
  // Overlap bins for the levels used, flattened for the shader.
  lighting::OverlapBinOptions bo;
  bo.lighting_levels = options.lighting_levels;
  bo.min_retention = options.overlap_min_retention;
  bo.cutoff = options.overlap_cutoff;
  bins_ = lighting::OverlapBins::Shared(bo);
  std::vector<glm::vec4> levels;
  std::vector<int> begin, srbfs;
  for (const auto& l : bins_->levels()) {
    levels.push_back(
        glm::vec4(static_cast<float>(l.lambda), static_cast<float>(l.n), static_cast<float>(begin.size()), 0));
    const int base = static_cast<int>(srbfs.size());
    for (int b : l.begin) begin.push_back(base + b);
    srbfs.insert(srbfs.end(), l.srbfs.begin(), l.srbfs.end());
  }
  bin_levels_ = MakeBuffer(levels);
  bin_begin_ = MakeBuffer(begin);
  bin_srbfs_ = MakeBuffer(srbfs);
}

void GpuLighting::Set(const lighting::SgLighting& model, const glm::dmat3& world_from_lighting, int lighting_levels) {
  prepared_ = Prepare(model, world_from_lighting, lighting_levels);
  std::vector<glm::vec4> srbfs;
  for (const auto& s : prepared_.srbfs) {
    srbfs.push_back(LightVec(s.axis, s.lambda));
    srbfs.push_back(glm::vec4(s.amplitude, 0));
  }
  std::vector<glm::vec4> peaks;
  for (const auto& s : prepared_.peaks) {
    peaks.push_back(LightVec(s.axis, s.lambda));
    peaks.push_back(glm::vec4(s.amplitude, 0));
  }
  srbf_buffer_ = MakeBuffer(srbfs);
  peak_buffer_ = MakeBuffer(peaks);
}

void GpuLighting::Bind() const {
  srbf_buffer_.BindBase(GL_SHADER_STORAGE_BUFFER, 0);
  peak_buffer_.BindBase(GL_SHADER_STORAGE_BUFFER, 1);
  bin_levels_.BindBase(GL_SHADER_STORAGE_BUFFER, 2);
  bin_begin_.BindBase(GL_SHADER_STORAGE_BUFFER, 3);
  bin_srbfs_.BindBase(GL_SHADER_STORAGE_BUFFER, 4);
}

void BindShadeInputs(const RenderFrame& fr, const ShadeScene& scene, RenderTargets& targets) {
  if (fr.geometry) glBindTextureUnit(0, scene.voxels.texture().id());
  targets.g_position.BindImage(0, GL_READ_ONLY);
  targets.g_normal.BindImage(1, GL_READ_ONLY);
  targets.g_base.BindImage(2, GL_READ_ONLY);
  targets.g_emission.BindImage(5, GL_READ_ONLY);
  targets.ShadedCar(fr).BindImage(3, GL_WRITE_ONLY);
  targets.ShadedShadow(fr).BindImage(4, GL_WRITE_ONLY);
  scene.lighting.Bind();
  scene.materials.Bind();
  targets.counts.BindBase(GL_SHADER_STORAGE_BUFFER, 6);
  glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_FRAMEBUFFER_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT);
}

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

}  // namespace odvr::render
