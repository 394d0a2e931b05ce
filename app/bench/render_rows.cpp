#include "app/bench/render_rows.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <vector>

#include "app/flags/command_flags.h"
#include "core/constants.h"
#include "core/error.h"
#include "core/statistics.h"
#include "core/timing.h"
#include "engine/image/image_io.h"
#include "engine/image/ssim.h"
#include "engine/lighting/lighting_builder.h"
#include "engine/scene/gltf_scene.h"

namespace odvr::app::render_rows {

double Luma(const float* c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

glm::dvec3 Vec3(const nlohmann::json& j) {
  return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()};
}

nlohmann::json ReadJsonFile(const std::filesystem::path& path) {
  std::ifstream f(path);
  if (!f) throw Error(path.string(), "cannot be read");
  try {
    return nlohmann::json::parse(f);
  } catch (const std::exception& e) {
    throw Error(path.string(), std::string("is not JSON: ") + e.what());
  }
}

glm::dmat4 Matrix4(const nlohmann::json& rows) {
  glm::dmat4 m(1.0);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m[c][r] = rows.at(static_cast<std::size_t>(r)).at(static_cast<std::size_t>(c));
  return m;
}

render::PinholeCamera CameraFromJson(const nlohmann::json& cam) {
  const auto& in = cam.at("intrinsics_opencv");
  return render::PinholeCamera::LookAt(Vec3(cam.at("position")), Vec3(cam.at("target")),
                                       cam.at("vfov_deg").get<double>(), in.at("width").get<int>(),
                                       in.at("height").get<int>(), Vec3(cam.at("up")));
}

// Cycles' scene has the catcher under the car: seen from the car, below the horizon is that
// plane, diffuse albedo 0.18 (references.json), lit by the map's upper half. Both renderers here
// light from the map's lower half, so the map's lower half becomes that plane's radiance,
// 0.18 E / π, E the horizontal irradiance from the upper half; the car's own shadow on the plane,
// which Cycles does see, the renderers add (RenderOptions::ground_shadows_bounce). The plane
// ends (60 m): within `keep_below_horizon` radians under the horizon the car's rays pass beyond
// it and Cycles sees the map itself, which stays.
void ReplaceLowerHemisphereByGround(sphere::EquirectImage* env, double albedo, double keep_below_horizon) {
  const int w = env->width, h = env->height;
  glm::dvec3 e(0);
  for (int y = 0; y < h; ++y) {
    const double lat = kPi * (0.5 - (y + 0.5) / h);
    if (lat <= 0) continue;
    const double d_omega = (2 * kPi / w) * (kPi / h) * std::cos(lat);
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) e[c] += env->at(x, y)[c] * std::sin(lat) * d_omega;
  }
  const glm::dvec3 radiance = albedo * e / kPi;
  for (int y = h / 2; y < h; ++y) {
    const double below = kPi * ((y + 0.5) / h - 0.5);
    if (below < keep_below_horizon) continue;
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) env->at(x, y)[c] = static_cast<float>(radiance[c]);
  }
}

// How far under the horizon the car's rays pass beyond Cycles' catcher: from the model's
// mid-height, at the mean distance from the centre of a square of half-size s to its edge,
// s (4/π) ln(1 + √2). A bright wall just under the horizon (studio.exr: mean radiance 2.9 within
// 5° under it, the stand-in 0.80) lit the car's sides in Cycles; replaced, studio_diffuse read 3.8 %
// dark (docs/notes/render_accuracy.md).
double KeepBelowHorizon(double mid_height) {
  const double mean_distance = render::RenderOptions{}.ground_half_size * (4 / kPi) * std::log(1 + std::sqrt(2.0));
  return std::atan2(std::max(mid_height, 0.0), mean_distance);
}

namespace {

// Relative-error sums over the car pixels of rows [y0, y1); `floor` keeps a dark pixel's
// relative error finite (a share of the whole car's mean).
struct CarSums {
  double rel = 0, abs = 0, ref = 0, ours = 0;
  int count = 0;
};
CarSums SumOverRows(const std::vector<float>& car, const std::vector<float>& ya, const std::vector<float>& yb, int w,
                    int y0, int y1, double floor) {
  CarSums s;
  for (int y = y0; y < y1; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      if (!(car[i] > 0)) continue;
      s.rel += std::abs(ya[i] - yb[i]) / std::max<double>(yb[i], floor);
      s.abs += std::abs(ya[i] - yb[i]);
      s.ref += yb[i];
      s.ours += ya[i];
      ++s.count;
    }
  return s;
}

}  // namespace

