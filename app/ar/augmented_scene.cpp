#include "app/ar/augmented_scene.h"

#include <spdlog/spdlog.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "app/ar/cube_face_composite.h"
#include "app/ar/frame_decoder.h"
#include "capture/source.h"
#include "core/constants.h"
#include "core/error.h"
#include "core/srgb.h"
#include "core/timing.h"
#include "engine/image/image_io.h"
#include "engine/lighting/lighting_builder.h"
#include "engine/scene/gltf_scene.h"
#include "engine/sphere/equirect.h"
#include "tracking/evaluation.h"

namespace odvr::app {
namespace {

using Clock = std::chrono::steady_clock;

double ParseDuration(const std::string& text, const std::string& step) {
  std::string number = text;
  double scale = 1;
  if (number.size() > 2 && number.substr(number.size() - 2) == "ms") {
    number.resize(number.size() - 2);
    scale = 1e-3;
  } else if (!number.empty() && number.back() == 's') {
    number.pop_back();
  }
  try {
    std::size_t used = 0;
    const double v = std::stod(number, &used) * scale;
    if (used != number.size() || !std::isfinite(v) || v < 0) throw std::invalid_argument(text);
    return v;
  } catch (const std::exception&) {
    throw UsageError("--drive", "'" + step + "': the duration must be like 2s, 500ms or 1.5");
  }
}

}  // namespace

std::vector<DriveStep> ParseDriveScript(const std::string& text) {
  std::vector<DriveStep> script;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t end = std::min(text.find(',', start), text.size());
    const std::string step = text.substr(start, end - start);
    start = end + 1;
    if (step.empty()) {
      if (end >= text.size()) break;
      throw UsageError("--drive", "empty step in '" + text + "'");
    }
    const auto colon = step.find(':');
    if (colon == std::string::npos) throw UsageError("--drive", "'" + step + "': want KEYS:DURATION, e.g. W:2s");
    DriveStep s;
    for (const char c : step.substr(0, colon)) {
      switch (std::toupper(static_cast<unsigned char>(c))) {
        case 'W':
          s.input.forward = true;
          break;
        case 'S':
          s.input.backward = true;
          break;
        case 'A':
          s.input.left = true;
          break;
        case 'D':
          s.input.right = true;
          break;
        case '-':
          break;
        default:
          throw UsageError("--drive", "'" + step + "': keys are W, A, S, D or - (none)");
      }
    }
    s.seconds = ParseDuration(step.substr(colon + 1), step);
    script.push_back(s);
    if (end >= text.size()) break;
  }
  return script;
}

CarInput DriveInputAt(const std::vector<DriveStep>& script, double t_s) {
  double t = 0;
  for (const auto& s : script) {
    if (t_s < t + s.seconds) return s.input;
    t += s.seconds;
  }
  return {};
}

glm::dvec3 BoundsCentre(const render::TripleProductRenderer& renderer) {
  glm::dvec3 lo(1e300), hi(-1e300);
  for (const auto& v : renderer.world_triangles()) {
    lo = glm::min(lo, glm::dvec3(v));
    hi = glm::max(hi, glm::dvec3(v));
  }
  return 0.5 * (lo + hi);
}

double DriveDuration(const std::vector<DriveStep>& script) {
  double t = 0;
  for (const auto& s : script) t += s.seconds;
  return t;
}

void AugmentedOptions::Check() const {
  if (video.empty()) throw UsageError("--video", "is required");
  if (trajectory.empty()) throw UsageError("--trajectory", "is required in augmented mode");
  if (car.empty()) throw UsageError("--car", "is required in augmented mode");
  if (!(light_smoothing_s >= 0)) throw UsageError("light smoothing", "must be non-negative");
  CarRendering::Check();
  if (!(vfov_deg >= 10 && vfov_deg <= 150)) throw UsageError("--fov", "must be 10..150 degrees");
  if (!(exposure > 0)) throw UsageError("--exposure", "must be positive");
  if (frame_cache < 2) throw UsageError("frame cache", "must hold at least 2 frames");
  picker.Check();
}

struct AugmentedScene::Impl {
  std::unique_ptr<FrameDecoder> decoder;
  long announced_frames = 0;
  std::vector<glm::dmat3> world_from_pano;  // per kept frame: C R Cᵀ
  std::vector<glm::dvec3> positions;        // rig centres, Y-up world
  double rig_height = 0;                    // mean height of the rig above the road

  struct Cached {
    cv::Mat rgb8;  // RGB, top row first
    long used = 0;
  };
  std::map<int, Cached> panos;
  long use_clock = 0;
  std::map<int, lighting::SgLighting> lights;
  std::map<int, lighting::LightingReport> light_reports;
  std::unique_ptr<lighting::LightingBuilder> builder;

