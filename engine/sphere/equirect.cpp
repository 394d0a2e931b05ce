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

EquirectCap::EquirectCap(const glm::dvec3& axis, double cos_max, int width, int height)
    : width_(width), height_(height) {
  const double theta = cos_max <= -1 ? kPi : std::acos(std::min(cos_max, 1.0));
  const double lat_c = std::asin(std::clamp(axis.y, -1.0, 1.0));
  sin_lat_c_ = std::sin(lat_c);
  cos_lat_c_ = std::cos(lat_c);
  cos_theta_ = std::cos(theta);
  col_c_ = EquirectPixel(axis, width, height).x;
  first_row_ = std::max(0, static_cast<int>(std::floor((kPi / 2 - lat_c - theta) / kPi * height)));
  last_row_ = std::min(height - 1, static_cast<int>(std::ceil((kPi / 2 - lat_c + theta) / kPi * height)));
}

EquirectCap::Span EquirectCap::Columns(int row) const {
  // Half-width in longitude of the cap at this row's latitude (all columns near a pole).
  const double lat = kPi / 2 - kPi * (row + 0.5) / height_;
  const double denom = std::cos(lat) * cos_lat_c_;
  double half = kPi;
  if (denom > 1e-12) {
    const double x = (cos_theta_ - std::sin(lat) * sin_lat_c_) / denom;
    if (x > 1) return {};
    if (x > -1) half = std::acos(x);
  }
  // Centres within `half` of the axis's column, and a column more each side.
  int count = half >= kPi ? width_ : 2 * static_cast<int>(std::ceil(half / (2 * kPi) * width_)) + 3;
  count = std::min(count, width_);
  return {count == width_ ? 0 : static_cast<int>(std::floor(col_c_)) - count / 2, count};
}

}  // namespace odvr::sphere
