// The outputs of odvr reconstruct: trajectory (JSON as the datasets' trajectory_gt.json, TUM),
// the sparse model as COLMAP text, the road plane and a summary. Each file is written atomically.
#include <Eigen/Geometry>
#include <cstdio>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "capture/equirect_view.h"
#include "capture/rig.h"
#include "core/atomic_file.h"
#include "core/axes.h"
#include "core/error.h"
#include "tracking/reconstruction.h"

namespace odvr::tracking {
namespace {

namespace fs = std::filesystem;

nlohmann::json Rows(const Eigen::Matrix4d& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return rows;
}

nlohmann::json Vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

// C = [[1,0,0],[0,0,1],[0,-1,0]] (core/axes.h): the datasets' Z-up world to odvr's Y-up one.
Eigen::Matrix4d YupFromZup() {
  Eigen::Matrix4d c = Eigen::Matrix4d::Identity();
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) c(r, k) = kYupFromZup[r][k];
  return c;
}

std::string Num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

std::string ImageName(const Reconstruction& r, int frame, int camera) {
  char name[32];
  std::snprintf(name, sizeof name, "%06ld.jpg", r.frames[frame].index);
  return r.rig.cameras[camera].name + "/" + name;
}

std::string TrajectoryJson(const Reconstruction& r) {
  nlohmann::json frames = nlohmann::json::array();
  for (const auto& f : r.frames) {
    nlohmann::json j{{"index", f.index},
                     {"timestamp", f.timestamp},
                     {"world_from_rig", Rows(f.world_from_rig.Matrix())},
                     {"world_yup_from_rig", Rows(YupFromZup() * f.world_from_rig.Matrix())},
                     {"inliers", f.inliers}};
    if (f.duplicate_of >= 0) j["duplicate_of_index"] = r.frames[f.duplicate_of].index;
    j["key"] = f.key;
    if (f.interpolated) j["interpolated"] = true;
    frames.push_back(j);
  }
  return nlohmann::json{{"pose", "world_from_rig (4x4 row-major, maps rig coords to world)"},
                        {"world",
                         "reconstructed: right-handed, Z up, metres; z = 0 is the fitted road plane, origin below the "
                         "first rig pose, x along its heading"},
                        {"world_yup",
                         "world_yup_from_rig = C @ world_from_rig with C = [[1,0,0],[0,0,1],[0,-1,0]] (odvr's Y-up "
                         "world; rig axes unchanged)"},
                        {"rig", "x forward, y left, z up (the rig file's frame)"},
                        {"rig_height_m", r.rig_height_m},
                        {"frames", frames}}
             .dump(1) +
         "\n";
}

std::string TrajectoryTum(const Reconstruction& r) {
  std::ostringstream s;
  s << "# timestamp tx ty tz qx qy qz qw  (world_from_rig, world Z up with the road at z = 0, metres)\n";
  for (const auto& f : r.frames) {
    const Eigen::Quaterniond q(f.world_from_rig.rotation);
    const Eigen::Vector3d& t = f.world_from_rig.translation;
    char line[256];
    std::snprintf(line, sizeof line, "%.6f %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n", f.timestamp, t.x(), t.y(), t.z(),
                  q.x(), q.y(), q.z(), q.w());
    s << line;
  }
  return s.str();
}

// COLMAP's pixel convention puts (0, 0) at the top-left corner of the first pixel, half a pixel
// from OpenCV's (centres at integers): principal points and 2D points move by +0.5.
std::string CamerasTxt(const Reconstruction& r) {
  std::ostringstream s;
  s << "# Camera list with one line of data per camera:\n"
    << "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
    << "# Number of cameras: " << r.rig.cameras.size() << "\n";
  for (size_t c = 0; c < r.rig.cameras.size(); ++c) {
    const auto& m = r.rig.cameras[c].model;
    std::string model;
    std::vector<double> params{m.fx(), m.fy(), m.cx() + 0.5, m.cy() + 0.5};
    switch (m.type()) {
      case capture::CameraModelType::kFisheye:
        model = "OPENCV_FISHEYE";
        for (double k : m.distortion()) params.push_back(k);
        break;
      case capture::CameraModelType::kPinhole:
        model = "FULL_OPENCV";
        // FULL_OPENCV: k1 k2 p1 p2 k3 k4 k5 k6.
        for (double k : m.distortion()) params.push_back(k);
        params.resize(12, 0.0);
        break;
      case capture::CameraModelType::kEquirectangular:  // AsCubeFaces replaced it
        throw Error("COLMAP export", "camera " + r.rig.cameras[c].name + " is equirectangular");
    }
    s << c + 1 << " " << model << " " << m.width() << " " << m.height();
    for (double p : params) s << " " << Num(p);
    s << "\n";
  }
  return s.str();
}

void ColmapModel(const Reconstruction& r, std::string* images_txt, std::string* points_txt) {
  const int cams = r.rig.camera_count();
  // Per image: (pixel, point id); per point: (image id, point2D index).
  std::map<int, std::vector<std::pair<Eigen::Vector2d, long>>> per_image;
  std::vector<std::vector<std::pair<int, int>>> tracks(r.points.size());
  for (size_t i = 0; i < r.points.size(); ++i)
    for (const auto& o : r.points[i].observations) {
      const int image_id = o.frame * cams + o.camera + 1;
      auto& list = per_image[image_id];
      tracks[i].emplace_back(image_id, static_cast<int>(list.size()));
      list.emplace_back(o.pixel, static_cast<long>(i) + 1);
    }
  std::ostringstream s;
  s << "# Image list with two lines of data per image:\n"
    << "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
    << "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
    << "# Number of images: " << r.frames.size() * cams << "\n";
  for (int f = 0; f < static_cast<int>(r.frames.size()); ++f)
    for (int c = 0; c < cams; ++c) {
      const Rigid3 cam_from_world =
          Rigid3::FromMatrix(r.rig.cameras[c].rig_from_cam).Inverse() * r.frames[f].world_from_rig.Inverse();
      const Eigen::Quaterniond q(cam_from_world.rotation);
      const int id = f * cams + c + 1;
      s << id << " " << Num(q.w()) << " " << Num(q.x()) << " " << Num(q.y()) << " " << Num(q.z()) << " "
        << Num(cam_from_world.translation.x()) << " " << Num(cam_from_world.translation.y()) << " "
        << Num(cam_from_world.translation.z()) << " " << c + 1 << " " << ImageName(r, f, c) << "\n";
      bool first = true;
      for (const auto& [pixel, point] : per_image[id]) {
        s << (first ? "" : " ") << Num(pixel.x() + 0.5) << " " << Num(pixel.y() + 0.5) << " " << point;
        first = false;
      }
      s << "\n";
    }
  *images_txt = s.str();

  std::ostringstream p;
  p << "# 3D point list with one line of data per point:\n"
    << "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
    << "# Number of points: " << r.points.size() << "\n";
  for (size_t i = 0; i < r.points.size(); ++i) {
    const auto& pt = r.points[i];
    p << i + 1 << " " << Num(pt.position.x()) << " " << Num(pt.position.y()) << " " << Num(pt.position.z()) << " "
      << static_cast<int>(pt.rgb[0]) << " " << static_cast<int>(pt.rgb[1]) << " " << static_cast<int>(pt.rgb[2]) << " "
      << Num(pt.error_px);
    for (const auto& [image, index] : tracks[i]) p << " " << image << " " << index;
    p << "\n";
  }
  *points_txt = p.str();
}

std::string RoadPlaneJson(const Reconstruction& r) {
  const RoadPlane& road = r.road;
  const Eigen::Vector3d n_yup(road.normal.x(), road.normal.z(), -road.normal.y());
  return nlohmann::json{{"found", road.found},
                        {"plane", "normal . x + offset = 0 in the trajectory's world (Z up); normal points to the rig"},
                        {"normal", Vec(road.normal)},
                        {"offset_m", road.offset},
                        {"normal_yup", Vec(n_yup)},
                        {"candidates", road.candidates},
                        {"inliers", road.inliers},
                        {"rms_distance_m", road.rms_distance},
                        {"rig_height_measured_m", road.rig_height},
                        {"rig_height_spread_m", road.rig_height_spread},
                        {"rig_height_configured_m", r.rig_height_m},
                        {"scale_applied", r.scale_applied},
                        {"scale_source", r.scale_source},
                        {"message", road.message}}
             .dump(1) +
         "\n";
}

// COLMAP has no equirectangular camera; its users split 360° frames into six 90° cube faces.
// The same here: each equirect camera becomes its six faces (capture::CubeFaceCameras), and each
// observation goes to the face its bearing points into, at that face's pixel. Other cameras pass
// unchanged.
Reconstruction AsCubeFaces(const Reconstruction& r) {
  bool any = false;
  for (const auto& cam : r.rig.cameras) any |= cam.model.type() == capture::CameraModelType::kEquirectangular;
  if (!any) return r;
  Reconstruction out;
  out.rig.path = r.rig.path;
  out.rig.height_m = r.rig.height_m;
  out.frames = r.frames;
  std::vector<int> first_face(r.rig.cameras.size());  // the camera's first index in out.rig
  for (size_t c = 0; c < r.rig.cameras.size(); ++c) {
    const auto& cam = r.rig.cameras[c];
    first_face[c] = out.rig.camera_count();
    if (cam.model.type() != capture::CameraModelType::kEquirectangular) {
      out.rig.cameras.push_back(cam);
      continue;
    }
    for (auto& face : capture::CubeFaceCameras(cam, std::max(2, cam.model.width() / 4)))
      out.rig.cameras.push_back(std::move(face));
  }
  for (const auto& pt : r.points) {
    ReconstructedPoint q = pt;
    q.observations.clear();
    for (const auto& o : pt.observations) {
      if (r.rig.cameras[o.camera].model.type() != capture::CameraModelType::kEquirectangular) {
        q.observations.push_back(o);
        q.observations.back().camera = first_face[o.camera];
        continue;
      }
      // The face the bearing points into: the one whose axis is nearest to it.
      const Eigen::Matrix3d rig_from_cam = r.rig.cameras[o.camera].rig_from_cam.topLeftCorner<3, 3>();
      int best = 0;
      double best_dot = -2;
      for (int k = 0; k < 6; ++k) {
        const Eigen::Matrix3d rig_from_face =
            out.rig.cameras[first_face[o.camera] + k].rig_from_cam.topLeftCorner<3, 3>();
        const double d = (rig_from_face.transpose() * rig_from_cam * o.bearing).z();
        if (d > best_dot) best_dot = d, best = k;
      }
      PointObservation f = o;
      f.camera = first_face[o.camera] + best;
      f.bearing = out.rig.cameras[f.camera].rig_from_cam.topLeftCorner<3, 3>().transpose() * rig_from_cam * o.bearing;
      const auto& m = out.rig.cameras[f.camera].model;
      f.pixel = Eigen::Vector2d(m.fx() * f.bearing.x() / f.bearing.z() + m.cx(),
                                m.fy() * f.bearing.y() / f.bearing.z() + m.cy());
      q.observations.push_back(f);
    }
    out.points.push_back(std::move(q));
  }
  return out;
}

}  // namespace

