// The CPU voxelizer, mips and cone tracer against independent geometry: the box shell worked
// out from interval logic, closed surfaces with no gaps (flood fill), marked voxels near their
// triangle, axis opacities of a sheet, and physical cone checks (a slab above, a box beside, a
// wall half across a cone, cones leaving a surface).
#include "engine/visibility/voxel_grid.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <queue>
#include <random>

#include "core/error.h"
#include "tests/engine/visibility/test_meshes.h"

namespace odvr::visibility {
namespace {

using odvr::testing::BoxMesh;
using odvr::testing::QuadMesh;
using odvr::testing::SphereMesh;

// Voxel units: the grid is [0, R]³ with unit voxels.
VoxelGridSpec UnitSpec(int resolution) {
  VoxelGridSpec s;
  s.resolution = resolution;
  return s;
}

bool Marked(const VoxelGrid& g, int x, int y, int z) {
  const int r = g.spec().resolution;
  return g.Level(0)[static_cast<std::size_t>(x + r * (y + r * z))] != 0;
}

// Voxels reachable from the grid's corner through unmarked 6-neighbours.
std::vector<char> OutsideFill(const VoxelGrid& g) {
  const int r = g.spec().resolution;
  std::vector<char> seen(static_cast<std::size_t>(r) * r * r, 0);
  std::queue<glm::ivec3> todo;
  todo.push({0, 0, 0});
  seen[0] = 1;
  while (!todo.empty()) {
    const glm::ivec3 p = todo.front();
    todo.pop();
    for (int k = 0; k < 6; ++k) {
      glm::ivec3 q = p;
      q[k / 2] += (k % 2) ? 1 : -1;
      if (glm::any(glm::lessThan(q, glm::ivec3(0))) || glm::any(glm::greaterThanEqual(q, glm::ivec3(r)))) continue;
      const std::size_t i = static_cast<std::size_t>(q.x + r * (q.y + r * q.z));
      if (seen[i] || Marked(g, q.x, q.y, q.z)) continue;
      seen[i] = 1;
      todo.push(q);
    }
  }
  return seen;
}

// Distance from p to triangle abc (Ericson, Real-Time Collision Detection 5.1.5).
double PointTriangleDistance(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  const glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return glm::length(p - a);
  const glm::dvec3 bp = p - b;
  const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return glm::length(p - b);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return glm::length(p - (a + d1 / (d1 - d3) * ab));
  const glm::dvec3 cp = p - c;
  const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return glm::length(p - c);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return glm::length(p - (a + d2 / (d2 - d6) * ac));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return glm::length(p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b)));
  const double denom = 1 / (va + vb + vc);
  return glm::length(p - (a + ab * (vb * denom) + ac * (vc * denom)));
}

TEST(VoxelGrid, BoxShellIsExactlyTheVoxelsTouchingItsFaces) {
  VoxelGrid g(UnitSpec(32));
  const glm::vec3 lo(5.25f, 8.0f, 3.5f), hi(20.75f, 17.0f, 26.5f);  // y faces on voxel faces
  g.Voxelize(BoxMesh(lo, hi));
  int mismatches = 0, expected_count = 0;
  for (int z = 0; z < 32; ++z)
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x) {
        const glm::vec3 vlo(x, y, z), vhi = vlo + 1.f;
        const bool touches = glm::all(glm::lessThanEqual(vlo, hi)) && glm::all(glm::lessThanEqual(lo, vhi));
        const bool interior = glm::all(glm::lessThan(lo, vlo)) && glm::all(glm::lessThan(vhi, hi));
        const bool expected = touches && !interior;
        expected_count += expected;
        mismatches += expected != Marked(g, x, y, z);
      }
  EXPECT_EQ(mismatches, 0);
  EXPECT_EQ(g.OccupiedCount(), static_cast<std::size_t>(expected_count));
}

