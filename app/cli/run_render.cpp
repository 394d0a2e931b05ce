// odvr render: a glTF car lit by an equirect frame through the SG triple product, with its shadow
// on the ground, composited over the frame seen from a pinhole camera.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <glm/geometric.hpp>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "app/bench/bench_common.h"
#include "app/cli/commands.h"
#include "app/flags/command_flags.h"
#include "app/flags/material_flag.h"
#include "app/flags/render_switches.h"
#include "core/error.h"
#include "core/timing.h"
#include "engine/gl/context.h"
#include "engine/image/image_io.h"
#include "engine/lighting/lighting_builder.h"
#include "engine/render/triple_product_renderer.h"
#include "engine/scene/gltf_scene.h"

namespace odvr::app {
namespace {

struct RenderCliOptions {
  std::string model, env, lighting, out, layers, background;
  int levels = 5;
  int cones = 7;
  int voxels = 128;
  int supersample = render::kStillSupersample;
  double supersample_contrast = render::RenderOptions{}.supersample_contrast;
  std::string size = "640x360";
  std::string camera;
  std::string model_matrix, env_rotation;
  std::vector<std::string> materials;
  bool no_peaks = false;
  render::RenderOptions switches;  // AddRenderSwitches' flags
  std::string device = "gpu";
  bool json = false;
  bool composite_only = false;
  int shade_lanes = render::RenderOptions{}.shade_lanes;
  int repeat = 1;
};

std::vector<double> Numbers(const std::string& text, const std::string& flag, std::size_t count) {
  const std::vector<double> v = ParseNumberList(text, flag);
  if (v.size() != count)
    throw UsageError(flag, "want " + std::to_string(count) + " comma-separated numbers, got " +
                               std::to_string(v.size()) + " in '" + text + "'");
  return v;
}

void SaveGrey(const std::filesystem::path& path, const std::vector<float>& v, int w, int h) {
  sphere::EquirectImage img(w, h);
  for (std::size_t i = 0; i < v.size(); ++i)
    for (int c = 0; c < 3; ++c) img.rgb[3 * i + c] = v[i];
  image::SaveImage(path, img);
}

// The renderer's refusals of its camera and model matrix ("view direction is parallel to up",
// "is singular") name the flag they came from, as usage errors: a user knows --camera, not the
// renderer's parameter names.
render::PinholeCamera CameraFromFlag(const std::vector<double>& cam, int width, int height) {
  try {
    return render::PinholeCamera::LookAt({cam[0], cam[1], cam[2]}, {cam[3], cam[4], cam[5]}, cam[6], width, height);
  } catch (const Error& e) {
    throw UsageError("--camera", (e.where() == "camera fov" ? "the field of view " : "") + e.reason());
  }
}

render::TripleProductRenderer RendererFor(const scene::GltfScene& model, const glm::dmat4& world_from_model,
                                          const render::RenderOptions& options) {
  try {
    return render::TripleProductRenderer(model, world_from_model, options);
  } catch (const Error& e) {
    if (e.where() != "world_from_model") throw;
    throw UsageError("--model-matrix", "the world_from_model matrix " + e.reason());
  }
}

// The renderer's options from the command's flags, checked.
render::RenderOptions RenderOptionsFor(const RenderCliOptions& o) {
  render::RenderOptions options = o.switches;
  options.lighting_levels = o.levels;
  options.cone_rings = ConeRingsForCount(o.cones);
  options.voxel_resolution = o.voxels;
  options.supersample = o.supersample;
  options.supersample_contrast = o.supersample_contrast;
  options.peak_cones = !o.no_peaks;
  options.read_layers = !o.composite_only;
  options.shade_lanes = o.shade_lanes;
  if (o.composite_only && !o.layers.empty())
    throw UsageError("--composite-only", "reads back the composite alone: it cannot write --layers");
  for (const auto& m : o.materials) options.materials.push_back(ParseMaterialOverride(m));
  options.Check();
  return options;
}

// --model-matrix (3x4, rows) and --env-rotation (3x3, rows, a rotation), identity when not given.
std::pair<glm::dmat4, glm::dmat3> TransformsFor(const RenderCliOptions& o) {
  glm::dmat4 world_from_model(1.0);
  if (!o.model_matrix.empty()) {
    const auto v = Numbers(o.model_matrix, "--model-matrix", 12);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) world_from_model[c][r] = v[static_cast<std::size_t>(4 * r + c)];
  }
  glm::dmat3 world_from_env(1.0);
  if (!o.env_rotation.empty()) {
    const auto v = Numbers(o.env_rotation, "--env-rotation", 9);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) world_from_env[c][r] = v[static_cast<std::size_t>(3 * r + c)];
    const glm::dmat3 should_be_identity = glm::transpose(world_from_env) * world_from_env;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        if (std::abs(should_be_identity[c][r] - (r == c ? 1.0 : 0.0)) > 1e-4)
          throw UsageError("--env-rotation", "is not a rotation matrix (R^T R != I)");
  }
  return {world_from_model, world_from_env};
}

