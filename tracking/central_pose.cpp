#include "tracking/central_pose.h"

#include <Eigen/Dense>
#include <opengv/absolute_pose/CentralAbsoluteAdapter.hpp>
#include <opengv/absolute_pose/methods.hpp>
#include <opengv/relative_pose/CentralRelativeAdapter.hpp>
#include <opengv/relative_pose/methods.hpp>

namespace odvr::tracking {
namespace {

// The central camera V sits at the cameras' common centre c with the rig's axes: a bearing b of
// camera k is R_k b in V, and x_rig = x_V + c.
Eigen::Vector3d Centre(const RigGeometry& rig) { return rig.rig_from_cam.front().translation; }

Eigen::Vector3d InV(const RigGeometry& rig, int camera, const Eigen::Vector3d& bearing) {
  return rig.rig_from_cam[static_cast<std::size_t>(camera)].rotation * bearing;
}

// E = [t]x R for x1 = R x2 + t (OpenGV's convention: viewpoint 2 seen from viewpoint 1). Its SVD
// U diag(s, s, 0) V^T gives R = U W V^T or U W^T V^T and t = ±u3 (Hartley & Zisserman 9.6.2).
void AppendDecompositions(const Eigen::Matrix3d& essential, const RigGeometry& rig, std::vector<Rigid3>* out) {
  if (!essential.allFinite()) return;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(essential, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU(), v = svd.matrixV();
  if (u.determinant() < 0) u = -u;
  if (v.determinant() < 0) v = -v;
  Eigen::Matrix3d w;
  w << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  const Eigen::Vector3d c = Centre(rig);
  for (const Eigen::Matrix3d& r :
       {Eigen::Matrix3d(u * w * v.transpose()), Eigen::Matrix3d(u * w.transpose() * v.transpose())})
    for (const double sign : {1.0, -1.0}) {
      // V1_from_V2 = (R, tv), and x_rig = x_V + c on both sides: t = tv - R c + c.
      const Eigen::Vector3d tv = sign * u.col(2);
      Rigid3 pose{r, tv - r * c + c};
      if (pose.AllFinite() && IsRotation(pose.rotation)) out->push_back(pose);
    }
}

// OpenGV's central absolute-pose adapter keeps references: the arrays live beside it.
struct CentralAbsoluteInput {
  CentralAbsoluteInput(const RigGeometry& rig, const std::vector<RigBearingPoint>& data) {
    for (const auto& d : data) {
      bearings.push_back(InV(rig, d.camera, d.bearing));
      points.push_back(d.point);
    }
  }
  opengv::bearingVectors_t bearings;
  opengv::points_t points;
};

// OpenGV returns world_from_V = (R, R c + t) for world_from_rig = (R, t).
Rigid3 RigFromV(const RigGeometry& rig, const Rigid3& world_from_v) {
  return {world_from_v.rotation, world_from_v.translation - world_from_v.rotation * Centre(rig)};
}

}  // namespace

std::vector<Rigid3> CentralRelativePoseEstimator::Estimate(const std::vector<RigBearingPair>& data) const {
  opengv::bearingVectors_t b1, b2;
  for (const auto& d : data) {
    b1.push_back(InV(*rig, d.camera1, d.bearing1));
    b2.push_back(InV(*rig, d.camera2, d.bearing2));
  }
  opengv::relative_pose::CentralRelativeAdapter adapter(b1, b2);
  std::vector<Rigid3> out;
  if (data.size() >= 8) {
    AppendDecompositions(opengv::relative_pose::eightpt(adapter), *rig, &out);
  } else if (data.size() >= 5) {
    std::vector<int> first5 = {0, 1, 2, 3, 4};
    for (const auto& e : opengv::relative_pose::fivept_nister(adapter, first5)) AppendDecompositions(e, *rig, &out);
  }
  return out;
}

void CentralRelativePoseEstimator::Residuals(const std::vector<RigBearingPair>& data, const Rigid3& model,
                                             std::vector<double>* residuals) const {
  RigRelativePoseEstimator{rig, focal_px}.Residuals(data, model, residuals);
}

std::vector<Rigid3> CentralAbsolutePoseEstimator::Estimate(const std::vector<RigBearingPoint>& data) const {
  CentralAbsoluteInput input(*rig, data);
  opengv::absolute_pose::CentralAbsoluteAdapter adapter(input.bearings, input.points);
  std::vector<Rigid3> out;
  auto keep = [&](const opengv::transformation_t& t) {
    const Rigid3 pose = RigFromV(*rig, RigidFromOpenGv(t));
    if (pose.AllFinite() && IsRotation(pose.rotation)) out.push_back(pose);
  };
  if (data.size() == 3) {
    for (const auto& t : opengv::absolute_pose::p3p_kneip(adapter, std::vector<int>{0, 1, 2})) keep(t);
  } else if (data.size() >= 6) {
    keep(opengv::absolute_pose::epnp(adapter));
  }
  return out;
}

void CentralAbsolutePoseEstimator::Residuals(const std::vector<RigBearingPoint>& data, const Rigid3& model,
                                             std::vector<double>* residuals) const {
  RigAbsolutePoseEstimator{rig, focal_px}.Residuals(data, model, residuals);
}

Rigid3 RefineCentralAbsolutePose(const RigGeometry& rig, const std::vector<RigBearingPoint>& data,
                                 const Rigid3& initial) {
  CentralAbsoluteInput input(rig, data);
  opengv::absolute_pose::CentralAbsoluteAdapter adapter(input.bearings, input.points);
  adapter.setR(initial.rotation);
  adapter.sett(initial.translation + initial.rotation * Centre(rig));
  const Rigid3 refined = RigFromV(rig, RigidFromOpenGv(opengv::absolute_pose::optimize_nonlinear(adapter)));
  return refined.AllFinite() && IsRotation(refined.rotation) ? refined : initial;
}

Eigen::Matrix3d BestRotation(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < a.size() && i < b.size(); ++i) cov += a[i] * b[i].transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d fix = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) fix(2, 2) = -1;
  return svd.matrixU() * fix * svd.matrixV().transpose();
}

}  // namespace odvr::tracking