TEST(VoxelGrid, SphereShellIsWatertightAndHugsTheSurface) {
  VoxelGrid g(UnitSpec(64));
  const glm::vec3 centre(31.3f, 32.6f, 30.9f);
  const float radius = 20.f;
  g.Voxelize(SphereMesh(centre, radius, 24, 48));
  const auto outside = OutsideFill(g);
  EXPECT_FALSE(outside[static_cast<std::size_t>(31 + 64 * (32 + 64 * 30))]) << "the shell leaks";
  // The mesh lies between the inscribed radius (a facet's distance) and the sphere: every
  // marked voxel's box must reach into that band.
  const double inner = radius * std::cos(std::numbers::pi / 24) * std::cos(std::numbers::pi / 48) - 1e-3;
  int far = 0;
  for (int z = 0; z < 64; ++z)
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x) {
        if (!Marked(g, x, y, z)) continue;
        const glm::dvec3 c = glm::dvec3(x, y, z) + 0.5 - glm::dvec3(centre);
        const double d = glm::length(c);
        if (d - std::sqrt(3.0) / 2 > radius || d + std::sqrt(3.0) / 2 < inner) ++far;
      }
  EXPECT_EQ(far, 0);
  EXPECT_GT(g.OccupiedCount(), 4000u);  // ≈ 4π r² × (1.5 voxels of conservative thickness)
}

TEST(VoxelGrid, TiltedThinPlateSeparatesItsTwoSides) {
  VoxelGrid g(UnitSpec(32));
  const glm::vec3 n = glm::normalize(glm::vec3(0.3f, 1.f, 0.45f));
  const glm::vec3 u = glm::normalize(glm::cross(n, glm::vec3(1, 0, 0))), v = glm::cross(n, u);
  const glm::vec3 centre(16.2f, 15.7f, 16.1f);
  g.Voxelize(QuadMesh(centre, u, v, 80.f));  // larger than the grid: it is clipped
  const auto outside = OutsideFill(g);
  // The corner (0,0,0) is below the plane; a voxel well above it must be unreachable.
  EXPECT_LT(glm::dot(glm::vec3(0.5f) - centre, n), 0);
  EXPECT_FALSE(outside[static_cast<std::size_t>(31 + 32 * (31 + 32 * 31))]);
  int off_plane = 0;
  for (int z = 0; z < 32; ++z)
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x)
        if (Marked(g, x, y, z)) {
          const glm::vec3 c = glm::vec3(x, y, z) + 0.5f - centre;
          // A voxel box reaches the plane iff |n·c| ≤ ½ Σ|n_i|.
          if (std::abs(glm::dot(n, c)) > 0.5f * (std::abs(n.x) + std::abs(n.y) + std::abs(n.z)) + 1e-4f) ++off_plane;
        }
  EXPECT_EQ(off_plane, 0);
}

TEST(VoxelGrid, TriangleOnAVoxelFaceMarksBothSides) {
  VoxelGrid g(UnitSpec(16));
  // In the plane x = 8, covering y, z ∈ [2, 10] below the diagonal y + z ≤ 12.
  g.Voxelize(std::vector<glm::vec3>{{8, 2, 2}, {8, 10, 2}, {8, 2, 10}});
  for (int z = 0; z < 16; ++z)
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x) {
        // The closed unit square [y, y+1]×[z, z+1] meets the triangle iff y+1, z+1 ≥ 2,
        // y, z ≤ 10 and y + z ≤ 12.
        const bool in_yz = y + 1 >= 2 && z + 1 >= 2 && y <= 10 && z <= 10 && y + z <= 12;
        const bool expected = in_yz && (x == 7 || x == 8);
        EXPECT_EQ(Marked(g, x, y, z), expected) << x << "," << y << "," << z;
      }
}

