#include "engine/lighting/sg.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <random>

#include "core/constants.h"

namespace odvr::lighting {
namespace {

// ∫ f over the sphere by quadrature in (cos θ, φ) around `pole`, with cos θ sampled densely near
// the pole: sharp lobes (λ up to 1e4, width ~0.01 rad) need it. Midpoint rule in u = 1 − cos θ on
// a geometric grid, uniform in φ.
template <class F>
double SphereQuadrature(const F& f, const glm::dvec3& pole) {
  glm::dvec3 t = std::abs(pole.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  const glm::dvec3 e1 = glm::normalize(glm::cross(pole, t)), e2 = glm::cross(pole, e1);
  const int n_u = 4000, n_phi = 256;
  // u in [0, 2]: geometric spacing from 1e-9 to 2.
  double sum = 0;
  double u_prev = 0;
  for (int i = 1; i <= n_u; ++i) {
    const double u = 2.0 * std::pow(1e-9 / 2.0, 1.0 - double(i) / n_u);
    const double um = 0.5 * (u_prev + u), du = u - u_prev;
    const double cos_t = 1 - um, sin_t = std::sqrt(std::max(0.0, 1 - cos_t * cos_t));
    double ring = 0;
    for (int j = 0; j < n_phi; ++j) {
      const double phi = 2 * kPi * (j + 0.5) / n_phi;
      ring += f(cos_t * pole + sin_t * (std::cos(phi) * e1 + std::sin(phi) * e2));
    }
    sum += ring * du * (2 * kPi / n_phi);
    u_prev = u;
  }
  return sum;
}

glm::dvec3 Dir(double theta, double phi) {
  return {std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi)};
}

TEST(Sg, SingleIntegralMatchesQuadratureAcrossSharpness) {
  for (double lambda : {0.0, 1e-6, 0.5, 5.5, 100.0, 1449.29, 1e4}) {
    const Sg g{Dir(0.3, 1.0), lambda, 2.0};
    const double q = SphereQuadrature([&](const glm::dvec3& w) { return Evaluate(g, w); }, g.axis);
    EXPECT_NEAR(Integral(g) / q, 1.0, 1e-5) << "lambda " << lambda;
  }
}

TEST(Sg, TripleProductIntegralMatchesQuadrature) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 12; ++trial) {
    Sg s[3];
    for (auto& g : s) {
      g.axis = glm::normalize(Dir(std::acos(1 - 2 * u(rng)), 2 * kPi * u(rng)));
      g.lambda = std::pow(10.0, 3.5 * u(rng) - 0.5);  // 0.3 .. 1e3
      g.amplitude = 0.1 + u(rng);
    }
    // Nearby axes so the product is not vanishingly small.
    s[1].axis = glm::normalize(s[0].axis + 0.05 * s[1].axis);
    s[2].axis = glm::normalize(s[0].axis + 0.05 * s[2].axis);
    const Sg p = Product(Product(s[0], s[1]), s[2]);
    const double q = SphereQuadrature(
        [&](const glm::dvec3& w) { return Evaluate(s[0], w) * Evaluate(s[1], w) * Evaluate(s[2], w); }, p.axis);
    const double exact = IntegralOfProduct(s[0], s[1], s[2]);
    EXPECT_NEAR(exact / q, 1.0, 1e-4) << "trial " << trial;
    EXPECT_NEAR(Integral(p) / exact, 1.0, 1e-9);  // the product SG integrates to the same
  }
}

TEST(Sg, NearlyCancellingAxesStayFiniteAndContinuous) {
  // |Σ λ c| → 0: opposite axes of equal sharpness. The series branch must meet the exact branch.
  const Sg a{{0, 0, 1}, 50, 1};
  for (double eps : {1e-2, 1e-4, 1.0001e-4, 0.9999e-4, 1e-7, 0.0}) {
    const Sg b{glm::normalize(glm::dvec3(eps, 0, -1)), 50, 1};
    const double v = IntegralOfProduct(a, b);
    EXPECT_TRUE(std::isfinite(v));
    EXPECT_GT(v, 0);
    const double r = glm::length(a.lambda * a.axis + b.lambda * b.axis);
    const double sinhc = r == 0 ? 1.0 : std::sinh(r) / r;
    EXPECT_NEAR(v / (4 * kPi * std::exp(-100.0) * sinhc), 1.0, 1e-9) << eps;
  }
}

TEST(Sg, HugeSharpnessDoesNotOverflow) {
  const Sg a{{0, 1, 0}, 1e4, 1}, b{{0, 1, 0}, 1e4, 1}, c{{0, 1, 0}, 1e4, 3};
  const double v = IntegralOfProduct(a, b, c);
  EXPECT_TRUE(std::isfinite(v));
  EXPECT_NEAR(v, 3 * 2 * kPi / 3e4, 1e-12);                 // aligned: one SG of λ = 3e4
  const Sg d{glm::normalize(glm::dvec3(1, 1, 0)), 1e4, 1};  // 45° away: underflows to 0, not NaN
  EXPECT_EQ(IntegralOfProduct(a, d), 0.0);
}

TEST(Sg, ConstantIsLambdaZero) {
  const Sg constant{{1, 0, 0}, 0, 0.25};
  EXPECT_DOUBLE_EQ(Evaluate(constant, {0, -1, 0}), 0.25);
  EXPECT_NEAR(Integral(constant), kPi, 1e-12);
  const Sg g{{0, 1, 0}, 20, 1};
  EXPECT_NEAR(IntegralOfProduct(constant, g), 0.25 * Integral(g), 1e-12);
}

TEST(Sg, HalfValueAngleRoundTrips) {
  for (double lambda : {5.50, 22.55, 1449.29, 1e4}) {
    const double a = HalfValueAngleForLambda(lambda);
    EXPECT_NEAR(LambdaForHalfValueAngle(a), lambda, 1e-6 * lambda);
    EXPECT_NEAR(std::exp(lambda * (std::cos(a) - 1)), 0.5, 1e-12);
  }
}

}  // namespace
}  // namespace odvr::lighting
