#include "tracking/rig_pose.h"

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <opengv/absolute_pose/NoncentralAbsoluteAdapter.hpp>
#include <opengv/absolute_pose/methods.hpp>
#include <opengv/relative_pose/NoncentralRelativeAdapter.hpp>
#include <opengv/relative_pose/methods.hpp>
#include <optional>

namespace odvr::tracking {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

double Angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

void CameraArrays(const RigGeometry& rig, opengv::translations_t* offsets, opengv::rotations_t* rotations) {
  for (const Rigid3& c : rig.rig_from_cam) {
    offsets->push_back(c.translation);
    rotations->push_back(c.rotation);
  }
}

// What OpenGV's non-central absolute-pose adapter reads: it keeps references, so the arrays
// live beside it.
struct AbsolutePoseInput {
  AbsolutePoseInput(const RigGeometry& rig, const std::vector<RigBearingPoint>& data) {
    for (const auto& d : data) {
      bearings.push_back(d.bearing);
      points.push_back(d.point);
      cams.push_back(d.camera);
    }
    CameraArrays(rig, &offsets, &rotations);
    adapter.emplace(bearings, cams, points, offsets, rotations);
  }
  AbsolutePoseInput(const AbsolutePoseInput&) = delete;  // the adapter points into this object
  AbsolutePoseInput& operator=(const AbsolutePoseInput&) = delete;
  opengv::bearingVectors_t bearings;
  opengv::points_t points;
  std::vector<int> cams;
  opengv::translations_t offsets;
  opengv::rotations_t rotations;
  std::optional<opengv::absolute_pose::NoncentralAbsoluteAdapter> adapter;  // made once the arrays are full
};

}  // namespace

bool IsRotation(const Eigen::Matrix3d& r) {
  return r.allFinite() && (r.transpose() * r - Eigen::Matrix3d::Identity()).norm() < 1e-6 && r.determinant() > 0;
}

Rigid3 RigidFromOpenGv(const Eigen::Matrix<double, 3, 4>& transformation) {
  Rigid3 out;
  out.rotation = transformation.leftCols<3>();
  out.translation = transformation.col(3);
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(out.rotation, Eigen::ComputeFullU | Eigen::ComputeFullV);
  out.rotation = svd.matrixU() * svd.matrixV().transpose();
  if (out.rotation.determinant() < 0) out.rotation = -out.rotation;
  return out;
}

bool RigGeometry::central() const {
  for (const Rigid3& c : rig_from_cam)
    if ((c.translation - rig_from_cam.front().translation).norm() > 1e-6) return false;
  return true;
}

Eigen::Matrix4d Rigid3::Matrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = rotation;
  m.topRightCorner<3, 1>() = translation;
  return m;
}

Rigid3 Rigid3::FromMatrix(const Eigen::Matrix4d& m) { return {m.topLeftCorner<3, 3>(), m.topRightCorner<3, 1>()}; }

RigGeometry RigGeometry::FromRig(const capture::Rig& rig) {
  RigGeometry g;
  for (const auto& cam : rig.cameras) {
    g.rig_from_cam.push_back(Rigid3::FromMatrix(cam.rig_from_cam));
    g.focal_px.push_back(0.5 * (cam.model.fx() + cam.model.fy()));
  }
  return g;
}

double TwoRayAngularError(const Eigen::Vector3d& origin1, const Eigen::Vector3d& direction1,
                          const Eigen::Vector3d& origin2, const Eigen::Vector3d& direction2) {
  const Eigen::Vector3d d1 = direction1.normalized(), d2 = direction2.normalized();
  const Eigen::Vector3d w = origin1 - origin2;
  const double b = d1.dot(d2), d = d1.dot(w), e = d2.dot(w);
  const double denom = 1 - b * b;
  // Parallel rays meet at infinity: the error is then the angle between them (a distant point
  // seen along both).
  if (denom < 1e-12) return Angle(d1, d2);
  const double s = (b * e - d) / denom, t = (e - b * d) / denom;
  if (!(s > 0) || !(t > 0)) return kInf;
  const Eigen::Vector3d x = 0.5 * ((origin1 + s * d1) + (origin2 + t * d2));
  return std::max(Angle(d1, x - origin1), Angle(d2, x - origin2));
}

