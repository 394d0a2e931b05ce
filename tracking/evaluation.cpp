#include "tracking/evaluation.h"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "core/error.h"

namespace odvr::tracking {

std::vector<TrajectoryPose> LoadTrajectoryJson(const std::filesystem::path& path) {
  const std::string where = path.string();
  std::ifstream in(path);
  if (!in) throw Error(where, "cannot open");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw Error(where, std::string("not valid JSON: ") + e.what());
  }
  if (!j.is_object() || !j.contains("frames") || !j["frames"].is_array())
    throw Error(where, "expected an object with a \"frames\" array");
  std::vector<TrajectoryPose> poses;
  std::set<long> seen;
  for (size_t i = 0; i < j["frames"].size(); ++i) {
    const auto& f = j["frames"][i];
    const std::string at = "frames[" + std::to_string(i) + "]";
    if (!f.is_object() || !f.contains("index") || !f["index"].is_number_integer())
      throw Error(where, at + ": missing integer \"index\"");
    if (!f.contains("world_from_rig") || !f["world_from_rig"].is_array() || f["world_from_rig"].size() != 4)
      throw Error(where, at + ": \"world_from_rig\" must be 4 rows of 4 numbers");
    TrajectoryPose p;
    p.index = f["index"].get<long>();
    p.timestamp = f.contains("timestamp") && f["timestamp"].is_number() ? f["timestamp"].get<double>() : 0.0;
    for (int r = 0; r < 4; ++r) {
      const auto& row = f["world_from_rig"][r];
      if (!row.is_array() || row.size() != 4)
        throw Error(where, at + ": \"world_from_rig\" row " + std::to_string(r) + " must hold 4 numbers");
      for (int c = 0; c < 4; ++c) {
        if (!row[c].is_number()) throw Error(where, at + ": \"world_from_rig\" holds a non-number");
        p.world_from_rig(r, c) = row[c].get<double>();
      }
    }
    const Eigen::Matrix3d rot = p.world_from_rig.topLeftCorner<3, 3>();
    if (!p.world_from_rig.allFinite() || (rot.transpose() * rot - Eigen::Matrix3d::Identity()).norm() > 1e-4 ||
        rot.determinant() < 0 || (p.world_from_rig.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9)
      throw Error(where, at + ": \"world_from_rig\" is not a rigid transform");
    if (!seen.insert(p.index).second) throw Error(where, at + ": index " + std::to_string(p.index) + " repeats");
    poses.push_back(p);
  }
  return poses;
}

std::vector<TrajectoryPose> LoadTrajectoryTum(const std::filesystem::path& path, double fps) {
  const std::string where = path.string();
  if (!(fps > 0)) throw Error(where, "a TUM trajectory needs the video's frame rate to name its frames");
  std::ifstream in(path);
  if (!in) throw Error(where, "cannot open");
  std::vector<TrajectoryPose> poses;
  std::set<long> seen;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::string at = "line " + std::to_string(number);
    std::istringstream fields(line);
    double v[8];
    for (double& x : v)
      if (!(fields >> x)) throw Error(where, at + ": expected 8 numbers (timestamp tx ty tz qx qy qz qw)");
    std::string extra;
    if (fields >> extra) throw Error(where, at + ": more than 8 fields");
    for (double x : v)
      if (!std::isfinite(x)) throw Error(where, at + ": a number is not finite");
    Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    if (std::abs(q.norm() - 1) > 1e-3) throw Error(where, at + ": the quaternion is not of unit length");
    TrajectoryPose p;
    p.timestamp = v[0];
    const double frame = std::round(v[0] * fps);
    if (!(std::abs(frame) < 1e9)) throw Error(where, at + ": timestamp " + std::to_string(v[0]) + " is out of range");
    p.index = static_cast<long>(frame);
    p.world_from_rig.topLeftCorner<3, 3>() = q.normalized().toRotationMatrix();
    p.world_from_rig.topRightCorner<3, 1>() = Eigen::Vector3d(v[1], v[2], v[3]);
    if (!seen.insert(p.index).second)
      throw Error(where,
                  at + ": a second pose for frame " + std::to_string(p.index) + " at " + std::to_string(fps) + " fps");
    poses.push_back(p);
  }
  if (poses.empty()) throw Error(where, "holds no pose");
  return poses;
}

std::vector<TrajectoryPose> LoadTrajectory(const std::filesystem::path& path, double fps) {
  const std::string ext = path.extension().string();
  if (ext == ".tum" || ext == ".txt") return LoadTrajectoryTum(path, fps);
  return LoadTrajectoryJson(path);
}

