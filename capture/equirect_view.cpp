#include "capture/equirect_view.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/imgproc.hpp>

#include "capture/libav_video.h"
#include "core/error.h"

namespace odvr::capture {
namespace {

namespace fs = std::filesystem;

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
    if (options_.width > 0 && (options_.width != w || options_.width != 2 * h))
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

EquirectClip OpenEquirectClip(std::unique_ptr<Source> raw, const std::string& name, std::optional<StereoLayout> stereo,
                              int eye, int max_width, long step, long first) {
  if (first > 0) raw->Seek(first);
  const auto set = raw->Next();
  if (!set || set->frames.empty() || set->frames.front().image.empty())
    throw Error(name, first > 0 ? "holds no decodable frame from frame " + std::to_string(first) + " on"
                                : "holds no decodable frame");
  const cv::Mat& image = set->frames.front().image;
  // What the file says (Spherical Video V2's st3d/sv3d), unless the caller says otherwise.
  std::error_code ec;
  bool declared_equirect = false;
  EquirectClip clip;
  clip.layout_from = stereo ? "the caller" : "the frame's shape";
  if (fs::is_regular_file(name, ec)) {
    const VideoProbe probe = ProbeVideo(name);
    if (!probe.projection.empty() && probe.projection != "equirectangular")
      throw Error(name, "is a " + probe.projection + " video by its metadata, not an equirectangular one");
    declared_equirect = probe.projection == "equirectangular";
    if (!stereo && probe.stereo) {
      stereo = probe.stereo;
      clip.layout_from = "its metadata";
    }
  }
  EquirectViewOptions view;
  view.layout = stereo ? *stereo : GuessStereoLayout(image.cols, image.rows);
  int w = 0, h = 0;
  EyeSize(view.layout, image.cols, image.rows, &w, &h);
  // An eye whose metadata says equirectangular spans 360° x 180° whatever its pixels' shape:
  // stereo videos often halve each eye's rows (3840x2160 top-bottom: two 3840x1080 eyes), to be
  // shown at 2:1. Resampled to 2:1 it is the equirect image every stage expects. Without that
  // word from the file, a frame that is not 2:1 is most likely not a 360° frame at all.
  if (w != 2 * h && !declared_equirect)
    throw Error(name, "a " + ToString(view.layout) + " frame of " + std::to_string(image.cols) + "x" +
                          std::to_string(image.rows) + " gives a " + std::to_string(w) + "x" + std::to_string(h) +
                          " eye, not an equirectangular 2:1 image");
  clip.eye_resampled = w != 2 * h;
  view.eye = eye;
  view.width = std::min(max_width - max_width % 2, w - w % 2);
  view.step = step;
  raw->Seek(first);
  clip.layout = view.layout;
  clip.width = view.width;
  clip.source = OpenEquirectView(std::move(raw), view);
  return clip;
}

cv::Mat NadirCapMask(int width, int height, double cap_deg) {
  cv::Mat mask = cv::Mat::zeros(height, width, CV_8U);
  const int rows = std::min(height, static_cast<int>(std::ceil(cap_deg / 180.0 * height)));
  if (rows > 0) mask.rowRange(height - rows, height).setTo(255);
  return mask;
}

std::vector<RigCamera> CubeFaceCameras(const RigCamera& equirect, int size) {
  struct Face {
    const char* name;
    Eigen::Vector3d z, y;  // optical axis and image down, in the equirect camera's frame
  };
  static const Face kFaces[6] = {{"front", {0, 0, 1}, {0, 1, 0}}, {"right", {1, 0, 0}, {0, 1, 0}},
                                 {"back", {0, 0, -1}, {0, 1, 0}}, {"left", {-1, 0, 0}, {0, 1, 0}},
                                 {"up", {0, -1, 0}, {0, 0, 1}},   {"down", {0, 1, 0}, {0, 0, -1}}};
  std::vector<RigCamera> faces;
  for (const Face& f : kFaces) {
    Eigen::Matrix3d cam_from_face;
    cam_from_face.col(0) = f.y.cross(f.z);
    cam_from_face.col(1) = f.y;
    cam_from_face.col(2) = f.z;
    RigCamera face;
    face.name = equirect.name + "_" + f.name;
    // 90° across: the focal is half the size; pixel centres at integers, so the centre is (size - 1) / 2.
    face.model =
        CameraModel::Pinhole(size, size, size / 2.0, size / 2.0, (size - 1) / 2.0, (size - 1) / 2.0, {0, 0, 0, 0, 0});
    face.rig_from_cam = equirect.rig_from_cam;
    face.rig_from_cam.topLeftCorner<3, 3>() = equirect.rig_from_cam.topLeftCorner<3, 3>() * cam_from_face;
    faces.push_back(face);
  }
  return faces;
}

cv::Mat CubeFaceImage(const cv::Mat& equirect_image, const RigCamera& equirect, const RigCamera& face) {
  const int size = face.model.width();
  const Eigen::Matrix3d cam_from_face =
      equirect.rig_from_cam.topLeftCorner<3, 3>().transpose() * face.rig_from_cam.topLeftCorner<3, 3>();
  cv::Mat map_x(size, size, CV_32F), map_y(size, size, CV_32F);
  const double sx = static_cast<double>(equirect_image.cols) / equirect.model.width();
  const double sy = static_cast<double>(equirect_image.rows) / equirect.model.height();
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      Eigen::Vector3d b;
      Eigen::Vector2d p(-1, -1);
      if (face.model.Unproject(Eigen::Vector2d(x, y), &b)) equirect.model.Project(cam_from_face * b, &p);
      map_x.at<float>(y, x) = static_cast<float>((p.x() + 0.5) * sx - 0.5);
      map_y.at<float>(y, x) = static_cast<float>((p.y() + 0.5) * sy - 0.5);
    }
  // The seam: columns wrap, so sample from the image with one column of the other side each way.
  cv::Mat wrapped;
  cv::copyMakeBorder(equirect_image, wrapped, 0, 0, 1, 1, cv::BORDER_WRAP);
  map_x += 1.0f;
  cv::Mat out;
  cv::remap(wrapped, out, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return out;
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
