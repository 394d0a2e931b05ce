#include "engine/scene/gltf_scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat4x4.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/error.h"

namespace odvr::scene {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kData = fs::path(ODVR_SHARED_DIR) / "data";

#define SKIP_IF_ABSENT(p) \
  if (!fs::exists(p)) GTEST_SKIP() << "shared test data absent: " << (p)

fs::path TempDir(const std::string& name) {
  const fs::path d = fs::path(testing::TempDir()) / ("odvr_gltf_scene_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::vector<char> ReadBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

void WriteBytes(const fs::path& p, const char* data, std::size_t n) {
  std::ofstream out(p, std::ios::binary);
  out.write(data, std::streamsize(n));
}

void WriteText(const fs::path& p, const std::string& s) { WriteBytes(p, s.data(), s.size()); }

// The JSON of a .gltf or of a .glb's first chunk: the test's own reading, independent of tinygltf.
json ReadGltfJson(const fs::path& p) {
  const auto bytes = ReadBytes(p);
  if (bytes.size() >= 20 && std::memcmp(bytes.data(), "glTF", 4) == 0) {
    std::uint32_t n;
    std::memcpy(&n, bytes.data() + 12, 4);
    return json::parse(bytes.begin() + 20, bytes.begin() + 20 + n);
  }
  return json::parse(bytes.begin(), bytes.end());
}

glm::dmat4 NodeMatrix(const json& node) {
  glm::dmat4 m(1.0);
  if (node.contains("matrix")) {
    for (int i = 0; i < 16; ++i) m[i / 4][i % 4] = node["matrix"][std::size_t(i)].get<double>();
    return m;
  }
  glm::dmat4 t(1.0), r(1.0), s(1.0);
  if (node.contains("translation")) {
    const auto& v = node["translation"];
    t[3] = glm::dvec4(v[0].get<double>(), v[1].get<double>(), v[2].get<double>(), 1);
  }
  if (node.contains("rotation")) {
    const auto& q = node["rotation"];
    r = glm::mat4_cast(
        glm::normalize(glm::dquat(q[3].get<double>(), q[0].get<double>(), q[1].get<double>(), q[2].get<double>())));
  }
  if (node.contains("scale")) {
    const auto& v = node["scale"];
    s = glm::scale(glm::dmat4(1.0), glm::dvec3(v[0].get<double>(), v[1].get<double>(), v[2].get<double>()));
  }
  return t * r * s;
}

// Expected triangle count and a box bound from the POSITION accessors' declared min/max, each
// box's corners taken through its node's world transform: independent of the loader's reading
// of the buffers. For axis-aligned rotations (all the models here) the box is exact.
struct Expected {
  std::size_t triangles = 0;
  glm::dvec3 min{1e300}, max{-1e300};
};

void VisitExpected(const json& j, int index, const glm::dmat4& parent, Expected* e) {
  const json& node = j["nodes"][std::size_t(index)];
  const glm::dmat4 world = parent * NodeMatrix(node);
  if (node.contains("mesh")) {
    for (const json& p : j["meshes"][node["mesh"].get<std::size_t>()]["primitives"]) {
      const json& pos = j["accessors"][p["attributes"]["POSITION"].get<std::size_t>()];
      const std::size_t count = p.contains("indices")
                                    ? j["accessors"][p["indices"].get<std::size_t>()]["count"].get<std::size_t>()
                                    : pos["count"].get<std::size_t>();
      e->triangles += count / 3;
      for (int c = 0; c < 8; ++c) {
        glm::dvec4 corner(1);
        for (int k = 0; k < 3; ++k) corner[k] = (c >> k & 1 ? pos["max"] : pos["min"])[std::size_t(k)].get<double>();
        const glm::dvec3 w(world * corner);
        e->min = glm::min(e->min, w);
        e->max = glm::max(e->max, w);
      }
    }
  }
  if (node.contains("children"))
    for (const json& c : node["children"]) VisitExpected(j, c.get<int>(), world, e);
}

Expected ExpectedFromJson(const fs::path& p) {
  const json j = ReadGltfJson(p);
  Expected e;
  for (const json& r : j["scenes"][j.value("scene", 0)]["nodes"]) VisitExpected(j, r.get<int>(), glm::dmat4(1.0), &e);
  return e;
}

void ExpectWellFormed(const GltfScene& s) {
  for (const auto& p : s.primitives) {
    ASSERT_EQ(p.indices.size() % 3, 0u) << p.name;
    ASSERT_EQ(p.normals.size(), p.positions.size()) << p.name;
    if (!p.uv0.empty()) {
      ASSERT_EQ(p.uv0.size(), p.positions.size()) << p.name;
    }
    if (!p.tangents.empty()) {
      ASSERT_EQ(p.tangents.size(), p.positions.size()) << p.name;
    }
    ASSERT_GE(p.material, 0);
    ASSERT_LT(std::size_t(p.material), s.materials.size());
    for (std::uint32_t i : p.indices) ASSERT_LT(i, p.positions.size()) << p.name;
    for (const auto& n : p.normals) ASSERT_NEAR(glm::length(n), 1.0f, 1e-4f) << p.name;
  }
  for (const auto& m : s.materials) {
    for (const TextureRef* t : {&m.base_color_texture, &m.metallic_roughness_texture, &m.normal_texture}) {
      if (!t->valid()) continue;
      ASSERT_LT(std::size_t(t->image), s.images.size());
      const auto& im = s.images[std::size_t(t->image)];
      ASSERT_GT(im.width, 0);
      ASSERT_EQ(im.rgba.size(), std::size_t(im.width) * std::size_t(im.height) * 4) << im.name;
    }
  }
}

void ExpectMatchesJson(const GltfScene& s, const fs::path& p, double box_tol) {
  const Expected e = ExpectedFromJson(p);
  EXPECT_EQ(s.triangle_count(), e.triangles);
  ASSERT_FALSE(s.bounds.empty());
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(s.bounds.min[k], e.min[k], box_tol) << "axis " << k;
    EXPECT_NEAR(s.bounds.max[k], e.max[k], box_tol) << "axis " << k;
  }
}

TEST(GltfScene, ToyCarLoadsWithTexturesAndToyScale) {
  const fs::path p = kData / "gltf/ToyCar.glb";
  SKIP_IF_ABSENT(p);
  const GltfScene s = LoadGltfScene(p);
  ExpectWellFormed(s);
  ExpectMatchesJson(s, p, 1e-5);
  EXPECT_GT(s.triangle_count(), 100000u);  // "109k triangles" in the data README
  // A toy: a few centimetres to decimetres long, Y up, so taller than nothing and not metres big.
  const glm::vec3 size = s.bounds.size();
  EXPECT_LT(std::max({size.x, size.y, size.z}), 0.5f);
  EXPECT_GT(size.y, 0.01f);
  ASSERT_EQ(s.materials.size(), 3u);
  EXPECT_EQ(s.materials[0].name, "ToyCar");
  EXPECT_TRUE(s.materials[0].base_color_texture.valid());
  EXPECT_TRUE(s.materials[0].metallic_roughness_texture.valid());
  // The textures are real pictures, not one flat colour.
  const auto& im = s.images[std::size_t(s.materials[0].base_color_texture.image)];
  std::uint8_t lo = 255, hi = 0;
  for (std::size_t i = 0; i < im.rgba.size(); i += 4) lo = std::min(lo, im.rgba[i]), hi = std::max(hi, im.rgba[i]);
  EXPECT_GT(hi - lo, 50);
}

TEST(GltfScene, KenneyPoliceReadsItsExternalTextureAndTangents) {
  const fs::path p = kData / "gltf/kenney/police/police.glb";
  SKIP_IF_ABSENT(p);
  const GltfScene s = LoadGltfScene(p);
  ExpectWellFormed(s);
  ExpectMatchesJson(s, p, 1e-5);
  EXPECT_EQ(s.primitives.size(), 6u);  // body, grill and four wheel instances
  ASSERT_EQ(s.materials.size(), 1u);
  const TextureRef& t = s.materials[0].base_color_texture;
  ASSERT_TRUE(t.valid());
  EXPECT_EQ(s.images[std::size_t(t.image)].uri, "Textures/colormap.png");
  EXPECT_EQ(s.images[std::size_t(t.image)].width, 512);
  for (const auto& prim : s.primitives) {
    EXPECT_FALSE(prim.tangents.empty()) << prim.name;
    EXPECT_FALSE(prim.uv0.empty()) << prim.name;
    EXPECT_FALSE(prim.normals_computed) << prim.name;
  }
  // A car on the ground, Y up, longest along Z.
  EXPECT_GT(s.bounds.size().z, s.bounds.size().y);
  EXPECT_NEAR(s.bounds.min.y, 0.0f, 0.05f);
}

TEST(GltfScene, DamagedHelmetHasAllPbrMaps) {
  const fs::path p = kData / "gltf/DamagedHelmet/DamagedHelmet.gltf";
  SKIP_IF_ABSENT(p);
  const GltfScene s = LoadGltfScene(p);
  ExpectWellFormed(s);
  ExpectMatchesJson(s, p, 1e-5);
  EXPECT_EQ(s.triangle_count(), 15452u);
  ASSERT_EQ(s.materials.size(), 1u);
  const PbrMaterial& m = s.materials[0];
  EXPECT_TRUE(m.base_color_texture.valid());
  EXPECT_TRUE(m.metallic_roughness_texture.valid());
  EXPECT_TRUE(m.normal_texture.valid());
  EXPECT_TRUE(m.emissive_texture.valid());
  EXPECT_EQ(s.images.size(), 4u);  // the AO map is not read
  for (const auto& im : s.images) EXPECT_EQ(im.width, 2048) << im.name;
  // The helmet's 90° node rotation about X turns its Z-up mesh Y-up: normals follow it, so the
  // mean normal of the top-most vertices points up.
  const auto& prim = s.primitives[0];
  glm::vec3 top_normal(0);
  for (std::size_t i = 0; i < prim.positions.size(); ++i)
    if (prim.positions[i].y > s.bounds.max.y - 0.02f * s.bounds.size().y) top_normal += prim.normals[i];
  EXPECT_GT(glm::normalize(top_normal).y, 0.7f);
}

TEST(GltfScene, StreetCarIsCarSizedWithEightMaterials) {
  const fs::path p = kData / "street_a/car.glb";
  SKIP_IF_ABSENT(p);
  const GltfScene s = LoadGltfScene(p);
  ExpectWellFormed(s);
  ExpectMatchesJson(s, p, 1e-4);
  EXPECT_EQ(s.materials.size(), 8u);
  EXPECT_EQ(s.materials[0].name, "CarPaint");
  const glm::vec3 size = s.bounds.size();
  const float length = std::max(size.x, size.z);
  EXPECT_GT(length, 3.0f);
  EXPECT_LT(length, 6.0f);
  EXPECT_GT(size.y, 1.0f);
  EXPECT_LT(size.y, 2.5f);
}

// --- Hand-written files -----------------------------------------------------------------------

std::string Base64(const std::vector<unsigned char>& in) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < in.size(); i += 3) {
    const std::uint32_t b = std::uint32_t(in[i]) << 16 | (i + 1 < in.size() ? std::uint32_t(in[i + 1]) << 8 : 0) |
                            (i + 2 < in.size() ? in[i + 2] : 0);
    out += k[b >> 18 & 63];
    out += k[b >> 12 & 63];
    out += i + 1 < in.size() ? k[b >> 6 & 63] : '=';
    out += i + 2 < in.size() ? k[b & 63] : '=';
  }
  return out;
}

