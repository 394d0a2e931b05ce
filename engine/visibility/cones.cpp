#include "engine/visibility/cones.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <numbers>
#include <string>

#include "core/error.h"
#include "engine/visibility/voxel_grid.h"

namespace odvr::visibility {

void ConeSubsampleOptions::Check() const {
  if (!(single_cone_max_half_angle > 0 && single_cone_max_half_angle <= kMaxConeHalfAngle))
    throw Error("cones single_cone_max_half_angle", "must be in (0, " + std::to_string(kMaxConeHalfAngle) + "]");
  if (rings < 0 || rings > 8) throw Error("cones rings", "must be in [0, 8], got " + std::to_string(rings));
  if (!(coverage > 0 && coverage < 1)) throw Error("cones coverage", "must be in (0, 1)");
}

double CapHalfAngleHolding(double lambda, double fraction) {
  if (lambda < 1e-8) return std::acos(1 - 2 * fraction);  // uniform: cap area fraction (1 − cos θ)/2
  // e^{λ(cos θ − 1)} = 1 − f (1 − e^{−2λ}); expm1 keeps small λ accurate.
  const double c = 1 + std::log1p(fraction * std::expm1(-2 * lambda)) / lambda;
  return std::acos(std::clamp(c, -1.0, 1.0));
}

std::vector<Cone> ConesForLobe(const lighting::Sg& lobe, const ConeSubsampleOptions& options) {
  options.Check();
  const glm::dvec3 axis = lobe.axis;
  if (!std::isfinite(axis.x) || !std::isfinite(axis.y) || !std::isfinite(axis.z) || !(glm::length(axis) > 0))
    throw Error("cone lobe axis", "must be finite and non-zero");
  if (!(lobe.lambda >= 0) || !std::isfinite(lobe.lambda)) throw Error("cone lobe lambda", "must be finite and ≥ 0");
  const glm::dvec3 c = glm::normalize(axis);
  // Below λ = ln 2 / 2 the SG never falls to 1/2 on the sphere: its half-value angle is π.
  const double half_value =
      lobe.lambda > std::log(2.0) / 2 ? lighting::HalfValueAngleForLambda(lobe.lambda) : std::numbers::pi;
  if (half_value <= options.single_cone_max_half_angle || options.rings == 0)
    return {Cone{c, std::min(half_value, kMaxConeHalfAngle), 1.0}};

  // Cap radius Θ = (2R + 1) β holds R rings of cones of radius β around the centre one.
  const double cap = CapHalfAngleHolding(lobe.lambda, options.coverage);
  const double beta = std::min(cap / (2 * options.rings + 1), kMaxConeHalfAngle);
  // An orthonormal frame around c (Frisvad's, branch-free enough for doubles).
  const glm::dvec3 helper = std::abs(c.z) < 0.9 ? glm::dvec3(0, 0, 1) : glm::dvec3(1, 0, 0);
  const glm::dvec3 e1 = glm::normalize(glm::cross(helper, c)), e2 = glm::cross(c, e1);

  std::vector<Cone> cones{Cone{c, beta, 0}};
  for (int r = 1; r <= options.rings; ++r) {
    const double theta = std::min(2 * r * beta, std::numbers::pi);
    const int count = 6 * r;
    // Alternate rings are turned by half a slot so cones of neighbouring rings interleave.
    const double phase = (r % 2 == 0) ? std::numbers::pi / count : 0;
    for (int k = 0; k < count; ++k) {
      const double phi = phase + 2 * std::numbers::pi * k / count;
      const glm::dvec3 d = std::cos(theta) * c + std::sin(theta) * (std::cos(phi) * e1 + std::sin(phi) * e2);
      cones.push_back(Cone{glm::normalize(d), beta, 0});
    }
  }
  const lighting::Sg g{c, lobe.lambda, 1.0};
  const double lambda_cone = lighting::LambdaForHalfValueAngle(beta);
  double total = 0;
  for (auto& cone : cones) {
    cone.weight = lighting::IntegralOfProduct(g, lighting::Sg{cone.axis, lambda_cone, 1.0});
    total += cone.weight;
  }
  for (auto& cone : cones) cone.weight /= total;
  return cones;
}

}  // namespace odvr::visibility
