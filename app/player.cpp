#include "app/player.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <glm/gtc/type_ptr.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "app/frame_decoder.h"
#include "app/playback_clock.h"
#include "engine/core/atomic_file.h"
#include "engine/core/error.h"
#include "engine/gl/context.h"
#include "engine/render/panorama_renderer.h"

namespace odvr::app {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// The pieces shared by the window and the headless loop: decoded frames onto the GPU, drawn.
class Playback {
 public:
  explicit Playback(const PlayerOptions& options)
      : decoder_(capture::OpenSource(options.video)), clock_(static_cast<int>(decoder_.frame_count()), decoder_.fps()) {
    clock_.SetLoop(options.loop);
    view_.Set(options.view);
    if (decoder_.camera_count() != 1)
      throw Error(options.video, "has " + std::to_string(decoder_.camera_count()) +
                                     " cameras: play an equirectangular video or stitch the rig first (odvr stitch)");
  }

  // Brings the clock's frame onto the GPU (waiting briefly for the decoder) and draws it.
  FrameTimings Draw(int width, int height, float exposure) {
    FrameTimings t;
    const auto start = Clock::now();
    if (decoder_.available_frames() < clock_.frame_count())
      clock_.TruncateTo(static_cast<int>(decoder_.available_frames()));
    const long wanted = clock_.frame();
    if (wanted != shown_index_) {
      if (auto f = decoder_.Get(wanted, std::chrono::milliseconds(shown_index_ < 0 ? 5000 : 30))) {
        t.decode_ms = f->decode_ms;
        const cv::Mat& bgr = f->set.frames[0].image;
        if (!bgr.empty()) {  // a corrupt frame keeps the previous picture
          const auto up = Clock::now();
          cv::cvtColor(bgr, rgb_, cv::COLOR_BGR2RGB);
          if (!rgb_.isContinuous()) rgb_ = rgb_.clone();
          panorama_.UploadSrgb8(rgb_.cols, rgb_.rows, rgb_.data);
          t.upload_ms = MsSince(up);
        }
        shown_index_ = f->index;
      }
    }
    const auto render = Clock::now();
    glViewport(0, 0, width, height);
    glClearColor(0.02f, 0.02f, 0.02f, 1);
    glClear(GL_COLOR_BUFFER_BIT);
    const double aspect = height > 0 ? double(width) / height : 1.0;
    panorama_.Draw(glm::mat4(view_.ViewMatrix()), glm::mat4(view_.ProjectionMatrix(aspect)), exposure, true);
    t.render_ms = MsSince(render);
    t.total_ms = MsSince(start);
    for (auto& e : decoder_.TakeEvents()) last_event_ = e.message;
    return t;
  }

  PlaybackClock& clock() { return clock_; }
  ViewController& view() { return view_; }
  long shown_index() const { return shown_index_; }
  const std::string& last_event() const { return last_event_; }

