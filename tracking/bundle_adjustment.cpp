#include "tracking/bundle_adjustment.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

#include "core/error.h"

namespace odvr::tracking {
namespace {

// Two unit vectors spanning the tangent plane at `b`.
void TangentBasis(const Eigen::Vector3d& b, Eigen::Vector3d* u, Eigen::Vector3d* v) {
  *u = b.unitOrthogonal();
  *v = b.cross(*u);
}

// Pose block: rig_from_world as angle-axis (3) then translation (3).
struct BearingResidual {
  BearingResidual(const Eigen::Vector3d& bearing, const Rigid3& cam_from_rig, double focal_px)
      : bearing_(bearing.normalized()), cam_from_rig_(cam_from_rig), focal_(focal_px) {
    TangentBasis(bearing_, &u_, &v_);
  }

  template <typename T>
  bool operator()(const T* pose, const T* point, T* residual) const {
    T in_rig[3];
    ceres::AngleAxisRotatePoint(pose, point, in_rig);
    for (int k = 0; k < 3; ++k) in_rig[k] += pose[3 + k];
    T in_cam[3];
    for (int r = 0; r < 3; ++r)
      in_cam[r] = T(cam_from_rig_.rotation(r, 0)) * in_rig[0] + T(cam_from_rig_.rotation(r, 1)) * in_rig[1] +
                  T(cam_from_rig_.rotation(r, 2)) * in_rig[2] + T(cam_from_rig_.translation(r));
    const T norm = ceres::sqrt(in_cam[0] * in_cam[0] + in_cam[1] * in_cam[1] + in_cam[2] * in_cam[2]);
    if (!(norm > T(1e-12))) return false;
    T du = T(0), dv = T(0), db = T(0);
    for (int k = 0; k < 3; ++k) {
      du += T(u_(k)) * in_cam[k];
      dv += T(v_(k)) * in_cam[k];
      db += T(bearing_(k)) * in_cam[k];
    }
    residual[0] = T(focal_) * du / norm;
    residual[1] = T(focal_) * dv / norm;
    // The tangent components alone would let a point sit behind the camera, opposite the ray;
    // a flat penalty of two focal lengths keeps such a point on the robust loss's flat tail
    // until the outlier pass removes it.
    if (db < T(0)) residual[0] += T(2 * focal_);
    return true;
  }

  Eigen::Vector3d bearing_, u_, v_;
  Rigid3 cam_from_rig_;
  double focal_;
};

// (|c_b - c_a| - distance) / sigma for the rig centres c = -R^T t of two rig_from_world blocks.
struct ScaleResidual {
  explicit ScaleResidual(const ScalePrior& prior) : prior_(prior) {}

  template <typename T>
  static void Center(const T* pose, T* c) {
    const T inverse[3] = {-pose[0], -pose[1], -pose[2]};
    const T t[3] = {-pose[3], -pose[4], -pose[5]};
    ceres::AngleAxisRotatePoint(inverse, t, c);
  }

  template <typename T>
  bool operator()(const T* a, const T* b, T* residual) const {
    T ca[3], cb[3];
    Center(a, ca);
    Center(b, cb);
    const T d2 =
        (cb[0] - ca[0]) * (cb[0] - ca[0]) + (cb[1] - ca[1]) * (cb[1] - ca[1]) + (cb[2] - ca[2]) * (cb[2] - ca[2]);
    if (!(d2 > T(0))) return false;
    residual[0] = (ceres::sqrt(d2) - T(prior_.distance)) / T(prior_.sigma);
    return true;
  }