TEST(VoxelGrid, RandomTrianglesMarkTheirPointsAndNothingFar) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> pos(-4.f, 36.f), small(-3.f, 3.f);
  VoxelGrid g(UnitSpec(32));
  std::vector<glm::vec3> tris;
  for (int t = 0; t < 60; ++t) {
    const glm::vec3 a(pos(rng), pos(rng), pos(rng));
    tris.insert(tris.end(), {a, a + glm::vec3(small(rng), small(rng), small(rng)) * 3.f,
                             a + glm::vec3(small(rng), small(rng), small(rng)) * 3.f});
  }
  g.Voxelize(tris);
  // Completeness: every point sampled on a triangle lies in a marked voxel (or outside).
  std::uniform_real_distribution<double> unit(0, 1);
  int missed = 0;
  for (std::size_t t = 0; t < tris.size(); t += 3)
    for (int s = 0; s < 400; ++s) {
      double b1 = unit(rng), b2 = unit(rng);
      if (b1 + b2 > 1) b1 = 1 - b1, b2 = 1 - b2;
      const glm::dvec3 p =
          glm::dvec3(tris[t]) + b1 * glm::dvec3(tris[t + 1] - tris[t]) + b2 * glm::dvec3(tris[t + 2] - tris[t]);
      const glm::ivec3 i(glm::floor(p));
      if (glm::any(glm::lessThan(i, glm::ivec3(0))) || glm::any(glm::greaterThanEqual(i, glm::ivec3(32)))) continue;
      missed += !Marked(g, i.x, i.y, i.z);
    }
  EXPECT_EQ(missed, 0);
  // Soundness: every marked voxel's centre is within half a voxel diagonal of some triangle.
  int far = 0;
  for (int z = 0; z < 32; ++z)
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x) {
        if (!Marked(g, x, y, z)) continue;
        double best = 1e9;
        for (std::size_t t = 0; t < tris.size(); t += 3)
          best = std::min(best, PointTriangleDistance(glm::dvec3(x, y, z) + 0.5, tris[t], tris[t + 1], tris[t + 2]));
        far += best > std::sqrt(3.0) / 2 + 1e-9;
      }
  EXPECT_EQ(far, 0);
  EXPECT_GT(g.OccupiedCount(), 200u);
}

TEST(VoxelGrid, MipsAreRoundedMeansAndSamplingIsTrilinear) {
  VoxelGrid g(UnitSpec(16));
  g.Voxelize(BoxMesh({1.5f, 1.5f, 1.5f}, {12.5f, 9.5f, 7.5f}));
  g.BuildMips();
  ASSERT_EQ(g.levels(), 5);
  // A solid 2×2×2 block of level 0 is 255 at level 1; the top level is the overall mean.
  double mean0 = 0;
  for (auto v : g.Level(0)) mean0 += v / 255.0;
  mean0 /= 4096.0;
  EXPECT_NEAR(g.Level(4)[0] / 255.0, mean0, 4 * 0.5 / 255);  // four roundings down the pyramid
  // Level-1 voxel (0,0,0) holds level-0 voxels 0..1 on each axis: only (1,1,1) touches the box
  // (its corner at 1.5); the rest lie outside it.
  EXPECT_EQ(g.Level(1)[0], static_cast<std::uint8_t>((255 + 4) / 8));
  // At a level-0 voxel centre the sample is the voxel; halfway between two it is their mean.
  EXPECT_DOUBLE_EQ(g.Sample({1.5, 1.5, 1.5}, 0), 1.0);
  EXPECT_DOUBLE_EQ(g.Sample({4.5, 4.5, 4.5}, 0), 0.0);
  EXPECT_DOUBLE_EQ(g.Sample({4.5, 1.5, 4.5}, 0), 1.0);
  EXPECT_DOUBLE_EQ(g.Sample({5.0, 2.0, 5.0}, 0), 0.5);  // between y = 1 (marked) and y = 2 (empty)
  // Outside the cube the border is empty; between levels the blend is linear.
  EXPECT_DOUBLE_EQ(g.Sample({-3, 5, 5}, 0), 0.0);
  const double a = g.Sample({6, 6, 6}, 1), b = g.Sample({6, 6, 6}, 2);
  EXPECT_NEAR(g.Sample({6, 6, 6}, 1.25), a + 0.25 * (b - a), 1e-12);
}

TEST(VoxelGrid, ASheetStaysOpaqueAcrossAndThinAlongAtEveryLevel) {
  VoxelGrid g(UnitSpec(32));
  // The plane y = 12.5 across the whole grid marks the level-0 layer y = 12 only.
  g.Voxelize(QuadMesh({16, 12.5f, 16}, {1, 0, 0}, {0, 0, 1}, 40.f));
  g.BuildMips();
  ASSERT_EQ(g.OccupiedCount(), 32u * 32u);
  for (int l = 0; l < g.levels(); ++l) {
    const int r = g.LevelResolution(l), y = 12 >> l;
    const auto& op = g.Opacity(l);
    const std::size_t i = 3 * static_cast<std::size_t>(r / 2 + r * (y + r * (r / 2)));
    // Every line along y through the voxel holding the sheet crosses it.
    EXPECT_EQ(op[i + 1], 255) << "level " << l;
    // Along x and z one layer of 2^l is occupied: 255 / 2^l, rounded at each level.
    EXPECT_NEAR(op[i], 255.0 / (1 << l), 1.0) << "level " << l;
    EXPECT_EQ(op[i + 2], op[i]) << "level " << l;
    // The mean occupancy is as thin.
    EXPECT_NEAR(g.Level(l)[i / 3], 255.0 / (1 << l), 1.0) << "level " << l;
    if (y + 1 < r) {  // the voxel above is empty at the finer levels
      EXPECT_EQ(op[3 * static_cast<std::size_t>(r / 2 + r * (y + 1 + r * (r / 2))) + 1], 0) << "level " << l;
    }
  }
}

