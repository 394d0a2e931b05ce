// Recorded sources: image sequences and video files. They read synchronously in the caller's
// thread (the player puts its own decode thread in front), so a test gets the same sets every run.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <opencv2/imgcodecs.hpp>

#include "capture/image_file.h"
#include "capture/libav_video.h"
#include "capture/source.h"
#include "core/error.h"

namespace odvr::capture {
namespace {

namespace fs = std::filesystem;

bool IsImageFile(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  return ext == ".jpg" || ext == ".jpeg" || ext == ".png" || ext == ".exr" || ext == ".bmp" || ext == ".tif" ||
         ext == ".tiff";
}

// Frame number from a file stem such as "000123" or "GPFR0003_img5" (the last digit run).
long FrameNumber(const fs::path& p, long fallback) {
  const std::string stem = p.stem().string();
  auto end = stem.find_last_of("0123456789");
  if (end == std::string::npos) return fallback;
  auto begin = stem.find_last_not_of("0123456789", end);
  begin = begin == std::string::npos ? 0 : begin + 1;
  return std::stol(stem.substr(begin, end - begin + 1));
}

class ImageSequenceSource final : public Source {
 public:
  ImageSequenceSource(const std::vector<std::string>& dirs, const SourceOptions& options) : options_(options) {
    if (dirs.empty()) throw Error("image sequences", "no camera directories given");
    if (!(options.fps > 0)) throw Error("fps", "must be positive");
    for (std::size_t c = 0; c < dirs.size(); ++c) {
      const fs::path dir(dirs[c]);
      if (!fs::is_directory(dir)) throw Error(dirs[c], "not a directory");
      std::map<long, fs::path> frames;
      long order = 0;
      std::vector<fs::path> files;
      for (const auto& e : fs::directory_iterator(dir))
        if (e.is_regular_file() && IsImageFile(e.path())) files.push_back(e.path());
      std::sort(files.begin(), files.end());
      for (const auto& f : files) frames.emplace(FrameNumber(f, order++), f);
      if (frames.empty()) throw Error(dirs[c], "holds no images (.jpg, .png, .exr, ...)");
      cameras_.push_back({dirs[c], std::move(frames)});
    }
    for (const auto& cam : cameras_) {
      first_ = std::min(first_, cam.frames.begin()->first);
      last_ = std::max(last_, cam.frames.rbegin()->first);
    }
    next_ = first_;
    lost_.assign(cameras_.size(), false);
    sizes_.assign(cameras_.size(), cv::Size());
  }

  int camera_count() const override { return static_cast<int>(cameras_.size()); }
  std::string description() const override {
    return std::to_string(cameras_.size()) + " image sequence(s) from " + cameras_.front().dir + ", frames " +
           std::to_string(first_) + ".." + std::to_string(last_);
  }
  bool live() const override { return false; }

  std::optional<FrameSet> Next(std::chrono::milliseconds) override {
    if (next_ > last_) return std::nullopt;
    const long index = next_++;
    FrameSet set;
    set.index = stats_.sets_delivered++;
    set.timestamp_s = static_cast<double>(index) / options_.fps;
    set.frames.resize(cameras_.size());
    for (std::size_t c = 0; c < cameras_.size(); ++c) {
      Frame& frame = set.frames[c];
      frame.camera = static_cast<int>(c);
      frame.index = index;
      frame.timestamp_s = set.timestamp_s;
      const auto& cam = cameras_[c];
      auto it = cam.frames.find(index);
      if (it == cam.frames.end()) {
        ++stats_.missing_frames;
        // A camera whose sequence has ended while others go on is gone for good: say so once.
        if (index > cam.frames.rbegin()->first && !lost_[c]) {
          lost_[c] = true;
          events_.push_back({SourceEvent::Kind::kCameraLost, static_cast<int>(c), index,
                             cam.dir + ": sequence ends at frame " + std::to_string(cam.frames.rbegin()->first)});
        } else if (index <= cam.frames.rbegin()->first) {
          events_.push_back({SourceEvent::Kind::kDroppedFrames, static_cast<int>(c), index,
                             cam.dir + ": frame " + std::to_string(index) + " is missing"});
        }
        continue;
      }
      std::string problem;
      cv::Mat image = ReadImageFile(it->second, cv::IMREAD_COLOR, &problem);
      if (image.empty()) {
        ++stats_.corrupt_frames;
        events_.push_back(
            {SourceEvent::Kind::kCorruptFrame, static_cast<int>(c), index, it->second.string() + ": " + problem});
        continue;
      }
      if (sizes_[c].area() == 0) sizes_[c] = image.size();
      if (image.size() != sizes_[c]) {
        ++stats_.corrupt_frames;
        events_.push_back({SourceEvent::Kind::kCorruptFrame, static_cast<int>(c), index,
                           it->second.string() + ": size " + std::to_string(image.cols) + "x" +
                               std::to_string(image.rows) + " differs from the camera's " +
                               std::to_string(sizes_[c].width) + "x" + std::to_string(sizes_[c].height)});
        continue;
      }
      frame.image = std::move(image);
    }
    return set;
  }

