#include "engine/scene/gltf_scene.h"

#include <tiny_gltf.h>

#include <spdlog/spdlog.h>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <map>
#include <mutex>
#include <set>
#include <type_traits>

#include "core/error.h"

namespace odvr::scene {

void Bounds::Extend(const glm::vec3& p) {
  min = glm::min(min, p);
  max = glm::max(max, p);
}

std::size_t GltfScene::triangle_count() const {
  std::size_t n = 0;
  for (const auto& p : primitives) n += p.triangle_count();
  return n;
}

std::size_t GltfScene::vertex_count() const {
  std::size_t n = 0;
  for (const auto& p : primitives) n += p.positions.size();
  return n;
}

void GltfLoadOptions::Check() const {
  if (max_triangles == 0) throw Error("GltfLoadOptions::max_triangles", "must be positive");
  if (max_vertices == 0) throw Error("GltfLoadOptions::max_vertices", "must be positive");
  if (max_texture_side <= 0) throw Error("GltfLoadOptions::max_texture_side", "must be positive");
  if (!(max_coordinate_m > 0)) throw Error("GltfLoadOptions::max_coordinate_m", "must be positive");
}

namespace {

// tinygltf reports several problems as multi-line text; a user sees one line.
std::string OneLine(std::string text) {
  std::string out;
  for (char c : text) {
    if (c == '\n' || c == '\r') {
      if (!out.empty() && out.back() != ' ') out += "; ";
    } else {
      out += c;
    }
  }
  while (!out.empty() && (out.back() == ' ' || out.back() == ';')) out.pop_back();
  return out;
}

// The pixel size an image header claims, read before stb decodes it, so that a file claiming
// 10⁶ × 10⁶ pixels is refused instead of allocating. PNG and JPEG are what glTF allows; other
// formats go to stb unchecked (stb caps them at 2^24 per side and refuses int overflow itself).
bool PeekImageSize(const unsigned char* bytes, int size, long* width, long* height) {
  const auto be16 = [&](int i) { return long(bytes[i]) << 8 | long(bytes[i + 1]); };
  const auto be32 = [&](int i) { return be16(i) << 16 | be16(i + 2); };
  static const unsigned char kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (size >= 24 && std::memcmp(bytes, kPng, 8) == 0) {
    *width = be32(16);
    *height = be32(20);
    return true;
  }
  if (size >= 4 && bytes[0] == 0xff && bytes[1] == 0xd8) {
    int i = 2;
    while (i + 9 < size) {
      if (bytes[i] != 0xff) return false;
      const int marker = bytes[i + 1];
      if (marker == 0xff) {  // fill byte
        ++i;
        continue;
      }
      const bool sof = marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 && marker != 0xcc;
      if (sof) {
        *height = be16(i + 5);
        *width = be16(i + 7);
        return true;
      }
      i += 2 + int(be16(i + 2));
    }
  }
  return false;
}

struct ImageLoaderContext {
  int max_side = 0;
};

bool LoadImageChecked(tinygltf::Image* image, const int image_idx, std::string* err, std::string* warn, int req_width,
                      int req_height, const unsigned char* bytes, int size, void* user) {
  const auto* ctx = static_cast<const ImageLoaderContext*>(user);
  long w = 0, h = 0;
  if (PeekImageSize(bytes, size, &w, &h) && (w > ctx->max_side || h > ctx->max_side)) {
    if (err) {
      *err += "image[" + std::to_string(image_idx) + "] claims " + std::to_string(w) + "x" + std::to_string(h) +
              " pixels, above the limit of " + std::to_string(ctx->max_side) + " per side\n";
    }
    return false;
  }
  return tinygltf::LoadImageData(image, image_idx, err, warn, req_width, req_height, bytes, size, nullptr);
}

// A validated, typed window onto an accessor's bytes.
struct AccessorView {
  const unsigned char* data = nullptr;
  std::size_t stride = 0;
  std::size_t count = 0;
  int component_type = 0;
  int components = 0;
  bool normalized = false;
};

class Reader {
 public:
  Reader(const tinygltf::Model& model, const std::string& file) : model_(model), file_(file) {}

  [[noreturn]] void Fail(const std::string& reason) const { throw Error(file_, reason); }

