#include "engine/gl/context.h"

#include <epoxy/egl.h>
#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <spdlog/spdlog.h>

#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "core/error.h"

namespace odvr::gl {
namespace {

bool HasExtension(const char* list, const char* name) {
  if (!list) return false;
  const std::size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n) {
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  }
  return false;
}

std::string EglErrorString(EGLint code) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "EGL error 0x%04X", static_cast<unsigned>(code));
  return buf;
}

bool GlDebugRequested() {
  const char* env = std::getenv("ODVR_GL_DEBUG");
  return env && std::string(env) != "0" && std::string(env) != "";
}

void GLAPIENTRY LogGlMessage(GLenum source, GLenum type, GLuint id, GLenum severity, GLsizei length,
                             const GLchar* message, const void*) {
  (void)source;
  if (severity == GL_DEBUG_SEVERITY_NOTIFICATION) return;
  const std::string text(message, length >= 0 ? static_cast<std::size_t>(length) : std::strlen(message));
  if (type == GL_DEBUG_TYPE_ERROR)
    spdlog::error("GL error {:#x}: {}", id, text);
  else
    spdlog::warn("GL {:#x}: {}", id, text);
}

// Creates a 4.5 core context on an initialized display; returns EGL_NO_CONTEXT on failure.
EGLContext CreateCoreContext(EGLDisplay display, std::string* why) {
  if (!eglBindAPI(EGL_OPENGL_API)) {
    *why = "eglBindAPI(EGL_OPENGL_API) failed";
    return EGL_NO_CONTEXT;
  }
  const EGLint config_attribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
  EGLConfig config = nullptr;
  EGLint num_configs = 0;
  const bool no_config = HasExtension(eglQueryString(display, EGL_EXTENSIONS), "EGL_KHR_no_config_context");
  if (!eglChooseConfig(display, config_attribs, &config, 1, &num_configs) || num_configs == 0) {
    if (!no_config) {
      *why = "no EGL config renders OpenGL";
      return EGL_NO_CONTEXT;
    }
    config = EGL_NO_CONFIG_KHR;
  }
  const EGLint context_attribs[] = {EGL_CONTEXT_MAJOR_VERSION,
                                    4,
                                    EGL_CONTEXT_MINOR_VERSION,
                                    5,
                                    EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                    EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                    EGL_CONTEXT_OPENGL_DEBUG,
                                    GlDebugRequested() ? EGL_TRUE : EGL_FALSE,
                                    EGL_NONE};
  EGLContext context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attribs);
  if (context == EGL_NO_CONTEXT) *why = "no OpenGL 4.5 core context (" + EglErrorString(eglGetError()) + ")";
  return context;
}

}  // namespace

struct HeadlessContext::State {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  std::string platform;
};

HeadlessContext::HeadlessContext() : state_(std::make_unique<State>()) {
  const char* client_ext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  const char* forced = std::getenv("ODVR_EGL_PLATFORM");
  const std::string force = forced ? forced : "";
  if (!force.empty() && force != "surfaceless" && force != "device")
    throw Error("ODVR_EGL_PLATFORM", "must be 'surfaceless' or 'device', not '" + force + "'");
  std::vector<std::string> failures;

  auto try_display = [&](EGLDisplay display, const std::string& platform) {
    if (display == EGL_NO_DISPLAY) {
      failures.push_back(platform + ": no display");
      return false;
    }
    EGLint major = 0, minor = 0;
    if (!eglInitialize(display, &major, &minor)) {
      failures.push_back(platform + ": eglInitialize failed (" + EglErrorString(eglGetError()) + ")");
      return false;
    }
    std::string why;
    EGLContext context = CreateCoreContext(display, &why);
    if (context == EGL_NO_CONTEXT || !eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
      failures.push_back(platform + ": " + (why.empty() ? "eglMakeCurrent failed" : why));
      if (context != EGL_NO_CONTEXT) eglDestroyContext(display, context);
      eglTerminate(display);
      return false;
    }
    state_->display = display;
    state_->context = context;
    state_->platform = platform;
    if (GlDebugRequested()) {
      // Each call's errors reported as it returns, so that the log line follows the call.
      glEnable(GL_DEBUG_OUTPUT);
      glEnable(GL_DEBUG_OUTPUT_SYNCHRONOUS);
      glDebugMessageCallback(LogGlMessage, nullptr);
      spdlog::info("ODVR_GL_DEBUG: logging the driver's GL errors and warnings");
    }
    return true;
  };

  // A hardware device first: on a machine with an NVIDIA driver, Mesa's surfaceless platform
  // would hand us llvmpipe. Mesa's own software device is skipped here and reached below.
  if (force != "surfaceless" && HasExtension(client_ext, "EGL_EXT_platform_device") &&
      HasExtension(client_ext, "EGL_EXT_device_enumeration")) {
    EGLDeviceEXT devices[16];
    EGLint count = 0;
    if (eglQueryDevicesEXT(16, devices, &count)) {
      for (EGLint i = 0; i < count; ++i) {
        const char* dev_ext = eglQueryDeviceStringEXT(devices[i], EGL_EXTENSIONS);
        if (force != "device" && HasExtension(dev_ext, "EGL_MESA_device_software")) continue;
        if (try_display(eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr), "egl-device")) return;
      }
    }
  }
  if (force != "device" && HasExtension(client_ext, "EGL_MESA_platform_surfaceless")) {
    // The core eglGetPlatformDisplay aborts through epoxy before a display exists (PLATFORM.md).
    if (try_display(eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr),
                    "egl-surfaceless"))
      return;
  } else if (force != "device") {
    failures.push_back("egl-surfaceless: EGL_MESA_platform_surfaceless not offered");
  }
  std::string reason = "cannot create a headless OpenGL 4.5 core context";
  for (const auto& f : failures) reason += "; " + f;
  if (failures.empty()) reason += "; no EGL platform available (install libegl-mesa0 and libgl1-mesa-dri)";
  throw Error("EGL", reason);
}

