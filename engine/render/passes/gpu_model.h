#pragma once
// The renderer's model placed in the world once: its primitives on the GPU for the G-buffer, its
// materials and their textures, and its triangles in world coordinates for the voxelization and
// the exact rays. Internal to engine/render.
#include <map>
#include <memory>
#include <utility>
#include <vector>

#include <glm/mat4x4.hpp>

#include "engine/gl/objects.h"
#include "engine/scene/gltf_scene.h"
#include "engine/visibility/triangle_bvh.h"

namespace odvr::render {

class GpuModel {
 public:
  struct Primitive {
    gl::VertexArray vao;
    gl::Buffer positions, normals, uv0, uv1, tangents, indices;
    GLsizei index_count = 0;
    int material = 0;
  };

  // Needs a current OpenGL 4.5 context. A mirroring world_from_model keeps faces' winding and
  // tangent frames right-handed.
  GpuModel(const scene::GltfScene& model, const glm::dmat4& world_from_model);
  GpuModel(const GpuModel&) = delete;
  GpuModel& operator=(const GpuModel&) = delete;

  bool has_geometry() const { return !triangles_.empty(); }
  const std::vector<Primitive>& primitives() const { return primitives_; }
  // The glTF's materials, one default material for a model without any.
  const std::vector<scene::PbrMaterial>& materials() const { return materials_; }
  // The texture of glTF image `image` as the G-buffer samples it (sRGB or linear); the white
  // texel where the model has no such texture.
  const gl::Texture& Texture(int image, bool srgb) const;
  const std::vector<glm::vec3>& triangles() const { return triangles_; }  // three world vertices each
  const scene::Bounds& bounds() const { return bounds_; }
  // The triangles as the GPU voxelizer reads them: three vec4 vertices each.
  const gl::Buffer& triangle_buffer() const { return triangle_buffer_; }

  // The triangles' BVH for exact rays (RenderOptions::exact_peak_shadows, the Monte-Carlo
  // baseline's exact visibility), on the CPU and the GPU; built on the first call.
  void BuildBvh();
  const visibility::TriangleBvh* bvh() const { return bvh_.get(); }
  const gl::Buffer& bvh_nodes() const { return bvh_nodes_; }
  const gl::Buffer& bvh_triangles() const { return bvh_triangles_; }
  // What a ray's hit on a triangle the camera does not see is shaded with (the specular bounce):
  // per material two rows, (base colour, metallic) and (emission, roughness), each its factor
  // times its texture's mean; then per BVH triangle three rows, its vertices' normals (world) with
  // w = its material. kBvhShadingRowsPerMaterial × materials().size() rows precede the triangles.
  static constexpr int kBvhShadingRowsPerMaterial = 2;
  const std::vector<glm::vec4>& bvh_shading() const { return bvh_shading_; }
  int bvh_shading_first_triangle_row() const {
    return kBvhShadingRowsPerMaterial * static_cast<int>(materials_.size());
  }
  const gl::Buffer& bvh_shading_buffer() const { return bvh_shading_buffer_; }
  int bvh_triangle_count() const { return bvh_ ? static_cast<int>(bvh_->triangle_count()) : 0; }

 private:
  const gl::Texture& Upload(const scene::GltfScene& model, int image, bool srgb);

  std::vector<Primitive> primitives_;
  std::vector<scene::PbrMaterial> materials_;
  std::map<std::pair<int, bool>, gl::Texture> textures_;  // (image, sRGB)
  gl::Texture white_{gl::NoCreate};
  std::vector<glm::vec3> triangles_;
  std::vector<glm::vec3> triangle_normals_;  // per vertex of triangles_
  std::vector<int> triangle_materials_;      // per triangle of triangles_
  scene::Bounds bounds_;
  gl::Buffer triangle_buffer_{gl::NoCreate};
  std::unique_ptr<visibility::TriangleBvh> bvh_;
  gl::Buffer bvh_nodes_{gl::NoCreate}, bvh_triangles_{gl::NoCreate};
  std::vector<glm::vec4> bvh_shading_;  // the materials' rows from the start, the triangles' with the BVH
  gl::Buffer bvh_shading_buffer_{gl::NoCreate};
};

// A buffer holding `data`, or 16 bytes for none (a shader's binding must name a buffer).
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

}  // namespace odvr::render
