#include "engine/render/passes/gpu_model.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>

#include "core/srgb.h"

namespace odvr::render {
namespace {

// The mean of a texture's channels, linear (sRGB decoded first where `srgb`); 1 without one.
glm::vec4 TextureMean(const scene::GltfScene& model, const scene::TextureRef& ref, bool srgb) {
  if (!ref.valid() || static_cast<std::size_t>(ref.image) >= model.images.size()) return glm::vec4(1);
  const scene::TextureImage& img = model.images[static_cast<std::size_t>(ref.image)];
  const std::size_t texels = img.rgba.size() / 4;
  if (texels == 0) return glm::vec4(1);
  const std::array<float, 256>& decode = Srgb8ToLinearTable();
  glm::dvec4 sum(0);
  for (std::size_t i = 0; i < texels; ++i)
    for (int c = 0; c < 4; ++c) {
      const std::uint8_t v = img.rgba[4 * i + static_cast<std::size_t>(c)];
      sum[c] += srgb && c < 3 ? decode[v] : v / 255.0;
    }
  return glm::vec4(sum / static_cast<double>(texels));
}

// GpuModel::bvh_shading's two rows of a material.
void AppendMaterialMeans(const scene::GltfScene& model, const scene::PbrMaterial& m, std::vector<glm::vec4>* rows) {
  const glm::vec4 base = TextureMean(model, m.base_color_texture, true);
  const glm::vec4 mr = TextureMean(model, m.metallic_roughness_texture, false);  // G roughness, B metallic
  const glm::vec4 emissive = TextureMean(model, m.emissive_texture, true);
  rows->emplace_back(glm::vec3(m.base_color_factor) * glm::vec3(base), m.metallic_factor * mr.b);
  rows->emplace_back(m.emission() * glm::vec3(emissive), m.roughness_factor * mr.g);
}

}  // namespace

GpuModel::GpuModel(const scene::GltfScene& model, const glm::dmat4& world_from_model) {
  white_ = gl::Texture::Create2D(GL_RGBA8, 1, 1);
  const std::uint8_t white[4] = {255, 255, 255, 255};
  white_.Upload2D(GL_RGBA, GL_UNSIGNED_BYTE, white);

  const glm::dmat3 linear(world_from_model);
  const glm::dmat3 normal_matrix = glm::transpose(glm::inverse(linear));
  const bool flips = glm::determinant(linear) < 0;
  materials_ = model.materials;
  if (materials_.empty()) materials_.emplace_back();
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
      bounds_.Extend(pos[i]);
    }
    std::vector<std::uint32_t> idx = prim.indices;
    if (flips)
      for (std::size_t t = 0; t + 2 < idx.size(); t += 3) std::swap(idx[t + 1], idx[t + 2]);
    for (std::uint32_t k : idx) {
      triangles_.push_back(pos[k]);
      triangle_normals_.push_back(nor[k]);
    }
    Primitive p;
    p.positions.SetData(pos);
    p.normals.SetData(nor);
    p.uv0.SetData(uv0);
    p.uv1.SetData(uv1);
    p.tangents.SetData(tan);
    p.indices.SetData(idx);
    p.index_count = static_cast<GLsizei>(idx.size());
    p.material = std::clamp(prim.material, 0, static_cast<int>(materials_.size()) - 1);
    triangle_materials_.insert(triangle_materials_.end(), idx.size() / 3, p.material);
    p.vao.AddFloatAttribute(0, p.positions, 0, 3, 0, sizeof(glm::vec3))
        .AddFloatAttribute(1, p.normals, 1, 3, 0, sizeof(glm::vec3))
        .AddFloatAttribute(2, p.uv0, 2, 2, 0, sizeof(glm::vec2))
        .AddFloatAttribute(3, p.uv1, 3, 2, 0, sizeof(glm::vec2))
        .AddFloatAttribute(4, p.tangents, 4, 4, 0, sizeof(glm::vec4))
        .SetIndexBuffer(p.indices);
    const auto& mat = materials_[static_cast<std::size_t>(p.material)];
    if (mat.base_color_texture.valid()) Upload(model, mat.base_color_texture.image, true);
    if (mat.metallic_roughness_texture.valid()) Upload(model, mat.metallic_roughness_texture.image, false);
    if (mat.normal_texture.valid()) Upload(model, mat.normal_texture.image, false);
    if (mat.emissive_texture.valid()) Upload(model, mat.emissive_texture.image, true);
    primitives_.push_back(std::move(p));
  }
  for (const scene::PbrMaterial& m : materials_) AppendMaterialMeans(model, m, &bvh_shading_);
  if (has_geometry()) {
    std::vector<glm::vec4> padded(triangles_.size());
    for (std::size_t i = 0; i < padded.size(); ++i) padded[i] = glm::vec4(triangles_[i], 1.f);
    triangle_buffer_ = MakeBuffer(padded);
  }
}

const gl::Texture& GpuModel::Upload(const scene::GltfScene& model, int image, bool srgb) {
  auto key = std::make_pair(image, srgb);
  auto it = textures_.find(key);
  if (it != textures_.end()) return it->second;
  const auto& img = model.images.at(static_cast<std::size_t>(image));
  const int levels = 1 + static_cast<int>(std::floor(std::log2(std::max(img.width, img.height))));
  gl::Texture t = gl::Texture::Create2D(srgb ? GL_SRGB8_ALPHA8 : GL_RGBA8, img.width, img.height, levels);
  t.Upload2D(GL_RGBA, GL_UNSIGNED_BYTE, img.rgba.data()).GenerateMipmaps();
  t.SetWrap(GL_REPEAT, GL_REPEAT).SetFilter(GL_LINEAR_MIPMAP_LINEAR, GL_LINEAR);
  return textures_.emplace(key, std::move(t)).first->second;
}

const gl::Texture& GpuModel::Texture(int image, bool srgb) const {
  const auto it = textures_.find({image, srgb});
  return it != textures_.end() ? it->second : white_;
}

void GpuModel::BuildBvh() {
  if (bvh_ || !has_geometry()) return;
  bvh_ = std::make_unique<visibility::TriangleBvh>(triangles_);
  bvh_nodes_ = MakeBuffer(bvh_->nodes());
  bvh_triangles_ = MakeBuffer(bvh_->triangles());
  for (int t : bvh_->source_triangles())
    for (int k = 0; k < 3; ++k)
      bvh_shading_.emplace_back(triangle_normals_[3 * static_cast<std::size_t>(t) + static_cast<std::size_t>(k)],
                                static_cast<float>(triangle_materials_[static_cast<std::size_t>(t)]));
  bvh_shading_buffer_ = MakeBuffer(bvh_shading_);
}

}  // namespace odvr::render
