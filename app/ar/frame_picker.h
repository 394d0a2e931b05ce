#pragma once
// Which recorded frames light the car and which one the viewer sees (seed §5.3.3, DESIGN.md §6).
// The seed lights the car with the frame whose camera is nearest to it; switching frames then
// pops, so the light here is a blend of the nearest frames' SG coefficients (the transform is
// linear, so blending coefficients = blending the lighting), with weights smoothed over time.
#include <glm/vec3.hpp>
#include <map>
#include <utility>
#include <vector>

namespace odvr::app {

struct FramePickerOptions {
  int light_neighbours = 3;      // frames blended for the car's light
  double view_distance_m = 6.0;  // the viewer's camera trails the car by this much along the path
  void Check() const;            // throws odvr::Error
};

class FramePicker {
 public:
  // Camera centre in the world for each frame, in frame order.
  FramePicker(std::vector<glm::dvec3> camera_positions, FramePickerOptions options = {});

  int frame_count() const { return static_cast<int>(positions_.size()); }
  // The frame whose camera is nearest to `p` (the seed's rule).
  int NearestFrame(const glm::dvec3& p) const;
  // The light_neighbours nearest frames with inverse-distance weights summing to 1; a car exactly
  // at a camera gets that frame alone. Far off the path the weights tend to equal.
  std::vector<std::pair<int, double>> LightWeights(const glm::dvec3& car) const;
  // Arc length along the camera path of the point of the path closest to `p` (clamped to the ends).
  double ArcLengthOf(const glm::dvec3& p) const;
  // The frame whose camera is view_distance_m behind the car along the path (clamped to the ends).
  int ViewFrame(const glm::dvec3& car) const;
  double path_length() const { return arc_.empty() ? 0 : arc_.back(); }
  // Arc length of frame k's camera along the path (frame order, from 0).
  double ArcLengthAt(int k) const { return arc_[static_cast<std::size_t>(k)]; }

 private:
  std::vector<glm::dvec3> positions_;
  std::vector<double> arc_;  // cumulative arc length at each frame
  FramePickerOptions options_;
};

// Exponential smoothing of light weights over time, so the car's light does not flicker as the
// nearest frames change: w ← w + (target − w)(1 − e^{−dt/τ}), renormalized, tiny weights dropped.
class LightWeightSmoother {
 public:
  explicit LightWeightSmoother(double time_constant_s = 0.25) : tau_(time_constant_s) {}
  const std::map<int, double>& Update(const std::vector<std::pair<int, double>>& target, double dt_s);
  const std::map<int, double>& weights() const { return weights_; }

 private:
  double tau_;
  std::map<int, double> weights_;
};

}  // namespace odvr::app
