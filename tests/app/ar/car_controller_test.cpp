#include "app/ar/car_controller.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>

#include "core/error.h"

namespace odvr::app {
namespace {

void Drive(CarController& car, CarInput input, double seconds, double dt = 1.0 / 60) {
  for (double t = 0; t < seconds; t += dt) car.Step(input, dt);
}

TEST(CarController, AcceleratesToTheSpeedLimitAndRollsToAStop) {
  CarController car(GroundPlane{});
  Drive(car, {.forward = true}, 10);
  EXPECT_NEAR(car.state().speed_mps, CarLimits{}.max_speed_mps, 1e-9);
  EXPECT_GT(car.state().position.x, 50);
  EXPECT_NEAR(car.state().position.z, 0, 1e-9);  // straight ahead
  Drive(car, {}, 20);
  EXPECT_EQ(car.state().speed_mps, 0.0);
}

TEST(CarController, LeftTurnsTowardMinusZAndTheTurnRadiusMatchesTheBicycleModel) {
  CarLimits limits;
  CarController car(GroundPlane{}, limits);
  Drive(car, {.forward = true}, 1.0);  // a little speed first
  const double v = car.state().speed_mps;
  CarInput turn{.left = true};
  Drive(car, turn, 1.0);  // steering reaches full lock (0.55 rad at 1.6 rad/s)
  EXPECT_NEAR(car.state().steer_rad, limits.max_steer_rad, 1e-9);
  EXPECT_LT(car.state().forward.z, 0);  // left is −Z in odvr's frame (+Z is right)
  // Heading change over a short step at full lock: Δψ = v tan δ / L · dt.
  const glm::dvec3 before = car.state().forward;
  car.Step(turn, 0.01);
  const double speed = car.state().speed_mps;  // the step integrates with its updated speed
  const double dpsi = std::acos(std::clamp(glm::dot(before, car.state().forward), -1.0, 1.0));
  EXPECT_NEAR(dpsi, speed * std::tan(limits.max_steer_rad) / limits.wheelbase_m * 0.01, 1e-6);
  EXPECT_GT(v, 0);
}

TEST(CarController, StaysOnATiltedRoadPlane) {
  const GroundPlane plane{glm::normalize(glm::dvec3(0.05, 1, -0.02)), 1.7};
  CarController car(plane);
  car.Reset({3, 10, 4}, {1, 0, 0});
  Drive(car, {.forward = true, .right = true}, 5);
  EXPECT_NEAR(glm::dot(plane.normal, car.state().position), plane.offset, 1e-9);
  const glm::dmat4 m = car.WorldFromCar();
  EXPECT_NEAR(glm::dot(glm::dvec3(m[1]), plane.normal), 1.0, 1e-12);  // car up = road normal
  EXPECT_NEAR(glm::dot(glm::dvec3(m[0]), glm::dvec3(m[2])), 0.0, 1e-12);
}

TEST(CarController, BrakesFasterThanItAcceleratesAndReversesSlowly) {
  CarController car(GroundPlane{});
  Drive(car, {.forward = true}, 2);
  const double v = car.state().speed_mps;
  Drive(car, {.backward = true}, v / CarLimits{}.braking_mps2 + 0.01);
  EXPECT_NEAR(car.state().speed_mps, 0, 0.2);
  Drive(car, {.backward = true}, 10);
  EXPECT_NEAR(car.state().speed_mps, -CarLimits{}.max_reverse_mps, 1e-9);
}

TEST(CarController, AHugeTimeStepCannotLaunchTheCar) {
  CarController car(GroundPlane{});
  car.Step({.forward = true}, 30.0);  // the window was dragged for 30 s
  EXPECT_LT(car.state().speed_mps, 1.0);
  car.Step({.forward = true}, std::nan(""));
  EXPECT_TRUE(std::isfinite(car.state().position.x));
}

TEST(CarController, BadLimitsAndPlanesAreClearErrors) {
  EXPECT_THROW(CarController(GroundPlane{{0, 0, 0}, 0}), Error);
  CarLimits bad;
  bad.wheelbase_m = 0;
  EXPECT_THROW(CarController(GroundPlane{}, bad), Error);
}

}  // namespace
}  // namespace odvr::app