  scene::GltfScene model;
  std::unique_ptr<render::TripleProductRenderer> renderer;
  glm::dvec3 car_centre{0};  // bounding-box middle in the car frame
  LightWeightSmoother smoother;

  double car_radius = 0;  // half the bounding box's diagonal
  int gpu_frame = -1;     // which view frame the renderer's background holds (the last shown)
  int linear_frame = -1;  // which view frame `linear` holds
  sphere::EquirectImage linear;
  // Cruise: the video's clock (seconds from the trajectory's first frame), the car's lead over
  // the camera along the path, the speed of the last step; driving: held at the street's end.
  double cruise_t = 0, cruise_lead_m = 0, cruise_speed_mps = 0;
  int cruise_view_k = 0;  // the trajectory frame nearest the video's clock
  bool cruising = false, at_stretch_end = false;

  // Linear float RGB of an 8-bit sRGB image.
  static cv::Mat Linear(const cv::Mat& rgb8) {
    static const cv::Mat lut = [] {
      const std::array<float, 256>& table = Srgb8ToLinearTable();
      return cv::Mat(1, 256, CV_32F, const_cast<float*>(table.data())).clone();
    }();
    cv::Mat f;
    rgb8.convertTo(f, CV_32F);
    f.forEach<cv::Vec3f>([](cv::Vec3f& p, const int*) {
      for (int c = 0; c < 3; ++c) p[c] = lut.at<float>(static_cast<int>(p[c]));
    });
    return f;
  }
};

namespace {

// A camera path shorter than this has no road to put the car on: it stands kStandingAheadM (at
// least) ahead of the camera instead (AugmentedScene::PlaceCar).
constexpr double kStandingPathM = 0.5, kStandingAheadM = 4.0;

// A pose far off the others (a corrupt file, a failed reconstruction) would send the car and the
// view there: one whose step from the previous frame is both over 10 m and over 50 times the
// median step is refused, naming the frame, as is any position beyond 1000 km. With fewer than
// three steps there is no median to compare with: a step faster than kFastestMps (540 km/h, past
// any road vehicle and a high-speed train) is refused instead.
void CheckPlausiblePath(const std::string& trajectory, const std::vector<int>& frames,
                        const std::vector<glm::dvec3>& positions, double fps) {
  constexpr double kFarM = 1e6, kJumpM = 10, kJumpOverMedian = 50, kFastestMps = 150;
  for (std::size_t i = 0; i < positions.size(); ++i)
    if (!(glm::length(positions[i]) < kFarM))
      throw Error(trajectory, "frame " + std::to_string(frames[i]) + ": the camera is " +
                                  std::to_string(glm::length(positions[i])) + " m from the origin, not a place");
  std::vector<double> steps;
  for (std::size_t i = 1; i < positions.size(); ++i) steps.push_back(glm::distance(positions[i - 1], positions[i]));
  if (steps.size() < 3) {
    for (std::size_t i = 0; i < steps.size(); ++i) {
      const double seconds = (frames[i + 1] - frames[i]) / (fps > 0 ? fps : 25.0);
      if (steps[i] > kFastestMps * seconds)
        throw Error(trajectory, "frame " + std::to_string(frames[i + 1]) + ": the camera moves " +
                                    std::to_string(steps[i]) + " m in " + std::to_string(seconds) +
                                    " s from the frame before, faster than any vehicle (" +
                                    std::to_string(static_cast<int>(kFastestMps)) + " m/s): an outlier pose");
    }
    return;
  }
  std::vector<double> sorted = steps;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2), sorted.end());
  const double median = sorted[sorted.size() / 2];
  for (std::size_t i = 0; i < steps.size(); ++i)
    if (steps[i] > kJumpM && steps[i] > kJumpOverMedian * median)
      throw Error(trajectory, "frame " + std::to_string(frames[i + 1]) + ": the camera jumps " +
                                  std::to_string(steps[i]) + " m from the frame before (the median step is " +
                                  std::to_string(median) + " m): an outlier pose");
}

// A camera that stands still has no road for the car: said once, naming the trajectory, so that a
// car placed ahead of the camera instead of on a path is not a surprise.
void WarnOfAStandingCamera(const std::string& trajectory, std::size_t poses, double path_m, double ahead_m) {
  const std::string why = poses < 2
                              ? "one pose shared with the video"
                              : fmt::format("the camera moves {:.2f} m in all (under {} m)", path_m, kStandingPathM);
  spdlog::warn("{}: {}: no road to drive on, so the car stands {:.1f} m ahead of the camera, along its forward",
               trajectory, why, std::max(ahead_m, kStandingAheadM));
}

}  // namespace