  AccessorView View(int index, const std::string& what) const {
    if (index < 0 || std::size_t(index) >= model_.accessors.size())
      Fail(what + " refers to accessor " + std::to_string(index) + ", which does not exist");
    const tinygltf::Accessor& a = model_.accessors[std::size_t(index)];
    const std::string name = what + " (accessor " + std::to_string(index) + ")";
    if (a.sparse.isSparse) Fail(name + " is sparse, which is not supported");
    if (a.bufferView < 0 || std::size_t(a.bufferView) >= model_.bufferViews.size())
      Fail(name + " has no valid buffer view");
    const tinygltf::BufferView& bv = model_.bufferViews[std::size_t(a.bufferView)];
    if (bv.buffer < 0 || std::size_t(bv.buffer) >= model_.buffers.size())
      Fail(name + " uses buffer view " + std::to_string(a.bufferView) + " with no valid buffer");
    const auto& buffer = model_.buffers[std::size_t(bv.buffer)].data;
    if (bv.byteOffset > buffer.size() || bv.byteLength > buffer.size() - bv.byteOffset)
      Fail(name + ": buffer view " + std::to_string(a.bufferView) + " runs past the end of its buffer (" +
           std::to_string(buffer.size()) + " bytes)");
    const int component_size = tinygltf::GetComponentSizeInBytes(std::uint32_t(a.componentType));
    const int components = tinygltf::GetNumComponentsInType(std::uint32_t(a.type));
    if (component_size <= 0 || components <= 0) Fail(name + " has an invalid component or element type");
    const std::size_t element = std::size_t(component_size) * std::size_t(components);
    const std::size_t stride = bv.byteStride ? bv.byteStride : element;
    if (stride < element) Fail(name + " has a byte stride smaller than its element");
    if (a.count > 0) {
      // Written so that no product can overflow: count is bounded by the view before multiplying.
      const bool fits = a.byteOffset <= bv.byteLength && element <= bv.byteLength - a.byteOffset &&
                        (a.count - 1) <= (bv.byteLength - a.byteOffset - element) / stride;
      if (!fits)
        Fail(name + " claims " + std::to_string(a.count) + " elements, beyond its buffer view of " +
             std::to_string(bv.byteLength) + " bytes");
    }
    AccessorView v;
    v.data = buffer.data() + bv.byteOffset + a.byteOffset;
    v.stride = stride;
    v.count = a.count;
    v.component_type = a.componentType;
    v.components = components;
    v.normalized = a.normalized;
    return v;
  }