// The model's light: --lighting's file, else built from the environment map, timed (the median
// of --repeat builds after the first, and the first).
lighting::SgLighting LightingFor(const RenderCliOptions& o, const sphere::EquirectImage& env, double* ms,
                                 double* first_ms) {
  using Clock = std::chrono::steady_clock;
  *ms = *first_ms = 0;
  if (!o.lighting.empty()) return lighting::SgLighting::Load(o.lighting);
  const auto t0 = Clock::now();
  lighting::LightingOptions lo;
  lo.transform.levels = o.levels;
  lo.detect_peaks = !o.no_peaks;
  lighting::LightingBuilder builder(lo);
  lighting::SgLighting lighting_model = builder.Build(env);
  *ms = *first_ms = MsSince(t0);
  // Like the render's stages, the repeats time the steady state: the first build also makes
  // each level's overlap lists, which every later frame reuses.
  std::vector<double> steady;
  for (int i = 1; i < o.repeat; ++i) {
    const auto t = Clock::now();
    lighting_model = builder.Build(env);
    steady.push_back(MsSince(t));
  }
  if (!steady.empty()) *ms = Median(std::move(steady));
  return lighting_model;
}

// Default: the model from its front-left, a little above, filling about half the frame.
render::PinholeCamera DefaultCamera(const render::TripleProductRenderer& renderer, int width, int height) {
  glm::dvec3 lo(-1), hi(1);
  const auto& tris = renderer.world_triangles();
  if (!tris.empty()) {
    lo = glm::dvec3(1e300);
    hi = glm::dvec3(-1e300);
    for (const auto& p : tris) {
      lo = glm::min(lo, glm::dvec3(p));
      hi = glm::max(hi, glm::dvec3(p));
    }
  }
  const glm::dvec3 centre = 0.5 * (lo + hi);
  const double radius = std::max(0.5 * glm::length(hi - lo), 1e-3);
  const glm::dvec3 dir = glm::normalize(glm::dvec3(0.75, 0.35, 0.9));
  return render::PinholeCamera::LookAt(centre + 3.2 * radius * dir, centre, 40, width, height);
}

// --layers: the car, its alpha, its shadow, the background and the composite as EXR files.
void SaveLayers(const std::filesystem::path& d, const render::RenderResult& r, int width, int height) {
  std::filesystem::create_directories(d);
  image::SaveImage(d / "car.exr", r.car);
  SaveGrey(d / "car_alpha.exr", r.car_alpha, width, height);
  image::SaveImage(d / "shadow.exr", r.shadow);
  image::SaveImage(d / "background.exr", r.background);
  image::SaveImage(d / "composite.exr", r.composite);
}

