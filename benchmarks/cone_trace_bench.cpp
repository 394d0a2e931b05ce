// engine/visibility: the CPU cone tracer (the reference the GPU's render_shade.comp is held to) on
// a real car. A query is what the renderer does per lighting lobe at a shaded point: split the
// lobe into cones (cones.h), trace each through the voxel mip-chain, weight the visibilities.
// The counters hold that estimate against the lobe-weighted visible fraction ∫ G V / ∫ G
// integrated once, untimed, by casting rays against the car's triangles (TriangleBvh).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <glm/geometric.hpp>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <vector>

#include "core/constants.h"
#include "core/error.h"
#include "engine/lighting/sg.h"
#include "engine/scene/gltf_scene.h"
#include "engine/visibility/cones.h"
#include "engine/visibility/triangle_bvh.h"
#include "engine/visibility/voxel_grid.h"

namespace odvr::bench {
namespace {

constexpr int kResolution = 128;  // the renderer's default voxel_resolution
constexpr int kQueries = 64;
constexpr int kStrata = 48;  // kStrata² rays per query for the truth

struct Scene {
  std::unique_ptr<visibility::VoxelGrid> grid;
  std::unique_ptr<visibility::TriangleBvh> bvh;
  std::vector<glm::dvec3> points;  // on the ground around and under the car
  std::size_t triangles = 0;
};

// ../shared/data/street_a/car.glb on a ground plane at its lowest point; the grid covers the car
// and a 1 m margin of ground around it, so that the query points lie inside it.
const Scene* Car(std::string* why) {
  static std::once_flag once;
  static std::unique_ptr<Scene> scene;
  static std::string error;
  std::call_once(once, [] {
    const auto path =
        (std::filesystem::path(ODVR_SOURCE_DIR) / ".." / "shared" / "data" / "street_a" / "car.glb").lexically_normal();
    if (!std::filesystem::is_regular_file(path)) {
      error = path.string() + " is absent (the shared data set sits beside the source tree)";
      return;
    }
    try {
      const scene::GltfScene car = scene::LoadGltfScene(path);
      const std::vector<glm::vec3> soup = visibility::TriangleSoup(car);
      auto s = std::make_unique<Scene>();
      const glm::dvec3 lo(car.bounds.min), hi(car.bounds.max);
      const glm::dvec3 margin(1, 0, 1);
      s->grid = std::make_unique<visibility::VoxelGrid>(
          visibility::VoxelGridSpec::Covering(lo - margin, hi + margin, kResolution));
      s->grid->Voxelize(soup);
      s->grid->BuildMips();
      s->bvh = std::make_unique<visibility::TriangleBvh>(soup);
      s->triangles = soup.size() / 3;
      std::mt19937_64 rng(7);
      std::uniform_real_distribution<double> x(lo.x - 0.9, hi.x + 0.9), z(lo.z - 0.9, hi.z + 0.9);
      for (int i = 0; i < kQueries; ++i) s->points.emplace_back(x(rng), lo.y + 0.02, z(rng));
      scene = std::move(s);
    } catch (const Error& e) {
      error = e.what();
    }
  });
  if (!scene && why) *why = error;
  return scene.get();
}

// ∫ G V / ∫ G by rays drawn from the SG's own density (stratified in (cos θ, φ) about its axis):
// cos θ = 1 + ln(1 − ξ (1 − e^{−2λ})) / λ inverts the SG's cumulative share of the cap.
double RayCastVisibleFraction(const visibility::TriangleBvh& bvh, const glm::dvec3& origin, const lighting::Sg& lobe) {
  const glm::dvec3 helper = std::abs(lobe.axis.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  const glm::dvec3 e1 = glm::normalize(glm::cross(lobe.axis, helper)), e2 = glm::cross(lobe.axis, e1);
  int visible = 0;
  for (int i = 0; i < kStrata; ++i)
    for (int j = 0; j < kStrata; ++j) {
      const double xi = (i + 0.5) / kStrata, phi = 2 * kPi * (j + 0.5) / kStrata;
      const double c =
          lobe.lambda > 0 ? 1 + std::log1p(-xi * (-std::expm1(-2 * lobe.lambda))) / lobe.lambda : 1 - 2 * xi;
      const double sn = std::sqrt(std::max(0.0, 1 - c * c));
      const glm::dvec3 w = c * lobe.axis + sn * (std::cos(phi) * e1 + std::sin(phi) * e2);
      if (!bvh.Occluded(glm::vec3(origin), glm::vec3(w), 1e-4f, 1e30f)) ++visible;
    }
  return static_cast<double>(visible) / (kStrata * kStrata);
}

double TracedVisibleFraction(const visibility::VoxelGrid& grid, const glm::dvec3& origin, const lighting::Sg& lobe) {
  double v = 0;
  for (const auto& c : visibility::ConesForLobe(lobe))
    v += c.weight * grid.TraceCone({glm::vec3(origin), glm::vec3(c.axis), static_cast<float>(c.half_angle)});
  return v;
}

// Arg: the lobe's λ. 5 and 20 are broad (7 cones each, cone_rings = 1 as the renderer), 200 is
// one cone (half-value angle under ConeSubsampleOptions::single_cone_max_half_angle).
void BM_ConeTraceLobe(benchmark::State& state) {
  std::string why;
  const Scene* car = Car(&why);
  if (!car) {
    state.SkipWithError(why.c_str());
    return;
  }
  const double lambda = static_cast<double>(state.range(0));
  struct Setup {
    std::vector<lighting::Sg> lobes;
    double mean_abs_err = 0, max_abs_err = 0, mean_visible = 0;
    std::size_t cones = 0;
  };
  static std::map<int, Setup> setups;
  Setup& setup = setups[static_cast<int>(lambda)];
  if (setup.lobes.empty()) {
    std::mt19937_64 rng(11 + static_cast<unsigned>(lambda));
    std::uniform_real_distribution<double> u(0, 1);
    for (std::size_t q = 0; q < car->points.size(); ++q) {
      // Axes over the sky above 10° of elevation, where the car's shadow falls on the ground.
      const double elevation = std::asin(std::sin(10 * kPi / 180) + u(rng) * (1 - std::sin(10 * kPi / 180)));
      const double azimuth = 2 * kPi * u(rng);
      const glm::dvec3 axis(std::cos(elevation) * std::cos(azimuth), std::sin(elevation),
                            std::cos(elevation) * std::sin(azimuth));
      const lighting::Sg lobe{axis, lambda, 1};
      const double truth = RayCastVisibleFraction(*car->bvh, car->points[q], lobe);
      const double err = std::abs(TracedVisibleFraction(*car->grid, car->points[q], lobe) - truth);
      setup.mean_abs_err += err / static_cast<double>(car->points.size());
      setup.max_abs_err = std::max(setup.max_abs_err, err);
      setup.mean_visible += truth / static_cast<double>(car->points.size());
      setup.cones = visibility::ConesForLobe(lobe).size();
      setup.lobes.push_back(lobe);
    }
  }
  std::size_t i = 0;
  for (auto _ : state) {
    const std::size_t q = i++ % setup.lobes.size();
    benchmark::DoNotOptimize(TracedVisibleFraction(*car->grid, car->points[q], setup.lobes[q]));
  }
  state.counters["cones"] = static_cast<double>(setup.cones);
  state.counters["mean_abs_err"] = setup.mean_abs_err;
  state.counters["max_abs_err"] = setup.max_abs_err;
  state.counters["visible"] = setup.mean_visible;
}
BENCHMARK(BM_ConeTraceLobe)->ArgName("lambda")->Arg(5)->Arg(20)->Arg(200)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace odvr::bench
