#pragma once
// The player windows' input and what they report, shared by the plain and the augmented loop.
//
// Input is gathered by GLFW callbacks rather than by polling the mouse once per frame: a drag or
// a key tap that begins and ends between two frames (a slow frame on a software GL, or scripted
// input) still turns the view by all of its pixels and still counts.
#include <string>
#include <vector>

#include "engine/gl/objects.h"
#include "engine/sphere/equirect_image.h"

struct GLFWwindow;

namespace odvr::app {

class WindowInput {
 public:
  // Installs the callbacks, chaining to Dear ImGui's backend: call after ImGui_ImplGlfw_Init.
  // Input that ImGui takes (a click on the panel, typing in a field) is not ours.
  explicit WindowInput(GLFWwindow* window);

  struct Events {
    double drag_dx = 0, drag_dy = 0;  // pixels dragged with the left button since the last Take
    double scroll = 0;                // wheel steps, positive up
    std::vector<int> keys;            // GLFW keys pressed (and auto-repeated), in order
  };
  Events Take();

 private:
  static WindowInput& Of(GLFWwindow* w);
  Events events_;
  bool dragging_ = false;
  double last_x_ = 0, last_y_ = 0;
};

// Dear ImGui on a window for the object's lifetime (no imgui.ini next to the user's files). Make it
// before the WindowInput, which chains to the backend's callbacks.
class ImGuiSession {
 public:
  explicit ImGuiSession(GLFWwindow* window);
  ~ImGuiSession();
  ImGuiSession(const ImGuiSession&) = delete;
  ImGuiSession& operator=(const ImGuiSession&) = delete;
  void NewFrame();
  void Render();  // draws what the frame's ImGui calls built over the back buffer
};

// Shows a rendered linear picture (rows top first) in the window's back buffer as 8-bit sRGB,
// scaled to the framebuffer: the augmented and the live player render off-screen at the window's
// size. From a CPU image (uploaded), or from the renderer's composite where it was made, which
// spares a player the read-back and the upload (TripleProductRenderer::composite_texture). `target`:
// the framebuffer drawn into, 0 for the window's.
class FramePresenter {
 public:
  void Show(const sphere::EquirectImage& linear, int framebuffer_width, int framebuffer_height, GLuint target = 0);
  // linear_rgba: RGB linear, rows top first; times `exposure` before the encoding.
  void Show(const gl::Texture& linear_rgba, float exposure, int framebuffer_width, int framebuffer_height,
            GLuint target = 0);

 private:
  gl::Texture texture_{gl::NoCreate};
  gl::Framebuffer read_fbo_;
  int width_ = 0, height_ = 0;
  gl::Program encode_{gl::NoCreate};  // present.vert + present.frag
  gl::VertexArray empty_{gl::NoCreate};
};

// printf into a std::string (the overlay's lines: drawn by ImGui and printed by --trace, so what a
// test reads is what the window shows).
std::string Printf(const char* format, ...) __attribute__((format(printf, 1, 2)));

// One line of --trace on stdout, flushed: a JSON object per event ("ready", "screenshot").
void PrintTrace(const std::string& json);

// The window's back buffer (what the frame drew, overlay included) to a PNG, written atomically.
void WriteWindowScreenshot(const std::string& path, int width, int height);

// Where the n-th F12 screenshot goes: next to --screenshot when it is given, else in the working
// directory.
std::string ScreenshotPath(const std::string& final_screenshot, int n);

}  // namespace odvr::app
