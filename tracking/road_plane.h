#pragma once
// Metric scale from the road (seed §5.3.2, DESIGN.md §6): a monocular or nearly central rig
// reconstructs up to scale; the one length it knows is how high it stands above the road. The
// road plane is fitted by RANSAC (tracking/ransac.h) to the reconstructed points below the rig,
// and the scale that puts the rig at its configured height follows.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "tracking/rig_pose.h"

namespace odvr::tracking {

struct RoadPlaneOptions {
  // Candidates: points seen this far below the horizon of the nearest rig pose (the road near
  // the rig, where it is best triangulated; facades far off rarely look this steep).
  double min_depression_deg = 15;
  // ... and within this angle of straight down seen across the rig (atan(|y_rig| / -z_rig)): the
  // lane the rig drives in, not the sidewalk a step to the side, whose kerb would bias the scale.
  double max_side_angle_deg = 35;
  // Inlier band, relative to the median depth of the candidates below the rig (about the rig
  // height, whatever unit the reconstruction is in): 1.5 % is 3 cm at 2 m, below a kerb's 15 cm.
  double inlier_band = 0.015;
  // The plane's normal must be within this angle of the rig's mean up axis.
  double max_tilt_deg = 15;
  // Short runs see little road in the corridor (street_a, 6 frames: ~20 candidates), and a plane
  // constrained to be level needs few points to be trusted.
  int min_inliers = 12;

  // Throws odvr::Error naming the first bad parameter.
  void Check() const;
};

struct RoadPlane {
  bool found = false;
  // n . x + d = 0 with |n| = 1 and n pointing to the rig (up); in the reconstruction's world.
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double offset = 0;
  int candidates = 0, inliers = 0;
  double rig_height = 0;         // mean distance of the rig centres above the plane (world units)
  double rig_height_spread = 0;  // their standard deviation
  double rms_distance = 0;       // of the inliers to the plane (world units)
  // configured height / rig_height: multiply the world by it to make it metric. 0 when not found.
  double scale = 0;
  std::string message;  // why not found, or a one-line summary

  double Distance(const Eigen::Vector3d& x) const { return normal.dot(x) + offset; }
};

// `world_from_rig`: the registered poses (rig axes x forward, y left, z up). Never throws for bad
// data: `found` is false and `message` says why (too few points below the rig, no plane).
RoadPlane FitRoadPlane(const std::vector<Eigen::Vector3d>& points, const std::vector<Rigid3>& world_from_rig,
                       double rig_height_m, const RoadPlaneOptions& options = RoadPlaneOptions());

}  // namespace odvr::tracking
