#include "app/ar/car_controller.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

#include "core/error.h"

namespace odvr::app {

void CarLimits::Check() const {
  if (!(max_speed_mps > 0) || !(max_reverse_mps >= 0) || !(acceleration_mps2 > 0) || !(braking_mps2 > 0) ||
      !(rolling_decel_mps2 >= 0))
    throw Error("car limits", "speeds and accelerations must be positive");
  if (!(max_steer_rad > 0 && max_steer_rad < 1.5)) throw Error("car limits", "max steer must be in (0, 1.5) rad");
  if (!(wheelbase_m > 0)) throw Error("car limits", "wheelbase must be positive");
}

CarController::CarController(GroundPlane plane, CarLimits limits) : plane_(plane), limits_(limits) {
  limits_.Check();
  const double n = glm::length(plane_.normal);
  if (!(n > 0) || !std::isfinite(n)) throw Error("ground plane", "normal must be non-zero and finite");
  plane_.normal /= n;
  plane_.offset /= n;
  Reset({0, plane_.offset, 0}, {1, 0, 0});
}

void CarController::Stop() {
  state_.speed_mps = 0;
  state_.steer_rad = 0;
}

void CarController::Reset(const glm::dvec3& position, const glm::dvec3& forward) {
  state_ = {};
  state_.position = position - (glm::dot(plane_.normal, position) - plane_.offset) * plane_.normal;
  glm::dvec3 f = forward - glm::dot(forward, plane_.normal) * plane_.normal;
  if (glm::length(f) < 1e-9) {  // heading along the normal: pick any direction in the plane
    f = std::abs(plane_.normal.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 0, 1);
    f -= glm::dot(f, plane_.normal) * plane_.normal;
  }
  state_.forward = glm::normalize(f);
}

void CarController::Step(const CarInput& input, double dt_s) {
  if (!(dt_s > 0)) return;
  dt_s = std::min(dt_s, 0.1);  // a stalled frame must not launch the car

  // Pedals: forward accelerates (or brakes when rolling backward), backward the opposite.
  double& v = state_.speed_mps;
  const int pedal = int(input.forward) - int(input.backward);
  if (pedal != 0) {
    const bool braking = (pedal > 0 && v < 0) || (pedal < 0 && v > 0);
    v += pedal * (braking ? limits_.braking_mps2 : limits_.acceleration_mps2) * dt_s;
  } else {
    const double dv = limits_.rolling_decel_mps2 * dt_s;
    v = std::abs(v) <= dv ? 0.0 : v - std::copysign(dv, v);
  }
  v = std::clamp(v, -limits_.max_reverse_mps, limits_.max_speed_mps);

  // Steering: turns toward full lock while held, recentres when released, at a finite rate.
  const int steer = int(input.left) - int(input.right);
  const double target = steer * limits_.max_steer_rad;
  const double ds = limits_.steer_rate_radps * dt_s;
  state_.steer_rad += std::clamp(target - state_.steer_rad, -ds, ds);

  // Kinematic bicycle: yaw rate = v tan(δ) / L about the plane normal (left = counter-clockwise
  // seen from above, i.e. positive about +normal).
  const double yaw = v * std::tan(state_.steer_rad) / limits_.wheelbase_m * dt_s;
  const glm::dvec3 n = plane_.normal, f = state_.forward;
  const glm::dvec3 rotated = f * std::cos(yaw) + glm::cross(n, f) * std::sin(yaw);
  state_.forward = glm::normalize(rotated - glm::dot(rotated, n) * n);
  state_.position += state_.forward * (v * dt_s);
  state_.position -= (glm::dot(n, state_.position) - plane_.offset) * n;  // stay on the road
}

glm::dmat4 CarController::WorldFromCar() const {
  const glm::dvec3 x = state_.forward, y = plane_.normal, z = glm::normalize(glm::cross(x, y));
  glm::dmat4 m(1.0);
  m[0] = glm::dvec4(x, 0);
  m[1] = glm::dvec4(y, 0);
  m[2] = glm::dvec4(z, 0);
  m[3] = glm::dvec4(state_.position, 1);
  return m;
}

}  // namespace odvr::app
