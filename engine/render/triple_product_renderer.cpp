#include "engine/render/triple_product_renderer.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>

#include "core/constants.h"
#include "core/error.h"
#include "core/timing.h"
#include "engine/gl/context.h"
#include "engine/gl/objects.h"
#include "engine/gl/shader_library.h"
#include "engine/render/triple_product_impl.h"
#include "engine/render/triple_product_internal.h"
#include "engine/scene/gltf_scene.h"
#include "engine/sphere/healpix.h"
#include "engine/visibility/triangle_bvh.h"
#include "engine/visibility/voxelizer_gpu.h"

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

template <class T>
gl::Buffer MakeBuffer(const std::vector<T>& data) {
  gl::Buffer b;
  if (data.empty()) {
    b.Allocate(16);
  } else {
    b.SetData(data);
  }
  return b;
}

}  // namespace

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

const gl::Texture& TripleProductRenderer::Impl::TextureFor(const scene::GltfScene& model, int image, bool srgb) {
  auto key = std::make_pair(image, srgb);
  auto it = textures.find(key);
  if (it != textures.end()) return it->second;
  const auto& img = model.images.at(static_cast<std::size_t>(image));
  const int levels = 1 + static_cast<int>(std::floor(std::log2(std::max(img.width, img.height))));
  gl::Texture t = gl::Texture::Create2D(srgb ? GL_SRGB8_ALPHA8 : GL_RGBA8, img.width, img.height, levels);
  t.Upload2D(GL_RGBA, GL_UNSIGNED_BYTE, img.rgba.data()).GenerateMipmaps();
  t.SetWrap(GL_REPEAT, GL_REPEAT).SetFilter(GL_LINEAR_MIPMAP_LINEAR, GL_LINEAR);
  return textures.emplace(key, std::move(t)).first->second;
}

// Geometry into the world once; the voxelizer and the G-buffer share it.
void TripleProductRenderer::Impl::UploadModel(const scene::GltfScene& model, const glm::dmat4& world_from_model) {
  const glm::dmat3 linear(world_from_model);
  const glm::dmat3 normal_matrix = glm::transpose(glm::inverse(linear));
  const bool flips = glm::determinant(linear) < 0;
  materials = model.materials;
  if (materials.empty()) materials.emplace_back();
  for (const auto& prim : model.primitives) {
    if (prim.indices.empty() || prim.positions.empty()) continue;
    const std::size_t n = prim.positions.size();
    std::vector<glm::vec3> pos(n), nor(n);
    std::vector<glm::vec2> uv0(n, glm::vec2(0)), uv1(n, glm::vec2(0));
    std::vector<glm::vec4> tan(n, glm::vec4(0));
    for (std::size_t i = 0; i < n; ++i) {
      pos[i] = glm::vec3(world_from_model * glm::dvec4(glm::dvec3(prim.positions[i]), 1.0));
      const glm::dvec3 nn = normal_matrix * glm::dvec3(i < prim.normals.size() ? prim.normals[i] : glm::vec3(0));
      nor[i] = glm::length(nn) > 0 ? glm::vec3(glm::normalize(nn)) : glm::vec3(0);
      if (i < prim.uv0.size()) uv0[i] = prim.uv0[i];
      if (i < prim.uv1.size()) uv1[i] = prim.uv1[i];
      if (i < prim.tangents.size()) {
        const glm::dvec3 t = linear * glm::dvec3(glm::vec3(prim.tangents[i]));
        tan[i] = glm::vec4(glm::length(t) > 0 ? glm::vec3(glm::normalize(t)) : glm::vec3(0),
                           prim.tangents[i].w * (flips ? -1.f : 1.f));
      }
      bounds.Extend(pos[i]);
    }
    std::vector<std::uint32_t> idx = prim.indices;
    if (flips)
      for (std::size_t t = 0; t + 2 < idx.size(); t += 3) std::swap(idx[t + 1], idx[t + 2]);
    for (std::uint32_t k : idx) triangles.push_back(pos[k]);
    Primitive p;
    p.positions.SetData(pos);
    p.normals.SetData(nor);
    p.uv0.SetData(uv0);
    p.uv1.SetData(uv1);
    p.tangents.SetData(tan);
    p.indices.SetData(idx);
    p.index_count = static_cast<GLsizei>(idx.size());
    p.material = std::clamp(prim.material, 0, static_cast<int>(materials.size()) - 1);
    p.vao.AddFloatAttribute(0, p.positions, 0, 3, 0, sizeof(glm::vec3))
        .AddFloatAttribute(1, p.normals, 1, 3, 0, sizeof(glm::vec3))
        .AddFloatAttribute(2, p.uv0, 2, 2, 0, sizeof(glm::vec2))
        .AddFloatAttribute(3, p.uv1, 3, 2, 0, sizeof(glm::vec2))
        .AddFloatAttribute(4, p.tangents, 4, 4, 0, sizeof(glm::vec4))
        .SetIndexBuffer(p.indices);
    const auto& mat = materials[static_cast<std::size_t>(p.material)];
    if (mat.base_color_texture.valid()) TextureFor(model, mat.base_color_texture.image, true);
    if (mat.metallic_roughness_texture.valid()) TextureFor(model, mat.metallic_roughness_texture.image, false);
    if (mat.normal_texture.valid()) TextureFor(model, mat.normal_texture.image, false);
    if (mat.emissive_texture.valid()) TextureFor(model, mat.emissive_texture.image, true);
    primitives.push_back(std::move(p));
  }
}

