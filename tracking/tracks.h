#pragma once
// Per-camera KLT tracks (seed §5.3.2): Shi-Tomasi corners, pyramidal Lucas-Kanade from frame to
// frame with a forward-backward check, and re-detection in empty grid cells so the whole image
// stays covered. The seed prefers LK to descriptor matching because it keeps tracks long, and
// long tracks tie many rig poses together.
//
// An equirectangular image wraps around: its left and right edges are one meridian. The tracker
// pads each frame with the columns from the other side, so a track crossing the seam goes on and
// its pixel is wrapped back into the image.
//
// Tracking runs on the camera's own image, not an undistorted one: a 160-degree fisheye has no
// pinhole image that keeps its field of view, and LK only needs locally smooth motion. Every
// observation carries its unit bearing through capture/camera_model.h, which is what the
// estimators downstream consume.
#include <Eigen/Core>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

#include "capture/camera_model.h"

namespace odvr::tracking {

struct KltOptions {
  // Shi-Tomasi: a corner is kept when its smaller structure-tensor eigenvalue is at least
  // quality_level times the strongest in the (masked) frame, so a textureless cell stays empty
  // instead of filling with noise corners.
  double quality_level = 0.01;
  double min_distance_px = 8;  // between a new corner and any corner already tracked
  int block_size = 7;          // structure-tensor window
  // Re-detection grid: a cell without a live track receives up to corners_per_cell new ones.
  int cell_size_px = 40;
  int corners_per_cell = 4;
  // Gaussian blur before detection and tracking (0: none). Rendered frames (Monte-Carlo noise)
  // and JPEG blocks add pixel noise that LK's gradients pick up; a small blur keeps it from
  // failing the forward-backward check. On street_a cam0, frames 0-9: sigma 1 lengthens the mean
  // track from 2.9 to 3.5 frames and halves the forward-backward losses (602 -> 301).
  double presmooth_sigma_px = 1.0;
  // Lucas-Kanade.
  int window_px = 21;
  int pyramid_levels = 4;
  int max_lk_iterations = 30;
  // A track survives a frame only if tracking its new position back lands within this distance
  // of where it started (Kalal et al. 2010).
  double max_forward_backward_px = 1.0;
  // Pixels within this distance of the image edge or of the model's invalid region are masked,
  // so LK windows and detection blocks stay on valid pixels.
  int border_px = 8;
  // Rays further than this from the optical axis are masked (0: the model's own max_theta).
  double max_angle_deg = 0;

  // Throws odvr::Error naming the first bad parameter.
  void Check() const;
};

struct TrackObservation {
  int frame = 0;            // index of the frame in the tracker's sequence (0, 1, ...)
  Eigen::Vector2d pixel;    // OpenCV pixel convention (capture/camera_model.h)
  Eigen::Vector3d bearing;  // unit, camera frame
};

struct Track {
  int id = 0;
  bool active = true;                          // still followed in the latest frame
  std::vector<TrackObservation> observations;  // consecutive frames

  int length() const { return static_cast<int>(observations.size()); }
};

struct KltFrameStats {
  int frame = 0;
  int continued = 0;  // tracks carried into this frame
  int lost_lk = 0;    // LK did not converge or left the mask
  int lost_forward_backward = 0;
  int detected = 0;          // new tracks started here
  int active = 0;            // live tracks after this frame
  double covered_cells = 0;  // fraction of grid cells (with valid pixels) holding a live track
};

class KltTracker {
 public:
  // Throws odvr::Error for bad options or an `ignore` mask of another size than the model's.
  // `ignore` (8-bit, optional): non-zero where the image shows no part of the world to track
  // (a car roof, the operator, a tripod); no corner is detected there and tracks entering it end.
  KltTracker(const capture::CameraModel& model, const KltOptions& options = KltOptions(),
             const cv::Mat& ignore = cv::Mat());

  // The next frame (8-bit gray or BGR, the model's size). Throws odvr::Error("klt frame N", ...)
  // for an empty image or one whose size contradicts the camera model.
  const KltFrameStats& AddFrame(const cv::Mat& image);

  const std::vector<Track>& tracks() const { return tracks_; }
  const std::vector<KltFrameStats>& stats() const { return stats_; }
  // 255 where tracking and detection may use a pixel.
  const cv::Mat& mask() const { return mask_; }
  int frame_count() const { return static_cast<int>(stats_.size()); }

  // Mean length (frames) of all tracks ever started; "n tracks, mean length L, ..." summary.
  double MeanTrackLength() const;
  std::string BriefReport() const;

 private:
  void Detect(const cv::Mat& gray, KltFrameStats* stats);
  bool Observe(Eigen::Vector2d pixel, TrackObservation* observation) const;

  capture::CameraModel model_;
  KltOptions options_;
  cv::Mat mask_;
  cv::Mat previous_;  // the last frame, smoothed and (equirect) padded by wrap_ columns a side
  int wrap_ = 0;
  std::vector<Track> tracks_;
  std::vector<int> active_;  // indices into tracks_
  std::vector<KltFrameStats> stats_;
  int valid_cells_ = 0;
};

}  // namespace odvr::tracking