AugmentedScene::AugmentedScene(AugmentedOptions options)
    : options_(std::move(options)), impl_(std::make_unique<Impl>()) {
  options_.Check();
  Impl& im = *impl_;
  im.smoother = LightWeightSmoother(options_.light_smoothing_s);
  if (!std::filesystem::exists(options_.car))
    throw Error(options_.car, "car model not found (a glTF 2.0 .glb or .gltf is needed for --car)");
  im.model = scene::LoadGltfScene(options_.car);  // refuses a model that draws no triangle
  im.decoder = std::make_unique<FrameDecoder>(OpenPlayableVideo(options_.video, options_.stereo), 8);
  const auto poses = tracking::LoadTrajectory(options_.trajectory, im.decoder->fps());
  im.announced_frames = im.decoder->frame_count();

  // Frames with both a pose and a picture; the rest of either is ignored.
  std::map<long, const tracking::TrajectoryPose*> by_index;
  for (const auto& p : poses) by_index[p.index] = &p;
  for (const auto& [index, p] : by_index) {
    if (index < 0 || index >= im.announced_frames) continue;
    glm::dmat3 r;
    glm::dvec3 t;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) r[j][i] = p->world_from_rig(i, j);
      t[i] = p->world_from_rig(i, 3);
    }
    frame_index_.push_back(static_cast<int>(index));
    const glm::dmat3 yup_from_zup = sphere::YupFromZup();
    im.world_from_pano.push_back(yup_from_zup * r * glm::transpose(yup_from_zup));
    im.positions.push_back(yup_from_zup * t);
  }
  if (frame_index_.empty())
    throw Error(options_.trajectory, "shares no frame index with " + options_.video + " (" +
                                         std::to_string(im.announced_frames) + " frames)");
  CheckPlausiblePath(options_.trajectory, frame_index_, im.positions, im.decoder->fps());
  for (const auto& p : im.positions) im.rig_height += p.y / static_cast<double>(im.positions.size());
  picker_ = std::make_unique<FramePicker>(im.positions, options_.picker);
  const double car_start_m = options_.car_start_m >= 0 ? options_.car_start_m : options_.picker.view_distance_m;
  if (im.positions.size() < 2 || picker_->path_length() < kStandingPathM)
    WarnOfAStandingCamera(options_.trajectory, im.positions.size(), picker_->path_length(), car_start_m);

  im.builder = std::make_unique<lighting::LightingBuilder>(options_.Lighting());
  render::RenderOptions render_options = options_.Render();
  // RenderEquirect composites the car's layers into the recorded panorama itself.
  if (options_.equirect_output) render_options.read_layers = render_options.read_composite = true;
  im.renderer = std::make_unique<render::TripleProductRenderer>(im.model, glm::dmat4(1.0), render_options);
  im.car_centre = BoundsCentre(*im.renderer);
  for (const auto& v : im.renderer->world_triangles())
    im.car_radius = std::max(im.car_radius, glm::distance(glm::dvec3(v), im.car_centre));

  car_ = std::make_unique<CarController>(GroundPlane{{0, 1, 0}, 0});
  PlaceCar(car_start_m, options_.lateral_m);
}

AugmentedScene::~AugmentedScene() = default;

const gl::Texture& AugmentedScene::composite() const { return impl_->renderer->composite_texture(); }

double AugmentedScene::fps() const { return impl_->decoder->fps(); }
long AugmentedScene::video_frames() const { return impl_->decoder->available_frames(); }

namespace {
// How far the driven car may go past the first or last camera, or to the side of the path,
// before it is held: a car's length beyond the ends, a wide street's half width to the side.
constexpr double kStretchEndMarginM = 5.0, kStretchSideMarginM = 15.0;

// The point at arc length s_m (clamped) of the polyline `p`, and the direction of its segment.
glm::dvec3 PathPoint(const std::vector<glm::dvec3>& p, double s_m, glm::dvec3* dir) {
  glm::dvec3 pos = p[0];
  *dir = {1, 0, 0};
  double s = 0;
  for (std::size_t i = 0; i + 1 < p.size(); ++i) {
    const double len = glm::distance(p[i], p[i + 1]);
    if (len <= 0) continue;
    *dir = (p[i + 1] - p[i]) / len;
    if (s + len >= s_m || i + 2 == p.size()) return p[i] + std::clamp(s_m - s, 0.0, len) * *dir;
    s += len;
  }
  return pos;
}

}  // namespace