 private:
  FrameDecoder decoder_;
  PlaybackClock clock_;
  ViewController view_;
  render::PanoramaRenderer panorama_;
  cv::Mat rgb_;
  long shown_index_ = -1;
  std::string last_event_;
};

struct WindowInput {
  double scroll = 0;
  bool toggle_pause = false;
  int step = 0;
  double speed_factor = 1;
};

void WriteScreenshot(const std::string& path, int width, int height) {
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

PlayerReport RunWindow(const PlayerOptions& options) {
  gl::WindowContext window(options.width, options.height, "odvr — " + options.video);
  GLFWwindow* w = window.window();
  Playback playback(options);
  WindowInput input;
  glfwSetWindowUserPointer(w, &input);
  glfwSwapInterval(1);

  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini next to the user's files
  ImGui_ImplGlfw_InitForOpenGL(w, true);
  ImGui_ImplOpenGL3_Init("#version 450");
  // ImGui's GLFW backend owns the callbacks; ours chain after it.
  glfwSetScrollCallback(w, [](GLFWwindow* win, double dx, double dy) {
    ImGui_ImplGlfw_ScrollCallback(win, dx, dy);
    if (!ImGui::GetIO().WantCaptureMouse) static_cast<WindowInput*>(glfwGetWindowUserPointer(win))->scroll += dy;
  });
  glfwSetKeyCallback(w, [](GLFWwindow* win, int key, int scancode, int action, int mods) {
    ImGui_ImplGlfw_KeyCallback(win, key, scancode, action, mods);
    if (ImGui::GetIO().WantCaptureKeyboard || action == GLFW_RELEASE) return;
    auto* in = static_cast<WindowInput*>(glfwGetWindowUserPointer(win));
    if (key == GLFW_KEY_SPACE && action == GLFW_PRESS) in->toggle_pause = true;
    if (key == GLFW_KEY_PERIOD) in->step += 1;
    if (key == GLFW_KEY_COMMA) in->step -= 1;
    if (key == GLFW_KEY_RIGHT_BRACKET && action == GLFW_PRESS) in->speed_factor *= 2;
    if (key == GLFW_KEY_LEFT_BRACKET && action == GLFW_PRESS) in->speed_factor /= 2;
    if (key == GLFW_KEY_ESCAPE || key == GLFW_KEY_Q) glfwSetWindowShouldClose(win, GLFW_TRUE);
  });

  PlayerReport report;
  report.mode = "window";
  std::vector<double> totals;
  double last_x = 0, last_y = 0;
  bool dragging = false;
  float exposure = static_cast<float>(options.exposure);
  const auto start = Clock::now();
  auto previous = Clock::now();
  FrameTimings timings;
  while (!glfwWindowShouldClose(w)) {
    glfwPollEvents();
    const double dt = std::chrono::duration<double>(Clock::now() - previous).count();
    previous = Clock::now();
    PlaybackClock& clock = playback.clock();
    ViewController& view = playback.view();

    // Input: drag to look, scroll to zoom, arrows to turn, space/,/./[/] for playback.
    const bool mouse_free = !ImGui::GetIO().WantCaptureMouse;
    double x, y;
    glfwGetCursorPos(w, &x, &y);
    int fb_w = 0, fb_h = 0;
    glfwGetFramebufferSize(w, &fb_w, &fb_h);
    if (glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS && (dragging || mouse_free)) {
      if (dragging) view.Drag(x - last_x, y - last_y, std::max(fb_h, 1));
      dragging = true;
    } else {
      dragging = false;
    }
    last_x = x;
    last_y = y;
    view.Scroll(std::exchange(input.scroll, 0.0));
    const double yaw_dir = (glfwGetKey(w, GLFW_KEY_RIGHT) == GLFW_PRESS) - (glfwGetKey(w, GLFW_KEY_LEFT) == GLFW_PRESS);
    const double pitch_dir = (glfwGetKey(w, GLFW_KEY_UP) == GLFW_PRESS) - (glfwGetKey(w, GLFW_KEY_DOWN) == GLFW_PRESS);
    view.Turn(yaw_dir, pitch_dir, dt);
    if (std::exchange(input.toggle_pause, false)) clock.TogglePause();
    if (const int step = std::exchange(input.step, 0)) clock.Step(step);
    if (input.speed_factor != 1) clock.SetSpeed(clock.speed() * std::exchange(input.speed_factor, 1.0));
    clock.Advance(dt);

    // A minimized or 1×1 window still runs the loop; it just draws nothing worth seeing.
    if (fb_w > 0 && fb_h > 0) {
      timings = playback.Draw(fb_w, fb_h, exposure);
      totals.push_back(timings.total_ms);

      ImGui_ImplOpenGL3_NewFrame();
      ImGui_ImplGlfw_NewFrame();
      ImGui::NewFrame();
      ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_FirstUseEver);
      ImGui::SetNextWindowBgAlpha(0.6f);
      ImGui::Begin("odvr", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
      ImGui::Text("frame %ld / %d   %.2f s", playback.shown_index(), clock.frame_count(), clock.position_s());
      ImGui::Text("decode %.2f ms  upload %.2f ms  render %.2f ms", timings.decode_ms, timings.upload_ms,
                  timings.render_ms);
      ImGui::Text("total %.2f ms (median %.2f)  %.0f fps", timings.total_ms, Median(totals), ImGui::GetIO().Framerate);
      ImGui::Text("yaw %.0f  pitch %.0f  fov %.0f", view.state().yaw_deg, view.state().pitch_deg, view.state().fov_deg);
      if (ImGui::Button(clock.playing() ? "pause" : "play")) clock.TogglePause();
      ImGui::SameLine();
      int frame = clock.frame();
      if (ImGui::SliderInt("frame", &frame, 0, clock.frame_count() - 1)) clock.Seek(frame);
      float speed = static_cast<float>(clock.speed());
      if (ImGui::SliderFloat("speed", &speed, 0.125f, 8.0f, "%.3g", ImGuiSliderFlags_Logarithmic))
        clock.SetSpeed(speed);
      ImGui::SliderFloat("exposure", &exposure, 0.05f, 20.0f, "%.2f", ImGuiSliderFlags_Logarithmic);
      if (!playback.last_event().empty())
        ImGui::TextColored(ImVec4(1, 0.7f, 0.2f, 1), "%s", playback.last_event().c_str());
      ImGui::End();
      ImGui::Render();
      ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
    }
    ++report.frames_shown;
    const bool quitting =
        options.quit_after_s > 0 && std::chrono::duration<double>(Clock::now() - start).count() > options.quit_after_s;
    if (quitting && !options.screenshot.empty() && fb_w > 0 && fb_h > 0)
      WriteScreenshot(options.screenshot, fb_w, fb_h);
    glfwSwapBuffers(w);
    if (quitting) glfwSetWindowShouldClose(w, GLFW_TRUE);
  }
  ImGui_ImplOpenGL3_Shutdown();
  ImGui_ImplGlfw_Shutdown();
  ImGui::DestroyContext();
  report.median_total_ms = Median(totals);
  report.last = timings;
  return report;
}

PlayerReport RunHeadless(const PlayerOptions& options) {
  gl::HeadlessContext context;
  Playback playback(options);
  gl::Texture color = gl::Texture::Create2D(GL_RGBA8, options.width, options.height);
  gl::Framebuffer fbo;
  fbo.AttachColor(color).CheckComplete().Bind();
  PlayerReport report;
  report.mode = "headless";
  report.output_dir = options.out_dir;
  std::filesystem::create_directories(options.out_dir);
  const int frames = options.headless_frames > 0 ? options.headless_frames : playback.clock().frame_count();
  std::vector<double> totals;
  PlaybackClock& clock = playback.clock();
  clock.SetPlaying(false);
  for (int i = 0; i < frames; ++i) {
    clock.Seek(i % clock.frame_count());
    const FrameTimings t = playback.Draw(options.width, options.height, static_cast<float>(options.exposure));
    totals.push_back(t.total_ms);
    report.last = t;
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d.png", i);
    WriteScreenshot((std::filesystem::path(options.out_dir) / name).string(), options.width, options.height);
    ++report.frames_shown;
  }
  report.median_total_ms = Median(totals);
  return report;
}

}  // namespace

void PlayerOptions::Check() const {
  if (video.empty()) throw UsageError("--video", "is required (an equirectangular video or image sequence)");
  if (width < 1 || height < 1 || width > 16384 || height > 16384)
    throw UsageError("--size", "must be between 1x1 and 16384x16384");
  if (!(exposure > 0)) throw UsageError("--exposure", "must be positive");
  if (headless_frames < 0) throw UsageError("--frames", "must be non-negative");
}

bool DisplayAvailable() {
  const char* x = std::getenv("DISPLAY");
  const char* wl = std::getenv("WAYLAND_DISPLAY");
  return (x && *x) || (wl && *wl);
}

PlayerReport RunPlayer(const PlayerOptions& options) {
  options.Check();
  const bool headless = options.headless || !DisplayAvailable();
  if (!options.trajectory.empty()) return headless ? RunAugmentedHeadless(options) : RunAugmentedWindow(options);
  return headless ? RunHeadless(options) : RunWindow(options);
}

}  // namespace odvr::app
