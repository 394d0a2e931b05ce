#pragma once
// SVD (DLT) triangulation of one point from N >= 2 unit bearings with known camera poses (seed
// §5.3.2: "SVD based triangulation, followed by an optimization step"; the refinement is bundle
// adjustment's job). Bearings rather than pixels, so fisheye, pinhole and equirect observations
// mix freely (STYLE.md).
#include <Eigen/Core>
#include <vector>

namespace odvr::tracking {

// x_cam = rotation * x_world + translation (COLMAP's rigid3 convention, STYLE.md).
struct CamFromWorld {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Vector3d operator*(const Eigen::Vector3d& x_world) const { return rotation * x_world + translation; }
  Eigen::Vector3d center() const { return -rotation.transpose() * translation; }
};

struct TriangulatedPoint {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // world frame
  // Largest angle between an observed bearing and the direction to the point (radians); the
  // model-independent reprojection error.
  double max_angular_error_rad = 0;
  // Largest angle between two viewing rays (degrees). Small parallax means depth is ill
  // determined even when the angular error is small; callers gate on it.
  double parallax_deg = 0;
  bool in_front = false;  // the point lies in front of (angle < 90 degrees to) every bearing
};

// Minimizes sum_v |[b_v]x (R_v X + t_v)|^2 over homogeneous X with |X| = 1 (each view's rows
// scaled by its distance-free form, so near and far cameras weigh alike). False when the rays
// are (nearly) parallel or the solution is at infinity; `out` is then unspecified. Throws
// odvr::Error("triangulation", ...) when the counts differ or fewer than 2 views are given.
bool TriangulateDlt(const std::vector<Eigen::Vector3d>& bearings, const std::vector<CamFromWorld>& cam_from_world,
                    TriangulatedPoint* out);

}  // namespace odvr::tracking