void AugmentedScene::PlaceCar(double s_m, double lateral_m) {
  const auto& p = impl_->positions;
  glm::dvec3 pos = p[0], dir{1, 0, 0};
  if (p.size() == 1 || picker_->path_length() < kStandingPathM) {
    // A camera that stands still (a tripod, or one pose) has no road to put the car on: it stands
    // on the ground s_m ahead of the camera (at least kStandingAheadM), not over it.
    dir = impl_->world_from_pano[0] * glm::dvec3(1, 0, 0);  // the panorama's forward: the rig's x
    dir.y = 0;
    if (glm::length(dir) > 1e-9) pos = p[0] + std::max(s_m, kStandingAheadM) * glm::normalize(dir);
  } else {
    pos = PathPoint(p, std::clamp(s_m, 0.0, picker_->path_length()), &dir);
  }
  dir.y = 0;
  if (glm::length(dir) < 1e-9) dir = {1, 0, 0};
  dir = glm::normalize(dir);
  const glm::dvec3 left = glm::cross(glm::dvec3(0, 1, 0), dir);
  car_->Reset(pos + lateral_m * left, dir);
}

void AugmentedScene::SetLook(const CarLook& look) {
  if (look == look_) return;
  if (look.model != look_.model || look.colour != look_.colour || look.ks != look_.ks ||
      look.phong_n != look_.phong_n || look.roughness != look_.roughness || look.fresnel_f0 != look_.fresnel_f0)
    impl_->renderer->SetMaterials(MaterialOverrides(look));
  else
    look.Check();
  impl_->renderer->SetPeakCones(look.cones);
  look_ = look;
}

void AugmentedScene::TeleportCar(const glm::dvec3& world_position) {
  car_->Reset(world_position, car_->state().forward);
}

void AugmentedScene::Drive(const CarInput& input, double dt_s) {
  Impl& im = *impl_;
  im.cruising = false;
  // Steps of at most 20 ms: the controller clamps longer steps, which would slow a scripted drive.
  while (dt_s > 0) {
    const double dt = std::min(dt_s, 0.02);
    const CarState before = car_->state();
    car_->Step(input, dt);
    dt_s -= dt;
    // Beyond the recorded street there is no frame to show the car in (it shrank to a few pixels
    // as the view stayed at the last frame): the car is held where it was, stopped.
    const auto& p = im.positions;
    if (p.size() < 2 || picker_->path_length() < kStandingPathM) continue;
    const glm::dvec3 at = car_->state().position;
    glm::dvec3 dir;
    const double s = picker_->ArcLengthOf(at);
    const glm::dvec3 nearest = PathPoint(p, s, &dir);
    const double off = glm::length(glm::dvec3(at.x - nearest.x, 0, at.z - nearest.z));
    const bool beyond_an_end = (s <= 0 || s >= picker_->path_length()) && off > kStretchEndMarginM;
    if (beyond_an_end || off > kStretchSideMarginM) {
      car_->Reset(before.position, before.forward);
      car_->Stop();
      im.at_stretch_end = true;
    } else {
      im.at_stretch_end = false;
    }
  }
}

void AugmentedScene::Cruise(double dt_s) {
  Impl& im = *impl_;
  const double fps = this->fps() > 0 ? this->fps() : 25.0;
  const int n = std::min(picker_->frame_count(), static_cast<int>(frame_index_.size()));
  if (!im.cruising) {  // (re)start from where the car stands: its lead over the camera's frame
    const double s_car = picker_->ArcLengthOf(car_->state().position);
    const int view = std::clamp(picker_->ViewFrame(car_->state().position), 0, n - 1);
    im.cruise_lead_m = std::max(0.0, s_car - picker_->ArcLengthAt(view));
    im.cruise_t = (frame_index_[static_cast<std::size_t>(view)] - frame_index_.front()) / fps;
    im.cruising = true;
  }
  const double duration = (frame_index_[static_cast<std::size_t>(n - 1)] - frame_index_.front() + 1) / fps;
  im.cruise_t = std::fmod(im.cruise_t + dt_s, duration);
  // The camera's arc length at video frame v, linear between the trajectory's frames.
  const double v = frame_index_.front() + im.cruise_t * fps + 1e-6;  // frame k at k/fps, not just before
  int k = 0;
  while (k + 1 < n && frame_index_[static_cast<std::size_t>(k + 1)] <= v) ++k;
  double s_camera = picker_->ArcLengthAt(k);
  im.cruise_view_k = k;
  if (k + 1 < n) {
    const double a =
        std::clamp((v - frame_index_[static_cast<std::size_t>(k)]) /
                       (frame_index_[static_cast<std::size_t>(k + 1)] - frame_index_[static_cast<std::size_t>(k)]),
                   0.0, 1.0);
    s_camera += a * (picker_->ArcLengthAt(k + 1) - picker_->ArcLengthAt(k));
    if (a > 0.5) im.cruise_view_k = k + 1;
  }
  const double s_before = picker_->ArcLengthOf(car_->state().position);
  PlaceCar(s_camera + im.cruise_lead_m, options_.lateral_m);
  // Its lead takes the car to the street's end before the camera: it waits there for the loop.
  im.at_stretch_end = picker_->path_length() >= kStandingPathM && s_camera + im.cruise_lead_m > picker_->path_length();
  const double s_after = picker_->ArcLengthOf(car_->state().position);
  im.cruise_speed_mps = dt_s > 0 && s_after >= s_before ? (s_after - s_before) / dt_s : im.cruise_speed_mps;
}

