// PinholeCamera (engine/render/pinhole_camera.h): OpenCV's axes from LookAt, the rays and focal
// length of a known field of view, and the sizes and poses it refuses.
#include "engine/render/pinhole_camera.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <string>
#include <utility>

#include "core/error.h"

namespace odvr::render {
namespace {

TEST(PinholeCamera, LookAtIsOpenCv) {
  const PinholeCamera c = PinholeCamera::LookAt({0, 1, 5}, {0, 1, 0}, 60, 200, 100);
  // Looking down −Z with +Y up: camera x = +X (right), y = −Y (down), z = −Z (forward).
  EXPECT_NEAR(glm::length(c.world_from_camera[0] - glm::dvec3(1, 0, 0)), 0, 1e-12);
  EXPECT_NEAR(glm::length(c.world_from_camera[1] - glm::dvec3(0, -1, 0)), 0, 1e-12);
  EXPECT_NEAR(glm::length(c.world_from_camera[2] - glm::dvec3(0, 0, -1)), 0, 1e-12);
  // The top row's centre ray: 49.5 pixels above the axis, f = 50 / tan 30°.
  const glm::dvec3 top = c.Ray(100, 0.5);
  EXPECT_NEAR(std::atan2(top.y, -top.z), std::atan(49.5 / 50 * std::tan(3.14159265358979 / 6)), 1e-12);
  EXPECT_NEAR(c.focal_px(), 50 / std::tan(3.14159265358979 / 6), 1e-9);
  EXPECT_THROW(PinholeCamera::LookAt({0, 1, 5}, {0, 1, 5}, 60, 200, 100), Error);
  EXPECT_THROW(PinholeCamera::LookAt({0, 5, 0}, {0, 0, 0}, 60, 200, 100), Error);  // straight down, up = +Y
  EXPECT_THROW(PinholeCamera::LookAt({0, 1, 5}, {0, 1, 0}, 0, 200, 100), Error);
  EXPECT_THROW(PinholeCamera::LookAt({0, 1, 5}, {0, 1, 0}, 60, 0, 100), Error);
}

TEST(PinholeCamera, SizeBeyondItsLimitIsAClearError) {
  PinholeCamera camera;
  camera.width = PinholeCamera::kMaxSide;
  camera.height = 8;
  EXPECT_NO_THROW(camera.Check());
  for (const auto& [w, h] : {std::pair{PinholeCamera::kMaxSide + 1, 8}, std::pair{8, PinholeCamera::kMaxSide + 1},
                             std::pair{0, 8}, std::pair{8, -1}}) {
    camera.width = w;
    camera.height = h;
    try {
      camera.Check();
      ADD_FAILURE() << w << "x" << h << " accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("camera size"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(std::to_string(w) + "x" + std::to_string(h)), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace odvr::render
