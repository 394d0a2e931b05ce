#pragma once
// The renderer's camera (triple_product_renderer.h): OpenCV's convention (x right, y down,
// z forward), square pixels, principal point at the image centre, world frame +Y up, metres.
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

namespace odvr::render {

struct PinholeCamera {
  static constexpr int kMaxSide = 16384;  // pixels per side

  glm::dvec3 position{0, 1.5, 6};
  glm::dmat3 world_from_camera{1.0};  // columns: camera x (right), y (down), z (forward) in the world
  double vfov_deg = 40;
  int width = 640, height = 360;

  // Looks from `position` at `target` with `up` above the image. Throws odvr::Error for a
  // degenerate view (target at the position, up along the view) or a bad fov or size.
  static PinholeCamera LookAt(const glm::dvec3& position, const glm::dvec3& target, double vfov_deg, int width,
                              int height, const glm::dvec3& up = {0, 1, 0});
  double focal_px() const;
  // Unit world direction through continuous pixel coordinates (pixel centres at +0.5).
  glm::dvec3 Ray(double x, double y) const;
  void Check() const;  // throws odvr::Error naming the field
};

}  // namespace odvr::render