TEST(VoxelGrid, ConesLeavingASurfaceDoNotSeeIt) {
  // A point just above a ground plane sees the whole sky, however wide its cone, as long as the
  // cone stays above the plane: the first samples must not take a level coarse enough to hold
  // the ground. Planes mid-voxel, near a voxel face and on one.
  const auto spec = VoxelGridSpec::Covering({-2, -2, -2}, {2, 2, 2}, 64);
  const float on_face = static_cast<float>(spec.origin.y + 31 * spec.voxel_size);
  double worst = 1;
  for (float ground : {0.f, 0.031f, on_face}) {
    VoxelGrid g(spec);
    g.Voxelize(QuadMesh({0, ground, 0}, {1, 0, 0}, {0, 0, 1}, 3.9f));
    g.BuildMips();
    for (float height : {0.005f, 0.02f, 0.05f})
      for (float alpha : {0.05f, 0.3f, 0.6f, 1.0f, 1.3f})
        for (float tilt : {0.f, 0.2f, 0.5f}) {
          if (alpha + tilt > 1.45f) continue;  // the cone would reach below the horizon
          for (float phi : {0.f, 0.8f, 2.f}) {
            const glm::vec3 d(std::sin(tilt) * std::cos(phi), std::cos(tilt), std::sin(tilt) * std::sin(phi));
            const double v = g.TraceCone({{0.13f, ground + height, -0.27f}, d, alpha});
            worst = std::min(worst, v);
            EXPECT_GT(v, 0.99) << "ground " << ground << " height " << height << " alpha " << alpha << " tilt " << tilt;
          }
        }
  }
  RecordProperty("worst_visibility", std::to_string(worst));
}

TEST(VoxelGrid, ConeUnderASlabIsBlockedAndAwayFromItIsClear) {
  const auto spec = VoxelGridSpec::Covering({-2, -2, -2}, {2, 2, 2}, 64);
  VoxelGrid g(spec);
  g.Voxelize(BoxMesh({-1.8f, 0.5f, -1.8f}, {1.8f, 0.6f, 1.8f}));  // a 10 cm slab 0.5 m above
  g.BuildMips();
  for (double alpha : {0.05, 0.2, 0.5}) {
    const double up = g.TraceCone({{0.1f, 0, -0.2f}, {0, 1, 0}, static_cast<float>(alpha)});
    const double down = g.TraceCone({{0.1f, 0, -0.2f}, {0, -1, 0}, static_cast<float>(alpha)});
    EXPECT_LT(up, 0.05) << "half-angle " << alpha;
    EXPECT_GT(down, 0.99) << "half-angle " << alpha;
  }
}

TEST(VoxelGrid, GroundPointBesideABoxIsOccludedOnlyTowardsIt) {
  const auto spec = VoxelGridSpec::Covering({-2, 0, -2}, {2, 4, 2}, 64);
  VoxelGrid g(spec);
  g.Voxelize(BoxMesh({0.5f, 0.f, -1.f}, {1.5f, 2.f, 1.f}));  // 1 m wide, 2 m tall, 2 m deep
  g.BuildMips();
  const glm::vec3 p(-0.5f, 0.02f, 0.f);
  auto vis = [&](glm::vec3 d, float a) { return g.TraceCone({p, glm::normalize(d), a}); };
  EXPECT_LT(vis({1, 0.3f, 0}, 0.1f), 0.05);     // low, towards the box
  EXPECT_LT(vis({1, 1.0f, 0.2f}, 0.1f), 0.05);  // up towards its face
  EXPECT_GT(vis({-1, 0.3f, 0}, 0.1f), 0.99);    // away from it
  EXPECT_GT(vis({0, 1, 0}, 0.1f), 0.99);        // straight up
  EXPECT_GT(vis({0, 0.3f, 1}, 0.1f), 0.99);     // sideways, along the box
  EXPECT_GT(vis({1, 4.f, 0}, 0.1f), 0.99);      // steeply over its top (2 m up, 1 m away)
}

