#pragma once
// Trajectory accuracy against ground truth (the bench numbers, after Sturm et al.'s TUM
// RGB-D benchmark): ATE, the RMSE of the positions after the similarity (Umeyama) alignment that
// best maps the estimate onto the truth; RPE, the error of frame-to-frame motions; and the scale
// error of a metric trajectory, the one thing ATE's similarity alignment hides.
#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

namespace odvr::tracking {

struct TrajectoryPose {
  long index = 0;  // frame number, what estimate and truth are matched by
  double timestamp = 0;
  Eigen::Matrix4d world_from_rig = Eigen::Matrix4d::Identity();
};

// Reads {"frames": [{"index", "timestamp", "world_from_rig": 4x4 row-major}, ...]}: the datasets'
// trajectory_gt.json and odvr reconstruct's trajectory.json. Throws odvr::Error naming the file
// and the problem (missing field, not a rigid transform, repeated index).
std::vector<TrajectoryPose> LoadTrajectoryJson(const std::filesystem::path& path);
// TUM's text format, one pose a line: "timestamp tx ty tz qx qy qz qw" (world_from_rig), '#'
// comments. A line has no frame number: frame = round(timestamp * fps). Throws odvr::Error naming
// the file and line for a malformed line, a quaternion far from unit length, or two lines on one
// frame.
std::vector<TrajectoryPose> LoadTrajectoryTum(const std::filesystem::path& path, double fps);
// By extension: .tum or .txt read as TUM (at `fps`), anything else as trajectory JSON.
std::vector<TrajectoryPose> LoadTrajectory(const std::filesystem::path& path, double fps);

// dst ~ scale * rotation * src + translation, least squares (Umeyama 1991).
struct Similarity3 {
  double scale = 1;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
};
// Throws odvr::Error for fewer than 3 pairs, mismatched counts or (nearly) coincident points.

Similarity3 AlignUmeyama(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                         bool with_scale);

struct TrajectoryErrors {
  int matched = 0;         // frames present in both
  double length_m = 0;     // of the ground-truth path over the matched frames
  double ate_rmse_m = 0;   // after the similarity alignment
  double ate_percent = 0;  // ate_rmse_m / length_m * 100
  double ate_max_m = 0;
  double ate_rigid_rmse_m = 0;  // after a rigid alignment only: the metric trajectory as it is
  // Length of the estimate relative to the truth, the inverse of the alignment's scale: 1.02 =
  // the estimate is 2 % too long. scale_error = |scale - 1|.
  double scale = 1;
  double scale_error = 0;
  // Consecutive matched frames: translation error of the relative motion (metric estimate, not
  // rescaled) and rotation error.
  double rpe_translation_rmse_m = 0;
  double rpe_rotation_rmse_deg = 0;

  std::string Summary() const;
};

// Matches frames by index. Throws odvr::Error when fewer than 3 frames match or the ground-truth
// positions are (nearly) collinear.
TrajectoryErrors EvaluateTrajectory(const std::vector<TrajectoryPose>& estimate,
                                    const std::vector<TrajectoryPose>& ground_truth);

}  // namespace odvr::tracking