  ScalePrior prior_;
};

std::array<double, 6> PoseBlock(const Rigid3& world_from_rig) {
  const Rigid3 rig_from_world = world_from_rig.Inverse();
  std::array<double, 6> block{};
  const Eigen::AngleAxisd aa(rig_from_world.rotation);
  const Eigen::Vector3d v = aa.angle() * aa.axis();
  for (int k = 0; k < 3; ++k) {
    block[k] = v(k);
    block[3 + k] = rig_from_world.translation(k);
  }
  return block;
}

Rigid3 FromPoseBlock(const std::array<double, 6>& block) {
  Rigid3 rig_from_world;
  const Eigen::Vector3d v(block[0], block[1], block[2]);
  const double angle = v.norm();
  rig_from_world.rotation =
      angle > 0 ? Eigen::AngleAxisd(angle, v / angle).toRotationMatrix() : Eigen::Matrix3d::Identity();
  rig_from_world.translation = Eigen::Vector3d(block[3], block[4], block[5]);
  return rig_from_world.Inverse();
}

class ProgressCallback : public ceres::IterationCallback {
 public:
  explicit ProgressCallback(const std::function<void(const std::string&)>& sink) : sink_(sink) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    char line[160];
    std::snprintf(line, sizeof line, "bundle adjustment iter %3d  cost %.6e  |step| %.2e  trust %.1e  %.2f s",
                  s.iteration, s.cost, s.step_norm, s.trust_region_radius, s.cumulative_time_in_seconds);
    sink_(line);
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const std::function<void(const std::string&)>& sink_;
};

double RmsePx(const BundleAdjustmentProblem& p) {
  double sum = 0;
  int n = 0;
  for (const auto& o : p.observations) {
    const double r = BundleAdjustmentResidualPx(p, o);
    if (!std::isfinite(r)) continue;
    sum += r * r;
    ++n;
  }
  return n > 0 ? std::sqrt(sum / n) : 0.0;
}

}  // namespace

void BundleAdjustmentOptions::Check() const {
  if (!(loss_scale_px > 0)) throw Error("bundle adjustment loss_scale_px", "must be > 0");
  if (max_iterations < 1) throw Error("bundle adjustment max_iterations", "must be >= 1");
  if (!(function_tolerance > 0)) throw Error("bundle adjustment function_tolerance", "must be > 0");
  if (threads < 1) throw Error("bundle adjustment threads", "must be >= 1");
}

double BundleAdjustmentResidualPx(const BundleAdjustmentProblem& p, const BundleAdjustmentObservation& o) {
  const Rigid3& cam_in_rig = p.rig.rig_from_cam[o.camera];
  const Eigen::Vector3d in_cam = cam_in_rig.Inverse() * (p.world_from_rig[o.frame].Inverse() * p.points[o.point]);
  if (!(in_cam.dot(o.bearing) > 0)) return std::numeric_limits<double>::infinity();
  return p.rig.focal_px[o.camera] * std::atan2(in_cam.cross(o.bearing).norm(), in_cam.dot(o.bearing));
}

BundleAdjustmentReport AdjustBundle(const BundleAdjustmentOptions& options, BundleAdjustmentProblem* p) {
  options.Check();
  const auto t0 = std::chrono::steady_clock::now();
  const int frames = static_cast<int>(p->world_from_rig.size());
  const int points = static_cast<int>(p->points.size());
  if (static_cast<int>(p->pose_constant.size()) != frames)
    throw Error("bundle adjustment", "pose_constant has " + std::to_string(p->pose_constant.size()) + " entries for " +
                                         std::to_string(frames) + " poses");
  bool gauge = false;
  for (char c : p->pose_constant) gauge = gauge || c;
  if (!gauge) throw Error("bundle adjustment", "no pose is held constant: the gauge would float");
  for (const auto& pose : p->world_from_rig)
    if (!pose.AllFinite()) throw Error("bundle adjustment", "a pose is not finite");
  for (const auto& x : p->points)
    if (!x.allFinite()) throw Error("bundle adjustment", "a point is not finite");
  // Before anything indexes with them (the initial RMSE included).
  for (const auto& o : p->observations)
    if (o.frame < 0 || o.frame >= frames || o.point < 0 || o.point >= points || o.camera < 0 ||
        o.camera >= p->rig.camera_count())
      throw Error("bundle adjustment", "observation refers to frame " + std::to_string(o.frame) + ", camera " +
                                           std::to_string(o.camera) + ", point " + std::to_string(o.point) +
                                           ", out of range");

  std::vector<std::array<double, 6>> pose_blocks(frames);
  for (int f = 0; f < frames; ++f) pose_blocks[f] = PoseBlock(p->world_from_rig[f]);
  std::vector<std::array<double, 3>> point_blocks(points);
  for (int i = 0; i < points; ++i) point_blocks[i] = {p->points[i].x(), p->points[i].y(), p->points[i].z()};

  BundleAdjustmentReport report;
  report.initial_rmse_px = RmsePx(*p);

  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  ceres::CauchyLoss loss(options.loss_scale_px);
  std::vector<char> used_pose(frames, 0), used_point(points, 0);
  for (const auto& o : p->observations) {
    auto* cost = new ceres::AutoDiffCostFunction<BearingResidual, 2, 6, 3>(
        new BearingResidual(o.bearing, p->rig.rig_from_cam[o.camera].Inverse(), p->rig.focal_px[o.camera]));
    problem.AddResidualBlock(cost, &loss, pose_blocks[o.frame].data(), point_blocks[o.point].data());
    used_pose[o.frame] = used_point[o.point] = 1;
  }
  if (p->scale_prior.enabled) {
    const ScalePrior& prior = p->scale_prior;
    if (prior.frame_a < 0 || prior.frame_a >= frames || prior.frame_b < 0 || prior.frame_b >= frames ||
        prior.frame_a == prior.frame_b || !used_pose[prior.frame_a] || !used_pose[prior.frame_b] ||
        !(prior.sigma > 0) || !(prior.distance > 0))
      throw Error("bundle adjustment", "the scale prior needs two distinct observed frames, a distance and sigma > 0");
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<ScaleResidual, 1, 6, 6>(new ScaleResidual(prior)), nullptr,
                             pose_blocks[prior.frame_a].data(), pose_blocks[prior.frame_b].data());
  }
  if (problem.NumResidualBlocks() == 0) {
    report.message = "no observations";
    return report;
  }
  for (int f = 0; f < frames; ++f)
    if (used_pose[f] && p->pose_constant[f]) problem.SetParameterBlockConstant(pose_blocks[f].data());

  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::SPARSE_SCHUR;
  // The reduced camera system is tiny (6 per frame); ordering points first is what Schur needs.
  auto* ordering = new ceres::ParameterBlockOrdering;
  for (int i = 0; i < points; ++i)
    if (used_point[i]) ordering->AddElementToGroup(point_blocks[i].data(), 0);
  for (int f = 0; f < frames; ++f)
    if (used_pose[f]) ordering->AddElementToGroup(pose_blocks[f].data(), 1);
  solver.linear_solver_ordering.reset(ordering);
  solver.max_num_iterations = options.max_iterations;
  solver.function_tolerance = options.function_tolerance;
  solver.num_threads = options.threads;
  solver.minimizer_progress_to_stdout = false;
  solver.logging_type = ceres::SILENT;
  ProgressCallback callback(options.progress);
  if (options.progress) solver.callbacks.push_back(&callback);
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);

  report.iterations = static_cast<int>(summary.iterations.size());
  report.message = summary.BriefReport();
  report.converged = summary.IsSolutionUsable();
  if (report.converged) {
    for (int f = 0; f < frames; ++f)
      if (used_pose[f] && !p->pose_constant[f]) p->world_from_rig[f] = FromPoseBlock(pose_blocks[f]);
    for (int i = 0; i < points; ++i)
      if (used_point[i]) p->points[i] = Eigen::Vector3d(point_blocks[i][0], point_blocks[i][1], point_blocks[i][2]);
  }
  report.final_rmse_px = RmsePx(*p);
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return report;
}

}  // namespace odvr::tracking