double AugmentedScene::car_speed_mps() const {
  return impl_->cruising ? impl_->cruise_speed_mps : car_->state().speed_mps;
}

const lighting::SgLighting& AugmentedScene::FrameLighting(int frame) {
  Impl& im = *impl_;
  if (auto it = im.lights.find(frame); it != im.lights.end()) return it->second;
  auto pano = im.panos.find(frame);
  if (pano == im.panos.end()) {
    auto f = im.decoder->Get(frame, std::chrono::seconds(20));
    if (!f || f->index != frame || f->set.frames[0].image.empty())
      throw Error(options_.video, "frame " + std::to_string(frame) + " cannot be decoded");
    cv::Mat rgb;
    cv::cvtColor(f->set.frames[0].image, rgb, cv::COLOR_BGR2RGB);
    pano = im.panos.emplace(frame, Impl::Cached{rgb, ++im.use_clock}).first;
  }
  cv::Mat lin = Impl::Linear(pano->second.rgb8);
  if (lin.cols > options_.lighting_width) {
    cv::Mat small;
    cv::resize(lin, small, cv::Size(options_.lighting_width, options_.lighting_width / 2), 0, 0, cv::INTER_AREA);
    lin = small;
  }
  sphere::EquirectImage e(lin.cols, lin.rows);
  std::memcpy(e.rgb.data(), lin.ptr<float>(), e.rgb.size() * sizeof(float));
  lighting::LightingReport report;
  lighting::SgLighting light = im.builder->Build(e, &report);
  report.peak_detection.residue = {};  // a frame-sized image; only the peaks' count is shown
  im.light_reports[frame] = std::move(report);
  return im.lights.emplace(frame, std::move(light)).first->second;
}

// A file that turned out shorter than announced: the poses past its real end are dropped, so that
// the picker stops choosing frames that are not there (the car may still drive on).
void AugmentedScene::DropPosesPastTheEnd() {
  Impl& im = *impl_;
  const long available = im.decoder->available_frames();
  if (available >= im.announced_frames || frame_index_.back() < available) return;
  std::size_t keep = 0;
  while (keep < frame_index_.size() && frame_index_[keep] < available) ++keep;
  if (keep == 0) throw Error(options_.video, "ends before the first frame of the trajectory");
  frame_index_.resize(keep);
  im.positions.resize(keep);
  im.world_from_pano.resize(keep);
  picker_ = std::make_unique<FramePicker>(im.positions, options_.picker);
  im.smoother = LightWeightSmoother(options_.light_smoothing_s);
}

