// Live cameras through libcamera (Debian 12: 0.0.3). Each camera streams BGR888 (or YUYV, or
// MJPEG) buffers; a completed request is copied out, its timestamp kept, and requeued. A camera
// that disconnects is reported lost and the others go on.
#include <libcamera/camera.h>
#include <libcamera/camera_manager.h>
#include <libcamera/formats.h>
#include <libcamera/framebuffer_allocator.h>
#include <libcamera/request.h>
#include <libcamera/stream.h>
#include <spdlog/spdlog.h>
#include <sys/mman.h>

#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/live_source.h"
#include "core/error.h"

namespace odvr::capture {
namespace {

class LibcameraSource final : public LiveSource {
 public:
  LibcameraSource(std::unique_ptr<libcamera::CameraManager> manager,
                  std::vector<std::shared_ptr<libcamera::Camera>> cameras, const SourceOptions& options)
      : LiveSource(static_cast<int>(cameras.size()), options), manager_(std::move(manager)) {
    for (std::size_t c = 0; c < cameras.size(); ++c) {
      streams_.push_back(std::make_unique<CameraStream>());
      Start(static_cast<int>(c), std::move(cameras[c]), options);
    }
  }

  ~LibcameraSource() override {
    for (auto& s : streams_) {
      if (!s->camera) continue;
      s->camera->stop();
      s->camera->requestCompleted.disconnect(this);
      s->requests.clear();
      s->allocator.reset();
      s->camera->release();
    }
    StopThreads();
  }

  int camera_count() const override { return static_cast<int>(streams_.size()); }
  std::string description() const override {
    std::string s = "libcamera:";
    for (const auto& st : streams_) s += " " + st->camera->id();
    return s;
  }

 private:
  struct Mapping {
    void* address = MAP_FAILED;
    std::size_t length = 0;
  };
  struct CameraStream {
    int index = 0;
    std::shared_ptr<libcamera::Camera> camera;
    std::unique_ptr<libcamera::CameraConfiguration> config;
    std::unique_ptr<libcamera::FrameBufferAllocator> allocator;
    std::vector<std::unique_ptr<libcamera::Request>> requests;
    std::map<const libcamera::FrameBuffer*, Mapping> mappings;
    libcamera::Stream* stream = nullptr;
    long sequence = 0;
    ~CameraStream() {
      for (auto& [buffer, m] : mappings)
        if (m.address != MAP_FAILED) munmap(m.address, m.length);
    }
  };

  void Start(int index, std::shared_ptr<libcamera::Camera> camera, const SourceOptions& options) {
    CameraStream& s = *streams_[static_cast<std::size_t>(index)];
    s.index = index;
    const std::string id = camera->id();
    if (camera->acquire() < 0) throw Error("libcamera " + id, "busy (another program is using it)");
    s.camera = std::move(camera);
    s.config = s.camera->generateConfiguration({libcamera::StreamRole::VideoRecording});
    if (!s.config || s.config->empty()) throw Error("libcamera " + id, "offers no video stream");
    libcamera::StreamConfiguration& sc = s.config->at(0);
    sc.pixelFormat = libcamera::formats::BGR888;
    if (options.width > 0) sc.size.width = static_cast<unsigned>(options.width);
    if (options.height > 0) sc.size.height = static_cast<unsigned>(options.height);
    if (s.config->validate() == libcamera::CameraConfiguration::Invalid)
      throw Error("libcamera " + id, "rejects every stream configuration");
    if (sc.pixelFormat != libcamera::formats::BGR888 && sc.pixelFormat != libcamera::formats::YUYV &&
        sc.pixelFormat != libcamera::formats::MJPEG)
      throw Error("libcamera " + id,
                  "offers only pixel format " + sc.pixelFormat.toString() + " (odvr reads BGR888, YUYV, MJPEG)");
    if (s.camera->configure(s.config.get()) < 0) throw Error("libcamera " + id, "cannot be configured");
    s.stream = sc.stream();
    s.allocator = std::make_unique<libcamera::FrameBufferAllocator>(s.camera);
    if (s.allocator->allocate(s.stream) < 0) throw Error("libcamera " + id, "cannot allocate buffers");
    for (const auto& buffer : s.allocator->buffers(s.stream)) {
      auto request = s.camera->createRequest(static_cast<std::uint64_t>(index));
      if (!request || request->addBuffer(s.stream, buffer.get()) < 0)
        throw Error("libcamera " + id, "cannot create capture requests");
      // All planes of a buffer share one dmabuf in the formats read here: map it once.
      const auto& plane = buffer->planes().front();
      std::size_t length = 0;
      for (const auto& p : buffer->planes()) length = std::max<std::size_t>(length, p.offset + p.length);
      Mapping m;
      m.length = length;
      m.address = mmap(nullptr, length, PROT_READ, MAP_SHARED, plane.fd.get(), 0);
      if (m.address == MAP_FAILED) throw Error("libcamera " + id, "cannot map its buffers");
      s.mappings[buffer.get()] = m;
      s.requests.push_back(std::move(request));
    }
    s.camera->requestCompleted.connect(this, &LibcameraSource::OnRequestCompleted);
    s.camera->disconnected.connect(this, [this, index, id] { Lose(index, "libcamera " + id + " disconnected"); });
    if (s.camera->start() < 0) throw Error("libcamera " + id, "cannot start streaming");
    for (auto& r : s.requests) s.camera->queueRequest(r.get());
  }