  static float Component(const AccessorView& v, std::size_t element, int c) {
    const unsigned char* p = v.data + element * v.stride;
    switch (v.component_type) {
      case TINYGLTF_COMPONENT_TYPE_FLOAT: {
        float f;
        std::memcpy(&f, p + 4 * c, 4);
        return f;
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: {
        const float f = p[c];
        return v.normalized ? f / 255.0f : f;
      }
      case TINYGLTF_COMPONENT_TYPE_BYTE: {
        const float f = float(static_cast<signed char>(p[c]));
        return v.normalized ? std::max(f / 127.0f, -1.0f) : f;
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        std::uint16_t s;
        std::memcpy(&s, p + 2 * c, 2);
        return v.normalized ? float(s) / 65535.0f : float(s);
      }
      case TINYGLTF_COMPONENT_TYPE_SHORT: {
        std::int16_t s;
        std::memcpy(&s, p + 2 * c, 2);
        return v.normalized ? std::max(float(s) / 32767.0f, -1.0f) : float(s);
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
        std::uint32_t u;
        std::memcpy(&u, p + 4 * c, 4);
        return float(u);
      }
      default:
        return 0;
    }
  }

  template <int N>
  std::vector<glm::vec<N, float>> Floats(int index, const std::string& what, bool allow_normalized_ints) const {
    const AccessorView v = View(index, what);
    if (v.components != N) Fail(what + " must have " + std::to_string(N) + " components per element");
    const bool ok_type =
        v.component_type == TINYGLTF_COMPONENT_TYPE_FLOAT ||
        (allow_normalized_ints && v.normalized &&
         (v.component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
          v.component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ||
          v.component_type == TINYGLTF_COMPONENT_TYPE_BYTE || v.component_type == TINYGLTF_COMPONENT_TYPE_SHORT));
    if (!ok_type) Fail(what + " has a component type glTF does not allow there");
    std::vector<glm::vec<N, float>> out(v.count);
    for (std::size_t i = 0; i < v.count; ++i) {
      for (int c = 0; c < N; ++c) {
        const float f = Component(v, i, c);
        if (!std::isfinite(f)) Fail(what + " holds a non-finite value at element " + std::to_string(i));
        out[i][c] = f;
      }
    }
    return out;
  }

  std::vector<std::uint32_t> Indices(int index, std::size_t vertex_count, const std::string& what) const {
    const AccessorView v = View(index, what);
    if (v.components != 1) Fail(what + " must be scalar");
    if (v.component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
        v.component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        v.component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
      Fail(what + " must be unsigned bytes, shorts or ints");
    std::vector<std::uint32_t> out(v.count);
    for (std::size_t i = 0; i < v.count; ++i) {
      // Not through Component(): indices above 2^24 would lose precision in a float.
      const unsigned char* p = v.data + i * v.stride;
      std::uint32_t exact = 0;
      if (v.component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE) {
        exact = p[0];
      } else if (v.component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) {
        std::uint16_t s;
        std::memcpy(&s, p, 2);
        exact = s;
      } else {
        std::memcpy(&exact, p, 4);
      }
      if (exact >= vertex_count)
        Fail(what + " index " + std::to_string(exact) + " at " + std::to_string(i) + " is beyond the " +
             std::to_string(vertex_count) + " vertices");
      out[i] = exact;
    }
    return out;
  }

  std::size_t Count(int index, const std::string& what) const { return View(index, what).count; }

 private:
  const tinygltf::Model& model_;
  const std::string& file_;
};

glm::dmat4 LocalTransform(const tinygltf::Node& node) {
  if (node.matrix.size() == 16) {
    glm::dmat4 m;
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) m[c][r] = node.matrix[std::size_t(4 * c + r)];
    return m;
  }
  glm::dmat4 m(1.0);
  if (node.translation.size() == 3) {
    m[3] = glm::dvec4(node.translation[0], node.translation[1], node.translation[2], 1);
  }
  if (node.rotation.size() == 4) {
    const glm::dquat q(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
    const glm::dmat3 r = glm::mat3_cast(glm::normalize(q));
    for (int c = 0; c < 3; ++c) m[c] = glm::dvec4(r[c], 0);
  }
  if (node.scale.size() == 3) {
    for (int c = 0; c < 3; ++c) m[c] *= node.scale[std::size_t(c)];
  }
  return m;
}

// Adjugate transpose of the linear part: the normal transform up to a positive-or-negative
// scale, defined even when the matrix is singular (a zero scale on one axis).
glm::dmat3 NormalMatrix(const glm::dmat3& m) {
  return glm::dmat3(glm::cross(m[1], m[2]), glm::cross(m[2], m[0]), glm::cross(m[0], m[1]));
}

glm::vec3 FaceNormal(const std::vector<glm::vec3>& p, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
  return glm::cross(p[b] - p[a], p[c] - p[a]);  // length = 2 × area
}

bool GoodUnit(const glm::vec3& n) {
  const float l = glm::length(n);
  return std::isfinite(l) && l > 1e-12f;
}

std::vector<std::uint32_t> TriangulateIndices(int mode, const std::vector<std::uint32_t>& in) {
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    std::vector<std::uint32_t> out(in.begin(), in.end() - std::ptrdiff_t(in.size() % 3));
    return out;
  }
  std::vector<std::uint32_t> out;
  if (in.size() < 3) return out;
  out.reserve(3 * (in.size() - 2));
  for (std::size_t i = 0; i + 2 < in.size(); ++i) {
    if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      // glTF: triangle i = {p_i, p_{i+1+i%2}, p_{i+2−i%2}}, keeping every triangle CCW.
      out.insert(out.end(), {in[i], in[i + 1 + i % 2], in[i + 2 - i % 2]});
    } else {  // fan
      out.insert(out.end(), {in[i + 1], in[i + 2], in[0]});
    }
  }
  return out;
}

// A coordinate for a message: short, and exact enough to recognise (1e+38, 12.5).
std::string Metres(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.4g", v);
  return text;
}

std::string Count(std::size_t n, const std::string& noun) {
  return std::to_string(n) + " " + noun + (n == 1 ? "" : noun.back() == 'h' ? "es" : "s");
}

class SceneBuilder {
 public:
  SceneBuilder(const tinygltf::Model& model, const std::string& file, const GltfLoadOptions& options,
               const std::string& warnings)
      : model_(model), options_(options), reader_(model, file), warnings_(warnings) {}