  bool Seek(long frame) override {
    next_ = std::clamp(first_ + frame, first_, last_);
    return true;
  }
  long frame_count() const override { return last_ - first_ + 1; }
  double fps() const override { return options_.fps; }

  std::vector<SourceEvent> TakeEvents() override { return std::exchange(events_, {}); }
  SourceStats stats() const override { return stats_; }

 private:
  struct Camera {
    std::string dir;
    std::map<long, fs::path> frames;
  };
  SourceOptions options_;
  std::vector<Camera> cameras_;
  std::vector<bool> lost_;
  std::vector<cv::Size> sizes_;
  long first_ = std::numeric_limits<long>::max(), last_ = std::numeric_limits<long>::min(), next_ = 0;
  std::vector<SourceEvent> events_;
  SourceStats stats_;
};

// One libav reader per file. Each Next() takes the next decodable frame of every camera; a frame
// index is the frame's own position in its stream, so frames the decoder skipped leave gaps.
class VideoFileSource final : public Source {
 public:
  VideoFileSource(const std::vector<std::string>& paths, const SourceOptions& options) : options_(options) {
    if (paths.empty()) throw Error("video files", "none given");
    for (const auto& path : paths) {
      Camera cam{path, std::make_unique<LibavVideoReader>(path)};  // throws naming the file
      cam.fps = cam.reader->fps();
      if (!(cam.fps > 0 && cam.fps < 1000)) cam.fps = options.fps;
      cam.expected_frames = cam.reader->frame_count();
      cam.exact_count = cam.reader->probe().frame_count_exact;
      cameras_.push_back(std::move(cam));
    }
  }

  int camera_count() const override { return static_cast<int>(cameras_.size()); }
  std::string description() const override {
    return std::to_string(cameras_.size()) + " video file(s), first " + cameras_.front().path;
  }
  bool live() const override { return false; }

  std::optional<FrameSet> Next(std::chrono::milliseconds) override {
    FrameSet set;
    set.frames.resize(cameras_.size());
    int present = 0;
    double t_sum = 0;
    for (std::size_t c = 0; c < cameras_.size(); ++c) {
      Camera& cam = cameras_[c];
      Frame& frame = set.frames[c];
      frame.camera = static_cast<int>(c);
      frame.index = cam.next;
      if (cam.ended) {
        ++stats_.missing_frames;
        continue;
      }
      std::optional<VideoFrame> decoded;
      try {
        decoded = cam.reader->Next();
      } catch (const Error& e) {  // a frame libswscale cannot convert: the camera is gone
        Lose(static_cast<int>(c), e.what());
      }
      ReportSkipped(static_cast<int>(c));
      if (cam.ended) {
        ++stats_.missing_frames;
        continue;
      }
      if (!decoded) {
        cam.ended = true;
        ++stats_.missing_frames;
        ReportEnd(static_cast<int>(c));
        continue;
      }
      if (decoded->concealed) {
        ++stats_.corrupt_frames;
        events_.push_back(
            {SourceEvent::Kind::kCorruptFrame, static_cast<int>(c), decoded->index,
             cam.path + ": frame " + std::to_string(decoded->index) + " decoded with errors (concealed)"});
      }
      cam.next = decoded->index + 1;
      frame.index = decoded->index;
      frame.timestamp_s = decoded->timestamp_s;
      frame.image = std::move(decoded->image);
      t_sum += frame.timestamp_s;
      ++present;
    }
    if (present == 0) return std::nullopt;
    set.timestamp_s = t_sum / present;
    set.index = stats_.sets_delivered++;
    return set;
  }

  bool Seek(long frame) override {
    for (std::size_t c = 0; c < cameras_.size(); ++c) {
      Camera& cam = cameras_[c];
      const long target = std::clamp(frame, 0L, std::max(0L, cam.expected_frames - 1));
      cam.next = target;
      cam.ended = false;
      try {
        cam.reader->Seek(target);
      } catch (const Error& e) {  // the file went away, or changed, since it was opened
        Lose(static_cast<int>(c), e.what());
      }
      cam.skipped_reported = cam.reader->skipped_frames();  // frames before the target do not count
    }
    return true;
  }
  long frame_count() const override {
    long n = 0;
    for (const auto& cam : cameras_) n = std::max(n, cam.expected_frames);
    return n;
  }
  double fps() const override { return cameras_.front().fps; }