template <class T>
void Append(std::vector<unsigned char>* buf, const std::vector<T>& v) {
  const auto* p = reinterpret_cast<const unsigned char*>(v.data());
  buf->insert(buf->end(), p, p + v.size() * sizeof(T));
}

// One quad (two triangles, in the z = 0 plane, CCW seen from +Z) without normals, under a parent
// node that mirrors X and a child that translates: the smallest file that exercises the
// hierarchy, the winding flip and the flat normals.
json QuadGltf() {
  std::vector<float> pos = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  std::vector<std::uint16_t> idx = {0, 1, 2, 0, 2, 3};
  std::vector<unsigned char> buf;
  Append(&buf, pos);
  Append(&buf, idx);
  json j;
  j["asset"] = {{"version", "2.0"}};
  j["buffers"] =
      json::array({{{"byteLength", buf.size()}, {"uri", "data:application/octet-stream;base64," + Base64(buf)}}});
  j["bufferViews"] = json::array({{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", 48}},
                                  {{"buffer", 0}, {"byteOffset", 48}, {"byteLength", 12}}});
  j["accessors"] = json::array({{{"bufferView", 0},
                                 {"componentType", 5126},
                                 {"count", 4},
                                 {"type", "VEC3"},
                                 {"min", {0, 0, 0}},
                                 {"max", {1, 1, 0}}},
                                {{"bufferView", 1}, {"componentType", 5123}, {"count", 6}, {"type", "SCALAR"}}});
  j["meshes"] = json::array({{{"primitives", json::array({{{"attributes", {{"POSITION", 0}}}, {"indices", 1}}})}}});
  j["nodes"] = json::array({{{"children", {1}}, {"scale", {-2, 1, 1}}}, {{"mesh", 0}, {"translation", {0, 0, 3}}}});
  j["scenes"] = json::array({{{"nodes", {0}}}});
  j["scene"] = 0;
  return j;
}

TEST(GltfScene, HierarchyMirrorsAndComputesFlatNormals) {
  const fs::path dir = TempDir("quad");
  const fs::path p = dir / "quad.gltf";
  WriteText(p, QuadGltf().dump());
  const GltfScene s = LoadGltfScene(p);
  ASSERT_EQ(s.primitives.size(), 1u);
  const auto& prim = s.primitives[0];
  EXPECT_EQ(prim.triangle_count(), 2u);
  EXPECT_TRUE(prim.normals_computed);
  EXPECT_EQ(prim.positions.size(), 6u);  // unwelded for flat normals
  // world = scale(-2,1,1) · translate(0,0,3): x ∈ [−2, 0], z = 3.
  EXPECT_FLOAT_EQ(s.bounds.min.x, -2.0f);
  EXPECT_FLOAT_EQ(s.bounds.max.x, 0.0f);
  EXPECT_FLOAT_EQ(s.bounds.min.z, 3.0f);
  EXPECT_FLOAT_EQ(s.bounds.max.z, 3.0f);
  // A mirror keeps the face pointing to +Z (the side it faced) only if the winding is flipped:
  // the geometric normal from the stored winding must agree with the stored normal.
  for (std::size_t t = 0; t < prim.indices.size(); t += 3) {
    const glm::vec3 a = prim.positions[prim.indices[t]], b = prim.positions[prim.indices[t + 1]],
                    c = prim.positions[prim.indices[t + 2]];
    const glm::vec3 g = glm::normalize(glm::cross(b - a, c - a));
    EXPECT_NEAR(g.z, 1.0f, 1e-6f);
    EXPECT_NEAR(prim.normals[prim.indices[t]].z, 1.0f, 1e-6f);
  }
  EXPECT_EQ(s.materials.size(), 1u);  // the spec's default material, added for the primitive
  EXPECT_FLOAT_EQ(s.materials[0].roughness_factor, 1.0f);
}

TEST(GltfScene, TriangleStripIsUnrolledCounterClockwise) {
  json j = QuadGltf();
  j["nodes"] = json::array({{{"mesh", 0}}});
  j["scenes"][0]["nodes"] = {0};
  j["accessors"][1]["count"] = 4;  // strip 0 1 2 0 → triangles (0 1 2), (2 1 0)
  j["meshes"][0]["primitives"][0]["mode"] = 5;
  const fs::path dir = TempDir("strip");
  WriteText(dir / "strip.gltf", j.dump());
  const GltfScene s = LoadGltfScene(dir / "strip.gltf");
  ASSERT_EQ(s.primitives.size(), 1u);
  EXPECT_EQ(s.primitives[0].triangle_count(), 2u);
}

// Every failure: an odvr::Error whose message is one line that names the file and contains
// `expect` (case-sensitive), and no crash on the way (the suite runs under ASan in CI).
void ExpectLoadError(const fs::path& p, const std::string& expect, const GltfLoadOptions& options = {}) {
  try {
    LoadGltfScene(p, options);
    ADD_FAILURE() << "loaded " << p << " without error";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_EQ(e.where(), p.string());
    EXPECT_NE(msg.find(p.string()), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    EXPECT_NE(msg.find(expect), std::string::npos) << msg;
    std::cout << "  [expected error] " << msg << "\n";
  }
}

TEST(GltfScene, MissingFileIsAnError) { ExpectLoadError(TempDir("missing") / "nothing.glb", "no such file"); }

TEST(GltfScene, TruncatedGlbIsAnErrorAtEveryCut) {
  const fs::path src = kData / "street_a/car.glb";
  SKIP_IF_ABSENT(src);
  const auto bytes = ReadBytes(src);
  const fs::path dir = TempDir("truncated");
  for (std::size_t cut : {std::size_t(3), std::size_t(12), std::size_t(19), std::size_t(20), std::size_t(100),
                          std::size_t(2000), bytes.size() / 2, bytes.size() - 1}) {
    const fs::path p = dir / ("cut_" + std::to_string(cut) + ".glb");
    WriteBytes(p, bytes.data(), cut);
    ExpectLoadError(p, "");
  }
}

TEST(GltfScene, BadJsonIsAnError) {
  const fs::path dir = TempDir("badjson");
  WriteText(dir / "bad.gltf", R"({"asset": {"version": "2.0"}, "meshes": [ {"primitives": )");
  ExpectLoadError(dir / "bad.gltf", "not a loadable glTF file");
  WriteText(dir / "empty.gltf", "");
  ExpectLoadError(dir / "empty.gltf", "empty");
}

TEST(GltfScene, EmissionIsTheFactorTimesItsStrengthAndOutOfRangeIsAnError) {
  // The demo car's lamps: emissiveFactor, and KHR_materials_emissive_strength for brighter ones.
  const fs::path dir = TempDir("emissive");
  json j = QuadGltf();
  j["materials"] = json::array({{{"name", "lamp"}, {"emissiveFactor", {1.0, 0.5, 0.25}}},
                                {{"name", "bright"},
                                 {"emissiveFactor", {0.5, 0.5, 0.5}},
                                 {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 8.0}}}}}},
                                {{"name", "plain"}}});
  j["extensionsUsed"] = {"KHR_materials_emissive_strength"};
  WriteText(dir / "lamps.gltf", j.dump());
  const GltfScene s = LoadGltfScene(dir / "lamps.gltf");
  ASSERT_GE(s.materials.size(), 3u);
  EXPECT_EQ(s.materials[0].emission(), glm::vec3(1.0f, 0.5f, 0.25f));
  EXPECT_EQ(s.materials[1].emission(), glm::vec3(4.0f));
  EXPECT_EQ(s.materials[2].emission(), glm::vec3(0.0f));
  j["materials"][0]["emissiveFactor"] = {1.5, 0.0, 0.0};
  WriteText(dir / "factor.gltf", j.dump());
  ExpectLoadError(dir / "factor.gltf", "material 'lamp' has an emissive factor outside [0, 1]");
  j["materials"][0]["emissiveFactor"] = {1.0, 0.0, 0.0};
  j["materials"][1]["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"] = -2.0;
  WriteText(dir / "strength.gltf", j.dump());
  ExpectLoadError(dir / "strength.gltf", "material 'bright' has an emissive strength outside [0, 1e6]");
}