  GltfScene Build(const std::filesystem::path& path) {
    scene_.source = path;
    for (const std::string& ext : model_.extensionsUsed)
      if (ext != "KHR_texture_transform" && ext != "KHR_materials_emissive_strength" && ext != "KHR_materials_sheen" &&
          ext != "KHR_materials_transmission")
        scene_.ignored_extensions.push_back(ext);
    for (std::size_t i = 0; i < model_.materials.size(); ++i) scene_.materials.push_back(Material(int(i)));

    std::vector<int> roots;
    if (!model_.scenes.empty()) {
      const int s = model_.defaultScene >= 0 ? model_.defaultScene : 0;
      if (std::size_t(s) >= model_.scenes.size())
        reader_.Fail("default scene " + std::to_string(s) + " does not exist");
      roots = model_.scenes[std::size_t(s)].nodes;
    } else {
      std::vector<bool> is_child(model_.nodes.size(), false);
      for (const auto& n : model_.nodes)
        for (int c : n.children)
          if (c >= 0 && std::size_t(c) < is_child.size()) is_child[std::size_t(c)] = true;
      for (std::size_t i = 0; i < model_.nodes.size(); ++i)
        if (!is_child[i]) roots.push_back(int(i));
    }
    std::vector<bool> on_path(model_.nodes.size(), false);
    for (int r : roots) Visit(r, glm::dmat4(1.0), &on_path);
    std::size_t triangles = 0;
    for (const auto& p : scene_.primitives) {
      triangles += p.indices.size() / 3;
      for (const auto& v : p.positions) scene_.bounds.Extend(v);
    }
    // A model that draws nothing renders a picture with no car and no error: refuse it instead.
    if (triangles == 0)
      reader_.Fail("holds no triangles to draw (the file has " + Count(model_.nodes.size(), "node") + " and " +
                   Count(model_.meshes.size(), "mesh") + "; its scene draws none)");
    const glm::vec3 extent = scene_.bounds.max - scene_.bounds.min;
    if (!(std::max({extent.x, extent.y, extent.z}) > 1e-6f))
      reader_.Fail("is a single point: its " + std::to_string(triangles) + " triangles have no extent");
    return std::move(scene_);
  }

 private:
  void Visit(int index, const glm::dmat4& parent, std::vector<bool>* on_path) {
    if (index < 0 || std::size_t(index) >= model_.nodes.size())
      reader_.Fail("node " + std::to_string(index) + " does not exist");
    if ((*on_path)[std::size_t(index)]) reader_.Fail("node " + std::to_string(index) + " is its own ancestor");
    (*on_path)[std::size_t(index)] = true;
    const tinygltf::Node& node = model_.nodes[std::size_t(index)];
    const glm::dmat4 world = parent * LocalTransform(node);
    if (node.mesh >= 0) AddMesh(node.mesh, world);
    for (int c : node.children) Visit(c, world, on_path);
    (*on_path)[std::size_t(index)] = false;
  }

  void AddMesh(int mesh_index, const glm::dmat4& world) {
    if (std::size_t(mesh_index) >= model_.meshes.size())
      reader_.Fail("mesh " + std::to_string(mesh_index) + " does not exist");
    const tinygltf::Mesh& mesh = model_.meshes[std::size_t(mesh_index)];
    for (std::size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
      const tinygltf::Primitive& prim = mesh.primitives[pi];
      const std::string name =
          (mesh.name.empty() ? "mesh " + std::to_string(mesh_index) : mesh.name) + "/" + std::to_string(pi);
      if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
          prim.mode != TINYGLTF_MODE_TRIANGLE_FAN && prim.mode != -1)
        reader_.Fail("primitive " + name + " has mode " + std::to_string(prim.mode) +
                     " (points or lines); only triangles can be rendered");
      AddPrimitive(prim, name, world);
    }
  }