int RunRender(const RenderCliOptions& o) {
  const auto [width, height] = ParseSize(o.size);
  if (width < 8 || height < 8 || width > 8192 || height > 8192)
    throw UsageError("--size", "each side must be 8..8192 pixels, got '" + o.size + "'");
  const render::RenderOptions options = RenderOptionsFor(o);
  const auto [world_from_model, world_from_env] = TransformsFor(o);
  std::vector<double> cam;
  if (!o.camera.empty()) {
    cam = Numbers(o.camera, "--camera", 7);
    if (cam[0] == cam[3] && cam[1] == cam[4] && cam[2] == cam[5])
      throw UsageError("--camera", "the target coincides with the position: the camera looks nowhere");
  }

  const scene::GltfScene model = scene::LoadGltfScene(o.model);
  const sphere::EquirectImage env = image::LoadImage(o.env, {.max_width = 8192, .require_equirect = true});

  gl::HeadlessContext context;
  double lighting_ms = 0, first_lighting_ms = 0;
  const lighting::SgLighting lighting_model = LightingFor(o, env, &lighting_ms, &first_lighting_ms);

  render::TripleProductRenderer renderer = RendererFor(model, world_from_model, options);
  renderer.SetLighting(lighting_model, world_from_env);
  if (!o.background.empty()) {
    renderer.SetBackgroundImage(image::LoadImage(o.background));
  } else {
    renderer.SetEnvironment(env);
  }

  const render::PinholeCamera camera =
      cam.empty() ? DefaultCamera(renderer, width, height) : CameraFromFlag(cam, width, height);

  const render::ShadeDevice device = o.device == "cpu" ? render::ShadeDevice::kCpu : render::ShadeDevice::kGpu;
  // Repeats time the steady state: on llvmpipe the first dispatch also compiles the shaders.
  render::RenderResult r = renderer.Render(camera, device);
  const render::RenderTimings first = r.ms;
  std::vector<render::RenderTimings> steady;
  for (int i = 1; i < o.repeat; ++i) {
    r = renderer.Render(camera, device);
    steady.push_back(r.ms);
  }
  // Per stage, the median of the repeats after the first (the first alone when there are none).
  const auto median = [&](double render::RenderTimings::*stage) {
    if (steady.empty()) return first.*stage;
    std::vector<double> v;
    for (const auto& t : steady) v.push_back(t.*stage);
    return Median(std::move(v));
  };
  image::SaveImage(o.out, r.composite);
  if (!o.layers.empty()) SaveLayers(o.layers, r, width, height);

  const auto& c = r.counts;
  if (o.json) {
    nlohmann::json j = {
        {"model", o.model},
        {"env", o.env},
        {"out", o.out},
        {"size", {width, height}},
        {"device", o.device},
        {"camera",
         {{"position", {camera.position.x, camera.position.y, camera.position.z}}, {"vfov_deg", camera.vfov_deg}}},
        {"ms",
         {{"lighting", lighting_ms},
          {"first_lighting", first_lighting_ms},
          {"voxelize", median(&render::RenderTimings::voxelize)},
          {"gbuffer", median(&render::RenderTimings::gbuffer)},
          {"shade", median(&render::RenderTimings::shade)},
          {"composite", median(&render::RenderTimings::composite)},
          {"readback", median(&render::RenderTimings::readback)},
          {"gpu_voxelize", median(&render::RenderTimings::gpu_voxelize)},
          {"gpu_gbuffer", median(&render::RenderTimings::gpu_gbuffer)},
          {"gpu_shade", median(&render::RenderTimings::gpu_shade)},
          {"gpu_composite", median(&render::RenderTimings::gpu_composite)},
          {"render_total", median(&render::RenderTimings::total)},
          {"first_render_total", first.total},
          {"repeat", o.repeat}}},
        {"counts",
         {{"lighting_sgs", c.lighting_sgs},
          {"peaks", c.peaks},
          {"peaks_without_cone", renderer.peaks_without_cone()},
          {"levels", o.levels},
          {"cones_per_broad_lobe", o.cones},
          {"voxels", o.voxels},
          {"supersample", o.supersample},
          {"shade_lanes", c.shade_lanes},
          {"pixels_sampled_fully", c.pixels_sampled_fully},
          {"car_pixels", c.car_pixels},
          {"ground_pixels_occluded", c.ground_pixels},
          {"lobes_per_car_pixel", c.lobes_per_car_pixel},
          {"cones_per_car_pixel", c.cones_per_car_pixel},
          {"sgs_per_car_pixel", c.sgs_per_car_pixel},
          {"triples_per_car_pixel", c.triples_per_car_pixel},
          {"cones_total", c.cones_total},
          {"triples_total", c.triples_total}}}};
    j["counts"].update(RenderSwitchesJson(options));
    std::cout << j.dump(2) << "\n";
  } else {
    std::cout << o.out << ": " << width << "x" << height << ", " << c.car_pixels
              << (o.supersample > 1 ? " shaded car samples, " : " car pixels, ") << c.lighting_sgs << " SGs ("
              << c.peaks << " peaks), " << fmt::format("{:.1f}", c.lobes_per_car_pixel) << " lobes and "
              << fmt::format("{:.1f}", c.cones_per_car_pixel) << " cones per car pixel\n"
              << fmt::format(
                     "ms: lighting {:.1f}, voxelize {:.1f}, G-buffer {:.1f}, shade {:.1f} ({}), composite {:.1f}\n",
                     lighting_ms, r.ms.voxelize, r.ms.gbuffer, r.ms.shade, o.device, r.ms.composite);
  }
  // The picture is written, but a user who asked for a car and sees none deserves to hear why.
  if (c.car_pixels == 0)
    spdlog::warn(
        "{}: the car ({}) covers no pixel of the view: it lies outside the camera's field "
        "(see --camera and --model-matrix)",
        o.out, o.model);
  return 0;
}

}  // namespace