std::vector<Rigid3> RigRelativePoseEstimator::Estimate(const std::vector<RigBearingPair>& data) const {
  opengv::bearingVectors_t b1, b2;
  std::vector<int> c1, c2;
  for (const auto& d : data) {
    b1.push_back(d.bearing1);
    b2.push_back(d.bearing2);
    c1.push_back(d.camera1);
    c2.push_back(d.camera2);
  }
  opengv::translations_t offsets;
  opengv::rotations_t rotations;
  CameraArrays(*rig, &offsets, &rotations);
  opengv::relative_pose::NoncentralRelativeAdapter adapter(b1, b2, c1, c2, offsets, rotations);
  const Rigid3 pose = RigidFromOpenGv(opengv::relative_pose::seventeenpt(adapter));
  if (!pose.AllFinite() || !IsRotation(pose.rotation)) return {};
  return {pose};
}

void RigRelativePoseEstimator::Residuals(const std::vector<RigBearingPair>& data, const Rigid3& rig1_from_rig2,
                                         std::vector<double>* residuals) const {
  residuals->resize(data.size());
  for (size_t i = 0; i < data.size(); ++i) {
    const RigBearingPair& d = data[i];
    const Rigid3& c1 = rig->rig_from_cam[d.camera1];
    const Rigid3 c2 = rig1_from_rig2 * rig->rig_from_cam[d.camera2];
    (*residuals)[i] = focal_px * TwoRayAngularError(c1.translation, c1.rotation * d.bearing1, c2.translation,
                                                    c2.rotation * d.bearing2);
  }
}

std::vector<Rigid3> RigAbsolutePoseEstimator::Estimate(const std::vector<RigBearingPoint>& data) const {
  AbsolutePoseInput input(*rig, data);
  auto& adapter = *input.adapter;
  std::vector<Rigid3> out;
  if (data.size() == 3) {
    for (const auto& t : opengv::absolute_pose::gp3p(adapter, 0, 1, 2)) {
      const Rigid3 pose = RigidFromOpenGv(t);
      if (pose.AllFinite() && IsRotation(pose.rotation)) out.push_back(pose);
    }
  } else if (data.size() >= 6) {
    // gPnP for the least-squares refit; the minimal solver's best candidate otherwise.
    const Rigid3 pose = RigidFromOpenGv(opengv::absolute_pose::gpnp(adapter));
    if (pose.AllFinite() && IsRotation(pose.rotation)) out.push_back(pose);
  }
  return out;
}

void RigAbsolutePoseEstimator::Residuals(const std::vector<RigBearingPoint>& data, const Rigid3& world_from_rig,
                                         std::vector<double>* residuals) const {
  residuals->resize(data.size());
  const Rigid3 rig_from_world = world_from_rig.Inverse();
  for (size_t i = 0; i < data.size(); ++i) {
    const RigBearingPoint& d = data[i];
    const Eigen::Vector3d in_cam = rig->rig_from_cam[d.camera].Inverse() * (rig_from_world * d.point);
    (*residuals)[i] = in_cam.dot(d.bearing) > 0 ? focal_px * Angle(in_cam, d.bearing) : kInf;
  }
}

Rigid3 RefineAbsolutePose(const RigGeometry& rig, const std::vector<RigBearingPoint>& data, const Rigid3& initial) {
  AbsolutePoseInput input(rig, data);
  auto& adapter = *input.adapter;
  adapter.setR(initial.rotation);
  adapter.sett(initial.translation);
  const Rigid3 refined = RigidFromOpenGv(opengv::absolute_pose::optimize_nonlinear(adapter));
  return refined.AllFinite() && IsRotation(refined.rotation) ? refined : initial;
}

}  // namespace odvr::tracking
