#include "app/player/player.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "app/ar/frame_decoder.h"
#include "app/player/playback_clock.h"
#include "app/player/window_input.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/statistics.h"
#include "core/timing.h"
#include "engine/gl/context.h"
#include "engine/render/panorama_renderer.h"

namespace odvr::app {
namespace {

using Clock = std::chrono::steady_clock;

// The pieces shared by the window and the headless loop: decoded frames onto the GPU, drawn.
class Playback {
 public:
  explicit Playback(const PlayerOptions& options)
      : video_(options.video),
        decoder_(OpenPlayableVideo(options.video, options.stereo)),
        clock_(static_cast<int>(decoder_.frame_count()), decoder_.fps()) {
    clock_.SetLoop(options.loop);
    view_.Set(options.view);
  }

  // Brings the clock's frame onto the GPU and draws it. A window waits briefly for the decoder
  // and keeps the previous picture when the frame is late (playback goes on); a headless run
  // writes frame i as file i, so it waits for exactly that frame whatever the machine's load,
  // and fails naming it if the decoder never delivers.
  enum class Wait { kBriefly, kForTheFrame };
  FrameTimings Draw(int width, int height, float exposure, Wait wait = Wait::kBriefly) {
    FrameTimings t;
    const auto start = Clock::now();
    if (decoder_.available_frames() < clock_.frame_count())
      clock_.TruncateTo(static_cast<int>(decoder_.available_frames()));
    const long wanted = clock_.frame();
    if (wanted != shown_index_) {
      const std::chrono::milliseconds patience(wait == Wait::kForTheFrame ? kHeadlessFrameWaitMs
                                               : shown_index_ < 0         ? 5000
                                                                          : 30);
      auto f = decoder_.Get(wanted, patience);
      if (!f && decoder_.available_frames() == 0) throw Error(video_, "holds no decodable frame");
      if (!f && wait == Wait::kForTheFrame)
        throw Error(video_, "frame " + std::to_string(wanted) + " was not decoded within " +
                                std::to_string(kHeadlessFrameWaitMs / 1000) + " s");
      if (f) {
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
  static constexpr long kHeadlessFrameWaitMs = 60000;
  std::string video_;
  FrameDecoder decoder_;
  PlaybackClock clock_;
  ViewController view_;
  render::PanoramaRenderer panorama_;
  cv::Mat rgb_;
  long shown_index_ = -1;
  std::string last_event_;
};

PlayerReport RunWindow(const PlayerOptions& options) {
  gl::WindowContext window(options.width, options.height, "odvr — " + options.video);
  GLFWwindow* w = window.window();
  Playback playback(options);
  glfwSwapInterval(1);

  ImGuiSession imgui(w);
  WindowInput input(w);

  PlayerReport report;
  report.mode = "window";
  std::vector<double> totals;
  float exposure = static_cast<float>(options.exposure);
  bool show_overlay = true, ready = false;
  int shots = 0;
  bool screenshot_pending = false;  // F12 pressed, the shot not yet taken
  auto screenshot_requested = Clock::now();
  const auto start = Clock::now();
  auto previous = Clock::now();
  FrameTimings timings;
  std::vector<std::string> overlay;
  while (!glfwWindowShouldClose(w)) {
    glfwPollEvents();
    const double dt = SecondsSince(previous);
    previous = Clock::now();
    PlaybackClock& clock = playback.clock();
    ViewController& view = playback.view();

    // Input: drag to look, scroll or +/- to zoom, arrows to turn, space/,/./[/] for playback,
    // F1 the overlay, F12 a screenshot.
    int fb_w = 0, fb_h = 0;
    glfwGetFramebufferSize(w, &fb_w, &fb_h);
    const WindowInput::Events in = input.Take();
    view.Drag(in.drag_dx, in.drag_dy, std::max(fb_h, 1));
    view.Scroll(in.scroll);
    for (const int key : in.keys) {
      if (key == GLFW_KEY_SPACE) clock.TogglePause();
      if (key == GLFW_KEY_PERIOD) clock.Step(1);
      if (key == GLFW_KEY_COMMA) clock.Step(-1);
      if (key == GLFW_KEY_RIGHT_BRACKET) clock.SetSpeed(clock.speed() * 2);
      if (key == GLFW_KEY_LEFT_BRACKET) clock.SetSpeed(clock.speed() / 2);
      if (key == GLFW_KEY_EQUAL || key == GLFW_KEY_KP_ADD) view.Scroll(1);
      if (key == GLFW_KEY_MINUS || key == GLFW_KEY_KP_SUBTRACT) view.Scroll(-1);
      if (key == GLFW_KEY_F1) show_overlay = !show_overlay;
      if (key == GLFW_KEY_F12 && !screenshot_pending) {
        screenshot_pending = true;
        screenshot_requested = Clock::now();
      }
    }
    const bool keys_free = !ImGui::GetIO().WantTextInput;
    auto held = [&](int key) { return keys_free && glfwGetKey(w, key) == GLFW_PRESS ? 1.0 : 0.0; };
    view.Turn(held(GLFW_KEY_RIGHT) - held(GLFW_KEY_LEFT), held(GLFW_KEY_UP) - held(GLFW_KEY_DOWN), dt);
    clock.Advance(dt);

    // A minimized or 1×1 window still runs the loop; it just draws nothing worth seeing.
    if (fb_w > 0 && fb_h > 0) {
      timings = playback.Draw(fb_w, fb_h, exposure);
      totals.push_back(timings.total_ms);
      overlay = {
          Printf("frame %ld / %d   %.2f s%s", playback.shown_index(), clock.frame_count(), clock.position_s(),
                 clock.playing() ? "" : "  (paused)"),
          Printf("decode %.2f ms  upload %.2f ms  render %.2f ms", timings.decode_ms, timings.upload_ms,
                 timings.render_ms),
          Printf("total %.2f ms (median %.2f)  %.0f fps", timings.total_ms, Median(totals),
                 static_cast<double>(ImGui::GetIO().Framerate)),
          Printf("yaw %.1f  pitch %.1f  fov %.1f", view.state().yaw_deg, view.state().pitch_deg, view.state().fov_deg)};

      imgui.NewFrame();
      if (show_overlay) {
        ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_FirstUseEver);
        ImGui::SetNextWindowBgAlpha(0.6f);
        ImGui::Begin("odvr", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
        for (const auto& line : overlay) ImGui::TextUnformatted(line.c_str());
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
      }
      imgui.Render();
    }
    ++report.frames_shown;
    const bool quitting = options.quit_after_s > 0 && SecondsSince(start) > options.quit_after_s;
    if (quitting && !options.screenshot.empty() && fb_w > 0 && fb_h > 0)
      WriteWindowScreenshot(options.screenshot, fb_w, fb_h);
    // A screenshot shows the frame the clock is on: while paused (a step, a seek) it waits for the
    // decoder to bring that frame, which a step back (a seek) can take longer than Draw's wait:
    // CI under ASan shot frame 11 after '.' '.' ',' from 9, frame 10 arriving a loop later.
    // Playing, or after 5 s (a frame that never comes), it shows what is on screen.
    const bool frame_shown = clock.playing() || playback.shown_index() == clock.frame() ||
                             Clock::now() - screenshot_requested > std::chrono::seconds(5);
    std::string shot;
    if (screenshot_pending && frame_shown && fb_w > 0 && fb_h > 0) {
      screenshot_pending = false;
      shot = ScreenshotPath(options.screenshot, ++shots);
      WriteWindowScreenshot(shot, fb_w, fb_h);
      if (!options.trace) spdlog::info("screenshot: {}", shot);
    }
    glfwSwapBuffers(w);
    // After the swap: a test that waits for "ready" sends its input to a window that is showing.
    if (options.trace && (!ready || !shot.empty()) && fb_w > 0 && fb_h > 0) {
      nlohmann::json j{{"event", ready ? "screenshot" : "ready"},
                       {"file", shot},
                       {"size", {fb_w, fb_h}},
                       {"frame", playback.shown_index()},
                       {"playing", clock.playing()},
                       {"yaw", view.state().yaw_deg},
                       {"pitch", view.state().pitch_deg},
                       {"fov", view.state().fov_deg},
                       {"overlay_shown", show_overlay},
                       {"overlay", overlay},
                       {"ms",
                        {{"decode", timings.decode_ms},
                         {"upload", timings.upload_ms},
                         {"render", timings.render_ms},
                         {"total", timings.total_ms}}}};
      PrintTrace(j.dump());
      ready = true;
    }
    if (quitting) glfwSetWindowShouldClose(w, GLFW_TRUE);
  }
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
    const FrameTimings t = playback.Draw(options.width, options.height, static_cast<float>(options.exposure),
                                         Playback::Wait::kForTheFrame);
    totals.push_back(t.total_ms);
    report.last = t;
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d.png", i);
    WriteWindowScreenshot((std::filesystem::path(options.out_dir) / name).string(), options.width, options.height);
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
