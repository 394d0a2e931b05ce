#pragma once
// Cross-camera links (seed §5.3.2): the same scene point tracked in two cameras of the rig is one
// 3D point. At one instant, SIFT descriptors (OpenCV) computed at the track points of two
// overlapping cameras are matched with Lowe's ratio test and a cross-check, and a match must pass
// the epipolar check of the rig's known camera-to-camera pose: the two rays, placed by the
// calibration, must meet (triangulation error below a bound) in front of both cameras within a
// parallax the small camera baseline allows. Tracks that leave one camera and appear in the next
// overlap there, so these links join them into one point's observations.
#include <Eigen/Core>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "tracking/rig_pose.h"

namespace odvr::tracking {

struct CrossCameraOptions {
  double ratio = 0.8;  // Lowe's ratio test: best distance < ratio * second best
  // Epipolar check: the two calibrated rays meet within this angle (midpoint triangulation error).
  double max_epipolar_deg = 0.4;
  // And their directions differ by at most this much: with cameras centimetres apart only a point
  // closer than about a metre shows more parallax, and none is that close to a street rig.
  double max_parallax_deg = 5;
  // Camera pairs are matched when their optical axes are at most this far apart (overlap).
  double max_axis_angle_deg = 90;
  float keypoint_size_px = 16;  // SIFT support (diameter) at every track point

  // Throws odvr::Error naming the first bad parameter.
  void Check() const;
};

// One camera's track points at the current instant.
struct CameraTrackPoints {
  int camera = 0;
  cv::Mat gray;                           // 8-bit, the camera's image
  std::vector<long> ids;                  // caller's track ids, one per point
  std::vector<Eigen::Vector2d> pixels;    // OpenCV pixel convention
  std::vector<Eigen::Vector3d> bearings;  // unit, camera frame
};

struct CrossCameraMatch {
  long id_a = 0, id_b = 0;  // track ids of the two cameras
  int camera_a = 0, camera_b = 0;
};

struct CrossCameraStats {
  int ratio_passed = 0;     // matches that pass the ratio test (both directions counted once)
  int cross_checked = 0;    // of those, mutual best matches
  int epipolar_passed = 0;  // of those, geometrically consistent: the links returned
};

// Matches every overlapping camera pair among `views`; each match links two tracks.
std::vector<CrossCameraMatch> MatchAcrossCameras(const RigGeometry& rig, const std::vector<CameraTrackPoints>& views,
                                                 const CrossCameraOptions& options, CrossCameraStats* stats = nullptr);

}  // namespace odvr::tracking
