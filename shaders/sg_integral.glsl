// Spherical-Gaussian integrals for the renderer (engine/lighting/sg.h is the definition; seed
// eq. 4.7, DESIGN.md §4). In float, r − Λ cannot be taken as a difference: at Λ ~ 2·10⁴ (a
// mirror lobe) its rounding alone is 10⁻³ relative in the exponent. For two SGs
//   r² − Λ² = |λ1 c1 + λ2 c2|² − (λ1 + λ2)² = −λ1 λ2 |c1 − c2|²,
// so r − Λ = −λ1 λ2 |c1 − c2|² / (r + Λ): no cancellation, exact for aligned axes.
const float kSgPi = 3.14159265358979323846;

// The product of two unit-amplitude SGs: axis, λ, and log of its amplitude (≤ 0).
struct SgProduct {
  vec3 axis;
  float lambda;
  float log_amplitude;
};

SgProduct sgProduct(vec3 c1, float l1, vec3 c2, float l2) {
  vec3 s = l1 * c1 + l2 * c2;
  float r = length(s);
  vec3 d = c1 - c2;
  float sum = l1 + l2;
  SgProduct p;
  p.axis = r > 1e-12 ? s / r : c1;
  p.lambda = r;
  p.log_amplitude = sum > 0.0 ? -l1 * l2 * dot(d, d) / (r + sum) : 0.0;
  return p;
}

// (1 − e^{−2r}) / r, the integral of a unit SG of λ = r divided by 2π; 2 at r → 0.
float sgShape(float r) { return r < 1e-3 ? 2.0 - 2.0 * r + (4.0 / 3.0) * r * r : (1.0 - exp(-2.0 * r)) / r; }

// ∫ of a unit-amplitude SG of sharpness λ over the sphere.
float sgIntegral(float lambda) { return 2.0 * kSgPi * sgShape(lambda); }

// ∫ of the product of two unit-amplitude SGs.
float sgIntegral2(vec3 c1, float l1, vec3 c2, float l2) {
  SgProduct p = sgProduct(c1, l1, c2, l2);
  return 2.0 * kSgPi * exp(p.log_amplitude) * sgShape(p.lambda);
}
