#pragma once
// Offline structure from motion for the calibrated rig (seed §5.3.2, DESIGN.md §6): per-camera
// KLT tracks, cross-camera SIFT links, an initial pair from the non-central relative pose,
// frame-by-frame registration by the non-central absolute pose, DLT triangulation, Ceres bundle
// adjustment with the extrinsics fixed, and metric scale from the road plane. A rig whose cameras
// share one centre (one equirectangular camera: a consumer 360° video) takes the central solvers
// of central_pose.h instead, its scale held by the initial pair until the road gives one; if it
// never moves enough to triangulate, every frame keeps one position and its tracked rotation. The result sits in
// a world whose z = 0 plane is the fitted road, z up, origin below the first rig pose and x along
// its heading: the Z-up convention of the datasets (odvr's Y-up world is (x, z, -y) of it).
#include <Eigen/Core>
#include <filesystem>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "capture/rig.h"
#include "capture/source.h"
#include "tracking/bundle_adjustment.h"
#include "tracking/cross_camera.h"
#include "tracking/road_plane.h"
#include "tracking/tracks.h"

namespace odvr::tracking {

struct ReconstructionOptions {
  KltOptions klt;
  CrossCameraOptions links;
  BundleAdjustmentOptions bundle;
  RoadPlaneOptions road;
  // Per rig camera (optional): non-zero where its images show no part of the world (a car roof,
  // the operator, a tripod); KltTracker's `ignore` mask.
  std::vector<cv::Mat> ignore_masks;
  double rig_height_m = 0;  // > 0 overrides the rig file's height
  long max_frames = 0;      // frame sets read from the source (0: all)
  // RANSAC thresholds of the relative and absolute pose (pixels at the camera's focal length).
  double ransac_threshold_px = 2.0;
  int min_init_inliers = 50;
  // The initial pair is frame 0 and the first later frame (up to max_init_gap) whose inlier rays
  // differ by this median angle after the rotation is taken out: below it depth is noise.
  double min_init_parallax_deg = 1.0;
  int max_init_gap = 10;
  int min_pose_inliers = 20;  // a frame with fewer agreeing 2D-3D matches cannot be registered
  double min_triangulation_angle_deg = 1.0;
  double max_reprojection_px = 4.0;  // observations beyond it are outliers after bundle adjustment
  int bundle_every = 8;              // intermediate bundle adjustments after this many new frames
  // Bundle adjustments while registering move only the last bundle_window key frames and the
  // points they see, holding the rest: their cost stays flat along a long clip. The final
  // adjustment moves every key frame. 0: every adjustment moves everything.
  int bundle_window = 32;

  // Key frames, chosen by parallax: a frame joins the map (triangulation, bundle adjustment) when
  // the median angle between its rays and the last key frame's, rotation taken out, reaches
  // keyframe_parallax_deg, or when it still sees fewer than keyframe_min_shared of the points the
  // last key frame saw. Frames between key frames add no depth (a stop at a traffic light, a slow
  // walk): they are posed against the finished map by absolute pose, and those that cannot be are
  // interpolated between the key frames around them. 0: every frame is a key frame.
  double keyframe_parallax_deg = 0.5;
  double keyframe_min_shared = 0.5;

  // A clip longer than chunk_frames frames is reconstructed in chunks of that many, each starting
  // with the last chunk_overlap frames of the one before and chained to it by the similarity of
  // those frames' poses: memory stays that of one chunk whatever the clip's length, time grows
  // linearly with it, and no bundle adjustment spans two chunks. 0: the clip in one piece.
  long chunk_frames = 200;
  int chunk_overlap = 20;

  // Trifocal check (seed §5.3.2): per camera and per three consecutive frames, the tensor of the
  // tracks seen in all three is estimated by RANSAC and a track is split where its triple does
  // not fit it. Points are the bearings projected to a virtual pinhole on the camera's optical
  // axis, so only bearings within trifocal_max_angle_deg of the axis take part.
  bool trifocal = true;
  // Reprojection error, as an angle times the camera's focal. On street_a, 40 frames (runs
  // differ by ~0.01 % ATE and ~0.1 % scale): off 0.022-0.043 % ATE and 0.07-0.19 % scale error
  // (4 runs); 1.5 px 0.019-0.022 % and 0.00-0.14 % (3 runs); 2 px 0.019-0.031 % and 0.22-0.34 %.
  double trifocal_threshold_px = 1.5;
  double trifocal_max_angle_deg = 60;
  int trifocal_min_triples = 30;  // fewer tracks through a triple: it is not checked
  // A tensor that fewer than this share of the triples support is not trusted (a degenerate
  // configuration: a static camera, pure rotation, one plane); its triple is not checked.
  double trifocal_min_inlier_ratio = 0.5;

