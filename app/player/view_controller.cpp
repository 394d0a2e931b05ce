#include "app/player/view_controller.h"

#include <algorithm>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>

#include "core/constants.h"

namespace odvr::app {
namespace {
constexpr double kDeg = kPi / 180.0;
double WrapDeg(double a) {
  a = std::fmod(a, 360.0);
  if (a > 180) a -= 360;
  if (a <= -180) a += 360;
  return a;
}
}  // namespace

void ViewController::Set(ViewState s) {
  state_.yaw_deg = std::isfinite(s.yaw_deg) ? WrapDeg(s.yaw_deg) : 0;
  state_.pitch_deg = std::isfinite(s.pitch_deg) ? std::clamp(s.pitch_deg, -kMaxPitchDeg, kMaxPitchDeg) : 0;
  state_.fov_deg = std::isfinite(s.fov_deg) ? std::clamp(s.fov_deg, kMinFovDeg, kMaxFovDeg) : 90;
}

void ViewController::Drag(double dx_px, double dy_px, int viewport_height_px) {
  if (viewport_height_px <= 0) return;
  const double deg_per_px = state_.fov_deg / viewport_height_px;
  ViewState s = state_;
  s.yaw_deg -= dx_px * deg_per_px;
  s.pitch_deg += dy_px * deg_per_px;
  Set(s);
}

void ViewController::Scroll(double steps) {
  ViewState s = state_;
  s.fov_deg *= std::pow(0.95, steps);
  Set(s);
}

void ViewController::Turn(double yaw_dir, double pitch_dir, double dt_s, double deg_per_s) {
  ViewState s = state_;
  s.yaw_deg += yaw_dir * deg_per_s * dt_s;
  s.pitch_deg += pitch_dir * deg_per_s * dt_s;
  Set(s);
}

glm::dvec3 ViewController::Forward() const {
  const double yaw = state_.yaw_deg * kDeg, pitch = state_.pitch_deg * kDeg;
  return {std::cos(pitch) * std::cos(yaw), std::sin(pitch), std::cos(pitch) * std::sin(yaw)};
}

glm::dvec3 ViewController::Up() const {
  const double yaw = state_.yaw_deg * kDeg, pitch = state_.pitch_deg * kDeg;
  return {-std::sin(pitch) * std::cos(yaw), std::cos(pitch), -std::sin(pitch) * std::sin(yaw)};
}

glm::dmat4 ViewController::ViewMatrix() const { return glm::lookAt(glm::dvec3(0), Forward(), Up()); }

glm::dmat4 ViewController::ProjectionMatrix(double aspect, double near_m, double far_m) const {
  return glm::perspective(state_.fov_deg * kDeg, std::max(aspect, 1e-6), near_m, far_m);
}

}  // namespace odvr::app
