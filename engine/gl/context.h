#pragma once
// OpenGL 4.5 core contexts, two ways: headless through EGL (tests, CLI, CI) and a GLFW window
// (the player). Both leave the context current on the calling thread.
#include <array>
#include <cstdint>
#include <memory>
#include <string>

struct GLFWwindow;

namespace odvr::gl {

// What the current context is and what compute work it allows (`odvr info`).
struct ContextInfo {
  std::string platform;  // "egl-surfaceless", "egl-device" or "glfw"
  std::string vendor, renderer, version, glsl_version;
  int major = 0, minor = 0;
  bool core_profile = false;
  int max_compute_invocations = 0;
  std::array<int, 3> max_compute_group_count{};
  std::array<int, 3> max_compute_group_size{};
  int max_compute_shared_bytes = 0;
  std::int64_t max_ssbo_bytes = 0;
  int max_texture_size = 0;
  int max_3d_texture_size = 0;
};

// Reads ContextInfo from the current context.
ContextInfo QueryContextInfo(const std::string& platform);

// Throws odvr::Error naming `who` unless a context of at least OpenGL 4.5 is current: the GPU
// stages compile their shaders in their constructors.
void RequireCurrentGl45(const std::string& who);

// Whether an OpenGL renderer string names a CPU rasterizer (Mesa's llvmpipe or softpipe,
// SwiftShader): its times are the CPU's, not a GPU's, and what pays on a GPU may not pay there.
bool IsSoftwareRenderer(const std::string& gl_renderer);
// The same for the current context's GL_RENDERER.
bool CurrentRendererIsSoftware();

// A 4.5 core context with no window. Prefers a hardware EGL device (NVIDIA's EGL device
// platform) and falls back to Mesa's surfaceless platform (a software rasterizer without a GPU).
// Set ODVR_EGL_PLATFORM=surfaceless|device to force one. Throws odvr::Error when neither works.
// ODVR_GL_DEBUG=1 makes it a debug context whose GL errors and warnings go to the log.
class HeadlessContext {
 public:
  HeadlessContext();
  ~HeadlessContext();
  HeadlessContext(HeadlessContext&&) noexcept;
  HeadlessContext& operator=(HeadlessContext&&) noexcept;
  HeadlessContext(const HeadlessContext&) = delete;
  HeadlessContext& operator=(const HeadlessContext&) = delete;

  void MakeCurrent() const;
  const std::string& platform() const;
  ContextInfo Info() const { return QueryContextInfo(platform()); }

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// A GLFW window with a 4.5 core context. Throws odvr::Error when there is no display.
class WindowContext {
 public:
  WindowContext(int width, int height, const std::string& title, bool visible = true);
  ~WindowContext();
  WindowContext(const WindowContext&) = delete;
  WindowContext& operator=(const WindowContext&) = delete;

  GLFWwindow* window() const { return window_; }
  void MakeCurrent() const;
  ContextInfo Info() const { return QueryContextInfo("glfw"); }

 private:
  GLFWwindow* window_ = nullptr;
};

}  // namespace odvr::gl
