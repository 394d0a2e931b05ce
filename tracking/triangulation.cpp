#include "tracking/triangulation.h"

#include <Eigen/Dense>
#include <cmath>
#include <string>

#include "core/error.h"

namespace odvr::tracking {

bool TriangulateDlt(const std::vector<Eigen::Vector3d>& bearings, const std::vector<CamFromWorld>& cam_from_world,
                    TriangulatedPoint* out) {
  const int n = static_cast<int>(bearings.size());
  if (n != static_cast<int>(cam_from_world.size()))
    throw Error("triangulation",
                std::to_string(n) + " bearings but " + std::to_string(cam_from_world.size()) + " poses");
  if (n < 2) throw Error("triangulation", "needs at least 2 views, got " + std::to_string(n));

  // b x (R X + t) = 0 in homogeneous X = (x, w): [b]x [R | t] X = 0. All three rows of each cross
  // product are kept: which two are independent depends on the bearing's direction (a 360-degree
  // camera has no "z = 1" to drop), and the SVD does not mind the redundant one. Unit bearings
  // and rotations keep the rows of different views at comparable scale.
  Eigen::MatrixXd a(3 * n, 4);
  for (int v = 0; v < n; ++v) {
    const Eigen::Vector3d b = bearings[v].normalized();
    Eigen::Matrix3d skew;
    skew << 0, -b.z(), b.y(), b.z(), 0, -b.x(), -b.y(), b.x(), 0;
    Eigen::Matrix<double, 3, 4> p;
    p << cam_from_world[v].rotation, cam_from_world[v].translation;
    a.middleRows(3 * v, 3) = skew * p;
  }
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeFullV);
  const Eigen::Vector4d x = svd.matrixV().col(3);
  // Parallel rays leave a pencil of solutions (a second zero singular value): no unique point.
  const Eigen::Vector4d sv = svd.singularValues().head<4>();
  if (!(sv(0) > 0) || sv(2) < 1e-12 * sv(0)) return false;
  // Scale of w relative to the translations: a point at (numerical) infinity has w ~ 0.
  double scale = 1;
  for (const auto& pose : cam_from_world) scale = std::max(scale, pose.translation.norm());
  if (!(std::abs(x(3)) * scale > 1e-12 * x.head<3>().norm())) return false;
  out->point = x.head<3>() / x(3);
  if (!out->point.allFinite()) return false;

  out->in_front = true;
  out->max_angular_error_rad = 0;
  std::vector<Eigen::Vector3d> rays;
  for (int v = 0; v < n; ++v) {
    const Eigen::Vector3d in_cam = cam_from_world[v] * out->point;
    const Eigen::Vector3d b = bearings[v].normalized();
    if (!(in_cam.dot(b) > 0)) out->in_front = false;
    out->max_angular_error_rad =
        std::max(out->max_angular_error_rad, std::atan2(b.cross(in_cam).norm(), b.dot(in_cam)));
    rays.push_back(cam_from_world[v].rotation.transpose() * b);  // world-frame ray direction
  }
  double max_parallax = 0;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j)
      max_parallax = std::max(max_parallax, std::atan2(rays[i].cross(rays[j]).norm(), rays[i].dot(rays[j])));
  out->parallax_deg = max_parallax * 180 / M_PI;
  return true;
}

}  // namespace odvr::tracking
