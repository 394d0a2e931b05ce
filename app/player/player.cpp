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
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "app/ar/frame_decoder.h"
#include "app/player/playback_clock.h"
#include "app/player/player_loop.h"
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

// A recorded 360° video: decoded frames onto the GPU, drawn around the viewer, with playback
// controls (space, comma, period, brackets, the overlay's sliders).
class VideoScene : public PlayerScene {
 public:
  VideoScene(const PlayerOptions& options, PlayerReport* report)
      : video_(options.video),
        decoder_(OpenPlayableVideo(options.video, options.stereo)),
        clock_(static_cast<int>(decoder_.frame_count()), decoder_.fps()),
        exposure_(static_cast<float>(options.exposure)),
        report_(report) {
    clock_.SetLoop(options.loop);
  }

  int SwapInterval() const override { return 1; }

  void Key(int key) override {
    if (key == GLFW_KEY_SPACE) clock_.TogglePause();
    if (key == GLFW_KEY_PERIOD) clock_.Step(1);
    if (key == GLFW_KEY_COMMA) clock_.Step(-1);
    if (key == GLFW_KEY_RIGHT_BRACKET) clock_.SetSpeed(clock_.speed() * 2);
    if (key == GLFW_KEY_LEFT_BRACKET) clock_.SetSpeed(clock_.speed() / 2);
  }

  // The arrows turn the view; the clock runs with the wall.
  void Advance(double dt, const std::function<bool(int)>& held, ViewController* look) override {
    auto down = [&](int key) { return held(key) ? 1.0 : 0.0; };
    look->Turn(down(GLFW_KEY_RIGHT) - down(GLFW_KEY_LEFT), down(GLFW_KEY_UP) - down(GLFW_KEY_DOWN), dt);
    clock_.Advance(dt);
  }

  void Draw(int width, int height, const ViewController& look) override {
    timings_ = DrawFrame(width, height, look, Wait::kBriefly);
    totals_.push_back(timings_.total_ms);
  }

  std::vector<std::string> Overlay(const ViewState& look) const override {
    return {Printf("frame %ld / %d   %.2f s%s", shown_index_, clock_.frame_count(), clock_.position_s(),
                   clock_.playing() ? "" : "  (paused)"),
            Printf("decode %.2f ms  upload %.2f ms  render %.2f ms", timings_.decode_ms, timings_.upload_ms,
                   timings_.render_ms),
            Printf("total %.2f ms (median %.2f)  %.0f fps", timings_.total_ms, RecentMedian(),
                   static_cast<double>(ImGui::GetIO().Framerate)),
            Printf("yaw %.1f  pitch %.1f  fov %.1f", look.yaw_deg, look.pitch_deg, look.fov_deg)};
  }

  void OverlayControls() override {
    if (ImGui::Button(clock_.playing() ? "pause" : "play")) clock_.TogglePause();
    ImGui::SameLine();
    int frame = clock_.frame();
    if (ImGui::SliderInt("frame", &frame, 0, clock_.frame_count() - 1)) clock_.Seek(frame);
    float speed = static_cast<float>(clock_.speed());
    if (ImGui::SliderFloat("speed", &speed, 0.125f, 8.0f, "%.3g", ImGuiSliderFlags_Logarithmic)) clock_.SetSpeed(speed);
    ImGui::SliderFloat("exposure", &exposure_, 0.05f, 20.0f, "%.2f", ImGuiSliderFlags_Logarithmic);
    if (!last_event_.empty()) ImGui::TextColored(ImVec4(1, 0.7f, 0.2f, 1), "%s", last_event_.c_str());
  }

  bool ShowsTheAskedFrame() const override { return clock_.playing() || shown_index_ == clock_.frame(); }

  nlohmann::json Trace() const override {
    return {{"frame", shown_index_},
            {"playing", clock_.playing()},
            {"ms",
             {{"decode", timings_.decode_ms},
              {"upload", timings_.upload_ms},
              {"render", timings_.render_ms},
              {"total", timings_.total_ms}}}};
  }

  int HeadlessFrameCount() const override { return clock_.frame_count(); }

  // Frame i of the video (looping), drawn off-screen and read back.
  void WriteHeadlessFrame(int i, int width, int height, const ViewState& look,
                          const std::filesystem::path& png) override {
    if (!target_.has_value()) {
      target_.emplace(gl::Texture::Create2D(GL_RGBA8, width, height));
      fbo_.AttachColor(*target_).CheckComplete().Bind();
      clock_.SetPlaying(false);
    }
    clock_.Seek(i % clock_.frame_count());
    ViewController view;
    view.Set(look);
    timings_ = DrawFrame(width, height, view, Wait::kForTheFrame);
    totals_.push_back(timings_.total_ms);
    WriteWindowScreenshot(png.string(), width, height);
  }

  void Finish() override {
    report_->last = timings_;
    report_->median_total_ms = Median(totals_);
  }

 private:
  // The overlay's median, of the last 256 frames: every frame sorting the whole session's timings
  // would grow the frame's cost with the session (the report's median, at the end, takes them all).
  double RecentMedian() const {
    const std::size_t n = std::min<std::size_t>(totals_.size(), 256);
    return Median(std::vector<double>(totals_.end() - static_cast<std::ptrdiff_t>(n), totals_.end()));
  }

  // A window waits briefly for the decoder and keeps the previous picture when the frame is late
  // (playback goes on); a headless run writes frame i as file i, so it waits for exactly that
  // frame whatever the machine's load, and fails naming it if the decoder never delivers.
  enum class Wait { kBriefly, kForTheFrame };
  static constexpr long kHeadlessFrameWaitMs = 60000;

  // Brings the clock's frame onto the GPU and draws it.
  FrameTimings DrawFrame(int width, int height, const ViewController& look, Wait wait) {
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
    panorama_.Draw(glm::mat4(look.ViewMatrix()), glm::mat4(look.ProjectionMatrix(aspect)), exposure_, true);
    t.render_ms = MsSince(render);
    t.total_ms = MsSince(start);
    for (auto& e : decoder_.TakeEvents()) last_event_ = e.message;
    return t;
  }

  std::string video_;
  FrameDecoder decoder_;
  PlaybackClock clock_;
  float exposure_;
  PlayerReport* report_;
  render::PanoramaRenderer panorama_;
  std::optional<gl::Texture> target_;  // headless: the off-screen picture
  gl::Framebuffer fbo_;
  cv::Mat rgb_;
  long shown_index_ = -1;
  std::string last_event_;
  FrameTimings timings_;
  std::vector<double> totals_;
};

PlayerReport RunVideoPlayer(const PlayerOptions& options, bool headless) {
  PlayerReport report;
  const SceneFactory make = [&] { return std::make_unique<VideoScene>(options, &report); };
  RunPlayerLoop(options, !headless, "odvr — " + options.video, make, &report);
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
  if (!options.trajectory.empty()) return RunAugmentedPlayer(options, !headless);
  return RunVideoPlayer(options, headless);
}

}  // namespace odvr::app