  void AddPrimitive(const tinygltf::Primitive& prim, const std::string& name, const glm::dmat4& world) {
    const auto attr = [&](const char* key) {
      auto it = prim.attributes.find(key);
      return it == prim.attributes.end() ? -1 : it->second;
    };
    const int pos_acc = attr("POSITION");
    if (pos_acc < 0) reader_.Fail("primitive " + name + " has no POSITION");
    const std::string what = "primitive " + name;

    // Caps first, from the accessor counts alone, before anything that size is allocated.
    const std::size_t vertex_count = reader_.Count(pos_acc, what + " POSITION");
    const std::size_t index_count = prim.indices >= 0 ? reader_.Count(prim.indices, what + " indices") : vertex_count;
    const std::size_t tri_estimate = prim.mode == TINYGLTF_MODE_TRIANGLES || prim.mode == -1
                                         ? index_count / 3
                                         : (index_count >= 3 ? index_count - 2 : 0);
    const bool flat = attr("NORMAL") < 0;
    total_triangles_ += tri_estimate;
    total_vertices_ += flat ? 3 * tri_estimate : vertex_count;
    if (total_triangles_ > options_.max_triangles)
      reader_.Fail("more than " + std::to_string(options_.max_triangles) + " triangles (limit reached at " + what +
                   ")");
    if (total_vertices_ > options_.max_vertices)
      reader_.Fail("more than " + std::to_string(options_.max_vertices) + " vertices (limit reached at " + what + ")");

    ScenePrimitive out;
    out.name = name;
    out.positions = reader_.Floats<3>(pos_acc, what + " POSITION", false);
    std::vector<glm::vec3> normals;
    if (!flat) {
      normals = reader_.Floats<3>(attr("NORMAL"), what + " NORMAL", false);
      if (normals.size() != vertex_count) reader_.Fail(what + " NORMAL count differs from POSITION count");
    }
    if (attr("TANGENT") >= 0) {
      out.tangents = reader_.Floats<4>(attr("TANGENT"), what + " TANGENT", false);
      if (out.tangents.size() != vertex_count) reader_.Fail(what + " TANGENT count differs from POSITION count");
    }
    for (int set = 0; set < 2; ++set) {
      const std::string key = "TEXCOORD_" + std::to_string(set);
      const int acc = attr(key.c_str());
      if (acc < 0) continue;
      auto& uv = set == 0 ? out.uv0 : out.uv1;
      uv = reader_.Floats<2>(acc, what + " " + key, true);
      if (uv.size() != vertex_count) reader_.Fail(what + " " + key + " count differs from POSITION count");
    }
    std::vector<std::uint32_t> raw;
    if (prim.indices >= 0) {
      raw = reader_.Indices(prim.indices, vertex_count, what + " indices");
    } else {
      raw.resize(vertex_count);
      for (std::size_t i = 0; i < vertex_count; ++i) raw[i] = std::uint32_t(i);
    }
    out.indices = TriangulateIndices(prim.mode == -1 ? TINYGLTF_MODE_TRIANGLES : prim.mode, raw);

    if (prim.material >= 0) {
      if (std::size_t(prim.material) >= model_.materials.size())
        reader_.Fail(what + " uses material " + std::to_string(prim.material) + ", which does not exist");
      out.material = prim.material;
    } else {
      out.material = DefaultMaterial();
    }

    // To world space.
    const glm::dmat3 linear(world);
    const double det = glm::determinant(linear);
    const glm::dmat3 normal_matrix = NormalMatrix(linear);
    for (std::size_t i = 0; i < out.positions.size(); ++i) {
      const glm::dvec3 p(world * glm::dvec4(out.positions[i], 1.0));
      if (!(glm::length(p) <= options_.max_coordinate_m))
        reader_.Fail(what + " POSITION " + std::to_string(i) + " lies at (" + Metres(p.x) + ", " + Metres(p.y) + ", " +
                     Metres(p.z) + ") m, beyond " + Metres(options_.max_coordinate_m) +
                     " m of the origin: a corrupt coordinate, or a scale that is not metres");
      out.positions[i] = glm::vec3(p);
    }
    if (det < 0) {
      for (std::size_t t = 0; t + 2 < out.indices.size(); t += 3) std::swap(out.indices[t + 1], out.indices[t + 2]);
    }
    for (auto& t : out.tangents) {
      glm::dvec3 v = linear * glm::dvec3(t);
      const double l = glm::length(v);
      v = l > 1e-30 ? v / l : glm::dvec3(1, 0, 0);
      t = glm::vec4(glm::vec3(v), (t.w < 0 ? -1.0f : 1.0f) * (det < 0 ? -1.0f : 1.0f));
    }

    if (flat) {
      Unweld(&out);
      out.normals.resize(out.positions.size());
      for (std::size_t t = 0; t + 2 < out.indices.size(); t += 3) {
        glm::vec3 n = FaceNormal(out.positions, out.indices[t], out.indices[t + 1], out.indices[t + 2]);
        n = GoodUnit(n) ? glm::normalize(n) : glm::vec3(0, 1, 0);
        for (int k = 0; k < 3; ++k) out.normals[out.indices[t + std::size_t(k)]] = n;
      }
      out.normals_computed = true;
    } else {
      out.normals.resize(normals.size());
      bool any_bad = false;
      for (std::size_t i = 0; i < normals.size(); ++i) {
        const glm::vec3 n(normal_matrix * glm::dvec3(normals[i]) * (det < 0 ? -1.0 : 1.0));
        any_bad |= !GoodUnit(n);
        out.normals[i] = GoodUnit(n) ? glm::normalize(n) : glm::vec3(0);
      }
      if (any_bad) RepairNormals(&out);
    }
    scene_.primitives.push_back(std::move(out));
  }