// KHR_materials_sheen's factors are read (the fabric of Khronos' ToyCar: red, roughness 0.5), and
// KHR_materials_transmission's; out of [0, 1] is an error; the extensions odvr renders without
// are listed.
TEST(GltfScene, SheenFactorsAreReadAndIgnoredExtensionsListed) {
  const fs::path dir = TempDir("sheen");
  json j = QuadGltf();
  j["materials"] = json::array(
      {{{"name", "cloth"},
        {"extensions",
         {{"KHR_materials_sheen", {{"sheenColorFactor", {1.0, 0.0, 0.0}}, {"sheenRoughnessFactor", 0.5}}}}}},
       {{"name", "coat"}, {"extensions", {{"KHR_materials_clearcoat", {{"clearcoatFactor", 1.0}}}}}},
       {{"name", "glass"}, {"extensions", {{"KHR_materials_transmission", {{"transmissionFactor", 0.75}}}}}}});
  j["extensionsUsed"] = {"KHR_materials_sheen", "KHR_materials_clearcoat", "KHR_materials_transmission"};
  WriteText(dir / "cloth.gltf", j.dump());
  const GltfScene s = LoadGltfScene(dir / "cloth.gltf");
  ASSERT_GE(s.materials.size(), 3u);
  EXPECT_EQ(s.materials[0].sheen_color, glm::vec3(1.0f, 0.0f, 0.0f));
  EXPECT_EQ(s.materials[0].sheen_roughness, 0.5f);
  EXPECT_EQ(s.materials[2].sheen_color, glm::vec3(0.0f));
  EXPECT_EQ(s.materials[2].transmission, 0.75f);
  EXPECT_EQ(s.materials[0].transmission, 0.0f);
  EXPECT_EQ(s.ignored_extensions, std::vector<std::string>{"KHR_materials_clearcoat"});
  j["materials"][0]["extensions"]["KHR_materials_sheen"]["sheenRoughnessFactor"] = 1.5;
  WriteText(dir / "rough.gltf", j.dump());
  ExpectLoadError(dir / "rough.gltf", "material 'cloth' has a sheen factor outside [0, 1]");
  j["materials"][0]["extensions"]["KHR_materials_sheen"]["sheenRoughnessFactor"] = "rough";
  WriteText(dir / "word.gltf", j.dump());
  ExpectLoadError(dir / "word.gltf", "material 'cloth''s sheenRoughnessFactor is not a number");
  j["materials"][0]["extensions"]["KHR_materials_sheen"]["sheenRoughnessFactor"] = 0.5;
  j["materials"][0]["extensions"]["KHR_materials_sheen"]["sheenColorFactor"] = {1.0, 0.0};
  WriteText(dir / "two.gltf", j.dump());
  ExpectLoadError(dir / "two.gltf", "material 'cloth''s sheenColorFactor is not three numbers");
  j["materials"][0]["extensions"]["KHR_materials_sheen"]["sheenColorFactor"] = {1.0, 0.0, 0.0};
  j["materials"][2]["extensions"]["KHR_materials_transmission"]["transmissionFactor"] = 2.0;
  WriteText(dir / "glass.gltf", j.dump());
  ExpectLoadError(dir / "glass.gltf", "material 'glass' has a transmission factor outside [0, 1]");
}

