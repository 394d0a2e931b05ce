#pragma once
// Live augmented playback (`odvr play --live`): the rig's cameras, stitched into an
// equirectangular frame and relit every shown frame, with the car standing on the road in front
// of the rig. Each shown frame:
//   capture wait  the newest frame set from the source (capture/source.h: V4L2, libcamera, or a
//                 recording replayed live), waiting for one to arrive;
//   stitch        the set into a panorama (capture/stitcher.h), missing cameras left out;
//   lighting      the SG model of that panorama (engine/lighting), rebuilt for every new set;
//   render        the car by the triple-product renderer;
//   composite     the panorama through the viewer's pinhole, the car's shadow and the car over it.
//
// Frames: with no trajectory the rig stands still at the world's origin, its centre rig_height_m
// above the road (y = 0), and its odvr frame is the world's (forward +X, up +Y, right +Z), so the
// stitched panorama needs no turning. The car stands `car_ahead_m` straight ahead on the road,
// heading away along +X: a rig faces along its street, and 6 m ahead (the augmented player's
// view distance) at a 2 m rig height puts the car ~19° below the horizon, in the forward
// cameras' view and inside the default 90° field of view.
#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "app/ar/augmented_scene.h"
#include "app/ar/car_controller.h"
#include "app/ar/car_rendering.h"
#include "capture/rig.h"
#include "capture/source.h"
#include "capture/stitcher.h"
#include "engine/sphere/equirect_image.h"

namespace odvr::app {

// With composite_on_gpu and a car, LiveFrame::image is left empty (the picture is in
// LiveScene::composite()).
struct LiveSceneOptions : CarRendering {
  std::string rig;     // rig calibration (capture/rig.h)
  std::string source;  // capture::OpenSource spec; empty: the rig's image folders, replayed live
  std::string car;     // glTF 2.0 model; empty: the panorama alone
  double car_ahead_m = 6;
  int stitch_width = 1024, stitch_height = 512;
  capture::StitchDevice stitch_device = capture::StitchDevice::kCpu;
  double vfov_deg = 90;
  double exposure = 1.0;
  std::chrono::milliseconds first_set_timeout{5000};  // a source that delivers nothing is an error
  std::chrono::milliseconds set_timeout{200};         // later: show the last picture and go on
  void Check() const;                                 // throws odvr::UsageError
};

struct LiveTimings {  // milliseconds of one shown frame
  double capture_wait = 0, stitch = 0, lighting = 0, render = 0, readback = 0, composite = 0, total = 0;
};

struct LiveFrame {
  sphere::EquirectImage image;  // linear RGB, width × height, top row first
  bool new_set = false;         // false: no set arrived in time, the last panorama was shown again
  long set_index = -1;          // of the set shown (the source's running count)
  long source_frame = -1;       // the frame index of its first present camera
  int cameras_present = 0;
  long sets_skipped = 0;  // older sets passed over to show the newest
  glm::dvec3 car_position{0};
  glm::dvec2 car_pixel{-1};
  bool car_in_front = false;
  int car_pixels = 0;
  LiveTimings ms;
};

class LiveScene {
 public:
  // Needs a current OpenGL 4.5 context. Throws odvr::Error for a missing or malformed rig, a
  // source that cannot start or whose camera count differs from the rig's, or a missing car.
  explicit LiveScene(LiveSceneOptions options);
  ~LiveScene();
  LiveScene(const LiveScene&) = delete;
  LiveScene& operator=(const LiveScene&) = delete;

  void Drive(const CarInput& input, double dt_s);
  // The newest frame set, stitched, relit and composited. Throws odvr::Error only when the
  // source delivers no set at all before the first frame's timeout.
  LiveFrame Render(int width, int height, const AugmentedView& view = {});
  // What went wrong since the last call, one line per event, naming the camera by the rig's
  // name: a camera lost, a corrupt frame. (Dropped and out-of-sync frames are counted instead.)
  std::vector<std::string> TakeMessages();
  // Cameras lost so far (rig names), in the order they were lost.
  const std::vector<std::string>& lost_cameras() const { return lost_; }
  capture::SourceStats source_stats() const;
  std::string source_description() const;
  const capture::Rig& rig() const;
  const CarController& car() const { return *car_; }
  // With composite_on_gpu and a car model: the last frame's picture (LiveFrame::image empty), the
  // street with or without the car, linear RGBA32F, rows top first, before the exposure.
  const gl::Texture& composite() const;

 private:
  struct Impl;
  LiveSceneOptions options_;
  std::unique_ptr<Impl> impl_;
  std::unique_ptr<CarController> car_;
  std::vector<std::string> lost_;
};

}  // namespace odvr::app
