#pragma once
// Augmented playback (seed §5.3.3, DESIGN.md §6): a glTF car standing on the road of a recorded
// street, driven by keys or a script. Each shown frame:
//   decode     the panoramas it needs (the viewer's frame, the car's light frames), cached;
//   lighting   each light frame's SG model (built once, cached), blended over the nearest frames
//              with weights smoothed over time;
//   render     the car by the triple-product renderer from the viewer frame's rig pose;
//   composite  the viewer frame's panorama seen through the same pinhole, darkened by the car's
//              shadow, the car over it.
//
// Frames: the trajectory's world is the datasets' (Z up, road z = 0; tracking's output too);
// odvr's world is its Y-up form p_yup = C p, C = [[1,0,0],[0,0,1],[0,-1,0]], road y = 0. A
// panorama is in its rig frame, and after C it is odvr's equirect frame, so the panorama of
// frame i is turned into the world by C R_i Cᵀ (R_i: world_from_rig's rotation).
// The renderer works in the car's frame (the model at the identity, ground y = 0 = the road):
// the car then never needs re-uploading, and the camera and the light are moved instead.
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "app/ar/car_controller.h"
#include "app/ar/car_look.h"
#include "app/ar/car_rendering.h"
#include "app/ar/frame_picker.h"
#include "engine/lighting/lighting_builder.h"
#include "engine/lighting/sg_lighting.h"
#include "engine/render/triple_product_renderer.h"
#include "engine/sphere/equirect_image.h"

namespace odvr::app {

// A scripted drive: "W:2s,A:1s,WD:0.5s,-:1s" — keys held (W/A/S/D, any combination; '-' none)
// for a duration ("2s", "500ms" or a bare number of seconds). Throws odvr::UsageError.
struct DriveStep {
  CarInput input;
  double seconds = 0;
};
std::vector<DriveStep> ParseDriveScript(const std::string& text);
// Keys held at time t since the start (none once the script has ended).
CarInput DriveInputAt(const std::vector<DriveStep>& script, double t_s);

// The centre of the car's bounding box in the renderer's world (where the car look aims).
glm::dvec3 BoundsCentre(const render::TripleProductRenderer& renderer);
double DriveDuration(const std::vector<DriveStep>& script);

// With composite_on_gpu, AugmentedFrame::image is left empty (the picture is in composite()).
struct AugmentedOptions : CarRendering {
  std::string video;            // equirect video or image sequence, frame i ↔ trajectory index i
  std::string stereo = "auto";  // OpenPlayableVideo's layout: auto, mono, top-bottom, side-by-side
  std::string trajectory;       // trajectory.json (tracking::LoadTrajectoryJson's schema)
  std::string car;              // glTF 2.0 model
  double car_start_m = -1;      // arc length of the car along the camera path; < 0: view_distance_m
  double lateral_m = 0;         // the car's offset left of the camera path at the start
  FramePickerOptions picker;
  double light_smoothing_s = 0.25;  // LightWeightSmoother's time constant
  double vfov_deg = 70;
  double exposure = 1.0;
  std::size_t frame_cache = 48;  // decoded panoramas kept (8-bit)
  // RenderEquirect is used: the renderer reads its layers back (the car's, the shadow's).
  bool equirect_output = false;
  void Check() const;  // throws odvr::UsageError
};

struct AugmentedTimings {  // milliseconds of one shown frame
  double decode = 0, lighting = 0, render = 0, readback = 0, composite = 0, total = 0;
};

struct AugmentedFrame {
  sphere::EquirectImage image;  // linear RGB, width × height, top row first
  int view_frame = 0;           // the trajectory/video frame shown
  int light_frame = 0;          // the frame nearest the car
  std::map<int, double> light_weights;
  glm::dvec3 car_position{0};  // world (Y up)
  glm::dvec2 car_pixel{-1};    // projection of the car's centre (bounding-box middle)
  bool car_in_front = false;
  int car_pixels = 0;
  // The driven car was held at an end of the reconstructed street (or too far off it): beyond,
  // there is no recorded frame to show it in.
  bool at_stretch_end = false;
  AugmentedTimings ms;
  // How well the light frame's model holds its panorama: the residual transform's levels (kept
  // SRBFs, the residue left after each) and the peaks taken out first.
  std::vector<lighting::LevelReport> light_levels;
  int light_peaks = 0;
  int cube_faces_rendered = 0;  // RenderEquirect: the faces the car or its shadow reached
  // The view frame's panorama frame from the renderer's (the car's): a ray of last_camera() turned
  // by it is a direction of the panorama (engine/sphere/equirect.h).
  glm::dmat3 pano_from_car{1.0};
};

// Viewer offsets on top of looking at the car.
struct AugmentedView {
  double yaw_deg = 0, pitch_deg = 0;  // positive: right, up
  double vfov_deg = 0;                // 0: the options' vfov
  bool draw_car = true;
};

class AugmentedScene {
 public:
  // Needs a current OpenGL 4.5 context. Throws odvr::Error for a missing or malformed video,
  // trajectory or car, and for a trajectory that shares no frame with the video.
  explicit AugmentedScene(AugmentedOptions options);
  ~AugmentedScene();
  AugmentedScene(const AugmentedScene&) = delete;
  AugmentedScene& operator=(const AugmentedScene&) = delete;

