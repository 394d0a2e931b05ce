#pragma once
// Poses of the calibrated rig from bearing vectors (seed §5.3.2's visual odometry): the
// non-central relative pose of two rig frames (OpenGV's 17-point solver) and the non-central
// absolute pose of one frame against triangulated points (OpenGV's gP3P, gPnP for refits),
// both plugged into the generic RANSAC of tracking/ransac.h so the project has one sampler, one
// stopping rule and one local optimisation (STYLE.md). Residuals are angles expressed in pixels
// (angle times a focal length), so one threshold reads the same for every estimator.
#include <Eigen/Core>
#include <vector>

#include "capture/rig.h"

namespace odvr::tracking {

// A rigid transform: y = rotation * x + translation.
struct Rigid3 {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Vector3d operator*(const Eigen::Vector3d& x) const { return rotation * x + translation; }
  Rigid3 operator*(const Rigid3& o) const { return {rotation * o.rotation, rotation * o.translation + translation}; }
  Rigid3 Inverse() const { return {rotation.transpose(), -(rotation.transpose() * translation)}; }
  Eigen::Matrix4d Matrix() const;
  static Rigid3 FromMatrix(const Eigen::Matrix4d& m);
  bool AllFinite() const { return rotation.allFinite() && translation.allFinite(); }
};

// Where each camera sits in the rig (rig_from_cam), the part of capture::Rig the geometry needs.
struct RigGeometry {
  std::vector<Rigid3> rig_from_cam;
  std::vector<double> focal_px;  // per camera, (fx + fy) / 2: converts angles to pixels

  static RigGeometry FromRig(const capture::Rig& rig);
  int camera_count() const { return static_cast<int>(rig_from_cam.size()); }
  // Every camera at one centre (one camera, or offsets under a micrometre): the rig is then a
  // central camera and needs the central solvers (central_pose.h).
  bool central() const;
};

// OpenGV's [R | t] as a Rigid3, its rotation projected back onto SO(3) (the linear solvers
// return one only up to numerical noise, and composing many frames would accumulate shear).
Rigid3 RigidFromOpenGv(const Eigen::Matrix<double, 3, 4>& transformation);
// A proper rotation to 1e-6.
bool IsRotation(const Eigen::Matrix3d& r);

// The same scene point seen in rig frame 1 by camera1 and in rig frame 2 by camera2 (any two
// cameras: a point that moved from the front camera into a side one still constrains the motion).
struct RigBearingPair {
  Eigen::Vector3d bearing1, bearing2;  // unit, in each camera's frame
  int camera1 = 0, camera2 = 0;
};

// The two rays triangulated by their midpoint; the larger angle between an observed bearing and
// the direction to the midpoint, in radians. +inf when the point lies behind either camera.
double TwoRayAngularError(const Eigen::Vector3d& origin1, const Eigen::Vector3d& direction1,
                          const Eigen::Vector3d& origin2, const Eigen::Vector3d& direction2);

// Model: rig1_from_rig2. The translation's length comes from the cameras' offsets in the rig, the
// only metric length a non-central rig sees: with 8 cm offsets and a street metres away it is
// poorly determined, so callers fix the scale elsewhere (the road plane).
struct RigRelativePoseEstimator {
  using Datum = RigBearingPair;
  using Model = Rigid3;
  static constexpr int kMinimalSample = 17;

  const RigGeometry* rig = nullptr;
  double focal_px = 1;  // residual unit: pixels at this focal length

  std::vector<Model> Estimate(const std::vector<Datum>& data) const;
  void Residuals(const std::vector<Datum>& data, const Model& model, std::vector<double>* residuals) const;
};

// A triangulated world point seen by one camera of the rig.
struct RigBearingPoint {
  Eigen::Vector3d bearing;  // unit, camera frame
  int camera = 0;
  Eigen::Vector3d point;  // world
};

// Model: world_from_rig.
struct RigAbsolutePoseEstimator {
  using Datum = RigBearingPoint;
  using Model = Rigid3;
  static constexpr int kMinimalSample = 3;

  const RigGeometry* rig = nullptr;
  double focal_px = 1;

  std::vector<Model> Estimate(const std::vector<Datum>& data) const;
  void Residuals(const std::vector<Datum>& data, const Model& model, std::vector<double>* residuals) const;
};

// Nonlinear refinement (OpenGV's Levenberg-Marquardt on the bearing errors) of world_from_rig from
// `initial` on the given (inlier) data.
Rigid3 RefineAbsolutePose(const RigGeometry& rig, const std::vector<RigBearingPoint>& data, const Rigid3& initial);

}  // namespace odvr::tracking