CommandFn AddRender(CLI::App* sub) {
  auto o = std::make_shared<RenderCliOptions>();
  sub->add_option("--car,--model", o->model, "The car: glTF 2.0 (.glb or .gltf)")->required();
  sub->add_option("--env", o->env, "Equirect frame that lights it and is the background (EXR, HDR, PNG, JPEG)")
      ->required();
  sub->add_option("--lighting", o->lighting, "A lighting model (odvr light --out) instead of fitting --env here");
  sub->add_option("--levels", o->levels, "HEALPix lighting levels used (1..6)")->check(CLI::Range(1, 6));
  sub->add_option("--cones", o->cones, "Visibility cones per broad BRDF lobe: 1, 7, 19 or 37");
  sub->add_option("--voxels", o->voxels, "Voxel resolution per side: 64, 128, 256 or 512")
      ->check(CLI::IsMember({64, 128, 256, 512}));
  sub->add_option("--size", o->size, "Output WIDTHxHEIGHT");
  const CLI::Option* supersample =
      sub->add_option("--supersample", o->supersample,
                      "Shade KxK samples per pixel where a pixel needs them (--supersample-contrast), resolved with "
                      "Cycles' pixel filter (up to K² the shading time)")
          ->check(CLI::Range(1, render::kMaxSupersample));
  sub->add_option("--supersample-contrast", o->supersample_contrast,
                  "Shade every sample only of pixels whose surfaces differ or whose luminance differs from a "
                  "neighbour's by more than this fraction (0: every pixel)")
      ->check(CLI::Range(0.0, 1.0));
  sub->add_option("--camera", o->camera, "px,py,pz,tx,ty,tz,vfov_deg: position, target (world, +Y up, metres)");
  sub->add_option("--material", o->materials,
                  "Override materials: [NAME=]KD,KS,N or [NAME=]MODEL:PARAMS[+MODEL:PARAMS] with MODEL lambert, phong, "
                  "blinn, ward, ct, mr (repeatable; NAME matches material names, case-insensitive)");
  sub->add_option("--model-matrix", o->model_matrix, "world_from_model, 12 numbers: the top 3 rows, row-major");
  sub->add_option("--env-rotation", o->env_rotation,
                  "world_from_env rotation, 9 numbers row-major (default: identity)");
  sub->add_option("--background", o->background, "Composite over this image (of the output size) instead of --env");
  sub->add_flag("--no-peaks", o->no_peaks, "No peak detection and no extra cone per peak light");
  AddRenderSwitches(sub, &o->switches);
  sub->add_option("--device", o->device, "Where the shading runs")->check(CLI::IsMember({"gpu", "cpu"}));
  sub->add_option("--out", o->out, "The composite (PNG: sRGB 8-bit; EXR: linear)")->required();
  sub->add_option("--layers", o->layers, "Also write car, car_alpha, shadow, background, composite as EXR here");
  sub->add_option("--shade-lanes", o->shade_lanes,
                  "GPU invocations per pixel, each shading every L-th lobe (1, 2 or 4; the same picture; 0: 4 "
                  "where the shading pass is small on a GPU, else 1)")
      ->check(CLI::IsMember({0, 1, 2, 4}));
  sub->add_flag("--composite-only", o->composite_only,
                "Read back the composite alone, the counts summed on the GPU (as the players do)");
  sub->add_option("--repeat", o->repeat,
                  "Render (and build the lighting) this many times; ms are each stage's median over the "
                  "renders after the first")
      ->check(CLI::Range(1, 1000));
  sub->add_flag("--json", o->json, "Print one JSON object: per-stage ms and the counts");
  // --help shows what each of these is when not given.
  for (const char* name :
       {"--levels", "--cones", "--voxels", "--size", "--supersample", "--supersample-contrast", "--camera",
        "--overlap-cutoff", "--ground-lit-map", "--shading-rate", "--device", "--shade-lanes", "--repeat"})
    sub->get_option(name)->capture_default_str();
  return [o, supersample] {
    // Half-rate shading and supersampling exclude each other: --shading-rate 2 alone shades 1×1.
    if (o->switches.shading_rate == 2 && supersample->count() == 0) o->supersample = 1;
    return RunRender(*o);
  };
}

}  // namespace odvr::app