void Score(const Reference& ref, const render::RenderResult& r, Row* row) {
  const int w = ref.rgb.width, h = ref.rgb.height;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  std::vector<float> car(n, 0.f), ya(n), yb(n);
  double mean_ref = 0;
  int count = 0, top = h, bottom = -1;
  for (std::size_t i = 0; i < n; ++i) {
    car[i] = ref.mask[i] > 0.99f && r.car_alpha[i] > 0.5f ? 1.f : 0.f;
    ya[i] = static_cast<float>(Luma(&r.car.rgb[3 * i]) * r.car_alpha[i]);
    yb[i] = static_cast<float>(Luma(&ref.rgb.rgb[3 * i]));
    if (car[i] > 0) {
      mean_ref += yb[i];
      ++count;
      top = std::min(top, static_cast<int>(i / static_cast<std::size_t>(w)));
      bottom = std::max(bottom, static_cast<int>(i / static_cast<std::size_t>(w)));
    }
  }
  row->car_pixels = count;
  if (count == 0) return;
  mean_ref /= count;
  const double floor = 0.05 * mean_ref;
  const CarSums all = SumOverRows(car, ya, yb, w, 0, h, floor);
  row->mean_rel = all.rel / all.count;
  row->rel_l1 = all.abs / all.ref;
  row->bias = all.ours / all.ref;
  const int rows = bottom - top + 1;
  const CarSums upper = SumOverRows(car, ya, yb, w, top, top + (rows + 1) / 2, floor);
  const CarSums lower = SumOverRows(car, ya, yb, w, top + (3 * rows) / 4, bottom + 1, floor);
  if (upper.count > 0 && upper.ref > 0) {
    row->upper_mean_rel = upper.rel / upper.count;
    row->upper_bias = upper.ours / upper.ref;
  }
  if (lower.count > 0 && lower.ref > 0) {
    row->lower_mean_rel = lower.rel / lower.count;
    row->lower_bias = lower.ours / lower.ref;
  }
  std::vector<float> ref_car;
  for (std::size_t i = 0; i < n; ++i)
    if (car[i] > 0) ref_car.push_back(yb[i]);
  // SSIM on the luminance scaled so that Cycles' 99th percentile on the car is 1.
  std::nth_element(ref_car.begin(), ref_car.begin() + static_cast<long>(ref_car.size() * 99 / 100), ref_car.end());
  const double scale = 1.0 / std::max(1e-12, static_cast<double>(ref_car[ref_car.size() * 99 / 100]));
  for (std::size_t i = 0; i < n; ++i) {
    ya[i] = static_cast<float>(ya[i] * scale);
    yb[i] = static_cast<float>(yb[i] * scale);
  }
  row->ssim = image::MeanSsim(ya, yb, w, h, car, 1.0);
  if (ref.shadow.empty()) return;
  double shadow_abs = 0;
  int shadow = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double sr = Luma(&ref.shadow.rgb[3 * i]);
    if (!(sr < 0.95) || ref.mask[i] > 0.01f || r.car_alpha[i] > 0.f || r.ground_mask[i] < 0.5f) continue;
    shadow_abs += std::abs(Luma(&r.shadow.rgb[3 * i]) - sr);
    ++shadow;
  }
  row->shadow_pixels = shadow;
  row->shadow_mae = shadow > 0 ? shadow_abs / shadow : -1;
}

std::string LobeName(const material::LobeOptions& l) {
  return std::string(l.warp == material::WarpMode::kIsotropic ? "iso" : "split") + "-" +
         (l.cosine == material::CosineTerm::kAtLobeAxis ? "axis" : "sg");
}

std::string DefaultLobes() { return LobeName(render::RenderOptions{}.lobes); }

