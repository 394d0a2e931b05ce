#pragma once
// Bundle adjustment of the rig (seed §5.3.2): rig poses and scene points refined together with
// Ceres, the camera-in-rig extrinsics held fixed (they come from calibration and the rig is
// rigid), a robust loss so the tracks RANSAC let through cannot drag the solution, the gauge fixed
// by holding chosen poses constant, and the sparse Schur complement that eliminates the points.
//
// Residuals live on the unit sphere, not in one camera model's pixels: the angle between the
// observed bearing and the direction to the point, split into its two tangent components and
// scaled by the camera's focal length. Near the optimum that equals the pixel error of any model
// (fisheye, pinhole, equirect) and it stays defined for rays beyond 90 degrees, where a fisheye's
// corners look.
#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "tracking/rig_pose.h"

namespace odvr::tracking {

struct BundleAdjustmentOptions {
  // Cauchy loss scale (pixels): residuals well above it count like outliers. KLT tracks are
  // sub-pixel; 1.5 px keeps the quadratic region for them and flattens the rest.
  double loss_scale_px = 1.5;
  int max_iterations = 100;
  double function_tolerance = 1e-7;
  int threads = 2;
  // Called with one line per Ceres iteration (iteration, cost, |step|, time); empty: silent.
  std::function<void(const std::string&)> progress;

  // Throws odvr::Error naming the first bad parameter.
  void Check() const;
};

struct BundleAdjustmentObservation {
  int frame = 0;  // index into world_from_rig
  int camera = 0;
  int point = 0;            // index into points
  Eigen::Vector3d bearing;  // unit, camera frame
};

// Holds the scale: the distance between the rig centres of two frames stays `distance` within
// `sigma`. With the first pose constant this fixes the seventh gauge freedom. The camera offsets
// make the scale observable only in principle: on street_a's 8 cm offsets a bundle adjustment left
// alone moved a metric world's scale by 3-30 %, so once the road has given the scale it is kept.
struct ScalePrior {
  bool enabled = false;
  int frame_a = 0, frame_b = 0;
  double distance = 0;
  double sigma = 1e-4;
};

struct BundleAdjustmentProblem {
  RigGeometry rig;
  std::vector<Rigid3> world_from_rig;   // per frame; refined in place
  std::vector<char> pose_constant;      // per frame; non-zero: held fixed (the gauge)
  std::vector<Eigen::Vector3d> points;  // world; refined in place
  std::vector<BundleAdjustmentObservation> observations;
  ScalePrior scale_prior;
};

struct BundleAdjustmentReport {
  bool converged = false;  // Ceres reported a usable solution (converged or out of iterations)
  int iterations = 0;
  double initial_rmse_px = 0;  // tangent-plane residual RMSE before and after (no loss applied)
  double final_rmse_px = 0;
  double seconds = 0;
  std::string message;  // Ceres's brief report
};

// Refines problem->world_from_rig and problem->points. Throws odvr::Error when an index is out of
// range, no pose is held constant (the gauge would float) or a value is not finite.
BundleAdjustmentReport AdjustBundle(const BundleAdjustmentOptions& options, BundleAdjustmentProblem* problem);

// The residual of one observation (pixels at the camera's focal length) under the current values;
// what AdjustBundle minimizes, without the loss. +inf for a point behind the camera.
double BundleAdjustmentResidualPx(const BundleAdjustmentProblem& problem, const BundleAdjustmentObservation& o);

}  // namespace odvr::tracking
