// engine/lighting/sg.h: the closed-form integral of a product of SGs (eq. 4.7), the inner loop of
// shading (lighting × BRDF lobe, × visibility cone for the triple product). Timed per call over a
// fixed set of random lobes; the counter is the largest relative error over that set against a
// brute-force quadrature done once, untimed, that never uses the closed form.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <glm/geometric.hpp>
#include <random>
#include <span>
#include <vector>

#include "core/constants.h"
#include "engine/lighting/sg.h"

namespace odvr::bench {
namespace {

using lighting::Sg;

// Gauss–Legendre nodes and weights on [−1, 1] (Newton on P_n).
struct GaussLegendre {
  std::vector<double> x, w;
  explicit GaussLegendre(int n) : x(static_cast<std::size_t>(n)), w(static_cast<std::size_t>(n)) {
    for (int i = 0; i < n; ++i) {
      double z = std::cos(kPi * (i + 0.75) / (n + 0.5)), dp = 0;
      for (int it = 0; it < 100; ++it) {
        double p0 = 1, p1 = 0;
        for (int k = 1; k <= n; ++k) {
          const double p2 = p1;
          p1 = p0;
          p0 = ((2 * k - 1) * z * p1 - (k - 1) * p2) / k;
        }
        dp = n * (z * p0 - p1) / (z * z - 1);
        const double dz = p0 / dp;
        z -= dz;
        if (std::abs(dz) < 1e-16) break;
      }
      x[static_cast<std::size_t>(i)] = z;
      w[static_cast<std::size_t>(i)] = 2 / ((1 - z * z) * dp * dp);
    }
  }
};

// ln ∫ Π G_i dω by quadrature, the integrand's log summed as Σ ln μ_i + λ_i (c_i·w − 1) at each node
// (the SG's own definition) and scaled by its largest value, so that lobes of λ ~ 1e4 neither
// underflow nor lose digits. Coordinates: polar about the direction the lobes pull towards
// (Σ λ_i c_i, where the integrand peaks), the polar angle through t = s (1 − cos θ) with
// s = max(|Σ λ_i c_i|, 1), so that the peak's width is about one unit of t: Gauss–Legendre on
// t-intervals of 1/2 up to t = 40, then doubling to 2s; the azimuth by the trapezoid rule
// (spectrally exact for a periodic integrand).
double LogQuadrature(std::span<const Sg> sgs) {
  static const GaussLegendre gl(16);
  constexpr int kAzimuth = 32;
  glm::dvec3 v(0);
  double log_mu = 0;
  for (const Sg& g : sgs) {
    v += g.lambda * g.axis;
    log_mu += std::log(g.amplitude);
  }
  const double r = glm::length(v);
  const glm::dvec3 pole = r > 0 ? v / r : glm::dvec3(0, 0, 1);
  const glm::dvec3 helper = std::abs(pole.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  const glm::dvec3 e1 = glm::normalize(glm::cross(pole, helper)), e2 = glm::cross(pole, e1);
  const double s = std::max(r, 1.0), t_end = 2 * s;
  std::vector<double> edges{0};
  while (edges.back() < std::min(40.0, t_end)) edges.push_back(std::min(edges.back() + 0.5, t_end));
  while (edges.back() < t_end) edges.push_back(std::min(2 * edges.back(), t_end));
  struct Node {
    double log_f, weight;
  };
  std::vector<Node> nodes;
  double peak = -INFINITY;
  for (std::size_t k = 0; k + 1 < edges.size(); ++k) {
    const double half = 0.5 * (edges[k + 1] - edges[k]), mid = 0.5 * (edges[k + 1] + edges[k]);
    for (std::size_t i = 0; i < gl.x.size(); ++i) {
      const double t = mid + half * gl.x[i];
      const double cos_theta = std::clamp(1 - t / s, -1.0, 1.0), sin_theta = std::sqrt(1 - cos_theta * cos_theta);
      for (int j = 0; j < kAzimuth; ++j) {
        const double phi = 2 * kPi * j / kAzimuth;
        const glm::dvec3 w = cos_theta * pole + sin_theta * (std::cos(phi) * e1 + std::sin(phi) * e2);
        double log_f = log_mu;
        for (const Sg& g : sgs) log_f += g.lambda * (glm::dot(g.axis, w) - 1);
        // dω = d(cos θ) dφ = (dt / s) dφ.
        nodes.push_back({log_f, half * gl.w[i] / s * (2 * kPi / kAzimuth)});
        peak = std::max(peak, log_f);
      }
    }
  }
  double sum = 0;
  for (const Node& n : nodes) sum += n.weight * std::exp(n.log_f - peak);
  return peak + std::log(sum);
}

glm::dvec3 RandomDirection(std::mt19937_64& rng) {
  std::normal_distribution<double> n;
  for (;;) {
    const glm::dvec3 d(n(rng), n(rng), n(rng));
    if (glm::length(d) > 1e-6) return glm::normalize(d);
  }
}

// A direction at `angle` from `axis`, at a random azimuth.
glm::dvec3 Tilted(const glm::dvec3& axis, double angle, std::mt19937_64& rng) {
  const glm::dvec3 side = glm::normalize(glm::cross(axis, RandomDirection(rng)));
  return std::cos(angle) * axis + std::sin(angle) * side;
}

// `count` sets of `n` lobes: λ log-uniform in [1e-2, 1e4] (every 16th set one λ = 0, the constant
// term), μ in [0.5, 2]. Half the sets have independent random axes; in the other half each further
// axis lies within a few lobe widths of the first, so that sharp lobes overlap (independent sharp
// axes give integrals that underflow to 0 in any double arithmetic, closed form or not).
template <std::size_t N>
std::vector<std::array<Sg, N>> RandomSets(int count, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<std::array<Sg, N>> sets(static_cast<std::size_t>(count));
  for (int k = 0; k < count; ++k) {
    auto& set = sets[static_cast<std::size_t>(k)];
    for (Sg& g : set) {
      g.lambda = std::pow(10.0, -2 + 6 * u(rng));
      g.amplitude = 0.5 + 1.5 * u(rng);
    }
    if (k % 16 == 5) set[N - 1].lambda = 0;
    set[0].axis = RandomDirection(rng);
    for (std::size_t i = 1; i < N; ++i) {
      if (k % 2 == 0) {
        set[i].axis = RandomDirection(rng);
      } else {
        const double width = 1 / std::sqrt(std::max(std::min(set[0].lambda, set[i].lambda), 1.0));
        set[i].axis = Tilted(set[0].axis, std::min(kPi, 4 * width * u(rng)), rng);
      }
    }
  }
  return sets;
}

template <std::size_t N>
struct Setup {
  std::vector<std::array<Sg, N>> sets;
  double max_rel_err = 0;
  int compared = 0, underflowed = 0;
  Setup() : sets(RandomSets<N>(256, 20261202u + N)) {
    for (const auto& set : sets) {
      const double closed = lighting::IntegralOfProduct(std::span<const Sg>(set));
      const double log_ref = LogQuadrature(set);
      // Both below the smallest normal double: nothing to compare in this arithmetic.
      if (closed < 1e-300 && log_ref < std::log(1e-300)) {
        ++underflowed;
        continue;
      }
      const double rel = closed > 0 && std::isfinite(closed) ? std::abs(std::exp(std::log(closed) - log_ref) - 1) : 1;
      max_rel_err = std::max(max_rel_err, rel);
      ++compared;
    }
  }
};

template <std::size_t N>
void BM_SgIntegralOfProduct(benchmark::State& state) {
  static const Setup<N> setup;
  const std::size_t mask = setup.sets.size() - 1;  // a power of two
  std::size_t i = 0;
  for (auto _ : state) {
    const auto& s = setup.sets[i++ & mask];
    double v;
    if constexpr (N == 2)
      v = lighting::IntegralOfProduct(s[0], s[1]);
    else
      v = lighting::IntegralOfProduct(s[0], s[1], s[2]);
    benchmark::DoNotOptimize(v);
  }
  state.counters["max_rel_err"] = setup.max_rel_err;
  state.counters["sets"] = setup.compared;
  state.counters["underflow"] = setup.underflowed;
}
BENCHMARK(BM_SgIntegralOfProduct<2>)->Name("BM_SgIntegralOfProduct/sgs:2")->Unit(benchmark::kNanosecond);
BENCHMARK(BM_SgIntegralOfProduct<3>)->Name("BM_SgIntegralOfProduct/sgs:3")->Unit(benchmark::kNanosecond);

}  // namespace
}  // namespace odvr::bench