  // Flat normals need a vertex per triangle corner.
  static void Unweld(ScenePrimitive* p) {
    const auto gather = [&](auto& v) {
      if (v.empty()) return;
      std::remove_reference_t<decltype(v)> u(p->indices.size());
      for (std::size_t i = 0; i < p->indices.size(); ++i) u[i] = v[p->indices[i]];
      v = std::move(u);
    };
    gather(p->positions);
    gather(p->tangents);
    gather(p->uv0);
    gather(p->uv1);
    for (std::size_t i = 0; i < p->indices.size(); ++i) p->indices[i] = std::uint32_t(i);
  }

  // Zero or non-finite normals in the file: use the area-weighted normal of the adjacent faces.
  static void RepairNormals(ScenePrimitive* p) {
    std::vector<glm::vec3> acc(p->positions.size(), glm::vec3(0));
    for (std::size_t t = 0; t + 2 < p->indices.size(); t += 3) {
      const glm::vec3 n = FaceNormal(p->positions, p->indices[t], p->indices[t + 1], p->indices[t + 2]);
      if (!GoodUnit(n)) continue;
      for (int k = 0; k < 3; ++k) acc[p->indices[t + std::size_t(k)]] += n;
    }
    for (std::size_t i = 0; i < p->normals.size(); ++i) {
      if (GoodUnit(p->normals[i])) continue;
      p->normals[i] = GoodUnit(acc[i]) ? glm::normalize(acc[i]) : glm::vec3(0, 1, 0);
    }
  }

  int DefaultMaterial() {
    if (default_material_ < 0) {
      default_material_ = int(scene_.materials.size());
      PbrMaterial m;
      m.name = "(default)";
      scene_.materials.push_back(m);
    }
    return default_material_;
  }

  static void ReadTextureTransform(const tinygltf::ExtensionMap& ext, TextureRef* ref) {
    auto it = ext.find("KHR_texture_transform");
    if (it == ext.end()) return;
    const tinygltf::Value& v = it->second;
    const auto vec2 = [&](const char* key, glm::vec2* out) {
      if (!v.Has(key)) return;
      const tinygltf::Value& a = v.Get(key);
      if (a.IsArray() && a.ArrayLen() == 2 && a.Get(0).IsNumber() && a.Get(1).IsNumber())
        *out = glm::vec2(float(a.Get(0).GetNumberAsDouble()), float(a.Get(1).GetNumberAsDouble()));
    };
    vec2("offset", &ref->offset);
    vec2("scale", &ref->scale);
    if (v.Has("rotation") && v.Get("rotation").IsNumber()) ref->rotation = float(v.Get("rotation").GetNumberAsDouble());
    if (v.Has("texCoord") && v.Get("texCoord").IsNumber()) ref->texcoord = int(v.Get("texCoord").GetNumberAsDouble());
  }

  TextureRef Texture(int texture_index, int texcoord, const tinygltf::ExtensionMap& ext, const std::string& what) {
    TextureRef ref;
    if (texture_index < 0) return ref;
    if (std::size_t(texture_index) >= model_.textures.size())
      reader_.Fail(what + " refers to texture " + std::to_string(texture_index) + ", which does not exist");
    const int source = model_.textures[std::size_t(texture_index)].source;
    if (source < 0 || std::size_t(source) >= model_.images.size())
      reader_.Fail(what + " uses texture " + std::to_string(texture_index) + " with no image odvr can decode");
    ref.texcoord = texcoord;
    ReadTextureTransform(ext, &ref);
    if (ref.texcoord < 0 || ref.texcoord > 1)
      reader_.Fail(what + " uses TEXCOORD_" + std::to_string(ref.texcoord) + " (only 0 and 1 are read)");
    ref.image = Image(source, what);
    return ref;
  }

