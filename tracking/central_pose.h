#pragma once
// Poses of a central camera (one equirectangular camera, or a rig whose cameras share one
// centre) from bearing vectors: the seed's §5.3.2 on one sphere. The rig's non-central solvers
// (rig_pose.h) are degenerate there: the 17-point solver reads the translation's length from the
// cameras' offsets, which are zero, and gP3P's lines all pass through one point. These use the
// central solvers instead (OpenGV: Nistér's 5-point and the 8-point algorithm on bearings for the
// relative pose, Kneip's P3P and EPnP for the absolute pose) and take the same data and give the
// same models and residuals as the rig's estimators, so the reconstruction swaps one for the
// other and keeps its RANSAC, thresholds and bundle adjustment.
//
// Bearings on the whole sphere are what makes this work for 360° video: the 8-point system on
// unit bearings is well conditioned when they spread over all directions, unlike a narrow
// pinhole's normalized image points.
#include <vector>

#include "tracking/rig_pose.h"

namespace odvr::tracking {

// Model: rig1_from_rig2, its translation of unit length (a central camera sees no metric scale).
// The cameras of `rig` must share one centre (RigGeometry::central()).
struct CentralRelativePoseEstimator {
  using Datum = RigBearingPair;
  using Model = Rigid3;
  static constexpr int kMinimalSample = 5;

  const RigGeometry* rig = nullptr;
  double focal_px = 1;

  // 5 bearings: Nistér's solutions; 8 or more: the least-squares 8-point essential matrix. Each
  // essential matrix gives its four (R, t) decompositions; the residuals' cheirality (a point
  // behind either view is an outlier) picks the right one.
  std::vector<Model> Estimate(const std::vector<Datum>& data) const;
  void Residuals(const std::vector<Datum>& data, const Model& model, std::vector<double>* residuals) const;
};

// Model: world_from_rig.
struct CentralAbsolutePoseEstimator {
  using Datum = RigBearingPoint;
  using Model = Rigid3;
  static constexpr int kMinimalSample = 3;

  const RigGeometry* rig = nullptr;
  double focal_px = 1;

  // 3 points: Kneip's P3P (up to four poses); 6 or more: EPnP.
  std::vector<Model> Estimate(const std::vector<Datum>& data) const;
  void Residuals(const std::vector<Datum>& data, const Model& model, std::vector<double>* residuals) const;
};

// Levenberg-Marquardt on the bearing errors of a central camera, from `initial`.
Rigid3 RefineCentralAbsolutePose(const RigGeometry& rig, const std::vector<RigBearingPoint>& data,
                                 const Rigid3& initial);

// The rotation that best maps bearings `b` onto bearings `a` (a ≈ R b; Wahba's problem by SVD).
Eigen::Matrix3d BestRotation(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b);

}  // namespace odvr::tracking
