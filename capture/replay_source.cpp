// A recording replayed as if live (capture/source.h OpenReplay): the same capture threads,
// frame-set assembly and camera-loss path as the V4L2 and libcamera sources, fed from files at
// the recording's frame rate, so the player's live mode can be rehearsed and tested without a rig.
#include <algorithm>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>

#include "capture/image_file.h"
#include "capture/live_source.h"
#include "core/error.h"

namespace odvr::capture {
namespace {

namespace fs = std::filesystem;

struct ReplayCamera {
  std::string dir;
  std::vector<fs::path> files;
  cv::Mat first;  // decoded at open: a camera that cannot deliver even one frame fails the start
};

std::vector<ReplayCamera> OpenCameras(const std::vector<std::string>& dirs) {
  if (dirs.empty()) throw Error("replay", "no camera folders given (replay:DIR or replay:DIR0,DIR1,...)");
  std::vector<ReplayCamera> cameras;
  for (const auto& dir : dirs) {
    if (!fs::is_directory(dir)) throw Error(dir, "not a directory (replay needs one image folder per camera)");
    ReplayCamera cam{dir, ImageFiles(dir), {}};
    if (cam.files.empty()) throw Error(dir, "holds no images (.jpg, .png, .exr, ...)");
    std::string problem;
    cam.first = ReadImageFile(cam.files.front(), cv::IMREAD_COLOR, &problem);
    if (cam.first.empty()) throw Error(cam.files.front().string(), problem + ": the camera cannot start");
    cameras.push_back(std::move(cam));
  }
  return cameras;
}

class ReplaySource final : public LiveSource {
 public:
  ReplaySource(std::vector<ReplayCamera> cameras, const SourceOptions& options)
      : LiveSource(static_cast<int>(cameras.size()), options), cameras_(std::move(cameras)), fps_(options.fps) {
    if (!(fps_ > 0)) throw Error("replay", "fps must be positive");
    for (const auto& cam : cameras_) length_ = std::max(length_, static_cast<long>(cam.files.size()));
    start_ = std::chrono::steady_clock::now();
    for (std::size_t c = 0; c < cameras_.size(); ++c) AddThread(std::thread([this, c] { Run(static_cast<int>(c)); }));
  }
  ~ReplaySource() override { StopThreads(); }

  int camera_count() const override { return static_cast<int>(cameras_.size()); }
  std::string description() const override {
    return "replay of " + std::to_string(cameras_.size()) + " camera(s) from " +
           fs::path(cameras_.front().dir).parent_path().lexically_normal().string() + " at " + FpsText() + " fps, " +
           std::to_string(length_) + " frames looped";
  }
  double fps() const override { return fps_; }

 private:
  std::string FpsText() const {
    char text[32];
    std::snprintf(text, sizeof text, "%g", fps_);
    return text;
  }
  void Run(int camera) {
    const ReplayCamera& cam = cameras_[static_cast<std::size_t>(camera)];
    const auto count = static_cast<long>(cam.files.size());
    for (long k = 0; !stopping(); ++k) {
      // Frame k is due k / fps after the start, on every camera alike (a hardware-synced rig);
      // sleep in short steps so that stopping is prompt.
      const auto due = start_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                    std::chrono::duration<double>(static_cast<double>(k) / fps_));
      while (!stopping() && std::chrono::steady_clock::now() < due)
        std::this_thread::sleep_until(std::min(due, std::chrono::steady_clock::now() + std::chrono::milliseconds(50)));
      if (stopping()) return;
      const long i = k % length_;
      if (i >= count) {
        Lose(camera, cam.dir + ": no frame after " + std::to_string(count) + " of the recording's " +
                         std::to_string(length_) + " (the camera is gone)");
        return;
      }
      Frame frame;
      frame.camera = camera;
      frame.index = k;
      frame.timestamp_s = static_cast<double>(k) / fps_;
      std::string problem;
      frame.image = i == 0 ? cam.first.clone()
                           : ReadImageFile(cam.files[static_cast<std::size_t>(i)], cv::IMREAD_COLOR, &problem);
      if (frame.image.empty()) {
        Lose(camera, cam.files[static_cast<std::size_t>(i)].string() + ": " + problem + " (the camera is gone)");
        return;
      }
      if (frame.image.size() != cam.first.size()) {
        Lose(camera, cam.files[static_cast<std::size_t>(i)].string() + ": size " + std::to_string(frame.image.cols) +
                         "x" + std::to_string(frame.image.rows) + " differs from the camera's " +
                         std::to_string(cam.first.cols) + "x" + std::to_string(cam.first.rows) +
                         " (the camera is gone)");
        return;
      }
      Deliver(std::move(frame));
    }
  }

  std::vector<ReplayCamera> cameras_;
  double fps_;
  long length_ = 0;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace

std::unique_ptr<Source> OpenReplay(const std::vector<std::string>& camera_dirs, const SourceOptions& options) {
  return std::make_unique<ReplaySource>(OpenCameras(camera_dirs), options);
}

}  // namespace odvr::capture
