#include "engine/sphere/healpix.h"

#include <healpix_base.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <memory>
#include <mutex>

#include "core/error.h"

namespace odvr::sphere {
namespace {
double AngleBetween(const glm::dvec3& a, const glm::dvec3& b) {
  // atan2 form: accurate for the tiny angles of deep levels, where acos(dot) loses digits.
  return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
}
}  // namespace

HealpixLevel::HealpixLevel(int level) : level_(level) {
  if (level < 0 || level > kMaxHealpixLevel)
    throw Error("healpix level",
                "must be in 0.." + std::to_string(kMaxHealpixLevel) + ", got " + std::to_string(level));
  const T_Healpix_Base<int> base(level, NEST);
  const int n = HealpixCount(level);
  centres_.resize(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    const vec3 v = base.pix2vec(i);
    centres_[static_cast<std::size_t>(i)] = FromHealpixFrame(v.x, v.y, v.z);
  }
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    double nearest = 10;
    for (int j : Neighbours(i)) {
      if (j >= 0) nearest = std::min(nearest, AngleBetween(centre(i), centre(j)));
    }
    sum += nearest;
  }
  mean_neighbour_angle_ = sum / n;
  lambda_ = std::log(0.5) / (std::cos(mean_neighbour_angle_ / 2) - 1);
  max_cell_radius_ = base.max_pixrad();
}

int HealpixLevel::CellOf(const glm::dvec3& d) const {
  const T_Healpix_Base<int> base(level_, NEST);
  const glm::dvec3 h = ToHealpixFrame(glm::normalize(d));
  return base.vec2pix(vec3(h.x, h.y, h.z));
}

std::array<int, 8> HealpixLevel::Neighbours(int i) const {
  const T_Healpix_Base<int> base(level_, NEST);
  fix_arr<int, 8> result;
  base.neighbors(i, result);
  std::array<int, 8> out{};
  for (int k = 0; k < 8; ++k) out[static_cast<std::size_t>(k)] = result[static_cast<std::size_t>(k)];
  return out;
}

const HealpixLevel& Healpix(int level) {
  static std::mutex mutex;
  static std::unique_ptr<HealpixLevel> levels[kMaxHealpixLevel + 1];
  if (level < 0 || level > kMaxHealpixLevel)
    throw Error("healpix level",
                "must be in 0.." + std::to_string(kMaxHealpixLevel) + ", got " + std::to_string(level));
  std::lock_guard lock(mutex);
  auto& slot = levels[level];
  if (!slot) slot = std::make_unique<HealpixLevel>(level);
  return *slot;
}

}  // namespace odvr::sphere