TEST(VoxelGrid, WideConeOverAnEdgeSeesAPartlyBlockedFraction) {
  const auto spec = VoxelGridSpec::Covering({-3, -3, -3}, {3, 3, 3}, 128);
  VoxelGrid g(spec);
  // A thick wall covering x < 0 at y ∈ [1, 1.2]: half of an upward cone at the origin.
  g.Voxelize(BoxMesh({-2.8f, 1.f, -2.8f}, {0.f, 1.2f, 2.8f}));
  g.BuildMips();
  const ConeQuery narrow_blocked{{0, 0, 0}, glm::normalize(glm::vec3(-0.3f, 1, 0)), 0.05f};
  const ConeQuery narrow_clear{{0, 0, 0}, glm::normalize(glm::vec3(0.3f, 1, 0)), 0.05f};
  const ConeQuery wide{{0, 0, 0}, {0, 1, 0}, 0.5f};
  EXPECT_LT(g.TraceCone(narrow_blocked), 0.05);
  EXPECT_GT(g.TraceCone(narrow_clear), 0.99);
  const double half = g.TraceCone(wide);
  EXPECT_GT(half, 0.25);
  EXPECT_LT(half, 0.75);
}

TEST(VoxelGrid, EmptySceneSeesEverything) {
  const auto spec = VoxelGridSpec::Covering({1, 1, 1}, {-1, -1, -1}, 16);  // an empty box
  VoxelGrid g(spec);
  g.Voxelize({});
  g.BuildMips();
  EXPECT_EQ(g.OccupiedCount(), 0u);
  EXPECT_DOUBLE_EQ(g.TraceCone({{0, 0, 0}, {0, 0, 1}, 1.2f}), 1.0);
}

TEST(VoxelGrid, ZeroAreaAndNonFiniteTrianglesAreHarmless) {
  VoxelGrid g(UnitSpec(16));
  const float nan = std::nanf("");
  g.Voxelize(std::vector<glm::vec3>{{3.5f, 3.5f, 3.5f},
                                    {3.5f, 3.5f, 3.5f},
                                    {3.5f, 3.5f, 3.5f},  // a point
                                    {1.5f, 9.5f, 9.5f},
                                    {5.5f, 9.5f, 9.5f},
                                    {3.5f, 9.5f, 9.5f},  // a segment
                                    {nan, 1, 1},
                                    {2, 2, 2},
                                    {3, 3, 3}});
  EXPECT_TRUE(Marked(g, 3, 3, 3));
  for (int x = 1; x <= 5; ++x) EXPECT_TRUE(Marked(g, x, 9, 9));
  EXPECT_EQ(g.OccupiedCount(), 6u);
}

TEST(VoxelGrid, BadInputsThrowNamingTheField) {
  EXPECT_THROW(VoxelGrid(UnitSpec(48)), Error);
  EXPECT_THROW(VoxelGrid(UnitSpec(1024)), Error);
  VoxelGridSpec bad = UnitSpec(16);
  bad.voxel_size = 0;
  EXPECT_THROW(VoxelGrid{bad}, Error);
  VoxelGrid g(UnitSpec(16));
  EXPECT_THROW(g.Voxelize(std::vector<glm::vec3>(4)), Error);
  EXPECT_THROW(g.TraceCone({{1, 1, 1}, {0, 0, 1}, 1.5f}), Error);
  EXPECT_THROW(g.TraceCone({{1, 1, 1}, {0, 0, 0}, 0.1f}), Error);
  ConeTraceOptions o;
  o.step_scale = 0;
  try {
    g.TraceCone({{1, 1, 1}, {0, 0, 1}, 0.1f}, o);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.where(), "cone step_scale");
  }
}

}  // namespace
}  // namespace odvr::visibility
