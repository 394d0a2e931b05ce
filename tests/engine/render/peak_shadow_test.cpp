// The peaks' shadows in the SG shading pass: the rays traced towards a peak (one for a sun, seven
// for a lamp), a roof nearer than the cones start, the ground's lit fraction, a wide peak's penumbra.
#include "engine/render/triple_product_renderer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>

#include "engine/render/triple_product_internal.h"
#include "tests/engine/gl/gl_test_context.h"
#include "tests/engine/render/render_test_measures.h"
#include "tests/engine/render/render_test_scenes.h"

namespace odvr::render {
namespace {

using odvr::testing::BoxPrimitive;
using odvr::testing::Luma;
using odvr::testing::MeanOnPlane;
using odvr::testing::Pbr;
using odvr::testing::SphereAndBox;
using odvr::testing::View;
using PeakShadowGL = odvr::testing::GlTest;

// RenderOptions::exact_peak_shadows: a floor under a roof 4 cm above it (about a voxel at 64³
// over the scene), lit by a sun straight above, seen from inside the gap. The sun's cone starts 2
// voxels off the floor, past the roof, and lets the sun through as if there were no roof; a ray
// stops at the roof. GPU and CPU reference alike.
TEST_F(PeakShadowGL, ExactPeakShadowsSeeARoofNearerThanTheConesStart) {
  const auto scene = [](bool roof) {
    scene::GltfScene s;
    s.materials = {Pbr("floor", {0.5f, 0.5f, 0.5f}, 0.f, 0.9f)};
    s.primitives.push_back(BoxPrimitive({-1.f, 0.40f, -1.f}, {1.f, 0.42f, 1.f}, 0));
    if (roof) s.primitives.push_back(BoxPrimitive({-1.f, 0.46f, -1.f}, {0.f, 0.48f, 1.f}, 0));  // over x < 0
    odvr::testing::Finish(&s);
    return s;
  };
  lighting::SgLighting sun;
  sun.constant = glm::vec3(0.01f);
  sun.peaks.push_back({glm::dvec3(0, 1, 0), 3000.0, glm::vec3(3000.f)});
  const PinholeCamera view = PinholeCamera::LookAt({0.9, 0.45, 0.0}, {-0.5, 0.42, 0.0}, 6, 96, 48);
  // The floor's top under the roof (x in [−0.8, −0.2]).
  const auto under_roof = [&](const RenderResult& r) { return MeanOnPlane(view, r, 0.42, -0.8, -0.2, 0.5); };
  double lum[2][2][2];  // [exact][roof][device: gpu, cpu]
  for (bool exact : {false, true})
    for (bool roof : {false, true}) {
      RenderOptions o;
      o.voxel_resolution = 64;
      o.ground = false;
      o.exact_peak_shadows = exact;
      TripleProductRenderer r(scene(roof), glm::dmat4(1.0), o);
      r.SetLighting(sun);
      lum[exact][roof][0] = under_roof(r.Render(view, ShadeDevice::kGpu));
      lum[exact][roof][1] = under_roof(r.Render(view, ShadeDevice::kCpu));
      std::printf("%s, %s: the floor under the roof's place %.3f (CPU %.3f)\n", exact ? "rays" : "cones",
                  roof ? "roof" : "no roof", lum[exact][roof][0], lum[exact][roof][1]);
    }
  for (int device : {0, 1}) {
    EXPECT_GT(lum[0][0][device], 1.0) << device;                       // the sun lights the open floor
    EXPECT_GT(lum[0][1][device], 0.8 * lum[0][0][device]) << device;   // the cone leaks under the roof
    EXPECT_LT(lum[1][1][device], 0.05 * lum[1][0][device]) << device;  // the ray does not
    EXPECT_NEAR(lum[1][0][device], lum[0][0][device], 0.02 * lum[0][0][device]) << device;  // alike in the open
  }
  for (bool exact : {false, true})
    for (bool roof : {false, true})
      EXPECT_NEAR(lum[exact][roof][0], lum[exact][roof][1], 0.02 * lum[exact][0][0]) << exact << roof;
}

// The car's bounce off the ground it shadows takes the peaks' rays too: a board 0.3 m up, under a
// sun straight above, leaves the ground beneath it in its shadow. A pebble 6 m away widens the
// voxel cube to 64 voxels of 11 cm, so a cone from the ground starts 0.44 m up, past the board,
// and the cones light that ground; the rays do not, and the
// board's underside, which sees only that ground, is darker by the sun's share of the ground's
// light. Before the ground's lit fraction took the rays, both read alike.
TEST_F(PeakShadowGL, TheGroundsLitFractionTakesThePeaksRays) {
  scene::GltfScene board;
  board.materials = {Pbr("board", {0.8f, 0.8f, 0.8f}, 0.f, 0.9f)};
  board.primitives.push_back(BoxPrimitive({-1.f, 0.30f, -1.f}, {0.f, 0.32f, 1.f}, 0));
  board.primitives.push_back(BoxPrimitive({6.f, 0.f, 0.f}, {6.1f, 0.1f, 0.1f}, 0));
  odvr::testing::Finish(&board);
  lighting::SgLighting sun;
  sun.constant = glm::vec3(1.f);  // the ground's bounce: the lighting below the horizon
  sun.peaks.push_back({glm::dvec3(0, 1, 0), 3000.0, glm::vec3(3000.f)});
  const PinholeCamera view = PinholeCamera::LookAt({1.2, 0.1, 0.0}, {-0.5, 0.3, 0.0}, 40, 96, 48);
  // The board's underside over x in [−0.8, −0.2].
  const auto underside = [&](const RenderResult& r) { return MeanOnPlane(view, r, 0.30, -0.8, -0.2, 0.5); };
  double lum[2][2];  // [exact][device: gpu, cpu]
  for (bool exact : {false, true}) {
    RenderOptions o;
    o.voxel_resolution = 64;
    o.exact_peak_shadows = exact;
    TripleProductRenderer r(board, glm::dmat4(1.0), o);
    r.SetLighting(sun);
    lum[exact][0] = underside(r.Render(view, ShadeDevice::kGpu));
    lum[exact][1] = underside(r.Render(view, ShadeDevice::kCpu));
    std::printf("%s: the board's underside %.4f (CPU %.4f)\n", exact ? "rays" : "cones", lum[exact][0], lum[exact][1]);
  }
  for (int device : {0, 1}) {
    EXPECT_GT(lum[0][device], 0.1) << device;                    // the ground's bounce reaches it
    EXPECT_LT(lum[1][device], 0.75 * lum[0][device]) << device;  // less of it with the rays
  }
  for (bool exact : {false, true}) EXPECT_NEAR(lum[exact][0], lum[exact][1], 0.02 * lum[exact][0]) << exact;
}

// A peak wider than 1° is seven rays, the axis and a ring whose second moment is the SG's: a lamp's
// penumbra. A sun is one ray.
TEST(PeakShadow, OneRayForASunSevenForALamp) {
  const glm::dvec3 axis = glm::normalize(glm::dvec3(0.3, 0.8, -0.2));
  const auto sun = detail::PeakRayDirections(axis, 20000.0);  // half-value 0.48°
  ASSERT_EQ(sun.size(), 1u);
  EXPECT_EQ(sun[0], axis);
  for (double lambda : {3000.0, 300.0}) {  // 1.2° and 3.9°
    const auto lamp = detail::PeakRayDirections(axis, lambda);
    ASSERT_EQ(lamp.size(), 7u);
    EXPECT_EQ(lamp[0], axis);
    double second = 0;
    glm::dvec3 mean(0);
    for (const auto& d : lamp) {
      EXPECT_NEAR(glm::length(d), 1.0, 1e-12);
      const double t = std::acos(std::clamp(glm::dot(d, axis), -1.0, 1.0));
      second += t * t / 7;
      mean += d / 7.0;
    }
    EXPECT_NEAR(second, 2 / lambda, 0.05 * 2 / lambda) << lambda;  // E[θ²] of e^{λ(cos θ − 1)}
    EXPECT_NEAR(glm::length(glm::cross(glm::normalize(mean), axis)), 0.0, 1e-9) << lambda;
  }
}

// The ground under a wide lamp has a penumbra as wide as the lamp: the shadow ratio takes values
// between its umbra's and the open ground's on more pixels than under a sun, GPU and CPU alike.
TEST_F(PeakShadowGL, AWidePeakCastsAPenumbra) {
  const auto penumbra = [](double lambda) {
    lighting::SgLighting l;
    l.constant = glm::vec3(0.02f);
    l.peaks.push_back({glm::normalize(glm::dvec3(-0.4, 1.0, 0.2)), lambda, glm::vec3(static_cast<float>(lambda))});
    RenderOptions o;
    o.voxel_resolution = 64;
    TripleProductRenderer r(SphereAndBox(), glm::dmat4(1.0), o);
    r.SetLighting(l);
    std::array<int, 2> partial{};
    int d = 0;
    for (ShadeDevice device : {ShadeDevice::kGpu, ShadeDevice::kCpu}) {
      const RenderResult res = r.Render(View(), device);
      for (std::size_t i = 0; i < res.ground_mask.size(); ++i) {
        const double ratio = Luma(&res.shadow.rgb[3 * i]);
        partial[d] += res.ground_mask[i] > 0.5f && ratio > 0.2 && ratio < 0.8;
      }
      ++d;
    }
    std::printf("lambda %.0f: %d ground pixels in the penumbra (CPU %d)\n", lambda, partial[0], partial[1]);
    EXPECT_NEAR(partial[0], partial[1], 0.1 * partial[1] + 5) << lambda;
    return partial[0];
  };
  const int sun = penumbra(30000.0), lamp = penumbra(150.0);  // half-value 0.39° and 5.5°
  EXPECT_GT(lamp, 3 * sun + 20);
}

}  // namespace
}  // namespace odvr::render
