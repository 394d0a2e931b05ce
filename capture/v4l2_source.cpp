// Live V4L2 cameras through libv4l2 (which also converts exotic pixel formats): mmap streaming,
// MJPEG or YUYV, one thread per device. Errors at start name the device; a device that vanishes
// mid-stream (ENODEV) is reported as lost and the others go on.
#include <fcntl.h>
#include <libv4l2.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/live_source.h"
#include "core/error.h"

namespace odvr::capture {
namespace {

int Ioctl(int fd, unsigned long request, void* arg) {
  int r;
  do {
    r = v4l2_ioctl(fd, request, arg);
  } while (r == -1 && errno == EINTR);
  return r;
}

std::string ErrnoText(int e) {
  if (e == EBUSY) return "busy (another program is using it)";
  if (e == ENOENT) return "no such device";
  if (e == ENOTTY || e == EINVAL) return "not a V4L2 device";
  if (e == EACCES) return "permission denied (add the user to the 'video' group)";
  return std::strerror(e);
}

struct MappedBuffer {
  void* start = MAP_FAILED;
  std::size_t length = 0;
};

class V4l2Device {
 public:
  V4l2Device(const std::string& path, const SourceOptions& options) : path_(path) {
    fd_ = v4l2_open(path.c_str(), O_RDWR | O_NONBLOCK);
    if (fd_ < 0) throw Error(path, "cannot open: " + ErrnoText(errno));
    try {
      Configure(options);
    } catch (...) {
      Close();
      throw;
    }
  }
  ~V4l2Device() { Close(); }
  V4l2Device(const V4l2Device&) = delete;
  V4l2Device& operator=(const V4l2Device&) = delete;

  const std::string& path() const { return path_; }

  // Blocks up to `timeout_ms` for one frame. Returns false on timeout; throws on device loss.
  bool Capture(int timeout_ms, Frame* frame) {
    pollfd p{fd_, POLLIN, 0};
    const int r = poll(&p, 1, timeout_ms);
    if (r < 0 && errno != EINTR) throw Error(path_, std::string("poll failed: ") + std::strerror(errno));
    if (r <= 0) return false;
    if (p.revents & (POLLERR | POLLHUP | POLLNVAL)) throw Error(path_, "device disappeared");
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    if (Ioctl(fd_, VIDIOC_DQBUF, &buf) < 0) {
      if (errno == EAGAIN) return false;
      throw Error(path_, errno == ENODEV ? "device disappeared" : std::string("VIDIOC_DQBUF: ") + std::strerror(errno));
    }
    const auto* data = static_cast<const unsigned char*>(buffers_[buf.index].start);
    cv::Mat image;
    if (fourcc_ == V4L2_PIX_FMT_MJPEG) {
      image = cv::imdecode(cv::Mat(1, static_cast<int>(buf.bytesused), CV_8UC1, const_cast<unsigned char*>(data)),
                           cv::IMREAD_COLOR);
    } else {
      cv::Mat yuyv(height_, width_, CV_8UC2, const_cast<unsigned char*>(data), bytes_per_line_);
      cv::cvtColor(yuyv, image, cv::COLOR_YUV2BGR_YUYV);
    }
    frame->timestamp_s = static_cast<double>(buf.timestamp.tv_sec) + 1e-6 * static_cast<double>(buf.timestamp.tv_usec);
    frame->index = sequence_++;
    frame->image = std::move(image);  // empty if the MJPEG frame was corrupt
    if (Ioctl(fd_, VIDIOC_QBUF, &buf) < 0) throw Error(path_, "device disappeared (VIDIOC_QBUF failed)");
    return true;
  }

