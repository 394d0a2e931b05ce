#include "capture/equirect_view.h"

#include <opencv2/imgproc.hpp>

#include "engine/core/error.h"

namespace odvr::capture {
namespace {

class EquirectViewSource final : public Source {
 public:
  EquirectViewSource(std::unique_ptr<Source> source, const EquirectViewOptions& options)
      : source_(std::move(source)), options_(options) {
    options_.Check();
    if (source_->camera_count() != 1)
      throw Error(source_->description(), "has " + std::to_string(source_->camera_count()) +
                                              " cameras: one equirectangular video or image folder is expected");
  }

  int camera_count() const override { return 1; }
  std::string description() const override {
    return source_->description() + " (" + ToString(options_.layout) +
           (options_.layout == StereoLayout::kMono ? ""
            : options_.eye == 0                    ? ", first eye"
                                                   : ", second eye") +
           (options_.width > 0 ? ", " + std::to_string(options_.width) + " wide" : "") +
           (options_.step > 1 ? ", every " + std::to_string(options_.step) + ". frame" : "") + ")";
  }
  bool live() const override { return source_->live(); }
  bool Seek(long frame) override { return source_->Seek(frame); }
  long frame_count() const override { return (source_->frame_count() + options_.step - 1) / options_.step; }
  double fps() const override { return source_->fps() / static_cast<double>(options_.step); }
  std::vector<SourceEvent> TakeEvents() override { return source_->TakeEvents(); }
  SourceStats stats() const override { return source_->stats(); }

  std::optional<FrameSet> Next(std::chrono::milliseconds timeout) override {
    std::optional<FrameSet> set = source_->Next(timeout);
    // The frames between two delivered ones are read and dropped: a video decodes them anyway.
    for (long skip = 1; skip < options_.step && set; ++skip)
      if (!source_->Next(timeout)) break;
    if (!set) return set;
    cv::Mat& image = set->frames.front().image;
    if (image.empty()) return set;
    int w = 0, h = 0;
    EyeSize(options_.layout, image.cols, image.rows, &w, &h);
    const cv::Rect eye = options_.layout == StereoLayout::kTopBottom    ? cv::Rect(0, options_.eye * h, w, h)
                         : options_.layout == StereoLayout::kSideBySide ? cv::Rect(options_.eye * w, 0, w, h)
                                                                        : cv::Rect(0, 0, w, h);
    cv::Mat view;
    if (options_.width > 0 && options_.width != w)
      cv::resize(image(eye), view, cv::Size(options_.width, options_.width / 2), 0, 0, cv::INTER_AREA);
    else
      view = eye.size() == image.size() ? image : image(eye).clone();
    image = view;
    return set;
  }

 private:
  std::unique_ptr<Source> source_;
  EquirectViewOptions options_;
};

}  // namespace

StereoLayout ParseStereoLayout(const std::string& name) {
  if (name == "mono") return StereoLayout::kMono;
  if (name == "top-bottom" || name == "tb") return StereoLayout::kTopBottom;
  if (name == "side-by-side" || name == "sbs") return StereoLayout::kSideBySide;
  throw Error("stereo layout", "\"" + name + "\" is none of mono, top-bottom, side-by-side");
}

std::string ToString(StereoLayout layout) {
  switch (layout) {
    case StereoLayout::kMono:
      return "mono";
    case StereoLayout::kTopBottom:
      return "top-bottom";
    case StereoLayout::kSideBySide:
      return "side-by-side";
  }
  return "?";
}

StereoLayout GuessStereoLayout(int width, int height) {
  if (width == height) return StereoLayout::kTopBottom;
  if (width == 4 * height) return StereoLayout::kSideBySide;
  return StereoLayout::kMono;
}

void EyeSize(StereoLayout layout, int width, int height, int* eye_width, int* eye_height) {
  *eye_width = layout == StereoLayout::kSideBySide ? width / 2 : width;
  *eye_height = layout == StereoLayout::kTopBottom ? height / 2 : height;
}

void EquirectViewOptions::Check() const {
  if (eye != 0 && eye != 1) throw Error("eye", "must be 0 or 1");
  if (width < 0 || width % 2 != 0) throw Error("tracking width", "must be a positive even number of pixels");
  if (step < 1) throw Error("step", "must be at least 1");
}

std::unique_ptr<Source> OpenEquirectView(std::unique_ptr<Source> source, const EquirectViewOptions& options) {
  return std::make_unique<EquirectViewSource>(std::move(source), options);
}

Rig EquirectCameraRig(int width, int height, double height_m) {
  Rig rig;
  RigCamera cam;
  cam.name = "cam0";
  cam.model = CameraModel::Equirectangular(width, height);
  // OpenCV camera axes (x right, y down, z forward) in the rig's (x forward, y left, z up).
  cam.rig_from_cam.topLeftCorner<3, 3>() << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  rig.cameras.push_back(cam);
  rig.height_m = height_m;
  return rig;
}

}  // namespace odvr::capture
