#include "app/ar/frame_picker.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <numeric>

#include "core/error.h"

namespace odvr::app {

void FramePickerOptions::Check() const {
  if (light_neighbours < 1) throw Error("light neighbours", "must be at least 1");
  if (!(view_distance_m >= 0)) throw Error("view distance", "must be non-negative");
}

FramePicker::FramePicker(std::vector<glm::dvec3> camera_positions, FramePickerOptions options)
    : positions_(std::move(camera_positions)), options_(options) {
  options_.Check();
  if (positions_.empty()) throw Error("trajectory", "has no frames");
  for (const auto& p : positions_)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      throw Error("trajectory", "has a non-finite camera position");
  arc_.resize(positions_.size());
  arc_[0] = 0;
  for (std::size_t i = 1; i < positions_.size(); ++i)
    arc_[i] = arc_[i - 1] + glm::distance(positions_[i], positions_[i - 1]);
}

int FramePicker::NearestFrame(const glm::dvec3& p) const {
  int best = 0;
  double best_d = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < positions_.size(); ++i) {
    const double d = glm::distance(positions_[i], p);
    if (d < best_d) {
      best_d = d;
      best = static_cast<int>(i);
    }
  }
  return best;
}

std::vector<std::pair<int, double>> FramePicker::LightWeights(const glm::dvec3& car) const {
  std::vector<std::pair<double, int>> by_distance;
  by_distance.reserve(positions_.size());
  for (std::size_t i = 0; i < positions_.size(); ++i)
    by_distance.emplace_back(glm::distance(positions_[i], car), static_cast<int>(i));
  const std::size_t k = std::min<std::size_t>(static_cast<std::size_t>(options_.light_neighbours), by_distance.size());
  std::partial_sort(by_distance.begin(), by_distance.begin() + static_cast<std::ptrdiff_t>(k), by_distance.end());
  // A car (almost) at a camera takes that frame alone: 1/d would blow up.
  if (by_distance[0].first < 1e-6) return {{by_distance[0].second, 1.0}};
  std::vector<std::pair<int, double>> weights;
  double sum = 0;
  for (std::size_t i = 0; i < k; ++i) {
    const double w = 1.0 / by_distance[i].first;
    weights.emplace_back(by_distance[i].second, w);
    sum += w;
  }
  for (auto& [frame, w] : weights) w /= sum;
  return weights;
}

double FramePicker::ArcLengthOf(const glm::dvec3& p) const {
  if (positions_.size() == 1) return 0;
  double best_s = 0, best_d = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + 1 < positions_.size(); ++i) {
    const glm::dvec3 a = positions_[i], ab = positions_[i + 1] - a;
    const double len2 = glm::dot(ab, ab);
    // Duplicated frames give zero-length segments: treat them as points.
    const double t = len2 > 0 ? std::clamp(glm::dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
    const double d = glm::distance(a + t * ab, p);
    if (d < best_d) {
      best_d = d;
      best_s = arc_[i] + t * (arc_[i + 1] - arc_[i]);
    }
  }
  return best_s;
}

int FramePicker::ViewFrame(const glm::dvec3& car) const {
  const double s = std::max(0.0, ArcLengthOf(car) - options_.view_distance_m);
  const auto it = std::lower_bound(arc_.begin(), arc_.end(), s);
  if (it == arc_.end()) return frame_count() - 1;
  const auto i = static_cast<int>(it - arc_.begin());
  if (i > 0 && s - arc_[static_cast<std::size_t>(i - 1)] < *it - s) return i - 1;
  return i;
}

const std::map<int, double>& LightWeightSmoother::Update(const std::vector<std::pair<int, double>>& target,
                                                         double dt_s) {
  if (weights_.empty() || tau_ <= 0) {
    weights_.clear();
    for (const auto& [frame, w] : target) weights_[frame] = w;
    return weights_;
  }
  const double alpha = 1.0 - std::exp(-std::max(0.0, dt_s) / tau_);
  std::map<int, double> goal;
  for (const auto& [frame, w] : target) goal[frame] = w;
  for (auto& [frame, w] : weights_) w += alpha * ((goal.count(frame) ? goal[frame] : 0.0) - w);
  for (const auto& [frame, w] : goal)
    if (!weights_.count(frame)) weights_[frame] = alpha * w;
  double sum = 0;
  for (auto it = weights_.begin(); it != weights_.end();) {
    if (it->second < 1e-3) {
      it = weights_.erase(it);
    } else {
      sum += it->second;
      ++it;
    }
  }
  if (sum <= 0) {
    weights_.clear();
    for (const auto& [frame, w] : target) weights_[frame] = w;
    return weights_;
  }
  for (auto& [frame, w] : weights_) w /= sum;
  return weights_;
}

}  // namespace odvr::app
