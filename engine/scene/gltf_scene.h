#pragma once
// A glTF 2.0 model (.gltf or .glb) as a plain CPU scene for the renderer (DESIGN.md §5).
//
// Conventions:
// - Geometry is flattened to world space through the node hierarchy of the default scene (the
//   first scene when none is marked; every root node when the file has no scene at all). glTF
//   is already right-handed, +Y up, metres, so its world frame is odvr's without a change.
// - Every triangle primitive (TRIANGLES, and STRIP/FAN unrolled to triangles) becomes one
//   `ScenePrimitive`. Normals are transformed by the inverse transpose; a node with a negative
//   determinant flips the winding (and the tangent's handedness) so front faces stay CCW.
// - Missing normals are computed flat, as the glTF spec demands (vertices are unwelded).
//   Degenerate or non-finite normals fall back to the face normal, then to +Y.
// - Textures are decoded once per glTF image to RGBA8 (16-bit images are reduced to 8 bits),
//   rows top-down as stored in the file; base colour and emission stay sRGB-encoded (the renderer
//   linearizes), metallic-roughness stays linear (G = roughness, B = metallic, as in glTF).
//
// Errors: a malformed, truncated or absurd file throws odvr::Error whose `where` is the path and
// whose reason is one line (tinygltf's own error and warning text folded in). Limits are in
// GltfLoadOptions so that a hostile file cannot make the loader allocate without bound.
#include <cstdint>
#include <filesystem>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <limits>
#include <string>
#include <vector>

namespace odvr::scene {

struct GltfLoadOptions {
  // Whole-scene caps, checked before anything of that size is allocated.
  std::size_t max_triangles = 20'000'000;
  std::size_t max_vertices = 30'000'000;
  int max_texture_side = 16384;  // pixels, per side
  // A vertex farther than this from the origin, in world metres, is refused: glTF's unit is the
  // metre, a car is a few metres across, and at 100 km a float's step is already 8 mm. One flipped
  // exponent bit puts a vertex at 1e38 and shrinks the rest of the car to nothing beside it.
  double max_coordinate_m = 1e5;
  // Throws odvr::Error naming the option when a limit is zero or negative.
  void Check() const;
};

struct TextureImage {
  std::string name;  // the glTF image's name, else its URI, else "image <index>"
  std::string uri;   // as written in the file (relative to it); empty for embedded images
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgba;  // width × height × 4, row-major, top row first
};

// A material's reference to one texture; `image` < 0 means no texture.
struct TextureRef {
  int image = -1;    // index into GltfScene::images
  int texcoord = 0;  // which UV set (0 or 1)
  // KHR_texture_transform, applied as uv' = offset + R(rotation) · (scale ⊙ uv).
  glm::vec2 offset{0, 0};
  glm::vec2 scale{1, 1};
  float rotation = 0;  // radians
  bool valid() const { return image >= 0; }
};

// glTF's PBR metallic-roughness material; defaults are the spec's.
struct PbrMaterial {
  std::string name;
  glm::vec4 base_color_factor{1, 1, 1, 1};  // linear RGBA
  TextureRef base_color_texture;
  float metallic_factor = 1;
  float roughness_factor = 1;  // perceptual roughness; GGX α = roughness² (glTF spec)
  TextureRef metallic_roughness_texture;
  TextureRef normal_texture;
  float normal_scale = 1;
  glm::vec3 emissive_factor{0, 0, 0};
  TextureRef emissive_texture;  // sRGB; multiplies the factor (glTF spec)
  float emissive_strength = 1;  // KHR_materials_emissive_strength
  // KHR_materials_sheen's factors (its textures are not read); a black sheen is none.
  glm::vec3 sheen_color{0, 0, 0};
  float sheen_roughness = 0;
  // KHR_materials_transmission's factor (its texture is not read). The renderer does not see
  // through: the transmitted share of the dielectric's diffuse layer is taken away (what passes
  // into a car's glass is mostly lost in its dark interior), its reflection stays.
  float transmission = 0;
  // The radiance the surface emits, linear, before the emissive texture's factor.
  glm::vec3 emission() const { return emissive_factor * emissive_strength; }
  bool double_sided = false;
  enum class AlphaMode { kOpaque, kMask, kBlend } alpha_mode = AlphaMode::kOpaque;
  float alpha_cutoff = 0.5f;
};

struct ScenePrimitive {
  std::string name;                    // "<mesh name>/<primitive index>"
  int material = 0;                    // index into GltfScene::materials (a default material is added if needed)
  std::vector<glm::vec3> positions;    // world space, metres
  std::vector<glm::vec3> normals;      // world space, unit
  std::vector<glm::vec4> tangents;     // world space xyz unit, w = ±1 handedness; empty if absent
  std::vector<glm::vec2> uv0, uv1;     // empty if absent
  std::vector<std::uint32_t> indices;  // 3 per triangle, CCW front faces
  bool normals_computed = false;       // the file had none: flat normals were made

  std::size_t triangle_count() const { return indices.size() / 3; }
};

struct Bounds {
  glm::vec3 min{std::numeric_limits<float>::infinity()};
  glm::vec3 max{-std::numeric_limits<float>::infinity()};
  bool empty() const { return !(min.x <= max.x); }
  glm::vec3 size() const { return empty() ? glm::vec3(0) : max - min; }
  glm::vec3 center() const { return empty() ? glm::vec3(0) : 0.5f * (min + max); }
  void Extend(const glm::vec3& p);
};

struct GltfScene {
  std::filesystem::path source;
  std::vector<ScenePrimitive> primitives;
  std::vector<PbrMaterial> materials;
  std::vector<TextureImage> images;
  Bounds bounds;  // of every world-space position; empty for an empty scene
  // The file's extensionsUsed that odvr renders without (KHR_materials_transmission,
  // _clearcoat, …): the materials that use them are shaded as their metallic-roughness alone.
  // LoadGltfScene warns of them once per file and process.
  std::vector<std::string> ignored_extensions;

  std::size_t triangle_count() const;
  std::size_t vertex_count() const;
};

// Loads `path` (.gltf with its external buffers and images, or .glb). Throws odvr::Error naming
// the file on anything it cannot load faithfully.
GltfScene LoadGltfScene(const std::filesystem::path& path, const GltfLoadOptions& options = {});

}  // namespace odvr::scene