 private:
  void Configure(const SourceOptions& options) {
    v4l2_capability cap{};
    if (Ioctl(fd_, VIDIOC_QUERYCAP, &cap) < 0) throw Error(path_, "not a V4L2 device");
    const unsigned caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
    if (!(caps & V4L2_CAP_VIDEO_CAPTURE)) throw Error(path_, "is not a video capture device");
    if (!(caps & V4L2_CAP_STREAMING)) throw Error(path_, "does not support streaming I/O");

    bool has_mjpeg = false, has_yuyv = false;
    v4l2_fmtdesc desc{};
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    for (desc.index = 0; Ioctl(fd_, VIDIOC_ENUM_FMT, &desc) == 0; ++desc.index) {
      has_mjpeg |= desc.pixelformat == V4L2_PIX_FMT_MJPEG;
      has_yuyv |= desc.pixelformat == V4L2_PIX_FMT_YUYV;
    }
    if (options.pixel_format == "MJPG" && !has_mjpeg) throw Error(path_, "does not offer MJPG");
    if (options.pixel_format == "YUYV" && !has_yuyv) throw Error(path_, "does not offer YUYV");
    if (!options.pixel_format.empty() && options.pixel_format != "MJPG" && options.pixel_format != "YUYV")
      throw Error("pixel format", "must be MJPG or YUYV, not '" + options.pixel_format + "'");
    // libv4l2 can emulate YUYV-like formats from others; fall back to asking for YUYV.
    fourcc_ = options.pixel_format == "YUYV" || (options.pixel_format.empty() && !has_mjpeg) ? V4L2_PIX_FMT_YUYV
                                                                                             : V4L2_PIX_FMT_MJPEG;
    v4l2_format fmt{};
    fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (Ioctl(fd_, VIDIOC_G_FMT, &fmt) < 0) throw Error(path_, "cannot read its format");
    if (options.width > 0) fmt.fmt.pix.width = static_cast<unsigned>(options.width);
    if (options.height > 0) fmt.fmt.pix.height = static_cast<unsigned>(options.height);
    fmt.fmt.pix.pixelformat = fourcc_;
    fmt.fmt.pix.field = V4L2_FIELD_ANY;
    if (Ioctl(fd_, VIDIOC_S_FMT, &fmt) < 0) throw Error(path_, "cannot set its format: " + ErrnoText(errno));
    if (fmt.fmt.pix.pixelformat != fourcc_) throw Error(path_, "refused the requested pixel format");
    width_ = static_cast<int>(fmt.fmt.pix.width);
    height_ = static_cast<int>(fmt.fmt.pix.height);
    bytes_per_line_ = fmt.fmt.pix.bytesperline ? fmt.fmt.pix.bytesperline : static_cast<unsigned>(2 * width_);

    v4l2_requestbuffers req{};
    req.count = 4;
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    if (Ioctl(fd_, VIDIOC_REQBUFS, &req) < 0 || req.count < 2)
      throw Error(path_, "cannot allocate streaming buffers: " + ErrnoText(errno));
    buffers_.resize(req.count);
    for (unsigned i = 0; i < req.count; ++i) {
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buf.memory = V4L2_MEMORY_MMAP;
      buf.index = i;
      if (Ioctl(fd_, VIDIOC_QUERYBUF, &buf) < 0) throw Error(path_, "VIDIOC_QUERYBUF failed");
      buffers_[i].length = buf.length;
      buffers_[i].start = v4l2_mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buf.m.offset);
      if (buffers_[i].start == MAP_FAILED) throw Error(path_, "cannot map its buffers");
      if (Ioctl(fd_, VIDIOC_QBUF, &buf) < 0) throw Error(path_, "VIDIOC_QBUF failed");
    }
    v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (Ioctl(fd_, VIDIOC_STREAMON, &type) < 0) throw Error(path_, "cannot start streaming: " + ErrnoText(errno));
    streaming_ = true;
  }

  void Close() {
    if (fd_ < 0) return;
    if (streaming_) {
      v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      Ioctl(fd_, VIDIOC_STREAMOFF, &type);
    }
    for (auto& b : buffers_)
      if (b.start != MAP_FAILED) v4l2_munmap(b.start, b.length);
    v4l2_close(fd_);
    fd_ = -1;
  }

  std::string path_;
  int fd_ = -1;
  unsigned fourcc_ = 0;
  int width_ = 0, height_ = 0;
  unsigned bytes_per_line_ = 0;
  std::vector<MappedBuffer> buffers_;
  bool streaming_ = false;
  long sequence_ = 0;
};

class V4l2Source final : public LiveSource {
 public:
  V4l2Source(const std::vector<std::string>& devices, const SourceOptions& options)
      : LiveSource(static_cast<int>(devices.size()), options) {
    // Open every device before starting any thread: a missing camera fails the start cleanly.
    for (const auto& d : devices) devices_.push_back(std::make_unique<V4l2Device>(d, options));
    for (std::size_t c = 0; c < devices_.size(); ++c) AddThread(std::thread([this, c] { Run(static_cast<int>(c)); }));
  }
  ~V4l2Source() override { StopThreads(); }

  int camera_count() const override { return static_cast<int>(devices_.size()); }
  std::string description() const override {
    std::string s = "V4L2:";
    for (const auto& d : devices_) s += " " + d->path();
    return s;
  }

 private:
  void Run(int camera) {
    auto& device = *devices_[static_cast<std::size_t>(camera)];
    try {
      while (!stopping()) {
        Frame frame;
        frame.camera = camera;
        if (device.Capture(200, &frame)) Deliver(std::move(frame));
      }
    } catch (const std::exception& e) {
      spdlog::warn("{}", e.what());
      Lose(camera, e.what());
    }
  }
  std::vector<std::unique_ptr<V4l2Device>> devices_;
};

}  // namespace

std::unique_ptr<Source> OpenV4l2(const std::vector<std::string>& devices, const SourceOptions& options) {
  if (devices.empty()) throw Error("v4l2", "no devices given (v4l2:/dev/video0,/dev/video1,...)");
  return std::make_unique<V4l2Source>(devices, options);
}

}  // namespace odvr::capture