  // The car driven by keys; it is held on the reconstructed street (AugmentedFrame::at_stretch_end).
  void Drive(const CarInput& input, double dt_s);
  // Playback without keys: the video plays at its rate and the car rides ahead of the camera by
  // the distance it started at, at the camera's speed, so that the viewer sees frame t·fps; the
  // video loops at the end of the trajectory.
  void Cruise(double dt_s);
  // The car's speed: the camera's while cruising, the controller's while driven.
  double car_speed_mps() const;
  // Puts the car at arc length s of the camera path (clamped), `lateral_m` to its left.
  void PlaceCar(double s_m, double lateral_m = 0);
  // Moves the car to a world position (projected on the road), keeping its heading.
  void TeleportCar(const glm::dvec3& world_position);
  AugmentedFrame Render(int width, int height, const AugmentedView& view = {}, double dt_s = 0.04);
  // The augmented 360° frame (needs AugmentedOptions::equirect_output): the view frame's panorama
  // as the video holds it (its own orientation), `width` × width/2 (≤ 0: the video's width), with
  // the car and its shadow composited into it (app/ar/cube_face_composite.h). The lighting and the
  // frames chosen are Render's.
  AugmentedFrame RenderEquirect(int width, double dt_s = 0.04);
  // The car's material and light toggles, from the next Render on. Throws odvr::UsageError.
  void SetLook(const CarLook& look);
  const CarLook& look() const { return look_; }

  const CarController& car() const { return *car_; }
  const FramePicker& picker() const { return *picker_; }
  // Trajectory frames the video holds (indices into both), in order.
  const std::vector<int>& frames() const { return frame_index_; }
  double fps() const;
  long video_frames() const;
  // The SG model of one frame in its own (equirect) frame; built on first use.
  const lighting::SgLighting& FrameLighting(int frame);
  // The camera of the last Render (car frame = renderer world).
  const render::PinholeCamera& last_camera() const { return last_camera_; }
  // The last frame's picture on the GPU: linear RGBA32F, rows top first, before the exposure.
  const gl::Texture& composite() const;

 private:
  // What Render and RenderEquirect share: the frames decoded, the car lit, the view frame chosen.
  struct ViewSetup {
    int view_k = 0;                // index into frames()
    glm::dvec3 eye{0};             // the view frame's rig centre (world)
    glm::dmat4 world_from_car{1};  // the car's pose
  };
  ViewSetup PrepareFrame(double dt_s, AugmentedFrame* out);
  void DropPosesPastTheEnd();
  const sphere::EquirectImage& LinearPanorama(int frame);

  struct Impl;
  AugmentedOptions options_;
  std::unique_ptr<Impl> impl_;
  std::unique_ptr<FramePicker> picker_;
  std::unique_ptr<CarController> car_;
  std::vector<int> frame_index_;
  render::PinholeCamera last_camera_;
  CarLook look_;
};

}  // namespace odvr::app