  // Throws odvr::Error naming the first bad parameter.
  void Check() const;
};

// The defaults for one equirectangular camera (a consumer 360° video). Its frame holds the whole
// sky and every facade, whose corners are the strongest, and the road's weak texture falls under
// 1 % of them; but the road is what gives the metric scale. A floor of 0.1 % keeps it: on
// street_a as H.264 (crf 23, 40 frames) the road plane rests on 98 points instead of 14, the
// scale error over 10-40 frames stays within 3 % where it had swung between 0.7 and 108 %.
ReconstructionOptions OneCameraReconstructionOptions();

struct PointObservation {
  int frame = 0;  // index into Reconstruction::frames
  int camera = 0;
  Eigen::Vector2d pixel;
  Eigen::Vector3d bearing;
};

struct ReconstructedPoint {
  Eigen::Vector3d position;  // world (z up, metres)
  std::array<unsigned char, 3> rgb{};
  double error_px = 0;  // RMS reprojection error over its observations (camera model pixels)
  std::vector<PointObservation> observations;
};

struct ReconstructedFrame {
  long index = 0;  // frame number of the images
  double timestamp = 0;
  Rigid3 world_from_rig;
  int duplicate_of = -1;      // >= 0: identical images to that frame, which carries the estimate
  int inliers = 0;            // 2D-3D observations that agree with the pose after bundle adjustment
  bool key = true;            // a key frame: its pose comes from the bundle adjustment
  bool interpolated = false;  // not registrable: its pose is interpolated between key frames
};

struct ReconstructionStage {
  std::string name;
  double seconds = 0;
  int inliers = 0;  // what survived the stage (its own unit, named in `what`)
  std::string what;
};

// What the trifocal check did. With the check off only the before/after counts are filled (equal).
struct TrifocalCheckSummary {
  bool enabled = false;
  long tracks_before = 0, tracks_after = 0;  // KLT tracks; after: the pieces they were cut into
  long observations_before = 0, observations_after = 0;
  int triples_checked = 0;         // (camera, three frames) whose tensor was trusted
  int triples_unchecked = 0;       // too few tracks through them, or a tensor without support
  long triples_tested = 0;         // track triples fitted against a trusted tensor
  long triples_rejected = 0;       // of those, the ones that did not fit it
  int tracks_split = 0;            // tracks cut at least once
  long untested_observations = 0;  // observations outside the virtual pinhole's field
  double seconds = 0;
};

// What one rig camera's tracks gave the reconstruction.
struct CameraContribution {
  long observations = 0;  // track observations that became point observations (after the trifocal check)
  long inliers = 0;       // of those, the ones in the final model
  long rejected = 0;      // the rest: outliers, or points that never agreed with the rig's poses
};

struct Reconstruction {
  capture::Rig rig;
  std::vector<ReconstructedFrame> frames;
  std::vector<ReconstructedPoint> points;
  RoadPlane road;            // measured in the final world (normal ~ +z, offset ~ 0)
  double scale_applied = 1;  // metres per unit of the initial reconstruction
  std::string scale_source;  // where the metric height came from
  double rig_height_m = 0;
  std::vector<ReconstructionStage> stages;
  std::vector<int> tracks_per_camera;
  // Per rig camera. A camera whose share of inliers is far below the others' gets a warning: its
  // images disagree with the rig's motion (another camera's or another time's images, wrong
  // extrinsics), and the other cameras carry the poses.
  std::vector<CameraContribution> camera_contributions;
  double mean_track_length = 0;
  int cross_camera_links = 0;
  TrifocalCheckSummary trifocal;
  double rmse_px = 0;  // over all inlier observations, through the camera models
  int observations = 0;
  std::vector<long> dropped_frames;  // frame numbers with no image from any camera
  std::vector<std::string> warnings;
};

// Progress: stage name, work done, work total (frames or iterations); `log`: one line per bundle
// adjustment iteration and per stage. Either may be empty.
struct ReconstructionCallbacks {
  std::function<void(const std::string& stage, int done, int total)> progress;
  std::function<void(const std::string& line)> log;
};

// Reads frame sets from `source` (one image per rig camera) and reconstructs. Throws odvr::Error
// with a message that names the cause for the hard cases: fewer than 3 usable frames, images
// whose size contradicts the rig file, a rig that does not move (static or purely rotating), a
// frame that cannot be registered (a textureless stretch), a bundle adjustment that fails.
Reconstruction Reconstruct(const capture::Rig& rig, capture::Source& source, const ReconstructionOptions& options,
                           const ReconstructionCallbacks& callbacks = {});

// Writes into `dir` (created): trajectory.json, trajectory.tum, cameras.txt, images.txt,
// points3D.txt (COLMAP text model), road_plane.json, summary.json: atomically as a set
// (core/atomic_file.h WriteTextFilesAtomically).
// `extra_summary`, when not empty, is a JSON object merged into summary.json.
void WriteReconstruction(const Reconstruction& r, const std::filesystem::path& dir,
                         const std::string& extra_summary_json = "");

// summary.json's content.
std::string ReconstructionSummaryJson(const Reconstruction& r);

}  // namespace odvr::tracking