void TripleProductRenderer::Impl::PlaceVoxelGrid(const scene::GltfScene& model, const RenderOptions& options) {
  has_geometry = !triangles.empty();
  if (has_geometry) {
    // The loader bounds the model in its own frame; a model matrix can still scale it past what a
    // float voxel grid can hold. Say which model and how large, not "voxel size: inf".
    const glm::dvec3 extent = glm::dvec3(bounds.max) - glm::dvec3(bounds.min);
    // The largest model taken: the loader's bound on a vertex's distance from the origin, across.
    const double max_extent_m = 2 * scene::GltfLoadOptions{}.max_coordinate_m;
    const double largest = std::max({extent.x, extent.y, extent.z});
    if (!std::isfinite(largest) || largest > max_extent_m)
      throw Error(model.source.string(), "placed by its model matrix it spans " + std::to_string(largest) +
                                             " m, more than the " + std::to_string(int(max_extent_m)) +
                                             " m a car's voxel grid can hold");
    spec =
        visibility::VoxelGridSpec::Covering(glm::dvec3(bounds.min), glm::dvec3(bounds.max), options.voxel_resolution);
    voxelizer = std::make_unique<visibility::VoxelizerGpu>(spec);
    std::vector<glm::vec4> padded(triangles.size());
    for (std::size_t i = 0; i < padded.size(); ++i) padded[i] = glm::vec4(triangles[i], 1.f);
    triangle_buffer = MakeBuffer(padded);
    if ((options.monte_carlo_samples > 0 && options.monte_carlo_exact_visibility) || options.exact_peak_shadows) {
      bvh = std::make_unique<visibility::TriangleBvh>(triangles);
      bvh_nodes = MakeBuffer(bvh->nodes());
      bvh_triangles = MakeBuffer(bvh->triangles());
      bvh_triangle_count = static_cast<int>(bvh->triangle_count());
    }
  } else {
    spec = visibility::VoxelGridSpec::Covering(glm::dvec3(-1), glm::dvec3(1), options.voxel_resolution);
  }
}

// The NDF table's nodes over α (brdf_lobes.glsl's kNdfTableNodes, which must equal it).
constexpr int kNdfTableNodes = 512;

// material::SheenAlbedoTable after the NDF's rows, four values a vec4 (brdf_lobes.glsl's
// sheenTableAt); made (a fraction of a second) and uploaded only once a material has a sheen.
void TripleProductRenderer::Impl::UploadSheenTable() {
  if (ndf_rows.size() > 2 * static_cast<std::size_t>(kNdfTableNodes)) return;
  const std::vector<double>& sheen = material::SheenAlbedoTable();
  std::vector<float> packed(sheen.begin(), sheen.end());
  packed.resize((packed.size() + 3) / 4 * 4, 0.f);
  for (std::size_t k = 0; k < packed.size(); k += 4)
    ndf_rows.emplace_back(packed[k], packed[k + 1], packed[k + 2], packed[k + 3]);
  ndf_table = MakeBuffer(ndf_rows);
}