TEST(GltfScene, MissingExternalTextureNamesTheTexture) {
  const fs::path src = kData / "gltf/kenney/police/police.glb";
  SKIP_IF_ABSENT(src);
  const fs::path dir = TempDir("notexture");
  fs::copy_file(src, dir / "police.glb");  // without its Textures/ folder
  ExpectLoadError(dir / "police.glb", "Textures/colormap.png");
}

TEST(GltfScene, AccessorBeyondItsBufferIsAnError) {
  json j = QuadGltf();
  j["accessors"][0]["count"] = 1000000;
  const fs::path dir = TempDir("accessor");
  WriteText(dir / "big_count.gltf", j.dump());
  ExpectLoadError(dir / "big_count.gltf", "beyond its buffer view");

  j = QuadGltf();
  j["bufferViews"][1]["byteLength"] = 4000;  // the view runs past the 60-byte buffer
  WriteText(dir / "big_view.gltf", j.dump());
  ExpectLoadError(dir / "big_view.gltf", "");

  j = QuadGltf();
  j["accessors"][1]["byteOffset"] = std::uint64_t(18446744073709551000u);  // near 2^64: overflow bait
  WriteText(dir / "huge_offset.gltf", j.dump());
  ExpectLoadError(dir / "huge_offset.gltf", "");
}

