#pragma once
// The rig calibration: per camera a model (capture/camera_model.h) and where it sits in the rig,
// plus the rig's height above the road (the length that fixes the tracker's scale, DESIGN.md §6).
//
// Two JSON layouts are read (DESIGN.md §3: the field's habit, Kalibr's camchain as the model):
//  * odvr / Kalibr-like (config/*.json): {"rig_height_m": h, "cam0": {...}, "cam1": {...}} or
//    {"rig_height_m": h, "cameras": [{...}, ...]}, each camera
//      {"camera_model": "pinhole" | "fisheye" | "omni-equirect", "distortion_model": "radtan" |
//       "equidistant" | "none", "intrinsics": [fx, fy, cx, cy], "distortion_coeffs": [...],
//       "resolution": [w, h], "T_rig_cam": 4x4 row-major}  (Kalibr's "pinhole"+"equidistant"
//       is the fisheye model);
//  * the datasets' rig.json (../shared/data/street_*/rig.json): {"rig_height_m": h,
//    "cameras": [{"id", "name", "model": "opencv_fisheye", "width", "height", "fx", "fy", "cx",
//    "cy", "k1".."k4", "T_rig_cam", "image_dir"}]}.
// T_rig_cam maps OpenCV camera coordinates to rig coordinates (x_rig = R x_cam + t); the rig
// frame is the datasets': x forward, y left, z up. Every malformed input is an odvr::Error
// naming the file and, where it helps, the camera and field.
#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "capture/camera_model.h"

namespace odvr::capture {

struct RigCamera {
  std::string name;  // "cam0"
  CameraModel model = CameraModel::Equirectangular(2, 1);
  Eigen::Matrix4d rig_from_cam = Eigen::Matrix4d::Identity();
  std::string image_dir;  // relative to the rig file's folder; empty when the file names none
};

struct Rig {
  std::vector<RigCamera> cameras;
  double height_m = 0;         // rig centre above the road; 0 when the file gives none
  std::filesystem::path path;  // the file it came from (empty when built in code)

  int camera_count() const { return static_cast<int>(cameras.size()); }
};

// Throws odvr::Error("<path>", "<one line>") for a missing, unreadable or malformed file, a
// camera missing from the numbering, an unknown model, a bad size or a T_rig_cam that is not a
// rigid transform.
Rig LoadRig(const std::filesystem::path& path);
Rig ParseRig(const std::string& json_text, const std::filesystem::path& path_for_errors);

// Writes the odvr/Kalibr-like layout, atomically; LoadRig reads it back unchanged.
void SaveRig(const std::filesystem::path& path, const Rig& rig);

// The rig frame (x forward, y left, z up) to odvr's Y-up frame (forward +X, up +Y, right +Z) and
// back: (x, y, z) -> (x, z, -y), as engine/sphere/equirect.h states.
inline Eigen::Vector3d OdvrFromRig(const Eigen::Vector3d& v) { return {v.x(), v.z(), -v.y()}; }
inline Eigen::Vector3d RigFromOdvr(const Eigen::Vector3d& v) { return {v.x(), -v.z(), v.y()}; }

}  // namespace odvr::capture
