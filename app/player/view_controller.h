#pragma once
// Free look inside the 360° frame: yaw unlimited, pitch clamped to ±90°, field of view 30–150°.
// Mouse drags turn the view by the angle the dragged pixels subtend, so the point under the
// cursor stays under the cursor whatever the zoom.
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

namespace odvr::app {

struct ViewState {
  double yaw_deg = 0;    // 0 looks forward (+X); positive turns right (toward +Z)
  double pitch_deg = 0;  // positive looks up
  double fov_deg = 90;   // vertical field of view
};

class ViewController {
 public:
  static constexpr double kMinFovDeg = 30, kMaxFovDeg = 150, kMaxPitchDeg = 90;

  const ViewState& state() const { return state_; }
  void Set(ViewState s);
  // A drag of (dx, dy) pixels in a viewport `height` pixels tall; dragging right turns left (the
  // scene follows the cursor), dragging down looks up.
  void Drag(double dx_px, double dy_px, int viewport_height_px);
  // Scroll up zooms in (narrower field of view), in steps of 5 %.
  void Scroll(double steps);
  // Keys: degrees per second of turning, applied over dt.
  void Turn(double yaw_dir, double pitch_dir, double dt_s, double deg_per_s = 90);

  // Unit view direction and the camera's up, in odvr's world frame (+Y up, +X forward, +Z right).
  glm::dvec3 Forward() const;
  glm::dvec3 Up() const;
  // World-from-camera rotation with the OpenGL camera convention (looks down −Z, +Y up).
  glm::dmat4 ViewMatrix() const;
  glm::dmat4 ProjectionMatrix(double aspect, double near_m = 0.05, double far_m = 1000) const;

 private:
  ViewState state_;
};

}  // namespace odvr::app