AugmentedScene::ViewSetup AugmentedScene::PrepareFrame(double dt_s, AugmentedFrame* result) {
  Impl& im = *impl_;
  AugmentedFrame& out = *result;
  DropPosesPastTheEnd();
  const CarState& car = car_->state();
  out.car_position = car.position;

  // Which frames: the viewer's and the car's light.
  const glm::dvec3 car_at_rig_height = car.position + glm::dvec3(0, im.rig_height, 0);
  // Cruising, the viewer sees the video's own frame (the car may already wait at the street's end).
  int view_k =
      im.cruising ? std::min(im.cruise_view_k, picker_->frame_count() - 1) : picker_->ViewFrame(car_at_rig_height);
  const int light_k = picker_->NearestFrame(car_at_rig_height);
  const auto target = picker_->LightWeights(car_at_rig_height);

  // Decode what is not cached, in frame order so that the decoder mostly reads ahead.
  auto t0 = Clock::now();
  std::vector<int> wanted{frame_index_[static_cast<std::size_t>(view_k)]};
  for (const auto& [k, w] : target) wanted.push_back(frame_index_[static_cast<std::size_t>(k)]);
  std::sort(wanted.begin(), wanted.end());
  std::map<int, bool> ok;
  for (const int frame : wanted) {
    auto it = im.panos.find(frame);
    if (it != im.panos.end()) {
      it->second.used = ++im.use_clock;
      ok[frame] = true;
      continue;
    }
    auto f = im.decoder->Get(frame, std::chrono::seconds(20));
    // A truncated file hands back its last good frame for anything past its end.
    ok[frame] = f && f->index == frame && !f->set.frames[0].image.empty();
    if (!ok[frame]) continue;
    cv::Mat rgb;
    cv::cvtColor(f->set.frames[0].image, rgb, cv::COLOR_BGR2RGB);
    im.panos[frame] = Impl::Cached{rgb, ++im.use_clock};
    while (im.panos.size() > options_.frame_cache) {
      auto oldest = std::min_element(im.panos.begin(), im.panos.end(),
                                     [](const auto& a, const auto& b) { return a.second.used < b.second.used; });
      im.panos.erase(oldest);
    }
  }
  out.ms.decode = MsSince(t0);

  // Lighting: each light frame's model (cached), peaks turned into the nearest frame's frame,
  // blended by the smoothed weights. The multiscale SGs are blended in their own frames: the
  // neighbours' rigs differ by a fraction of a degree.
  t0 = Clock::now();
  std::vector<std::pair<int, double>> usable;
  for (const auto& [k, w] : target)
    if (ok[frame_index_[static_cast<std::size_t>(k)]] || im.lights.count(frame_index_[static_cast<std::size_t>(k)]))
      usable.emplace_back(k, w);
  if (usable.empty()) {
    // Nothing decodable near the car: the nearest frame that has a model, else the first.
    int best = -1;
    double best_d = 1e300;
    for (std::size_t k = 0; k < frame_index_.size(); ++k)
      if (im.lights.count(frame_index_[k]) || im.panos.count(frame_index_[k])) {
        const double d = glm::distance(im.positions[k], car_at_rig_height);
        if (d < best_d) best_d = d, best = static_cast<int>(k);
      }
    if (best < 0) throw Error(options_.video, "no frame near the car can be decoded");
    usable.emplace_back(best, 1.0);
  }
  double sum = 0;
  for (const auto& [k, w] : usable) sum += w;
  for (auto& [k, w] : usable) w /= sum;
  const std::map<int, double> weights = im.smoother.Update(usable, dt_s);
  int ref_k = light_k;
  if (!weights.count(ref_k))
    ref_k =
        std::max_element(weights.begin(), weights.end(), [](auto& a, auto& b) { return a.second < b.second; })->first;
  const glm::dmat3 ref_from_world = glm::transpose(im.world_from_pano[static_cast<std::size_t>(ref_k)]);
  std::vector<lighting::SgLighting> turned;
  turned.reserve(weights.size());
  std::vector<std::pair<const lighting::SgLighting*, double>> blend;
  for (const auto& [k, w] : weights) {
    const int frame = frame_index_[static_cast<std::size_t>(k)];
    turned.push_back(FrameLighting(frame));
    const glm::dmat3 ref_from_k = ref_from_world * im.world_from_pano[static_cast<std::size_t>(k)];
    for (auto& p : turned.back().peaks) p.axis = glm::normalize(ref_from_k * p.axis);
    out.light_weights[frame] = w;
  }
  for (std::size_t i = 0; i < turned.size(); ++i)
    blend.emplace_back(&turned[i], std::next(weights.begin(), static_cast<std::ptrdiff_t>(i))->second);
  const lighting::SgLighting light = ApplyLightToggles(lighting::SgLighting::Blend(blend), look_);
  const glm::dmat4 world_from_car = car_->WorldFromCar();
  const glm::dmat3 car_from_world = glm::transpose(glm::dmat3(world_from_car));
  im.renderer->SetLighting(light, car_from_world * im.world_from_pano[static_cast<std::size_t>(ref_k)]);
  out.ms.lighting = MsSince(t0);
  out.light_frame = frame_index_[static_cast<std::size_t>(light_k)];
  if (auto r = im.light_reports.find(out.light_frame); r != im.light_reports.end()) {
    out.light_levels = r->second.transform.levels;
    out.light_peaks = static_cast<int>(r->second.peak_detection.peaks.size());
  }

  // The view frame: the one chosen, else (undecodable) the last picture shown and its pose, else
  // any decoded one.
  int view_frame = frame_index_[static_cast<std::size_t>(view_k)];
  if (!ok[view_frame] && im.gpu_frame >= 0) {
    view_frame = im.gpu_frame;
    view_k = static_cast<int>(std::find(frame_index_.begin(), frame_index_.end(), view_frame) - frame_index_.begin());
  }
  if (!ok[view_frame] && im.gpu_frame < 0) {
    for (const auto& [f, good] : ok)
      if (good) view_frame = f;
    view_k = static_cast<int>(std::find(frame_index_.begin(), frame_index_.end(), view_frame) - frame_index_.begin());
  }
  if (view_k >= static_cast<int>(frame_index_.size())) throw Error(options_.video, "no frame to show can be decoded");
  out.view_frame = view_frame;
  out.at_stretch_end = im.at_stretch_end;
  return {view_k, im.positions[static_cast<std::size_t>(view_k)], world_from_car};
}

