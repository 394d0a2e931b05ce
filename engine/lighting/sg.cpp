#include "engine/lighting/sg.h"

#include <cmath>
#include <glm/geometric.hpp>

#include "core/constants.h"

namespace odvr::lighting {

double Evaluate(const Sg& g, const glm::dvec3& w) {
  return g.amplitude * std::exp(g.lambda * (glm::dot(w, g.axis) - 1.0));
}

Sg Product(const Sg& a, const Sg& b) {
  const glm::dvec3 v = a.lambda * a.axis + b.lambda * b.axis;
  const double r = glm::length(v);
  Sg p;
  p.lambda = r;
  p.axis = r > 0 ? v / r : a.axis;
  p.amplitude = a.amplitude * b.amplitude * std::exp(r - a.lambda - b.lambda);
  return p;
}

namespace {
double IntegralFromSums(double mu, double big_lambda, double r) {
  if (r < 1e-4) return 4 * kPi * mu * std::exp(-big_lambda) * (1 + r * r / 6);
  // 2π μ (e^{r−Λ} − e^{−r−Λ}) / r = 2π μ e^{r−Λ} (1 − e^{−2r}) / r; -expm1 keeps small r exact.
  return 2 * kPi * mu * std::exp(r - big_lambda) * (-std::expm1(-2 * r)) / r;
}
}  // namespace

double IntegralOfProduct(std::span<const Sg> sgs) {
  glm::dvec3 v(0);
  double big_lambda = 0, mu = 1;
  for (const Sg& g : sgs) {
    v += g.lambda * g.axis;
    big_lambda += g.lambda;
    mu *= g.amplitude;
  }
  return IntegralFromSums(mu, big_lambda, glm::length(v));
}

double Integral(const Sg& a) { return IntegralOfProduct(std::span<const Sg>(&a, 1)); }

double IntegralOfProduct(const Sg& a, const Sg& b) {
  const Sg s[2] = {a, b};
  return IntegralOfProduct(s);
}

double IntegralOfProduct(const Sg& a, const Sg& b, const Sg& c) {
  const Sg s[3] = {a, b, c};
  return IntegralOfProduct(s);
}

double LambdaForHalfValueAngle(double half_angle_rad) { return std::log(0.5) / (std::cos(half_angle_rad) - 1.0); }

double HalfValueAngleForLambda(double lambda) { return std::acos(1.0 + std::log(0.5) / lambda); }

}  // namespace odvr::lighting
