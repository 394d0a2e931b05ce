#include "engine/visibility/triangle_bvh.h"

#include <gtest/gtest.h>

#include <glm/geometric.hpp>
#include <random>

#include "core/error.h"
#include "tests/engine/visibility/test_meshes.h"

namespace odvr::visibility {
namespace {

bool BruteForce(const std::vector<glm::vec3>& v, const glm::vec3& o, const glm::vec3& d, float t_min, float t_max) {
  for (std::size_t i = 0; i < v.size(); i += 3) {
    const TriangleBvh one(std::span<const glm::vec3>(v).subspan(i, 3));
    if (one.Occluded(o, d, t_min, t_max)) return true;
  }
  return false;
}

// Six spheres (and, with `boxes`, a box beside each) scattered in [-1, 1]³ so that rays pass
// between, graze and hit them.
std::vector<glm::vec3> ScatteredMesh(std::mt19937& rng, bool boxes) {
  std::vector<glm::vec3> mesh;
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  for (int i = 0; i < 6; ++i) {
    const glm::vec3 c(u(rng), u(rng), u(rng));
    auto s = testing::SphereMesh(c, 0.15f + 0.1f * std::abs(u(rng)), 8, 12);
    mesh.insert(mesh.end(), s.begin(), s.end());
    if (!boxes) continue;
    auto b = testing::BoxMesh(c + glm::vec3(0.3f, 0, 0), c + glm::vec3(0.4f, 0.2f, 0.05f));
    mesh.insert(mesh.end(), b.begin(), b.end());
  }
  return mesh;
}

TEST(TriangleBvh, AgreesWithEveryTriangleTestedAlone) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  const std::vector<glm::vec3> mesh = ScatteredMesh(rng, true);
  const TriangleBvh bvh(mesh);
  ASSERT_EQ(bvh.triangle_count(), mesh.size() / 3);
  int hits = 0, misses = 0;
  for (int i = 0; i < 2000; ++i) {
    const glm::vec3 o(1.5f * u(rng), 1.5f * u(rng), 1.5f * u(rng));
    // Aimed near a random vertex: about as many hits as misses, many of them grazing.
    const glm::vec3 target =
        mesh[static_cast<std::size_t>(i * 7919) % mesh.size()] + 0.1f * glm::vec3(u(rng), u(rng), u(rng));
    const glm::vec3 d = glm::normalize(target - o);
    const float t_max = i % 2 ? 1e30f : 1.f + u(rng);
    const bool expected = BruteForce(mesh, o, d, 0.f, t_max);
    EXPECT_EQ(bvh.Occluded(o, d, 0.f, t_max), expected) << "ray " << i;
    (expected ? hits : misses) += 1;
  }
  // Both outcomes are common, so the agreement says something.
  EXPECT_GT(hits, 200);
  EXPECT_GT(misses, 200);
}

// ClosestHit: the nearest of the triangles tested alone, its t and barycentrics giving back the
// hit point, and no hit exactly where Occluded finds none.
TEST(TriangleBvh, ClosestHitIsTheNearestOfEveryTriangle) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  const std::vector<glm::vec3> mesh = ScatteredMesh(rng, false);
  const TriangleBvh bvh(mesh);
  int hits = 0;
  for (int i = 0; i < 1000; ++i) {
    const glm::vec3 o(1.5f * u(rng), 1.5f * u(rng), 1.5f * u(rng));
    const glm::vec3 d = glm::normalize(mesh[static_cast<std::size_t>(i * 7919) % mesh.size()] - o +
                                       0.1f * glm::vec3(u(rng), u(rng), u(rng)));
    // The nearest t by testing ever shorter intervals against each triangle alone.
    float nearest = 1e30f;
    for (std::size_t k = 0; k < mesh.size(); k += 3) {
      const TriangleBvh one(std::span<const glm::vec3>(mesh).subspan(k, 3));
      TriangleBvh::Hit h;
      if (one.ClosestHit(o, d, 0.f, nearest, &h)) nearest = h.t;
    }
    TriangleBvh::Hit hit;
    const bool found = bvh.ClosestHit(o, d, 0.f, 1e30f, &hit);
    ASSERT_EQ(found, bvh.Occluded(o, d, 0.f, 1e30f)) << "ray " << i;
    if (!found) continue;
    ++hits;
    EXPECT_NEAR(hit.t, nearest, 1e-5f * std::max(1.f, nearest)) << "ray " << i;
    const std::size_t v = 3 * static_cast<std::size_t>(hit.triangle);
    const glm::vec3 a(bvh.triangles()[v]), b(bvh.triangles()[v + 1]), c(bvh.triangles()[v + 2]);
    const glm::vec3 at = (1.f - hit.u - hit.v) * a + hit.u * b + hit.v * c;
    EXPECT_LT(glm::length(at - (o + hit.t * d)), 1e-4f) << "ray " << i;
    // source_triangles() names the input triangle with those vertices.
    const std::size_t src =
        3 * static_cast<std::size_t>(bvh.source_triangles()[static_cast<std::size_t>(hit.triangle)]);
    EXPECT_EQ(mesh[src], a) << "ray " << i;
  }
  EXPECT_GT(hits, 200);
}

TEST(TriangleBvh, RespectsTheRaysInterval) {
  const auto quad = testing::QuadMesh(glm::vec3(0, 0, 1), glm::vec3(1, 0, 0), glm::vec3(0, 1, 0), 1.f);
  const TriangleBvh bvh(quad);
  EXPECT_TRUE(bvh.Occluded(glm::vec3(0), glm::vec3(0, 0, 1), 0.f, 2.f));
  EXPECT_FALSE(bvh.Occluded(glm::vec3(0), glm::vec3(0, 0, 1), 0.f, 0.9f));          // stops short
  EXPECT_FALSE(bvh.Occluded(glm::vec3(0), glm::vec3(0, 0, 1), 1.1f, 2.f));          // starts past it
  EXPECT_FALSE(bvh.Occluded(glm::vec3(0), glm::vec3(0, 0, -1), 0.f, 2.f));          // away from it
  EXPECT_TRUE(bvh.Occluded(glm::vec3(0, 0, 2), glm::vec3(0, 0, -1), 0.f, 2.f));     // its back side
  EXPECT_FALSE(bvh.Occluded(glm::vec3(0.6f, 0, 0), glm::vec3(0, 0, 1), 0.f, 2.f));  // beside it
}

TEST(TriangleBvh, EmptyAndBadInput) {
  const TriangleBvh empty(std::vector<glm::vec3>{});
  EXPECT_EQ(empty.triangle_count(), 0u);
  EXPECT_FALSE(empty.Occluded(glm::vec3(0), glm::vec3(0, 0, 1), 0.f, 1e30f));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<glm::vec3> with_nan = {{0, 0, 1}, {1, 0, 1}, {0, nan, 1}};
  EXPECT_EQ(TriangleBvh(with_nan).triangle_count(), 0u);
  const std::vector<glm::vec3> partial = {{0, 0, 1}, {1, 0, 1}};
  try {
    TriangleBvh bad(partial);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("whole number of triangles"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace odvr::visibility