std::string ReconstructionSummaryJson(const Reconstruction& r) {
  nlohmann::json stages = nlohmann::json::array();
  double total = 0;
  for (const auto& s : r.stages) {
    stages.push_back({{"name", s.name}, {"seconds", s.seconds}, {"inliers", s.inliers}, {"what", s.what}});
    total += s.seconds;
  }
  nlohmann::json cams = nlohmann::json::array();
  for (size_t c = 0; c < r.rig.cameras.size(); ++c) {
    const CameraContribution k = c < r.camera_contributions.size() ? r.camera_contributions[c] : CameraContribution{};
    cams.push_back({{"name", r.rig.cameras[c].name},
                    {"tracks", c < r.tracks_per_camera.size() ? r.tracks_per_camera[c] : 0},
                    {"observations", k.observations},
                    {"inlier_observations", k.inliers},
                    {"rejected_observations", k.rejected}});
  }
  int duplicates = 0, keys = 0, interpolated = 0;
  for (const auto& f : r.frames) {
    duplicates += f.duplicate_of >= 0;
    keys += f.key && f.duplicate_of < 0;
    interpolated += f.interpolated;
  }
  return nlohmann::json{{"rig", r.rig.path.string()},
                        {"frames", r.frames.size()},
                        {"first_index", r.frames.empty() ? 0 : r.frames.front().index},
                        {"last_index", r.frames.empty() ? 0 : r.frames.back().index},
                        {"dropped_frames", r.dropped_frames},
                        {"duplicate_frames", duplicates},
                        {"key_frames", keys},
                        {"interpolated_frames", interpolated},
                        {"cameras", cams},
                        {"mean_track_length", r.mean_track_length},
                        {"cross_camera_links", r.cross_camera_links},
                        {"trifocal",
                         {{"enabled", r.trifocal.enabled},
                          {"tracks_before", r.trifocal.tracks_before},
                          {"tracks_after", r.trifocal.tracks_after},
                          {"observations_before", r.trifocal.observations_before},
                          {"observations_after", r.trifocal.observations_after},
                          {"tracks_split", r.trifocal.tracks_split},
                          {"frame_triples_checked", r.trifocal.triples_checked},
                          {"frame_triples_unchecked", r.trifocal.triples_unchecked},
                          {"track_triples_tested", r.trifocal.triples_tested},
                          {"track_triples_rejected", r.trifocal.triples_rejected},
                          {"untested_observations", r.trifocal.untested_observations},
                          {"seconds", r.trifocal.seconds}}},
                        {"points", r.points.size()},
                        {"observations", r.observations},
                        {"reprojection_rmse_px", r.rmse_px},
                        {"rig_height_m", r.rig_height_m},
                        {"scale_applied", r.scale_applied},
                        {"scale_source", r.scale_source},
                        {"road_plane_found", r.road.found},
                        {"stages", stages},
                        {"seconds_total", total},
                        {"warnings", r.warnings}}
      .dump(1);
}

void WriteReconstruction(const Reconstruction& r, const fs::path& dir, const std::string& extra_summary_json) {
  const Reconstruction colmap = AsCubeFaces(r);
  std::string images, points;
  ColmapModel(colmap, &images, &points);
  nlohmann::json summary = nlohmann::json::parse(ReconstructionSummaryJson(r));
  if (!extra_summary_json.empty()) summary.update(nlohmann::json::parse(extra_summary_json));
  WriteTextFilesAtomically(dir, {{"trajectory.json", TrajectoryJson(r)},
                                 {"trajectory.tum", TrajectoryTum(r)},
                                 {"cameras.txt", CamerasTxt(colmap)},
                                 {"images.txt", images},
                                 {"points3D.txt", points},
                                 {"road_plane.json", RoadPlaneJson(r)},
                                 {"summary.json", summary.dump(1) + "\n"}});
}

}  // namespace odvr::tracking