void TripleProductRenderer::Impl::UploadShaderTables(const RenderOptions& options) {
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
  ndf_table = MakeBuffer(table);
  ndf_rows = std::move(table);
  // The clamped cosine's two tables interleaved, so that the shader reads both with one vec2.
  const std::vector<double>& cosine = material::ClampedCosineTable();
  const std::size_t block = cosine.size() / 2;
  std::vector<glm::vec2> interleaved(block);
  for (std::size_t i = 0; i < block; ++i)
    interleaved[i] = glm::vec2(static_cast<float>(cosine[i]), static_cast<float>(cosine[block + i]));
  cosine_table = MakeBuffer(interleaved);

  // Overlap bins for the levels used, flattened for the shader.
  lighting::OverlapBinOptions bo;
  bo.lighting_levels = options.lighting_levels;
  bo.min_retention = options.overlap_min_retention;
  bo.cutoff = options.overlap_cutoff;
  bins = lighting::OverlapBins::Shared(bo);
  std::vector<glm::vec4> levels;
  std::vector<int> begin, srbfs;
  for (const auto& l : bins->levels()) {
    levels.push_back(
        glm::vec4(static_cast<float>(l.lambda), static_cast<float>(l.n), static_cast<float>(begin.size()), 0));
    const int base = static_cast<int>(srbfs.size());
    for (int b : l.begin) begin.push_back(base + b);
    srbfs.insert(srbfs.end(), l.srbfs.begin(), l.srbfs.end());
  }
  bin_levels = MakeBuffer(levels);
  bin_begin = MakeBuffer(begin);
  bin_srbfs = MakeBuffer(srbfs);
}

TripleProductRenderer::TripleProductRenderer(const scene::GltfScene& model, const glm::dmat4& world_from_model,
                                             RenderOptions options)
    : options_(std::move(options)), impl_(std::make_unique<Impl>()) {
  options_.Check();
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      if (!std::isfinite(world_from_model[i][j])) throw Error("world_from_model", "must be finite");
  const glm::dmat3 linear(world_from_model);
  if (!(std::abs(glm::determinant(linear)) > 1e-12)) throw Error("world_from_model", "is singular");
  gl::RequireCurrentGl45("triple-product renderer");
  Impl& im = *impl_;
  im.gbuffer_program = gl::ShaderLibrary::Graphics("render_gbuffer.vert", "render_gbuffer.frag");
  im.cone_rings = options_.cone_rings;
  im.software_renderer = gl::CurrentRendererIsSoftware();
  if (options_.shade_lanes != 0) im.ShadeProgram(options_.shade_lanes);
  im.composite_program = gl::ShaderLibrary::Compute("render_composite.comp");
  {
    const int cones = 1 + 3 * options_.cone_rings * (options_.cone_rings + 1);  // render_shade.comp's kMaxCones
    im.ground_table = gl::Buffer();
    im.ground_table.Allocate(static_cast<std::size_t>(cones + 1 + kMaxPeakCones) * 4 * sizeof(float));
  }
  if (!options_.read_layers) im.counts_program = gl::ShaderLibrary::Compute("render_counts.comp");
  if (options_.supersample > 1) {
    im.resolve_program = gl::ShaderLibrary::Compute("render_resolve.comp");
    im.flag_program = gl::ShaderLibrary::Compute("render_flag.comp");
  }
  if (options_.shading_rate == 2) {
    im.flag_program = gl::ShaderLibrary::Compute("render_flag.comp");
    im.fill_program = gl::ShaderLibrary::Compute("render_fill.comp");
  }
  if (options_.supersample > 1 || options_.shading_rate == 2) {
    im.list_args_program = gl::ShaderLibrary::Compute("render_list_args.comp");
    im.list_args = gl::Buffer();
    im.list_args.Allocate(3 * sizeof(std::uint32_t));
  }
  if (options_.monte_carlo_samples > 0) im.mc_program = gl::ShaderLibrary::Compute("render_mc.comp");
  im.white = gl::Texture::Create2D(GL_RGBA8, 1, 1);
  const std::uint8_t white[4] = {255, 255, 255, 255};
  im.white.Upload2D(GL_RGBA, GL_UNSIGNED_BYTE, white);

  im.UploadModel(model, world_from_model);
  im.PlaceVoxelGrid(model, options_);

  im.UploadShaderTables(options_);  // before SetMaterials, which may append the sheen's table
  SetMaterials(options_.materials);
  SetLighting(lighting::SgLighting{});
}

TripleProductRenderer::~TripleProductRenderer() = default;

const std::vector<glm::vec3>& TripleProductRenderer::world_triangles() const { return impl_->triangles; }
const visibility::VoxelGridSpec& TripleProductRenderer::voxel_spec() const { return impl_->spec; }
const gl::Texture& TripleProductRenderer::composite_texture() const { return impl_->composite_layer; }

int TripleProductRenderer::peaks_without_cone() const {
  return std::max(0, static_cast<int>(impl_->lighting.peaks.size()) - kMaxPeakCones);
}

int TripleProductRenderer::PrepareShading(const PinholeCamera& camera) {
  return impl_->PrepareShading(options_, camera);
}

