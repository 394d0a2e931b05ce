#include "tracking/road_plane.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "tracking/ransac.h"

namespace odvr::tracking {
namespace {

// Plane (n, d), |n| = 1, from 3 points (minimal) or a least-squares fit (more), kept only when its
// normal is within max_tilt of `up`: a facade or a parked car's side is then no candidate at all.
struct PlaneEstimator {
  using Datum = Eigen::Vector3d;
  using Model = Eigen::Vector4d;
  static constexpr int kMinimalSample = 3;

  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  double min_cos_tilt = 0.9;

  std::vector<Model> Estimate(const std::vector<Datum>& data) const {
    Eigen::Vector3d n;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& x : data) centroid += x;
    centroid /= static_cast<double>(data.size());
    if (data.size() == 3) {
      n = (data[1] - data[0]).cross(data[2] - data[0]);
    } else {
      Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
      for (const auto& x : data) scatter += (x - centroid) * (x - centroid).transpose();
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
      n = eig.eigenvectors().col(0);
    }
    const double len = n.norm();
    if (!(len > 1e-12)) return {};
    n /= len;
    if (n.dot(up) < 0) n = -n;
    if (n.dot(up) < min_cos_tilt) return {};
    Model m;
    m << n, -n.dot(centroid);
    return {m};
  }

  void Residuals(const std::vector<Datum>& data, const Model& m, std::vector<double>* r) const {
    r->resize(data.size());
    for (size_t i = 0; i < data.size(); ++i) (*r)[i] = std::abs(m.head<3>().dot(data[i]) + m(3));
  }
};

}  // namespace

void RoadPlaneOptions::Check() const {
  if (!(min_depression_deg >= 0 && min_depression_deg < 90))
    throw Error("road min_depression_deg", "must be in [0, 90)");
  if (!(max_side_angle_deg > 0 && max_side_angle_deg <= 90))
    throw Error("road max_side_angle_deg", "must be in (0, 90]");
  if (!(inlier_band > 0 && inlier_band < 1)) throw Error("road inlier_band", "must be in (0, 1)");
  if (!(max_tilt_deg > 0 && max_tilt_deg < 90)) throw Error("road max_tilt_deg", "must be in (0, 90)");
  if (min_inliers < 3) throw Error("road min_inliers", "must be >= 3");
}

RoadPlane FitRoadPlane(const std::vector<Eigen::Vector3d>& points, const std::vector<Rigid3>& world_from_rig,
                       double rig_height_m, const RoadPlaneOptions& options) {
  options.Check();
  RoadPlane plane;
  if (world_from_rig.empty()) {
    plane.message = "no rig poses";
    return plane;
  }
  Eigen::Vector3d up = Eigen::Vector3d::Zero();
  for (const auto& pose : world_from_rig) up += pose.rotation.col(2);
  up.normalize();

  const double tan_min = std::tan(options.min_depression_deg * M_PI / 180);
  const double tan_side = std::tan(options.max_side_angle_deg * M_PI / 180);
  std::vector<Eigen::Vector3d> candidates;
  std::vector<double> depths;
  for (const auto& x : points) {
    if (!x.allFinite()) continue;
    int nearest = 0;
    double best = std::numeric_limits<double>::infinity();
    for (int f = 0; f < static_cast<int>(world_from_rig.size()); ++f) {
      const double d = (world_from_rig[f].translation - x).squaredNorm();
      if (d < best) best = d, nearest = f;
    }
    const Eigen::Vector3d in_rig = world_from_rig[nearest].Inverse() * x;
    if (in_rig.z() >= 0 || -in_rig.z() < tan_min * in_rig.head<2>().norm()) continue;
    if (std::abs(in_rig.y()) > tan_side * -in_rig.z()) continue;
    candidates.push_back(x);
    depths.push_back(-in_rig.z());
  }
  plane.candidates = static_cast<int>(candidates.size());
  if (plane.candidates < options.min_inliers) {
    plane.message = "only " + std::to_string(plane.candidates) + " points lie below the rig (need " +
                    std::to_string(options.min_inliers) + ")";
    return plane;
  }
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  const double typical_depth = depths[depths.size() / 2];

  RansacOptions ransac;
  ransac.max_residual = options.inlier_band * typical_depth;
  ransac.max_iterations = 2000;
  PlaneEstimator estimator;
  estimator.up = up;
  estimator.min_cos_tilt = std::cos(options.max_tilt_deg * M_PI / 180);
  const auto result = Ransac<PlaneEstimator>(ransac, estimator).Estimate(candidates);
  plane.inliers = result.num_inliers;
  if (!result.success || result.num_inliers < options.min_inliers) {
    plane.message = "no level plane below the rig: " + std::to_string(result.num_inliers) + " of " +
                    std::to_string(plane.candidates) + " candidate points agree (need " +
                    std::to_string(options.min_inliers) + ")";
    return plane;
  }
  plane.normal = result.model.head<3>();
  plane.offset = result.model(3);
  double sq = 0;
  for (size_t i = 0; i < candidates.size(); ++i)
    if (result.inlier_mask[i]) sq += std::pow(plane.Distance(candidates[i]), 2);
  plane.rms_distance = std::sqrt(sq / result.num_inliers);
  double sum = 0, sum2 = 0;
  for (const auto& pose : world_from_rig) {
    const double h = plane.Distance(pose.translation);
    sum += h;
    sum2 += h * h;
  }
  const double n = static_cast<double>(world_from_rig.size());
  plane.rig_height = sum / n;
  plane.rig_height_spread = std::sqrt(std::max(0.0, sum2 / n - plane.rig_height * plane.rig_height));
  if (!(plane.rig_height > 0)) {
    plane.message = "the fitted plane lies above the rig";
    return plane;
  }
  plane.found = true;
  plane.scale = rig_height_m > 0 ? rig_height_m / plane.rig_height : 0;
  plane.message = "road plane from " + std::to_string(plane.inliers) + " of " + std::to_string(plane.candidates) +
                  " points below the rig, rig height " + std::to_string(plane.rig_height) + " units";
  return plane;
}

}  // namespace odvr::tracking