// The view frame's panorama as linear RGB, converted once per view frame.
const sphere::EquirectImage& AugmentedScene::LinearPanorama(int frame) {
  Impl& im = *impl_;
  if (im.linear_frame != frame && im.panos.count(frame)) {
    const cv::Mat lin = Impl::Linear(im.panos[frame].rgb8);
    im.linear = sphere::EquirectImage(lin.cols, lin.rows);
    std::memcpy(im.linear.rgb.data(), lin.ptr<float>(), im.linear.rgb.size() * sizeof(float));
    im.linear_frame = frame;
  }
  return im.linear;
}

AugmentedFrame AugmentedScene::Render(int width, int height, const AugmentedView& view, double dt_s) {
  if (width < 1 || height < 1) throw Error("augmented view", "size must be at least 1x1");
  Impl& im = *impl_;
  AugmentedFrame out;
  const auto t_total = Clock::now();
  const ViewSetup setup = PrepareFrame(dt_s, &out);
  const glm::dmat4& world_from_car = setup.world_from_car;
  const glm::dmat3 car_from_world = glm::transpose(glm::dmat3(world_from_car));

  // The viewer: at the view frame's rig centre, looking at the car, turned by the user.
  auto t0 = Clock::now();
  const glm::dvec3 eye = setup.eye;
  const glm::dvec3 car_centre_world = glm::dvec3(world_from_car * glm::dvec4(im.car_centre, 1));
  glm::dvec3 d = car_centre_world - eye;
  if (glm::length(d) < 1e-6) d = car_->state().forward;
  d = glm::normalize(d);
  const double pi = kPi;
  const double az = std::atan2(d.z, d.x) + view.yaw_deg * pi / 180;  // +z is right of +x seen from above
  const double el = std::clamp(std::asin(std::clamp(d.y, -1.0, 1.0)) + view.pitch_deg * pi / 180, -1.55, 1.55);
  const glm::dvec3 look(std::cos(el) * std::cos(az), std::sin(el), std::cos(el) * std::sin(az));
  const glm::dvec3 eye_car = glm::dvec3(glm::inverse(world_from_car) * glm::dvec4(eye, 1));
  const glm::dvec3 look_car = car_from_world * look;
  const double vfov = view.vfov_deg > 0 ? view.vfov_deg : options_.vfov_deg;
  render::PinholeCamera camera = render::PinholeCamera::LookAt(eye_car, eye_car + look_car, vfov, width, height);
  last_camera_ = camera;
  {
    const glm::dvec3 c = glm::transpose(camera.world_from_camera) * (im.car_centre - camera.position);
    out.car_in_front = c.z > 1e-3;
    if (out.car_in_front)
      out.car_pixel = {0.5 * width + camera.focal_px() * c.x / c.z, 0.5 * height + camera.focal_px() * c.y / c.z};
  }

  // Background: the view frame's panorama through the camera, sampled by the renderer's
  // composite on the GPU (uploaded once per view frame, turned each frame), the car (unless
  // hidden) and its shadow over it.
  if (im.gpu_frame != out.view_frame && im.panos.count(out.view_frame)) {
    im.renderer->SetBackgroundEquirect(LinearPanorama(out.view_frame));
    im.gpu_frame = out.view_frame;
  }
  const glm::dmat3 pano_from_car =
      glm::transpose(im.world_from_pano[static_cast<std::size_t>(setup.view_k)]) * glm::dmat3(world_from_car);
  im.renderer->SetBackgroundRotation(glm::transpose(pano_from_car));
  out.pano_from_car = pano_from_car;
  double composite_ms = MsSince(t0);
  t0 = Clock::now();
  render::RenderResult r = im.renderer->Render(camera, render::ShadeDevice::kGpu, view.draw_car);
  const double wall = MsSince(t0);
  out.ms.readback = r.ms.readback;
  out.ms.render = std::max(0.0, wall - r.ms.composite - r.ms.readback);
  composite_ms += r.ms.composite;
  out.image = std::move(r.composite);
  out.car_pixels = r.counts.car_pixels;
  t0 = Clock::now();
  if (options_.exposure != 1.0)
    for (float& v : out.image.rgb) v *= static_cast<float>(options_.exposure);
  out.ms.composite = composite_ms + MsSince(t0);
  out.ms.total = MsSince(t_total);
  return out;
}