void TripleProductRenderer::SetMaterials(std::vector<MaterialOverride> overrides) {
  Impl& im = *impl_;
  // Material terms: the glTF metallic-roughness (and its sheen) unless an override names the
  // material; each material's row in the buffer holds its kTermsPerMaterial terms. What it emits: the glTF
  // material's, none under an override, which replaces the whole material (as the Cycles
  // references' paint overrides do: bench render's paints cover the lamps).
  for (const auto& o : overrides)
    for (const auto& brdf : o.brdfs) material::CheckBrdf(brdf);
  std::vector<GpuTerm> gpu_terms;
  detail::MaterialTerms material_terms;
  bool sheen = false;
  im.emission.clear();
  for (const auto& mat : im.materials) {
    std::vector<material::Brdf> terms;
    for (const auto& o : overrides)
      if (o.material.empty() || Lower(mat.name).find(Lower(o.material)) != std::string::npos) terms = o.brdfs;
    if (terms.size() > static_cast<std::size_t>(kTermsPerMaterial))
      throw Error("material override", "at most " + std::to_string(kTermsPerMaterial) + " BRDF terms");
    std::vector<GpuTerm> row(kTermsPerMaterial);
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
    im.emission.push_back(list.from_gbuffer ? mat.emission() : glm::vec3(0));
    gpu_terms.insert(gpu_terms.end(), row.begin(), row.end());
    for (const auto& brdf : list.terms) sheen = sheen || std::holds_alternative<material::Sheen>(brdf);
    material_terms.push_back(std::move(list));
  }
  if (sheen) im.UploadSheenTable();
  im.terms_buffer = MakeBuffer(gpu_terms);
  im.material_terms = std::move(material_terms);
  options_.materials = std::move(overrides);
}

void TripleProductRenderer::SetLighting(const lighting::SgLighting& model, const glm::dmat3& world_from_lighting) {
  Impl& im = *impl_;
  im.lighting = Prepare(model, world_from_lighting, options_.lighting_levels);
  std::vector<glm::vec4> srbfs;
  for (const auto& s : im.lighting.srbfs) {
    srbfs.push_back(LightVec(s.axis, s.lambda));
    srbfs.push_back(glm::vec4(s.amplitude, 0));
  }
  std::vector<glm::vec4> peaks;
  for (const auto& s : im.lighting.peaks) {
    peaks.push_back(LightVec(s.axis, s.lambda));
    peaks.push_back(glm::vec4(s.amplitude, 0));
  }
  im.srbf_buffer = MakeBuffer(srbfs);
  im.peak_buffer = MakeBuffer(peaks);
}

void TripleProductRenderer::SetBackgroundEquirect(const sphere::EquirectImage& equirect) {
  if (equirect.empty()) throw Error("background", "empty image");
  Impl& im = *impl_;
  im.environment = equirect;
  im.background_is_image = false;
  im.environment_texture = gl::Texture::Create2D(GL_RGB32F, equirect.width, equirect.height);
  im.environment_texture.Upload2D(GL_RGB, GL_FLOAT, equirect.rgb.data());
  im.environment_texture.SetWrap(GL_REPEAT, GL_CLAMP_TO_EDGE).SetFilter(GL_LINEAR, GL_LINEAR);
}

void TripleProductRenderer::SetBackgroundRotation(const glm::dmat3& world_from_background) {
  impl_->background_from_world = glm::transpose(world_from_background);
}

void TripleProductRenderer::SetEnvironment(const sphere::EquirectImage& equirect) {
  SetBackgroundEquirect(equirect);
  Impl& im = *impl_;
  im.background_from_world.reset();
  if (options_.monte_carlo_samples > 0) {
    // Texel probabilities ∝ (luminance + a floor) × solid angle; the floor (1e-3 of the mean)
    // keeps every direction reachable by this strategy alone.
    const int w = equirect.width, h = equirect.height;
    std::vector<double> lum(static_cast<std::size_t>(w) * h);
    double mean = 0;
    for (std::size_t i = 0; i < lum.size(); ++i) {
      const float* c = &equirect.rgb[3 * i];
      lum[i] = std::max(0.0, 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]);
      mean += lum[i] / static_cast<double>(lum.size());
    }
    const double floor_value = std::max(1e-3 * mean, 1e-12);
    std::vector<double> weight(lum.size());
    double total = 0;
    for (int y = 0; y < h; ++y) {
      const double sin_theta = std::sin(kPi * (y + 0.5) / h);
      for (int x = 0; x < w; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        weight[i] = (lum[i] + floor_value) * sin_theta;
        total += weight[i];
      }
    }
    std::vector<float> prob(lum.size()), rows(static_cast<std::size_t>(h) + 1, 0.f),
        cols(static_cast<std::size_t>(h) * (w + 1), 0.f);
    double row_acc = 0;
    for (int y = 0; y < h; ++y) {
      double row_sum = 0;
      for (int x = 0; x < w; ++x) row_sum += weight[static_cast<std::size_t>(y) * w + x];
      double acc = 0;
      for (int x = 0; x < w; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        prob[i] = static_cast<float>(weight[i] / total);
        acc += weight[i];
        cols[static_cast<std::size_t>(y) * (w + 1) + x + 1] = static_cast<float>(acc / row_sum);
      }
      cols[static_cast<std::size_t>(y) * (w + 1) + w] = 1.f;
      row_acc += row_sum;
      rows[static_cast<std::size_t>(y) + 1] = static_cast<float>(row_acc / total);
    }
    rows[static_cast<std::size_t>(h)] = 1.f;
    im.env_row_cdf = MakeBuffer(rows);
    im.env_col_cdf = MakeBuffer(cols);
    im.env_texel_prob = MakeBuffer(prob);
    im.mc_environment = gl::Texture::Create2D(GL_RGB32F, w, h);
    im.mc_environment.Upload2D(GL_RGB, GL_FLOAT, equirect.rgb.data());
    im.mc_environment.SetFilter(GL_NEAREST, GL_NEAREST);
  }
}

