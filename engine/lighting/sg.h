#pragma once
// Spherical Gaussians (seed §4.1, DESIGN.md §4): G(ω; c, λ, μ) = μ · exp(λ (ω·c − 1)).
// Lighting, BRDF lobes and visibility cones are all SGs, so shading is a sum of closed-form
// integrals of products of SGs. Amplitudes are scalar here; RGB lighting keeps one μ per channel
// beside a shared axis and sharpness. λ = 0 is a constant function, and every formula below
// stays closed-form and finite for it.
#include <glm/vec3.hpp>
#include <span>

namespace odvr::lighting {

struct Sg {
  glm::dvec3 axis{0, 0, 1};  // unit
  double lambda = 0;         // sharpness ≥ 0
  double amplitude = 1;      // μ
};

// Value at unit direction w.
double Evaluate(const Sg& g, const glm::dvec3& w);

// The product of two SGs is an SG: λ c = λa ca + λb cb, μ = μa μb exp(|λa ca + λb cb| − λa − λb).
// When the axes cancel (r = 0) the product is a constant and the axis is arbitrary (kept as a's).
Sg Product(const Sg& a, const Sg& b);

// ∫ over the sphere of the product of the given SGs (one or more), eq. 4.7:
//   μ 4π e^{−Λ} sinh(r)/r,  Λ = Σ λi, r = |Σ λi ci|, μ = Π μi.
// Evaluated as 2π μ (e^{r−Λ} − e^{−r−Λ}) / r: r ≤ Λ, so neither exponential overflows even at
// λ ~ 1e4, and for r < 1e-4 as the series 4π μ e^{−Λ} (1 + r²/6), where the difference above
// would cancel catastrophically.
double IntegralOfProduct(std::span<const Sg> sgs);
double Integral(const Sg& a);
double IntegralOfProduct(const Sg& a, const Sg& b);
double IntegralOfProduct(const Sg& a, const Sg& b, const Sg& c);

// λ of the SG whose value falls to 1/2 at angle `half_angle` from its axis (eq. 4.12–4.13 and
// the HEALPix lobe rule): e^{λ(cos α − 1)} = 1/2.
double LambdaForHalfValueAngle(double half_angle_rad);
double HalfValueAngleForLambda(double lambda);

}  // namespace odvr::lighting