TEST(GltfScene, IndexBeyondTheVerticesIsAnError) {
  json j = QuadGltf();
  std::vector<float> pos = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  std::vector<std::uint16_t> idx = {0, 1, 2, 0, 2, 9};
  std::vector<unsigned char> buf;
  Append(&buf, pos);
  Append(&buf, idx);
  j["buffers"][0]["uri"] = "data:application/octet-stream;base64," + Base64(buf);
  const fs::path dir = TempDir("index");
  WriteText(dir / "index.gltf", j.dump());
  ExpectLoadError(dir / "index.gltf", "index 9");
}

TEST(GltfScene, LinesAreRefused) {
  json j = QuadGltf();
  j["meshes"][0]["primitives"][0]["mode"] = 1;
  const fs::path dir = TempDir("lines");
  WriteText(dir / "lines.gltf", j.dump());
  ExpectLoadError(dir / "lines.gltf", "only triangles");
}

TEST(GltfScene, NodeCycleIsAnError) {
  json j = QuadGltf();
  j["nodes"][1]["children"] = {0};
  const fs::path dir = TempDir("cycle");
  WriteText(dir / "cycle.gltf", j.dump());
  ExpectLoadError(dir / "cycle.gltf", "ancestor");
}

// Models that would render a picture with no car in it, each an error naming the file and why.
TEST(GltfScene, AModelThatDrawsNothingIsAnError) {
  const fs::path dir = TempDir("nothing");
  json j = QuadGltf();
  j["scenes"][0]["nodes"] = json::array();  // a scene of no nodes
  WriteText(dir / "no_nodes.gltf", j.dump());
  ExpectLoadError(dir / "no_nodes.gltf", "holds no triangles to draw");
  j = QuadGltf();
  j["nodes"][1].erase("mesh");  // nodes, but no mesh on any
  WriteText(dir / "no_mesh.gltf", j.dump());
  ExpectLoadError(dir / "no_mesh.gltf", "holds no triangles to draw");
  j = QuadGltf();
  j["accessors"][1]["count"] = 2;  // fewer indices than one triangle
  WriteText(dir / "two_indices.gltf", j.dump());
  ExpectLoadError(dir / "two_indices.gltf", "holds no triangles to draw");
  j = QuadGltf();
  j["nodes"][0]["scale"] = {0, 0, 0};  // every vertex on one point
  WriteText(dir / "point.gltf", j.dump());
  ExpectLoadError(dir / "point.gltf", "is a single point");
}