  int Image(int source, const std::string& what) {
    auto it = image_map_.find(source);
    if (it != image_map_.end()) return it->second;
    const tinygltf::Image& im = model_.images[std::size_t(source)];
    const std::string label = !im.uri.empty() ? "'" + im.uri + "'" : "image " + std::to_string(source);
    if (im.image.empty() || im.width <= 0 || im.height <= 0) {
      std::string reason = what + ": texture " + label + " could not be loaded";
      if (!warnings_.empty()) reason += " (" + warnings_ + ")";
      reader_.Fail(reason);
    }
    if (im.width > options_.max_texture_side || im.height > options_.max_texture_side)
      reader_.Fail(what + ": texture " + label + " is " + std::to_string(im.width) + "x" + std::to_string(im.height) +
                   ", above the limit of " + std::to_string(options_.max_texture_side) + " per side");
    const int comp = im.component, bytes = im.bits / 8;
    const std::size_t pixels = std::size_t(im.width) * std::size_t(im.height);
    if (comp < 1 || comp > 4 || (bytes != 1 && bytes != 2) || im.image.size() < pixels * std::size_t(comp * bytes))
      reader_.Fail(what + ": texture " + label + " has an unsupported pixel layout");
    TextureImage t;
    t.name = im.name.empty() ? (im.uri.empty() ? "image " + std::to_string(source) : im.uri) : im.name;
    t.uri = im.uri;
    t.width = im.width;
    t.height = im.height;
    t.rgba.resize(pixels * 4);
    for (std::size_t i = 0; i < pixels; ++i) {
      std::uint8_t c[4] = {0, 0, 0, 255};
      for (int k = 0; k < comp; ++k) {
        const std::size_t at = (i * std::size_t(comp) + std::size_t(k)) * std::size_t(bytes);
        // 16-bit samples are little-endian in tinygltf's buffer; keep the high byte.
        c[k] = bytes == 1 ? im.image[at] : im.image[at + 1];
      }
      if (comp <= 2) {  // grey (+ alpha)
        const std::uint8_t a = comp == 2 ? c[1] : 255;
        c[1] = c[2] = c[0];
        c[3] = a;
      }
      std::memcpy(&t.rgba[4 * i], c, 4);
    }
    const int index = int(scene_.images.size());
    scene_.images.push_back(std::move(t));
    image_map_[source] = index;
    return index;
  }

  PbrMaterial Material(int index) {
    const tinygltf::Material& m = model_.materials[std::size_t(index)];
    const std::string what = "material " + (m.name.empty() ? std::to_string(index) : "'" + m.name + "'");
    PbrMaterial out;
    out.name = m.name;
    const auto& pbr = m.pbrMetallicRoughness;
    if (pbr.baseColorFactor.size() == 4)
      out.base_color_factor = glm::vec4(float(pbr.baseColorFactor[0]), float(pbr.baseColorFactor[1]),
                                        float(pbr.baseColorFactor[2]), float(pbr.baseColorFactor[3]));
    out.metallic_factor = float(pbr.metallicFactor);
    out.roughness_factor = float(pbr.roughnessFactor);
    const auto finite01 = [](float x) { return std::isfinite(x) && x >= 0 && x <= 1; };
    if (!finite01(out.metallic_factor) || !finite01(out.roughness_factor) || !finite01(out.base_color_factor.r) ||
        !finite01(out.base_color_factor.g) || !finite01(out.base_color_factor.b) || !finite01(out.base_color_factor.a))
      reader_.Fail(what + " has a factor outside [0, 1]");
    out.base_color_texture = Texture(pbr.baseColorTexture.index, pbr.baseColorTexture.texCoord,
                                     pbr.baseColorTexture.extensions, what + " base colour");
    out.metallic_roughness_texture = Texture(pbr.metallicRoughnessTexture.index, pbr.metallicRoughnessTexture.texCoord,
                                             pbr.metallicRoughnessTexture.extensions, what + " metallic-roughness");
    out.normal_texture =
        Texture(m.normalTexture.index, m.normalTexture.texCoord, m.normalTexture.extensions, what + " normal");
    out.normal_scale = float(m.normalTexture.scale);
    if (m.emissiveFactor.size() == 3)
      out.emissive_factor =
          glm::vec3(float(m.emissiveFactor[0]), float(m.emissiveFactor[1]), float(m.emissiveFactor[2]));
    if (!finite01(out.emissive_factor.r) || !finite01(out.emissive_factor.g) || !finite01(out.emissive_factor.b))
      reader_.Fail(what + " has an emissive factor outside [0, 1]");
    out.emissive_texture =
        Texture(m.emissiveTexture.index, m.emissiveTexture.texCoord, m.emissiveTexture.extensions, what + " emissive");
    if (const auto strength = m.extensions.find("KHR_materials_emissive_strength"); strength != m.extensions.end()) {
      const tinygltf::Value& value = strength->second.Get("emissiveStrength");
      if (value.IsNumber()) out.emissive_strength = float(value.GetNumberAsDouble());
      if (!std::isfinite(out.emissive_strength) || out.emissive_strength < 0 || out.emissive_strength > 1e6f)
        reader_.Fail(what + " has an emissive strength outside [0, 1e6]");
    }
    // An extension's factor: absent keeps the default, anything but a number is an error.
    const auto read_factor = [&](const tinygltf::Value& ext, const std::string& key, float* value) {
      if (!ext.Has(key)) return;
      if (!ext.Get(key).IsNumber()) reader_.Fail(what + "'s " + key + " is not a number");
      *value = float(ext.Get(key).GetNumberAsDouble());
    };
    if (const auto sheen = m.extensions.find("KHR_materials_sheen"); sheen != m.extensions.end()) {
      if (sheen->second.Has("sheenColorFactor")) {
        const tinygltf::Value& color = sheen->second.Get("sheenColorFactor");
        if (!color.IsArray() || color.ArrayLen() != 3) reader_.Fail(what + "'s sheenColorFactor is not three numbers");
        for (int c = 0; c < 3; ++c) {
          if (!color.Get(c).IsNumber()) reader_.Fail(what + "'s sheenColorFactor is not three numbers");
          out.sheen_color[c] = float(color.Get(c).GetNumberAsDouble());
        }
      }
      read_factor(sheen->second, "sheenRoughnessFactor", &out.sheen_roughness);
      if (!finite01(out.sheen_color.r) || !finite01(out.sheen_color.g) || !finite01(out.sheen_color.b) ||
          !finite01(out.sheen_roughness))
        reader_.Fail(what + " has a sheen factor outside [0, 1]");
    }
    if (const auto t = m.extensions.find("KHR_materials_transmission"); t != m.extensions.end()) {
      read_factor(t->second, "transmissionFactor", &out.transmission);
      if (!finite01(out.transmission)) reader_.Fail(what + " has a transmission factor outside [0, 1]");
    }
    out.double_sided = m.doubleSided;
    if (m.alphaMode == "MASK") out.alpha_mode = PbrMaterial::AlphaMode::kMask;
    if (m.alphaMode == "BLEND") out.alpha_mode = PbrMaterial::AlphaMode::kBlend;
    out.alpha_cutoff = float(m.alphaCutoff);
    return out;
  }