AugmentedFrame AugmentedScene::RenderEquirect(int width, double dt_s) {
  if (!options_.equirect_output) throw Error("augmented view", "a 360° frame needs AugmentedOptions::equirect_output");
  Impl& im = *impl_;
  AugmentedFrame out;
  const auto t_total = Clock::now();
  const ViewSetup setup = PrepareFrame(dt_s, &out);
  auto t0 = Clock::now();
  const sphere::EquirectImage& recorded = LinearPanorama(out.view_frame);
  if (recorded.empty()) throw Error(options_.video, "no frame to show can be decoded");
  // The video's own width, made even (4:2:0 video and a 2:1 frame need one).
  if (width <= 0) width = recorded.width - recorded.width % 2;
  if (width < 2 || width % 2)
    throw Error("augmented view", "a 360° frame's width must be even, got " + std::to_string(width));
  out.image = sphere::EquirectImage(width, width / 2);
  if (width == recorded.width) {
    out.image.rgb = recorded.rgb;
  } else {
    const cv::Mat from(recorded.height, recorded.width, CV_32FC3, const_cast<float*>(recorded.rgb.data()));
    cv::Mat to(out.image.height, out.image.width, CV_32FC3, out.image.rgb.data());
    cv::resize(from, to, to.size(), 0, 0, width < recorded.width ? cv::INTER_AREA : cv::INTER_LINEAR);
  }
  double composite_ms = MsSince(t0);

  // The car's frame seen from the view frame's rig centre, and the panorama's frame in it.
  const glm::dmat3 pano_from_car =
      glm::transpose(im.world_from_pano[static_cast<std::size_t>(setup.view_k)]) * glm::dmat3(setup.world_from_car);
  const glm::dmat3 car_from_pano = glm::transpose(pano_from_car);
  out.pano_from_car = pano_from_car;
  const glm::dvec3 eye_car = glm::dvec3(glm::inverse(setup.world_from_car) * glm::dvec4(setup.eye, 1));
  // A face of a quarter of the panorama's width has its pixels' size at the face's centre.
  const int side = std::max(16, width / 4) + 2 * kCubeFaceMargin;
  CubeFaces faces;
  std::vector<int> queue = CubeFacesMeetingSphere(pano_from_car * (im.car_centre - eye_car), im.car_radius);
  std::vector<bool> queued(6, false);
  for (const int f : queue) queued[static_cast<std::size_t>(f)] = true;
  while (!queue.empty()) {
    const int face = queue.back();
    queue.pop_back();
    const render::PinholeCamera camera = CubeFaceCamera(face, side, eye_car, car_from_pano);
    t0 = Clock::now();
    const render::RenderResult r = im.renderer->Render(camera, render::ShadeDevice::kGpu, true);
    out.ms.render += std::max(0.0, MsSince(t0) - r.ms.composite - r.ms.readback);
    out.ms.readback += r.ms.readback;
    faces[static_cast<std::size_t>(face)] = TakeCubeFaceLayers(camera, r);
    for (const int next : CubeFacesBeyondBorder(face, *faces[static_cast<std::size_t>(face)], pano_from_car))
      if (!queued[static_cast<std::size_t>(next)]) queued[static_cast<std::size_t>(next)] = true, queue.push_back(next);
  }
  for (const auto& f : faces) out.cube_faces_rendered += f.has_value();
  t0 = Clock::now();
  out.car_pixels = CompositeCubeFaces(faces, car_from_pano, &out.image);
  const glm::dvec2 centre = sphere::EquirectPixel(pano_from_car * (im.car_centre - eye_car), width, width / 2);
  out.car_pixel = centre;
  out.car_in_front = true;  // a panorama shows every direction
  if (options_.exposure != 1.0)
    for (float& v : out.image.rgb) v *= static_cast<float>(options_.exposure);
  out.ms.composite = composite_ms + MsSince(t0);
  out.ms.total = MsSince(t_total);
  return out;
}

}  // namespace odvr::app
