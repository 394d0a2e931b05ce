#include "engine/render/pinhole_camera.h"

#include <cmath>
#include <glm/geometric.hpp>
#include <string>

#include "core/constants.h"
#include "core/error.h"

namespace odvr::render {

PinholeCamera PinholeCamera::LookAt(const glm::dvec3& position, const glm::dvec3& target, double vfov_deg, int width,
                                    int height, const glm::dvec3& up) {
  const glm::dvec3 forward = target - position;
  if (!(glm::length(forward) > 1e-9)) throw Error("camera", "target coincides with the position");
  const glm::dvec3 z = glm::normalize(forward);
  const glm::dvec3 side = glm::cross(z, up);
  if (!(glm::length(side) > 1e-9 * glm::length(up))) throw Error("camera", "view direction is parallel to up");
  const glm::dvec3 x = glm::normalize(side);
  PinholeCamera c;
  c.position = position;
  c.world_from_camera = glm::dmat3(x, glm::cross(z, x), z);
  c.vfov_deg = vfov_deg;
  c.width = width;
  c.height = height;
  c.Check();
  return c;
}

double PinholeCamera::focal_px() const { return 0.5 * height / std::tan(0.5 * vfov_deg * kPi / 180.0); }

glm::dvec3 PinholeCamera::Ray(double x, double y) const {
  const double f = focal_px();
  return glm::normalize(world_from_camera * glm::dvec3((x - 0.5 * width) / f, (y - 0.5 * height) / f, 1.0));
}

void PinholeCamera::Check() const {
  if (!(vfov_deg > 0.1 && vfov_deg < 179)) throw Error("camera fov", "must be in (0.1, 179) degrees");
  if (width < 1 || height < 1 || width > kMaxSide || height > kMaxSide)
    throw Error("camera size", "must be 1.." + std::to_string(kMaxSide) + " pixels per side, got " +
                                   std::to_string(width) + "x" + std::to_string(height));
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(position[i])) throw Error("camera position", "must be finite");
}

}  // namespace odvr::render