  void OnRequestCompleted(libcamera::Request* request) {
    if (request->status() == libcamera::Request::RequestCancelled || stopping()) return;
    const int index = static_cast<int>(request->cookie());
    CameraStream& s = *streams_[static_cast<std::size_t>(index)];
    libcamera::FrameBuffer* buffer = request->buffers().begin()->second;
    const libcamera::StreamConfiguration& sc = s.config->at(0);
    const Mapping& m = s.mappings.at(buffer);
    auto* data = static_cast<unsigned char*>(m.address) + buffer->planes().front().offset;
    const int w = static_cast<int>(sc.size.width), h = static_cast<int>(sc.size.height);
    Frame frame;
    frame.camera = index;
    frame.index = s.sequence++;
    frame.timestamp_s = static_cast<double>(buffer->metadata().timestamp) * 1e-9;
    if (buffer->metadata().status == libcamera::FrameMetadata::FrameSuccess) {
      if (sc.pixelFormat == libcamera::formats::BGR888) {
        frame.image = cv::Mat(h, w, CV_8UC3, data, sc.stride).clone();
      } else if (sc.pixelFormat == libcamera::formats::YUYV) {
        cv::cvtColor(cv::Mat(h, w, CV_8UC2, data, sc.stride), frame.image, cv::COLOR_YUV2BGR_YUYV);
      } else {
        const auto bytes = buffer->metadata().planes().front().bytesused;
        frame.image = cv::imdecode(cv::Mat(1, static_cast<int>(bytes), CV_8UC1, data), cv::IMREAD_COLOR);
      }
    }
    Deliver(std::move(frame));
    request->reuse(libcamera::Request::ReuseBuffers);
    s.camera->queueRequest(request);
  }

  std::unique_ptr<libcamera::CameraManager> manager_;
  std::vector<std::unique_ptr<CameraStream>> streams_;
};

}  // namespace

std::unique_ptr<Source> OpenLibcamera(const std::vector<std::string>& camera_ids, const SourceOptions& options) {
  auto manager = std::make_unique<libcamera::CameraManager>();
  if (manager->start() < 0) throw Error("libcamera", "cannot start the camera manager");
  std::vector<std::shared_ptr<libcamera::Camera>> cameras;
  if (camera_ids.empty()) {
    cameras = manager->cameras();
    if (cameras.empty()) throw Error("libcamera", "no cameras found");
  } else {
    for (const auto& id : camera_ids) {
      auto camera = manager->get(id);
      if (!camera) {
        std::string known;
        for (const auto& c : manager->cameras()) known += (known.empty() ? "" : ", ") + c->id();
        throw Error("libcamera " + id, "no such camera (found: " + (known.empty() ? "none" : known) + ")");
      }
      cameras.push_back(std::move(camera));
    }
  }
  return std::make_unique<LibcameraSource>(std::move(manager), std::move(cameras), options);
}

}  // namespace odvr::capture