  const tinygltf::Model& model_;
  const GltfLoadOptions& options_;
  Reader reader_;
  const std::string& warnings_;
  GltfScene scene_;
  std::map<int, int> image_map_;
  int default_material_ = -1;
  std::size_t total_triangles_ = 0, total_vertices_ = 0;
};

}  // namespace

GltfScene LoadGltfScene(const std::filesystem::path& path, const GltfLoadOptions& options) {
  options.Check();
  const std::string file = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw Error(file, "no such file");
  const auto file_size = std::filesystem::file_size(path, ec);
  if (ec) throw Error(file, "cannot read its size: " + ec.message());

  // The container is decided by the magic, not the extension: a renamed file still loads, and a
  // truncated GLB header gets a message of ours rather than a parser's.
  char magic[4] = {0, 0, 0, 0};
  {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(file, "cannot open");
    in.read(magic, 4);
  }
  const bool binary = std::memcmp(magic, "glTF", 4) == 0;
  if (binary && file_size < 20) throw Error(file, "truncated GLB: " + std::to_string(file_size) + " bytes");
  if (file_size == 0) throw Error(file, "empty file");

  tinygltf::TinyGLTF loader;
  ImageLoaderContext ctx{options.max_texture_side};
  loader.SetImageLoader(&LoadImageChecked, &ctx);
  tinygltf::Model model;
  std::string err, warn;
  const bool ok = binary ? loader.LoadBinaryFromFile(&model, &err, &warn, file)
                         : loader.LoadASCIIFromFile(&model, &err, &warn, file);
  const std::string err_line = OneLine(err), warn_line = OneLine(warn);
  if (!ok) {
    std::string reason = "not a loadable glTF file";
    if (!err_line.empty()) reason += ": " + err_line;
    if (!warn_line.empty()) reason += " (" + warn_line + ")";
    throw Error(file, reason);
  }
  for (const std::string& ext : model.extensionsRequired) {
    if (ext != "KHR_texture_transform" && ext != "KHR_materials_emissive_strength")
      throw Error(file, "requires the extension " + ext + ", which odvr does not support");
  }
  GltfScene scene = SceneBuilder(model, file, options, warn_line).Build(path);
  if (!scene.ignored_extensions.empty()) {
    static std::mutex mutex;
    static std::set<std::string> warned;
    const std::lock_guard<std::mutex> lock(mutex);
    if (warned.insert(file).second) {
      std::string names;
      for (const std::string& ext : scene.ignored_extensions) names += (names.empty() ? "" : ", ") + ext;
      spdlog::warn("{}: rendered without {} (those materials are shaded as their metallic-roughness alone)", file,
                   names);
    }
  }
  return scene;
}

}  // namespace odvr::scene