void TripleProductRenderer::SetBackgroundImage(const sphere::EquirectImage& image) {
  if (image.empty()) throw Error("background", "empty image");
  Impl& im = *impl_;
  im.background_image = image;
  im.background_is_image = true;
  im.environment_texture = gl::Texture::Create2D(GL_RGB32F, image.width, image.height);
  im.environment_texture.Upload2D(GL_RGB, GL_FLOAT, image.rgb.data());
  im.environment_texture.SetFilter(GL_NEAREST, GL_NEAREST);
}

// Each pass is an Impl member (triple_product_impl.h says which file holds it).
RenderResult TripleProductRenderer::Render(const PinholeCamera& camera, ShadeDevice device, bool draw_model) {
  Impl& im = *impl_;
  const Impl::Frame fr = im.MakeFrame(options_, camera, device, draw_model);
  RenderResult out;
  const auto t_total = SteadyClock::now();
  gl::Finish();

  // Voxelize. GL timestamps around the GPU path's stages, read once the composite is done.
  im.Stamp(fr, 0);
  im.Voxelize(fr, &out.ms);
  im.Stamp(fr, 1);

  // G-buffer, at the shaded size (RenderOptions::supersample).
  im.RasterizeGBuffer(fr, &out.ms);
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

void TripleProductRenderer::Impl::SumCounts(const Frame& fr, const Tally& tally, RenderResult* out) const {
  detail::CountSums sums;
  if (tally.gpu_sums) {
    sums = *tally.gpu_sums;
  } else {
    const std::vector<detail::PixelCounts>& sample_counts = tally.counts;
    // The car's coverage per shaded sample: the output's own when not supersampled.
    const std::vector<float>& sample_alpha = fr.k > 1 ? tally.sample_alpha : out->car_alpha;
    for (std::size_t i = 0; i < fr.samples; ++i) {
      sums.cones_total += sample_counts[i].cones;
      sums.triples_total += sample_counts[i].triples;
      if (sample_alpha[i] > 0) {
        ++sums.car;
        sums.lobes += sample_counts[i].lobes;
        sums.cones += sample_counts[i].cones;
        sums.sgs += sample_counts[i].sgs;
        sums.triples += sample_counts[i].triples;
      } else if (sample_counts[i].lobes > 0) {
        ++sums.ground;
      }
    }
    sums.pixels_sampled_fully = std::count(out->sampled_fully.begin(), out->sampled_fully.end(), 1);
  }
  RenderCounts& c = out->counts;
  c.lighting_sgs = lighting.sg_count;
  c.peaks = static_cast<int>(lighting.peaks.size());
  c.car_pixels = static_cast<int>(sums.car);
  c.ground_pixels = static_cast<int>(sums.ground);
  c.pixels_sampled_fully = static_cast<int>(sums.pixels_sampled_fully);
  c.cones_total = sums.cones_total;
  c.triples_total = sums.triples_total;
  if (c.car_pixels > 0) {
    c.lobes_per_car_pixel = static_cast<double>(sums.lobes) / c.car_pixels;
    c.cones_per_car_pixel = static_cast<double>(sums.cones) / c.car_pixels;
    c.sgs_per_car_pixel = static_cast<double>(sums.sgs) / c.car_pixels;
    c.triples_per_car_pixel = static_cast<double>(sums.triples) / c.car_pixels;
  }
}

}  // namespace odvr::render