  std::vector<SourceEvent> TakeEvents() override { return std::exchange(events_, {}); }
  SourceStats stats() const override { return stats_; }

 private:
  struct Camera {
    std::string path;
    std::unique_ptr<LibavVideoReader> reader;
    double fps = 25;
    long expected_frames = 0;
    bool exact_count = false;  // expected_frames is the container's count, not an estimate
    long next = 0;             // the index the next frame should have
    long skipped_reported = 0;
    bool ended = false;
  };

  void ReportSkipped(int c) {
    Camera& cam = cameras_[c];
    for (; cam.skipped_reported < cam.reader->skipped_frames(); ++cam.skipped_reported) {
      ++stats_.corrupt_frames;
      events_.push_back({SourceEvent::Kind::kCorruptFrame, c, cam.next, cam.path + ": undecodable frame skipped"});
    }
  }

  // An error the reader cannot go on from ends the camera's stream, as its end would.
  void Lose(int c, const std::string& what) {
    Camera& cam = cameras_[c];
    cam.ended = true;
    events_.push_back({SourceEvent::Kind::kCameraLost, c, cam.next, what});
  }

  // A stream that ends short of its frame count was cut off. An estimated count (duration × fps)
  // can be one over, so that much shortfall is no truncation.
  void ReportEnd(int c) {
    const Camera& cam = cameras_[c];
    const long tolerance = cam.exact_count ? 0 : 1;
    if (cam.expected_frames <= 0 || cam.next >= cam.expected_frames - tolerance) return;
    std::string message = cam.path + ": stream ends after " + std::to_string(cam.next) + " of " +
                          std::to_string(cam.expected_frames) + " frames (truncated?)";
    if (!cam.reader->read_error().empty()) message += ": " + cam.reader->read_error();
    events_.push_back({SourceEvent::Kind::kCameraLost, c, cam.next, message});
  }

  SourceOptions options_;
  std::vector<Camera> cameras_;
  std::vector<SourceEvent> events_;
  SourceStats stats_;
};

std::vector<std::string> Split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= s.size()) {
    const auto end = s.find(sep, start);
    const std::string part = s.substr(start, end == std::string::npos ? std::string::npos : end - start);
    if (!part.empty()) out.push_back(part);
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return out;
}

}  // namespace

std::vector<std::string> CameraDirectories(const std::string& dir) {
  if (!fs::is_directory(dir)) throw Error(dir, "not a directory");
  std::vector<std::string> dirs;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (!e.is_directory()) continue;
    bool has_images = false;
    for (const auto& f : fs::directory_iterator(e.path())) {
      if (f.is_regular_file() && IsImageFile(f.path())) {
        has_images = true;
        break;
      }
    }
    if (has_images) dirs.push_back(e.path().string());
  }
  std::sort(dirs.begin(), dirs.end());
  if (dirs.empty()) dirs.push_back(dir);
  return dirs;
}

std::vector<std::filesystem::path> ImageFiles(const std::string& dir) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file() && IsImageFile(e.path())) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

std::unique_ptr<Source> OpenImageSequences(const std::vector<std::string>& camera_dirs, const SourceOptions& options) {
  return std::make_unique<ImageSequenceSource>(camera_dirs, options);
}

std::unique_ptr<Source> OpenVideoFiles(const std::vector<std::string>& paths, const SourceOptions& options) {
  return std::make_unique<VideoFileSource>(paths, options);
}

std::unique_ptr<Source> OpenSource(const std::string& spec, const SourceOptions& options) {
  if (spec.rfind("v4l2:", 0) == 0) return OpenV4l2(Split(spec.substr(5), ','), options);
  if (spec.rfind("libcamera:", 0) == 0) return OpenLibcamera(Split(spec.substr(10), ','), options);
  if (spec.rfind("replay:", 0) == 0) {
    // One folder holding the camera folders, or the camera folders themselves.
    auto dirs = Split(spec.substr(7), ',');
    if (dirs.size() == 1) dirs = CameraDirectories(dirs[0]);
    return OpenReplay(dirs, options);
  }
  if (spec.empty()) throw Error("source", "empty source name");
  const fs::path path(spec);
  if (fs::is_directory(path)) return OpenImageSequences(CameraDirectories(spec), options);
  const auto parts = Split(spec, ',');
  for (const auto& p : parts)
    if (!fs::exists(p)) throw Error(p, "no such file or directory");
  return OpenVideoFiles(parts, options);
}

}  // namespace odvr::capture