TEST(GltfScene, AVertexFarOffIsAnErrorNamingIt) {
  // One flipped exponent bit: vertex 2's x becomes 1e38 (the fuzzer's mutant that showed no car).
  json j = QuadGltf();
  std::vector<float> pos = {0, 0, 0, 1, 0, 0, 1e38f, 1, 0, 0, 1, 0};
  std::vector<std::uint16_t> idx = {0, 1, 2, 0, 2, 3};
  std::vector<unsigned char> buf;
  Append(&buf, pos);
  Append(&buf, idx);
  j["buffers"][0]["uri"] = "data:application/octet-stream;base64," + Base64(buf);
  const fs::path dir = TempDir("far");
  WriteText(dir / "far.gltf", j.dump());
  ExpectLoadError(dir / "far.gltf", "POSITION 2 lies at (-2e+38, 1, 3) m, beyond 1e+05 m of the origin");
  // A scale that is not metres (millimetres read as metres: 2 km across) passes the default and
  // is refused by a tighter limit.
  j = QuadGltf();
  j["nodes"][0]["scale"] = {-2000, 1000, 1000};
  WriteText(dir / "km.gltf", j.dump());
  EXPECT_NO_THROW(LoadGltfScene(dir / "km.gltf"));
  GltfLoadOptions o;
  o.max_coordinate_m = 100;
  ExpectLoadError(dir / "km.gltf", "beyond 100 m of the origin", o);
}

