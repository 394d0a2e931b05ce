#include "app/player/window_input.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <utility>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/srgb.h"
#include "engine/gl/objects.h"
#include "engine/gl/shader_library.h"
#include "engine/image/image_io.h"

namespace odvr::app {

WindowInput& WindowInput::Of(GLFWwindow* w) { return *static_cast<WindowInput*>(glfwGetWindowUserPointer(w)); }

WindowInput::WindowInput(GLFWwindow* w) {
  glfwSetWindowUserPointer(w, this);
  glfwGetCursorPos(w, &last_x_, &last_y_);
  glfwSetMouseButtonCallback(w, [](GLFWwindow* win, int button, int action, int mods) {
    ImGui_ImplGlfw_MouseButtonCallback(win, button, action, mods);
    if (button != GLFW_MOUSE_BUTTON_LEFT) return;
    WindowInput& in = Of(win);
    // A press on the panel belongs to ImGui; a drag begun on the picture keeps turning the view
    // even when it crosses the panel. The drag starts where the last motion event left the cursor, not where the
    // server's pointer is now (glfwGetCursorPos asks it): by now it may be well into the drag.
    if (action == GLFW_PRESS && !ImGui::GetIO().WantCaptureMouse) in.dragging_ = true;
    if (action == GLFW_RELEASE) in.dragging_ = false;
  });
  // ImGui 1.86's backend reads the cursor by polling, so this callback is ours alone.
  glfwSetCursorPosCallback(w, [](GLFWwindow* win, double x, double y) {
    WindowInput& in = Of(win);
    if (in.dragging_) {
      in.events_.drag_dx += x - in.last_x_;
      in.events_.drag_dy += y - in.last_y_;
    }
    in.last_x_ = x;
    in.last_y_ = y;
  });
  glfwSetScrollCallback(w, [](GLFWwindow* win, double dx, double dy) {
    ImGui_ImplGlfw_ScrollCallback(win, dx, dy);
    if (!ImGui::GetIO().WantCaptureMouse) Of(win).events_.scroll += dy;
  });
  glfwSetKeyCallback(w, [](GLFWwindow* win, int key, int scancode, int action, int mods) {
    ImGui_ImplGlfw_KeyCallback(win, key, scancode, action, mods);
    // Only typing belongs to ImGui: a click on a checkbox makes it "want" the keyboard for a
    // frame (its item is active), and a key pressed then (F12, space, W) would be lost.
    if (ImGui::GetIO().WantTextInput || action == GLFW_RELEASE) return;
    if (key == GLFW_KEY_ESCAPE || key == GLFW_KEY_Q) glfwSetWindowShouldClose(win, GLFW_TRUE);
    Of(win).events_.keys.push_back(key);
  });
}

WindowInput::Events WindowInput::Take() { return std::exchange(events_, Events{}); }

ImGuiSession::ImGuiSession(GLFWwindow* window) {
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;
  ImGui_ImplGlfw_InitForOpenGL(window, true);
  ImGui_ImplOpenGL3_Init("#version 450");
}

ImGuiSession::~ImGuiSession() {
  ImGui_ImplOpenGL3_Shutdown();
  ImGui_ImplGlfw_Shutdown();
  ImGui::DestroyContext();
}

void ImGuiSession::NewFrame() {
  ImGui_ImplOpenGL3_NewFrame();
  ImGui_ImplGlfw_NewFrame();
  ImGui::NewFrame();
}

void ImGuiSession::Render() {
  ImGui::Render();
  ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
}

void FramePresenter::Show(const sphere::EquirectImage& linear, int framebuffer_width, int framebuffer_height,
                          GLuint target) {
  static const std::vector<std::uint8_t> lut = [] {
    std::vector<std::uint8_t> l(4096);
    for (int i = 0; i < 4096; ++i)
      l[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(std::lround(255 * LinearToSrgb(i / 4095.f)));
    return l;
  }();
  std::vector<std::uint8_t> srgb(linear.rgb.size());
  for (std::size_t i = 0; i < srgb.size(); ++i)
    srgb[i] = lut[static_cast<std::size_t>(std::clamp(linear.rgb[i], 0.f, 1.f) * 4095 + 0.5f)];
  const int width = linear.width, height = linear.height;
  if (width_ != width || height_ != height) {
    texture_ = gl::Texture::Create2D(GL_RGBA8, width, height);
    read_fbo_.AttachColor(texture_);
    width_ = width;
    height_ = height;
  }
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  texture_.Upload2D(GL_RGB, GL_UNSIGNED_BYTE, srgb.data());
  glBindFramebuffer(GL_FRAMEBUFFER, target);
  glViewport(0, 0, framebuffer_width, framebuffer_height);
  // Rows were uploaded top first; the window's y grows upward: flip in the blit.
  glBlitNamedFramebuffer(read_fbo_.id(), target, 0, 0, width, height, 0, framebuffer_height, framebuffer_width, 0,
                         GL_COLOR_BUFFER_BIT, GL_LINEAR);
}

void FramePresenter::Show(const gl::Texture& linear_rgba, float exposure, int framebuffer_width, int framebuffer_height,
                          GLuint target) {
  if (!linear_rgba) throw Error("frame presenter", "no picture to show (nothing rendered yet)");
  if (!encode_) {
    encode_ = gl::ShaderLibrary::Graphics("present.vert", "present.frag");
    empty_ = gl::VertexArray();
  }
  glBindFramebuffer(GL_FRAMEBUFFER, target);
  glViewport(0, 0, framebuffer_width, framebuffer_height);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_BLEND);
  glDisable(GL_CULL_FACE);
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_FRAMEBUFFER_SRGB);  // the shader encodes
  // Equal sizes (the players render at the window's) sample texel centres exactly.
  glTextureParameteri(linear_rgba.id(), GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTextureParameteri(linear_rgba.id(), GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTextureParameteri(linear_rgba.id(), GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTextureParameteri(linear_rgba.id(), GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glBindTextureUnit(0, linear_rgba.id());
  encode_.Set("uExposure", exposure)
      .Set("uTargetSize", static_cast<float>(framebuffer_width), static_cast<float>(framebuffer_height))
      .Use();
  empty_.Bind();
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glBindVertexArray(0);
}

void WriteWindowScreenshot(const std::string& path, int width, int height) {
  std::vector<unsigned char> rgba(static_cast<std::size_t>(width) * height * 4);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
  cv::Mat image(height, width, CV_8UC4, rgba.data()), bgr;
  cv::cvtColor(image, bgr, cv::COLOR_RGBA2BGR);
  cv::flip(bgr, bgr, 0);  // GL rows are bottom-up
  WriteFileAtomically(path, [&](const std::filesystem::path& tmp) {
    if (!cv::imwrite(tmp.string(), bgr)) throw Error(path, "cannot write PNG");
  });
}

std::string Printf(const char* format, ...) {
  char buf[512];
  va_list args;
  va_start(args, format);
  std::vsnprintf(buf, sizeof buf, format, args);
  va_end(args);
  return buf;
}

void PrintTrace(const std::string& json) { std::cout << json << std::endl; }

std::string ScreenshotPath(const std::string& final_screenshot, int n) {
  char name[40];
  std::snprintf(name, sizeof name, "odvr_screenshot_%03d.png", n);
  const std::filesystem::path dir = final_screenshot.empty() ? std::filesystem::current_path()
                                                             : std::filesystem::path(final_screenshot).parent_path();
  return (dir / name).string();
}

}  // namespace odvr::app