Similarity3 AlignUmeyama(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                         bool with_scale) {
  if (src.size() != dst.size())
    throw Error("umeyama", std::to_string(src.size()) + " source but " + std::to_string(dst.size()) + " target points");
  if (src.size() < 3) throw Error("umeyama", "needs at least 3 point pairs, got " + std::to_string(src.size()));
  const int n = static_cast<int>(src.size());
  Eigen::Matrix3Xd a(3, n), b(3, n);
  for (int i = 0; i < n; ++i) a.col(i) = src[i], b.col(i) = dst[i];
  const Eigen::Vector3d ma = a.rowwise().mean(), mb = b.rowwise().mean();
  a.colwise() -= ma;
  b.colwise() -= mb;
  const double var_a = a.squaredNorm() / n;
  if (!(var_a > 1e-18)) throw Error("umeyama", "the source points coincide");
  const Eigen::Matrix3d cov = b * a.transpose() / n;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d s = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) s(2, 2) = -1;
  Similarity3 out;
  out.rotation = svd.matrixU() * s * svd.matrixV().transpose();
  out.scale = with_scale ? (svd.singularValues().asDiagonal() * s).trace() / var_a : 1.0;
  out.translation = mb - out.scale * out.rotation * ma;
  return out;
}

TrajectoryErrors EvaluateTrajectory(const std::vector<TrajectoryPose>& estimate,
                                    const std::vector<TrajectoryPose>& ground_truth) {
  std::map<long, const TrajectoryPose*> truth;
  for (const auto& p : ground_truth) truth[p.index] = &p;
  std::vector<const TrajectoryPose*> est, gt;
  std::map<long, const TrajectoryPose*> sorted;
  for (const auto& p : estimate) sorted[p.index] = &p;
  for (const auto& [index, p] : sorted) {
    auto it = truth.find(index);
    if (it == truth.end()) continue;
    est.push_back(p);
    gt.push_back(it->second);
  }
  TrajectoryErrors e;
  e.matched = static_cast<int>(est.size());
  if (e.matched < 3)
    throw Error("trajectory evaluation",
                "only " + std::to_string(e.matched) + " frames match the ground truth by index (need 3)");
  std::vector<Eigen::Vector3d> pe, pg;
  for (int i = 0; i < e.matched; ++i) {
    pe.push_back(est[i]->world_from_rig.topRightCorner<3, 1>());
    pg.push_back(gt[i]->world_from_rig.topRightCorner<3, 1>());
    if (i > 0) e.length_m += (pg[i] - pg[i - 1]).norm();
  }
  if (!(e.length_m > 1e-6))
    throw Error("trajectory evaluation", "the ground truth does not move: ATE relative to its length is undefined");

  const Similarity3 sim = AlignUmeyama(pe, pg, true);
  const Similarity3 rigid = AlignUmeyama(pe, pg, false);
  double sq = 0, sq_rigid = 0;
  for (int i = 0; i < e.matched; ++i) {
    const double d = (sim.scale * sim.rotation * pe[i] + sim.translation - pg[i]).norm();
    sq += d * d;
    e.ate_max_m = std::max(e.ate_max_m, d);
    sq_rigid += (rigid.rotation * pe[i] + rigid.translation - pg[i]).squaredNorm();
  }
  e.ate_rmse_m = std::sqrt(sq / e.matched);
  e.ate_percent = 100 * e.ate_rmse_m / e.length_m;
  e.ate_rigid_rmse_m = std::sqrt(sq_rigid / e.matched);
  e.scale = 1 / sim.scale;
  e.scale_error = std::abs(e.scale - 1);

  // RPE between consecutive matched frames: relative motion rig_i -> rig_{i+1} compared in the
  // rig frame, which no world alignment changes.
  double rt = 0, rr = 0;
  int pairs = 0;
  for (int i = 0; i + 1 < e.matched; ++i) {
    const Eigen::Matrix4d de = est[i]->world_from_rig.inverse() * est[i + 1]->world_from_rig;
    const Eigen::Matrix4d dg = gt[i]->world_from_rig.inverse() * gt[i + 1]->world_from_rig;
    const Eigen::Matrix4d err = dg.inverse() * de;
    rt += err.topRightCorner<3, 1>().squaredNorm();
    const Eigen::AngleAxisd aa(Eigen::Matrix3d(err.topLeftCorner<3, 3>()));
    rr += std::pow(aa.angle() * 180 / M_PI, 2);
    ++pairs;
  }
  e.rpe_translation_rmse_m = std::sqrt(rt / pairs);
  e.rpe_rotation_rmse_deg = std::sqrt(rr / pairs);
  return e;
}

std::string TrajectoryErrors::Summary() const {
  char line[320];
  std::snprintf(line, sizeof line,
                "%d frames, path %.2f m: ATE %.4f m (%.3f %% of the path, max %.4f m), rigid ATE %.4f m, scale %.4f "
                "(error %.2f %%), RPE %.4f m / %.3f deg",
                matched, length_m, ate_rmse_m, ate_percent, ate_max_m, ate_rigid_rmse_m, scale, 100 * scale_error,
                rpe_translation_rmse_m, rpe_rotation_rmse_deg);
  return line;
}

}  // namespace odvr::tracking
