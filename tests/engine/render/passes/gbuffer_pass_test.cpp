// The G-buffer pass: its clip transform projects a point to the pixel whose ray passes through it;
// each covered pixel holds the nearest surface on its ray, its material, its normal and the
// emission it was given; nothing is drawn without the model; a normal map bends the normal in the
// frame of the mesh's tangents, or of its UVs where it has none.
#include "engine/render/passes/gbuffer_pass.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <random>
#include <string>
#include <vector>

#include "tests/engine/gl/gl_test_context.h"
#include "tests/engine/render/render_test_scenes.h"

namespace odvr::render {
namespace {

using GbufferPassGL = odvr::testing::GlTest;
using odvr::testing::View;

TEST(GbufferPass, ClipFromWorldProjectsAPointOntoItsPixelsRay) {
  const PinholeCamera camera = View(96, 64);
  scene::Bounds bounds;
  bounds.Extend({-1, 0, -1});
  bounds.Extend({1, 1.2f, 1});
  const glm::dmat4 clip(ClipFromWorld(camera, bounds));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < 100; ++i) {
    const glm::dvec3 p(-1 + 2 * u(rng), 1.2 * u(rng), -1 + 2 * u(rng));
    const glm::dvec4 c = clip * glm::dvec4(p, 1);
    ASSERT_GT(c.w, 0);
    const glm::dvec3 ndc = glm::dvec3(c) / c.w;
    EXPECT_GT(ndc.z, -1);  // between the near and far planes fitted to the bounds
    EXPECT_LT(ndc.z, 1);
    // NDC y grows with the image's rows (the G-buffer's first row is the image's top).
    const double x = (ndc.x + 1) / 2 * camera.width, y = (ndc.y + 1) / 2 * camera.height;
    const glm::dvec3 ray = camera.Ray(x, y), to_p = glm::normalize(p - camera.position);
    EXPECT_GT(glm::dot(ray, to_p), 1 - 1e-9) << i;
  }
}

TEST_F(GbufferPassGL, EachPixelHoldsTheNearestSurfaceOnItsRay) {
  scene::GltfScene source = odvr::testing::SphereAndBox();  // sphere r 0.5 at (0, 0.5, 0); box
  source.materials[1].emissive_factor = glm::vec3(1, 2, 3);
  const GpuModel model(source, glm::dmat4(1.0));
  GpuMaterials materials;
  materials.Set(model.materials(), {});
  const RenderOptions o;
  GBufferPass pass;
  RenderTargets targets;
  for (const bool geometry : {true, false}) {
    const RenderFrame fr = RenderFrame::Make(o, View(), ShadeDevice::kGpu, geometry, {0, 0});
    targets.Ensure(fr);
    pass.Run(fr, model, materials, targets);
    const detail::GBuffer g = targets.ReadGBuffer();
    ASSERT_EQ(g.width, fr.sw);
    int sphere = 0, box = 0;
    double off_ray = 0, off_sphere = 0, normal_cos = 1, emission_error = 0;
    for (int y = 0; y < g.height; ++y)
      for (int x = 0; x < g.width; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * g.width + x;
        const float material = g.position[4 * i + 3];
        if (material == 0) continue;
        const glm::dvec3 p(g.position[4 * i], g.position[4 * i + 1], g.position[4 * i + 2]);
        const glm::dvec3 n(g.normal[4 * i], g.normal[4 * i + 1], g.normal[4 * i + 2]);
        const glm::dvec3 e(g.emission[4 * i], g.emission[4 * i + 1], g.emission[4 * i + 2]);
        const glm::dvec3 ray = fr.shaded_camera.Ray(x + 0.5, y + 0.5), to_p = p - fr.shaded_camera.position;
        off_ray = std::max(off_ray, glm::length(glm::cross(ray, to_p)));
        if (material == 1) {
          ++sphere;
          const glm::dvec3 radial = p - glm::dvec3(0, 0.5, 0);
          off_sphere = std::max(off_sphere, std::abs(glm::length(radial) - 0.5));
          normal_cos = std::min(normal_cos, glm::dot(glm::normalize(n), glm::normalize(radial)));
          emission_error = std::max(emission_error, glm::length(e));
        } else {
          ++box;
          emission_error = std::max(emission_error, glm::length(e - glm::dvec3(1, 2, 3)));
        }
      }
    if (!geometry) {
      EXPECT_EQ(sphere + box, 0);
      continue;
    }
    EXPECT_GT(sphere, 300);
    EXPECT_GT(box, 200);
    EXPECT_LT(off_ray, 1e-3);     // on the pixel's own ray
    EXPECT_LT(off_sphere, 6e-3);  // within the 24-stack tessellation of the sphere
    EXPECT_GT(normal_cos, 0.99);  // interpolated normals, radial
    EXPECT_LT(emission_error, 1e-6);
  }
}

// A floor quad (normal +y) whose UVs run along +x and +z, or mirrored along −x, with a normal map
// of one texel tilted toward the map's +x and +y. glTF's frame: t along ∂p/∂u, b = n × t against
// ∂p/∂v (the map's +y is −v), flipped with the layout.
scene::GltfScene NormalMappedFloor(bool tangents, bool mirrored, const glm::vec3& tn) {
  scene::GltfScene s;
  scene::PbrMaterial m = odvr::testing::Pbr("floor", glm::vec3(0.5f), 0.f, 0.5f);
  m.normal_texture.image = 0;
  s.materials = {m};
  scene::TextureImage image;
  image.width = image.height = 2;
  for (int i = 0; i < 4; ++i)
    for (int c = 0; c < 3; ++c)
      image.rgba.push_back(static_cast<std::uint8_t>(std::lround((tn[c] * 0.5f + 0.5f) * 255.f)));
  for (int i = 0; i < 4; ++i) image.rgba.insert(image.rgba.begin() + 4 * i + 3, 255);
  s.images = {image};
  scene::ScenePrimitive p;
  p.positions = {{-1, 0, -1}, {-1, 0, 1}, {1, 0, 1}, {1, 0, -1}};
  p.normals.assign(4, glm::vec3(0, 1, 0));
  for (const auto& q : p.positions) p.uv0.emplace_back(mirrored ? (1 - q.x) / 2 : (q.x + 1) / 2, (q.z + 1) / 2);
  if (tangents) p.tangents.assign(4, glm::vec4(mirrored ? -1 : 1, 0, 0, mirrored ? -1 : 1));
  p.indices = {0, 1, 2, 0, 2, 3};
  s.primitives = {p};
  odvr::testing::Finish(&s);
  return s;
}

// Under an override the surface is the override's: no normal map (as the Cycles references'
// paints have none).
TEST_F(GbufferPassGL, ANormalMapWithoutTangentsTakesTheFrameItsUvsGive) {
  const glm::vec3 tn = glm::normalize(glm::vec3(0.5f, 0.3f, 0.81f));
  RenderOptions o;
  o.valid_reflection_normals = false;  // the map's normal as it is
  GBufferPass pass;
  RenderTargets targets;
  for (const bool mirrored : {false, true})
    for (const bool tangents : {true, false})
      for (const bool overridden : {false, true}) {
        SCOPED_TRACE(std::string(mirrored ? "mirrored" : "plain") + (tangents ? ", tangents" : ", none") +
                     (overridden ? ", overridden" : ""));
        std::vector<MaterialOverride> overrides;
        if (overridden) overrides.push_back({"", {material::Lambertian{}}});
        const scene::GltfScene source = NormalMappedFloor(tangents, mirrored, tn);
        const GpuModel model(source, glm::dmat4(1.0));
        const RenderFrame fr = RenderFrame::Make(o, View(), ShadeDevice::kGpu, true, {0, 0});
        targets.Ensure(fr);
        GpuMaterials materials;
        materials.Set(model.materials(), overrides);
        pass.Run(fr, model, materials, targets);
        const detail::GBuffer g = targets.ReadGBuffer();
        // t along ∂p/∂u: +x, or −x mirrored; b = −z (against ∂p/∂v = +z) in both layouts.
        const glm::dvec3 t(mirrored ? -1 : 1, 0, 0), b(0, 0, -1), n(0, 1, 0);
        const glm::dvec3 expected =
            overridden ? n : glm::normalize(double(tn.x) * t + double(tn.y) * b + double(tn.z) * n);
        int covered = 0;
        double worst = 0;
        for (std::size_t i = 0; i < g.position.size() / 4; ++i) {
          if (g.position[4 * i + 3] == 0) continue;
          ++covered;
          const glm::dvec3 got(g.normal[4 * i], g.normal[4 * i + 1], g.normal[4 * i + 2]);
          worst = std::max(worst, glm::length(got - expected));
        }
        EXPECT_GT(covered, 1000);
        EXPECT_LT(worst, 0.02);  // the map's 8-bit texel
      }
}

}  // namespace
}  // namespace odvr::render