HeadlessContext::~HeadlessContext() {
  if (!state_ || state_->display == EGL_NO_DISPLAY) return;
  eglMakeCurrent(state_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  eglDestroyContext(state_->display, state_->context);
  // The display is left initialized: EGL displays are per process and others may share it.
}

HeadlessContext::HeadlessContext(HeadlessContext&&) noexcept = default;
HeadlessContext& HeadlessContext::operator=(HeadlessContext&&) noexcept = default;

void HeadlessContext::MakeCurrent() const {
  if (!eglMakeCurrent(state_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, state_->context))
    throw Error("EGL", "eglMakeCurrent failed (" + EglErrorString(eglGetError()) + ")");
}

const std::string& HeadlessContext::platform() const { return state_->platform; }

WindowContext::WindowContext(int width, int height, const std::string& title, bool visible) {
  glfwSetErrorCallback([](int code, const char* text) { spdlog::debug("GLFW error {}: {}", code, text); });
  if (!glfwInit()) throw Error("GLFW", "cannot initialize (no display? set DISPLAY or use xvfb-run)");
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_VISIBLE, visible ? GLFW_TRUE : GLFW_FALSE);
  window_ = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
  if (!window_) {
    glfwTerminate();
    throw Error("GLFW", "cannot create a window with an OpenGL 4.5 core context");
  }
  glfwMakeContextCurrent(window_);
}

WindowContext::~WindowContext() {
  if (window_) glfwDestroyWindow(window_);
  glfwTerminate();
}

void WindowContext::MakeCurrent() const { glfwMakeContextCurrent(window_); }

ContextInfo QueryContextInfo(const std::string& platform) {
  ContextInfo info;
  info.platform = platform;
  auto str = [](GLenum name) {
    const auto* s = reinterpret_cast<const char*>(glGetString(name));
    return std::string(s ? s : "");
  };
  info.vendor = str(GL_VENDOR);
  info.renderer = str(GL_RENDERER);
  info.version = str(GL_VERSION);
  info.glsl_version = str(GL_SHADING_LANGUAGE_VERSION);
  glGetIntegerv(GL_MAJOR_VERSION, &info.major);
  glGetIntegerv(GL_MINOR_VERSION, &info.minor);
  GLint mask = 0;
  glGetIntegerv(GL_CONTEXT_PROFILE_MASK, &mask);
  info.core_profile = (mask & GL_CONTEXT_CORE_PROFILE_BIT) != 0;
  glGetIntegerv(GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS, &info.max_compute_invocations);
  for (int i = 0; i < 3; ++i) {
    glGetIntegeri_v(GL_MAX_COMPUTE_WORK_GROUP_COUNT, i, &info.max_compute_group_count[i]);
    glGetIntegeri_v(GL_MAX_COMPUTE_WORK_GROUP_SIZE, i, &info.max_compute_group_size[i]);
  }
  glGetIntegerv(GL_MAX_COMPUTE_SHARED_MEMORY_SIZE, &info.max_compute_shared_bytes);
  GLint64 ssbo = 0;
  glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &ssbo);
  info.max_ssbo_bytes = ssbo;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &info.max_texture_size);
  glGetIntegerv(GL_MAX_3D_TEXTURE_SIZE, &info.max_3d_texture_size);
  return info;
}

void RequireCurrentGl45(const std::string& who) {
  GLint major = 0, minor = 0;
  glGetIntegerv(GL_MAJOR_VERSION, &major);
  glGetIntegerv(GL_MINOR_VERSION, &minor);
  if (major * 10 + minor < 45)
    throw Error(who, "needs a current OpenGL 4.5 context, the current one is " + std::to_string(major) + "." +
                         std::to_string(minor));
}

bool IsSoftwareRenderer(const std::string& gl_renderer) {
  for (const char* name : {"llvmpipe", "softpipe", "SwiftShader"})
    if (gl_renderer.find(name) != std::string::npos) return true;
  return false;
}

bool CurrentRendererIsSoftware() {
  const auto* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  return IsSoftwareRenderer(renderer ? renderer : "");
}

}  // namespace odvr::gl
