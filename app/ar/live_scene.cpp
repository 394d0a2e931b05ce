#include "app/ar/live_scene.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "core/error.h"
#include "core/timing.h"
#include "engine/lighting/lighting_builder.h"
#include "engine/render/triple_product_renderer.h"
#include "engine/scene/gltf_scene.h"
#include "engine/sphere/equirect.h"

namespace odvr::app {
namespace {

using Clock = std::chrono::steady_clock;
// The rig's own image folders (image_dir, relative to the rig file), replayed live.
std::unique_ptr<capture::Source> OpenRigSource(const capture::Rig& rig, const std::string& rig_path) {
  std::vector<std::string> dirs;
  for (const auto& cam : rig.cameras) {
    if (cam.image_dir.empty())
      throw UsageError("--source", "not given, and the rig " + rig_path + " names no image_dir for camera " + cam.name +
                                       ": pass --source (v4l2:/dev/video0,..., libcamera:, replay:DIR)");
    dirs.push_back((rig.path.parent_path() / cam.image_dir).string());
  }
  return capture::OpenReplay(dirs, {});
}

}  // namespace

void LiveSceneOptions::Check() const {
  if (rig.empty()) throw UsageError("--rig", "is required in live mode (the rig's calibration)");
  if (!(car_ahead_m > 0 && car_ahead_m < 1000)) throw UsageError("--car-start", "must be 0..1000 m ahead of the rig");
  if (stitch_width < 16 || stitch_height < 8 || stitch_width > 16384 || stitch_height > 8192)
    throw UsageError("--stitch-size", "must be between 16x8 and 16384x8192");
  CarRendering::Check();
  if (!(vfov_deg >= 10 && vfov_deg <= 150)) throw UsageError("--fov", "must be 10..150 degrees");
  if (!(exposure > 0)) throw UsageError("--exposure", "must be positive");
}

struct LiveScene::Impl {
  capture::Rig rig;
  std::unique_ptr<capture::Source> source;
  std::unique_ptr<capture::Stitcher> stitcher;
  capture::StitchedFrame stitched;
  bool have_panorama = false;
  long set_index = -1, source_frame = -1;
  int cameras_present = 0;
  std::unique_ptr<lighting::LightingBuilder> builder;
  lighting::SgLighting light;  // of the last panorama
  scene::GltfScene model;
  std::unique_ptr<render::TripleProductRenderer> renderer;
  glm::dvec3 car_centre{0};  // bounding-box middle in the car frame
  cv::Mat padded;            // the panorama, one wrapped column each side, one replicated row
  std::vector<std::string> messages;
};

LiveScene::LiveScene(LiveSceneOptions options) : options_(std::move(options)), impl_(std::make_unique<Impl>()) {
  options_.Check();
  Impl& im = *impl_;
  im.rig = capture::LoadRig(options_.rig);
  if (!(im.rig.height_m > 0))
    throw Error(options_.rig, "gives no rig_height_m: live mode stands the car on the road that far below the rig");
  capture::StitchOptions so;
  so.width = options_.stitch_width;
  so.height = options_.stitch_height;
  so.device = options_.stitch_device;
  im.stitcher = std::make_unique<capture::Stitcher>(im.rig, so);

  im.builder = std::make_unique<lighting::LightingBuilder>(options_.Lighting());

  if (!options_.car.empty()) {
    if (!std::filesystem::exists(options_.car))
      throw Error(options_.car, "car model not found (a glTF 2.0 .glb or .gltf is needed for --car)");
    im.model = scene::LoadGltfScene(options_.car);  // refuses a model that draws no triangle
    im.renderer = std::make_unique<render::TripleProductRenderer>(im.model, glm::dmat4(1.0), options_.Render());
    im.car_centre = BoundsCentre(*im.renderer);
  }
  car_ = std::make_unique<CarController>(GroundPlane{{0, 1, 0}, 0});
  car_->Reset({options_.car_ahead_m, 0, 0}, {1, 0, 0});
  // The cameras start last: a live source runs from here on, and what it delivers while the car
  // is still being loaded would only be passed over.
  im.source = options_.source.empty() ? OpenRigSource(im.rig, options_.rig) : capture::OpenSource(options_.source);
  if (im.source->camera_count() != im.rig.camera_count())
    throw Error(options_.source.empty() ? options_.rig : options_.source,
                "delivers " + std::to_string(im.source->camera_count()) + " cameras but the rig " + options_.rig +
                    " describes " + std::to_string(im.rig.camera_count()));
}

LiveScene::~LiveScene() = default;

const capture::Rig& LiveScene::rig() const { return impl_->rig; }

const gl::Texture& LiveScene::composite() const {
  if (!impl_->renderer) throw Error("live scene", "no car, so no composite on the GPU");
  return impl_->renderer->composite_texture();
}
capture::SourceStats LiveScene::source_stats() const { return impl_->source->stats(); }
std::string LiveScene::source_description() const { return impl_->source->description(); }

void LiveScene::Drive(const CarInput& input, double dt_s) {
  while (dt_s > 0) {  // the controller clamps long steps: take them in 20 ms pieces
    const double dt = std::min(dt_s, 0.02);
    car_->Step(input, dt);
    dt_s -= dt;
  }
}

std::vector<std::string> LiveScene::TakeMessages() {
  Impl& im = *impl_;
  for (const auto& e : im.source->TakeEvents()) {
    const bool named = e.camera >= 0 && e.camera < im.rig.camera_count();
    const std::string cam = named ? im.rig.cameras[static_cast<std::size_t>(e.camera)].name : "a camera";
    if (e.kind == capture::SourceEvent::Kind::kCameraLost) {
      if (named) lost_.push_back(cam);
      const int left = im.rig.camera_count() - static_cast<int>(lost_.size());
      im.messages.push_back("camera " + cam + " lost: " + e.message +
                            (left > 0 ? "; playing on with the other " + std::to_string(left)
                                      : "; no camera left: showing the last picture"));
    } else if (e.kind == capture::SourceEvent::Kind::kCorruptFrame) {
      im.messages.push_back("camera " + cam + ": " + e.message);
    }
  }
  return std::exchange(im.messages, {});
}

LiveFrame LiveScene::Render(int width, int height, const AugmentedView& view) {
  if (width < 1 || height < 1) throw Error("live view", "size must be at least 1x1");
  Impl& im = *impl_;
  LiveFrame out;
  const auto t_total = Clock::now();

  // Capture: wait for a set, then take the newest one queued (a live view shows the present,
  // not a backlog).
  auto t0 = Clock::now();
  std::optional<capture::FrameSet> set =
      im.source->Next(im.have_panorama ? options_.set_timeout : options_.first_set_timeout);
  if (set) {
    while (auto newer = im.source->Next(std::chrono::milliseconds(0))) {
      set = std::move(newer);
      ++out.sets_skipped;
    }
  }
  out.ms.capture_wait = MsSince(t0);
  if (!set && !im.have_panorama)
    throw Error(options_.source.empty() ? options_.rig : options_.source,
                "delivered no frame set within " + std::to_string(options_.first_set_timeout.count()) + " ms");

  if (set) {
    // Stitch: cameras without a frame are left out and what only they saw is filled.
    t0 = Clock::now();
    std::vector<cv::Mat> images;
    im.source_frame = -1;
    im.cameras_present = 0;
    for (const auto& f : set->frames) {
      images.push_back(f.image);
      if (f.image.empty()) continue;
      ++im.cameras_present;
      if (im.source_frame < 0) im.source_frame = f.index;
    }
    im.stitcher->Stitch(images, &im.stitched);
    im.set_index = set->index;
    const sphere::EquirectImage& pano = im.stitched.image;
    const cv::Mat lin(pano.height, pano.width, CV_32FC3, im.stitched.image.rgb.data());
    if (im.renderer) {
      // The renderer's composite samples it through the camera on the GPU, once uploaded.
      im.renderer->SetBackgroundEquirect(pano);
    } else {
      cv::Mat wrapped;
      cv::copyMakeBorder(lin, wrapped, 0, 0, 1, 1, cv::BORDER_WRAP);
      cv::copyMakeBorder(wrapped, im.padded, 1, 1, 0, 0, cv::BORDER_REPLICATE);
    }
    out.ms.stitch = MsSince(t0);

    // Lighting: the new panorama's SG model, in the world's frame (the rig's, unturned).
    if (im.renderer) {
      t0 = Clock::now();
      cv::Mat small = lin;
      if (lin.cols > options_.lighting_width)
        cv::resize(lin, small, cv::Size(options_.lighting_width, options_.lighting_width / 2), 0, 0, cv::INTER_AREA);
      sphere::EquirectImage e(small.cols, small.rows);
      std::memcpy(e.rgb.data(), small.ptr<float>(), e.rgb.size() * sizeof(float));
      im.light = im.builder->Build(e);
      out.ms.lighting = MsSince(t0);
    }
    im.have_panorama = true;
  }
  // Set every frame: the car may have turned since the light was built.
  if (im.renderer) {
    t0 = Clock::now();
    im.renderer->SetLighting(im.light, glm::transpose(glm::dmat3(car_->WorldFromCar())));
    out.ms.lighting += MsSince(t0);
  }
  out.new_set = set.has_value();
  out.set_index = im.set_index;
  out.source_frame = im.source_frame;
  out.cameras_present = im.cameras_present;

  // The viewer at the rig's centre, looking forward turned by the user.
  t0 = Clock::now();
  const CarState& car = car_->state();
  out.car_position = car.position;
  const glm::dmat4 world_from_car = car_->WorldFromCar();
  const glm::dmat3 car_from_world = glm::transpose(glm::dmat3(world_from_car));
  const double pi = kPi;
  const double az = view.yaw_deg * pi / 180;  // positive: right, toward +Z
  const double el = std::clamp(view.pitch_deg * pi / 180, -1.55, 1.55);
  const glm::dvec3 look(std::cos(el) * std::cos(az), std::sin(el), std::cos(el) * std::sin(az));
  const glm::dvec3 eye(0, im.rig.height_m, 0);
  const glm::dvec3 eye_car = glm::dvec3(glm::inverse(world_from_car) * glm::dvec4(eye, 1));
  const double vfov = view.vfov_deg > 0 ? view.vfov_deg : options_.vfov_deg;
  const render::PinholeCamera camera =
      render::PinholeCamera::LookAt(eye_car, eye_car + car_from_world * look, vfov, width, height);
  {
    const glm::dvec3 c = glm::transpose(camera.world_from_camera) * (im.car_centre - camera.position);
    out.car_in_front = c.z > 1e-3;
    if (out.car_in_front)
      out.car_pixel = {0.5 * width + camera.focal_px() * c.x / c.z, 0.5 * height + camera.focal_px() * c.y / c.z};
  }
  const glm::dmat3 pano_from_car(world_from_car);
  double composite_ms = 0;
  if (im.renderer) {
    // The panorama through the camera, the car (unless hidden) and its shadow over it: all in the
    // renderer's composite on the GPU, as the augmented player does.
    im.renderer->SetBackgroundRotation(glm::transpose(pano_from_car));
    composite_ms = MsSince(t0);
    t0 = Clock::now();
    render::RenderResult r = im.renderer->Render(camera, render::ShadeDevice::kGpu, view.draw_car);
    out.ms.readback = r.ms.readback;
    out.ms.render = std::max(0.0, MsSince(t0) - r.ms.composite - r.ms.readback);
    composite_ms += r.ms.composite;
    out.image = std::move(r.composite);
    out.car_pixels = view.draw_car ? r.counts.car_pixels : 0;
  } else {
    sphere::EquirectImage background(width, height);
    const int pw = im.padded.cols - 2, ph = im.padded.rows - 2;
    cv::Mat map_x(height, width, CV_32F), map_y(height, width, CV_32F);
    cv::parallel_for_(cv::Range(0, height), [&](const cv::Range& rows) {
      for (int y = rows.start; y < rows.end; ++y)
        for (int x = 0; x < width; ++x) {
          const glm::dvec2 px = sphere::EquirectPixel(pano_from_car * camera.Ray(x + 0.5, y + 0.5), pw, ph);
          map_x.at<float>(y, x) = static_cast<float>(px.x + 0.5);  // +1 border − 0.5 centre
          map_y.at<float>(y, x) = static_cast<float>(px.y + 0.5);
        }
    });
    cv::Mat bg(height, width, CV_32FC3, background.rgb.data());
    cv::remap(im.padded, bg, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    composite_ms = MsSince(t0);
    out.image = std::move(background);
  }
  t0 = Clock::now();
  if (options_.exposure != 1.0)
    for (float& v : out.image.rgb) v *= static_cast<float>(options_.exposure);
  out.ms.composite = composite_ms + MsSince(t0);
  out.ms.total = MsSince(t_total);
  return out;
}

}  // namespace odvr::app
