#pragma once
// The drivable car: a kinematic bicycle model on the road plane, with speed and steering limits,
// driven by WASD/arrow keys. The plane comes from tracking (road fitted to the reconstruction);
// the car's pose is built on it so the car stands on the road wherever it is driven.
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

namespace odvr::app {

struct CarLimits {
  double max_speed_mps = 14.0;  // ~50 km/h: a street
  double max_reverse_mps = 4.0;
  double acceleration_mps2 = 3.5;
  double braking_mps2 = 8.0;
  double rolling_decel_mps2 = 1.5;  // no pedal: the car slows down by itself
  double max_steer_rad = 0.55;
  double steer_rate_radps = 1.6;
  double wheelbase_m = 2.6;
  void Check() const;  // throws odvr::Error
};

struct CarInput {
  bool forward = false, backward = false, left = false, right = false;
};

// A plane n·x = d with unit normal n pointing up (away from the ground).
struct GroundPlane {
  glm::dvec3 normal{0, 1, 0};
  double offset = 0;
};

struct CarState {
  glm::dvec3 position{0};       // on the plane
  glm::dvec3 forward{1, 0, 0};  // unit, in the plane
  double speed_mps = 0;         // signed along forward
  double steer_rad = 0;
};

class CarController {
 public:
  CarController(GroundPlane plane, CarLimits limits = {});
  // Places the car on the plane at (the projection of) `position`, heading along `forward`.
  void Reset(const glm::dvec3& position, const glm::dvec3& forward);
  void Step(const CarInput& input, double dt_s);
  // Stands the car still where it is (speed and steering to 0), keeping its heading.
  void Stop();
  const CarState& state() const { return state_; }
  // Car frame: +X forward, +Y up (the plane normal), +Z right, as the glTF car is modelled.
  glm::dmat4 WorldFromCar() const;

 private:
  GroundPlane plane_;
  CarLimits limits_;
  CarState state_;
};

}  // namespace odvr::app