Row RenderRow(const render::RenderOptions& base, const Reference& ref, const std::string& method, int levels, int cones,
              int voxels, int samples, const material::LobeOptions& lobes, int width, int height, unsigned seed,
              const std::string& images_dir, int supersample, double contrast) {
  render::RenderOptions o = base;
  o.supersample = supersample;
  o.supersample_contrast = contrast;
  // The Monte-Carlo baseline and the supersampled rows shade every pixel; the half-rate rows
  // judge their blocks at the renderer's contrast (0 would shade every pixel).
  if (method != "sg" || supersample > 1) o.shading_rate = 1;
  if (o.shading_rate == 2) o.supersample_contrast = base.supersample_contrast;
  o.lighting_levels = levels;
  o.cone_rings = ConeRingsForCount(cones);
  o.voxel_resolution = voxels;
  o.materials = ref.materials;
  o.ground = base.ground && ref.ground;
  o.lobes = lobes;
  o.monte_carlo_samples = samples / (supersample * supersample);
  o.monte_carlo_seed = seed;
  o.monte_carlo_exact_visibility = method == "mc-exact";
  lighting::LightingOptions lo;
  lo.transform.levels = levels;
  lighting::LightingBuilder builder(lo);
  const lighting::SgLighting model = builder.Build(ref.env);
  render::TripleProductRenderer renderer(scene::LoadGltfScene(ref.model), ref.world_from_model, o);
  renderer.SetLighting(model, ref.world_from_env);
  renderer.SetEnvironment(ref.env);
  render::PinholeCamera camera = ref.camera;
  const bool scored = width == 0;
  if (!scored) {
    camera.width = width;
    camera.height = height;
  }
  {
    // A shader variant is compiled at its first dispatch (llvmpipe: seconds, ~8 s for 19 cones),
    // which a row that is the first of its variant would time: a small untimed render first.
    // llvmpipe keys its variants on whether each bound texture's sides are powers of two too, so
    // the small render keeps the timed size's kind: the former 32×18 compiled a variant the
    // 320×180 rows never used, and with Mesa's shader cache empty every first row of a variant
    // timed its compile (sky_diffuse, 7 cones: 3975 ms against 141 ms with the cache warm).
    const auto small_side_like = [](int n) { return n <= 33 ? n : (n & (n - 1)) == 0 ? 32 : 33; };
    render::PinholeCamera warm = camera;
    warm.width = small_side_like(camera.width);
    warm.height = small_side_like(camera.height);
    renderer.Render(warm);
    renderer.PrepareShading(camera);  // GPU: the timed size may shade with other lanes than the small one
  }
  render::RenderResult r = renderer.Render(camera);
  Row row;
  row.reference = ref.name;
  row.method = method;
  row.lobes = method != "sg" ? "exact" : LobeName(lobes);
  row.width = camera.width;
  row.height = camera.height;
  row.levels = method != "sg" ? 0 : levels;
  row.cones = method != "sg" ? 0 : cones;
  row.voxels = voxels;
  row.samples = samples;
  row.supersample = supersample;
  row.contrast = supersample > 1 ? contrast : 0;
  row.shade_ms = r.ms.shade;
  row.total_ms = r.ms.total;
  if (!scored) {
    // A frame rate: the window player's frame (nothing read back but the counts' sums, the
    // composite drawn where it was made), median of kFrameRepeats after the first render.
    constexpr int kFrameRepeats = 5;
    o.read_layers = false;
    o.read_composite = false;
    render::TripleProductRenderer frames(scene::LoadGltfScene(ref.model), ref.world_from_model, o);
    frames.SetLighting(model, ref.world_from_env);
    frames.SetEnvironment(ref.env);
    frames.Render(camera);
    std::vector<double> shade, total;
    for (int i = 0; i < kFrameRepeats; ++i) {
      const render::RenderResult f = frames.Render(camera);
      shade.push_back(f.ms.shade);
      total.push_back(f.ms.total);
    }
    row.frame_shade_ms = Median(shade);
    row.frame_total_ms = Median(total);
  }
  if (scored) Score(ref, r, &row);
  if (scored && !images_dir.empty()) {
    // For looking at where a row's error lies: the car layer beside the reference's.
    std::filesystem::create_directories(images_dir);
    const std::string name =
        ref.name + "_" + method +
        (method == "sg" ? "_l" + std::to_string(levels) + "_c" + std::to_string(cones) + "_" + row.lobes
                        : "_s" + std::to_string(samples)) +
        "_v" + std::to_string(voxels) +
        (supersample > 1 ? "_ss" + std::to_string(supersample) + (contrast > 0 ? fmt::format("_c{}", contrast) : "")
                         : "") +
        ".exr";
    image::SaveImage(std::filesystem::path(images_dir) / name, r.car);
    image::SaveImage(std::filesystem::path(images_dir) / (name.substr(0, name.size() - 4) + "_shadow.exr"), r.shadow);
  }
  return row;
}

}  // namespace odvr::app::render_rows
