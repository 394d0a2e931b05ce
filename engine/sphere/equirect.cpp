#include "engine/sphere/equirect.h"

#include <algorithm>
#include <cmath>

namespace odvr::sphere {

glm::dvec3 EquirectDirection(double x, double y, int width, int height) {
  const double lon = kPi * (1.0 - 2.0 * x / width);
  const double lat = kPi / 2 - kPi * y / height;
  const double c = std::cos(lat);
  return {c * std::cos(lon), std::sin(lat), -c * std::sin(lon)};
}

glm::dvec2 EquirectPixel(const glm::dvec3& d, int width, int height) {
  const double len = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
  const double lat = std::asin(std::clamp(d.y / len, -1.0, 1.0));
  const double lon = std::atan2(-d.z, d.x);
  double x = 0.5 * (1.0 - lon / kPi) * width;
  if (x >= width) x -= width;
  if (x < 0) x += width;
  return {x, (kPi / 2 - lat) / kPi * height};
}

double EquirectPixelSolidAngle(int row, int width, int height) {
  const double lat_top = kPi / 2 - kPi * row / height;
  const double lat_bottom = kPi / 2 - kPi * (row + 1) / height;
  return 2.0 * kPi / width * (std::sin(lat_top) - std::sin(lat_bottom));
}

}  // namespace odvr::sphere