TEST(GltfScene, TriangleCapIsEnforced) {
  const fs::path src = kData / "gltf/ToyCar.glb";
  SKIP_IF_ABSENT(src);
  GltfLoadOptions o;
  o.max_triangles = 1000;
  ExpectLoadError(src, "more than 1000 triangles", o);
}

TEST(GltfScene, ImageClaimingAbsurdSizeIsRefusedBeforeDecoding) {
  // A PNG signature and IHDR claiming 100000 × 100000 pixels: stb would try to allocate 40 GB.
  std::vector<unsigned char> png = {0x89, 'P',  'N',  'G', '\r', '\n', 0x1a, '\n', 0, 0, 0, 13, 'I', 'H', 'D', 'R', 0,
                                    1,    0x86, 0xa0, 0,   1,    0x86, 0xa0, 8,    6, 0, 0, 0,  0,   0,   0,   0};
  json j = QuadGltf();
  j["images"] = json::array({{{"uri", "data:image/png;base64," + Base64(png)}}});
  j["textures"] = json::array({{{"source", 0}}});
  j["materials"] = json::array({{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}});
  j["meshes"][0]["primitives"][0]["material"] = 0;
  const fs::path dir = TempDir("hugeimage");
  WriteText(dir / "huge.gltf", j.dump());
  ExpectLoadError(dir / "huge.gltf", "100000x100000");
}

TEST(GltfScene, OptionsAreChecked) {
  GltfLoadOptions o;
  o.max_texture_side = 0;
  EXPECT_THROW(o.Check(), Error);
  o = {};
  o.max_coordinate_m = std::nan("");
  EXPECT_THROW(o.Check(), Error);
}

}  // namespace
}  // namespace odvr::scene
