// odvr bench render: the triple-product renderer against Cycles references — mean
// relative error and SSIM on car pixels, the shadow ratio's error, shade and total ms — over
// lighting levels × cones × voxel resolution, beside the brute-force Monte-Carlo shader
// (RenderOptions::monte_carlo_samples) on the same device at several sample counts. Writes a
// Markdown table, the rows (TSV), and a plot of error against shade time.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "app/bench/bench_common.h"
#include "app/bench/bench_render.h"
#include "app/bench/bench_render_set.h"
#include "app/bench/render_rows.h"
#include "app/flags/command_flags.h"
#include "app/flags/render_switches.h"
#include "core/atomic_file.h"
#include "core/constants.h"
#include "core/error.h"
#include "engine/gl/context.h"
#include "engine/image/image_io.h"
#include "engine/lighting/lighting_builder.h"
#include "engine/material/brdf.h"
#include "engine/render/triple_product_renderer.h"
#include "engine/scene/gltf_scene.h"
#include "engine/sphere/equirect.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;
using render_rows::CameraFromJson;
using render_rows::DefaultLobes;
using render_rows::kDefaultCones;
using render_rows::kDefaultLevels;
using render_rows::kDefaultVoxels;
using render_rows::KeepBelowHorizon;
using render_rows::Matrix4;
using render_rows::ReadJsonFile;
using render_rows::Reference;
using render_rows::RenderRow;
using render_rows::ReplaceLowerHemisphereByGround;
using render_rows::Row;
using render_rows::Vec3;

// KeepBelowHorizon at the mid-height of a references.json's model box.
double KeepBelowHorizonOfBox(const nlohmann::json& j) {
  const auto& box = j.at("model_box_odvr");
  return KeepBelowHorizon(0.5 * (box.at(0).at(1).get<double>() + box.at(1).at(1).get<double>()));
}

std::vector<Reference> LoadMediaReferences(const fs::path& dir, const fs::path& repo, bool ground_bounce) {
  const fs::path json_path = dir / "references.json";
  const nlohmann::json j = ReadJsonFile(json_path);
  std::vector<Reference> refs;
  try {
    const double keep_below_horizon = ground_bounce ? KeepBelowHorizonOfBox(j) : 0.0;
    for (const auto& im : j.at("images")) {
      Reference r;
      r.name = im.at("name").get<std::string>();
      r.model = repo / j.at("model").get<std::string>();
      // The maps are the project's shared data (../shared/data/env), absent from a user's clone:
      // a reference without its map is left out, as the street reference is without street_a.
      const fs::path env = repo / im.at("env").get<std::string>();
      if (!fs::exists(env)) {
        spdlog::warn("bench render: reference {} left out: its environment map {} is absent", r.name, env.string());
        continue;
      }
      r.env = image::LoadImage(env, {.max_width = 8192, .require_equirect = true});
      image::SanitizePixels(&r.env);  // Cycles clamps the lossy EXR's negative pixels to 0 too
      if (ground_bounce)
        ReplaceLowerHemisphereByGround(&r.env, j.at("catcher").at("albedo_seen_by_the_car").get<double>(),
                                       keep_below_horizon);
      const auto& m = im.at("env_world_from_env_odvr");
      for (int row = 0; row < 3; ++row)
        for (int c = 0; c < 3; ++c) r.world_from_env[c][row] = m.at(row).at(c).get<double>();
      r.rgb = image::LoadImage(dir / im.at("files").at("rgba").get<std::string>());
      r.shadow = image::LoadImage(dir / im.at("files").at("shadow").get<std::string>());
      const sphere::EquirectImage mask = image::LoadImage(dir / im.at("files").at("mask").get<std::string>());
      r.mask.resize(static_cast<std::size_t>(mask.width) * mask.height);
      for (std::size_t i = 0; i < r.mask.size(); ++i) r.mask[i] = mask.rgb[3 * i];
      r.camera = CameraFromJson(im.at("camera"));
      const auto& mp = im.at("material_params");
      const auto base = Vec3(mp.at("base_color"));
      render::MaterialOverride paint;
      paint.brdfs = {
          material::MetallicRoughness{base, mp.at("metallic").get<double>(), mp.at("roughness").get<double>()}};
      try {
        material::CheckBrdf(paint.brdfs[0]);
      } catch (const Error& e) {
        throw Error(json_path.string(), r.name + ": " + e.what());
      }
      r.materials.push_back(std::move(paint));
      if (r.rgb.width != r.camera.width || r.mask.size() != r.rgb.rgb.size() / 3 || r.shadow.width != r.rgb.width)
        throw Error(json_path.string(), r.name + ": the image sizes disagree with the camera");
      refs.push_back(std::move(r));
    }
  } catch (const nlohmann::json::exception& e) {
    throw Error(json_path.string(), std::string("a field is missing or malformed: ") + e.what());
  }
  return refs;
}

// The albedo of the catcher under street_a's car, which the dataset does not state: its frame-10
// reference rendered again by tools/blender/render_reference.py (the same car, map, rotation and
// camera; 640x360, 64 spp) matches it on the rear panel, which sees mostly the catcher, at 0.199
// (0.1, 0.18, 0.2, 0.3 give 0.77, 0.955, 1.00, 1.23 of it; the whole car 0.96, 0.999, 1.009, 1.06).
constexpr double kStreetCatcherAlbedo = 0.2;

// street_a's frame 10 relight reference (tests/engine/render/cycles_reference_test.cpp explains
// the frames), box-filtered to half size. Its film holds no shadow, so no shadow error. With
// `ground_bounce`, as the media references: the car sees Cycles' catcher below the horizon, not
// the panorama's road (the rig's tilt, under 1°, is left in: the map's lower half is replaced).
Reference LoadStreetFrame10(const fs::path& street, bool ground_bounce) {
  const glm::dmat3 yup_from_zup = sphere::YupFromZup();
  const fs::path pose_path = street / "car_pose.json";
  const nlohmann::json j = ReadJsonFile(pose_path);
  const auto& fr = j.at("frames").at(0);
  if (fr.at("frame").get<int>() != 10) throw Error(pose_path.string(), "frames[0] is not frame 10");
  Reference r;
  r.name = "street_a_f10";
  r.model = street / "car.glb";
  r.world_from_model = Matrix4(fr.at("world_yup_from_car_gltf"));
  const glm::dmat4 cam = Matrix4(fr.at("world_from_persp_cam_opencv"));
  const fs::path ref_path = street / "augment/frame_000010/relight_ref.exr";
  const sphere::EquirectImage full = image::LoadImage(ref_path);
  int aw = 0, ah = 0;
  const std::vector<float> alpha = image::LoadAlpha(ref_path, &aw, &ah);
  const int w = full.width / 2, h = full.height / 2;
  r.rgb = sphere::EquirectImage(w, h, 0.f);
  r.mask.assign(static_cast<std::size_t>(w) * h, 0.f);
  for (int y = 0; y < 2 * h; ++y)
    for (int x = 0; x < 2 * w; ++x) {
      const std::size_t o = static_cast<std::size_t>(y / 2) * w + x / 2, i = static_cast<std::size_t>(y) * aw + x;
      for (int c = 0; c < 3; ++c) r.rgb.rgb[3 * o + c] += full.rgb[3 * i + c] / 4;
      r.mask[o] += alpha[i] / 4;
    }
  r.camera.position = yup_from_zup * glm::dvec3(cam[3]);
  r.camera.world_from_camera = yup_from_zup * glm::dmat3(cam);
  r.camera.vfov_deg = j.at("persp_camera").at("vfov_deg").get<double>();
  r.camera.width = w;
  r.camera.height = h;
  const glm::dmat3 rig = glm::dmat3(Matrix4(fr.at("world_from_rig")));
  r.world_from_env = yup_from_zup * rig * glm::transpose(yup_from_zup);
  r.env = image::LoadImage(street / "pano_hdr/000010.exr", {.max_width = 8192, .require_equirect = true});
  image::SanitizePixels(&r.env);
  if (ground_bounce) {
    const scene::Bounds box = scene::LoadGltfScene(r.model).bounds;
    ReplaceLowerHemisphereByGround(&r.env, kStreetCatcherAlbedo, KeepBelowHorizon(box.center().y));
  }
  return r;
}

const char* kHeader =
    "reference\tmethod\tlobes\twidth\theight\tlevels\tcones\tvoxels\tsamples\tmean_rel\trel_l1\tbias\tssim\t"
    "shadow_mae\tshadow_px\tcar_px\tshade_ms\ttotal_ms\tsupersample\tsupersample_contrast\tframe_shade_ms\t"
    "frame_total_ms";

std::vector<Row> ReadRows(const fs::path& tsv, std::string* machine) {
  std::ifstream in(tsv);
  if (!in) throw Error(tsv.string(), "cannot be read");
  std::vector<Row> rows;
  std::string line;
  const std::string tag = "# odvr bench render on ";
  while (std::getline(in, line)) {
    if (line.rfind(tag, 0) == 0) {
      *machine = line.substr(tag.size());
      continue;
    }
    if (line.empty() || line.rfind("reference\t", 0) == 0) continue;
    std::vector<std::string> v;
    std::istringstream f(line);
    std::string field;
    while (std::getline(f, field, '\t')) v.push_back(field);
    // 18 columns: written before supersampling (every row k = 1); 19: before its contrast (every
    // sample shaded); 20: before the frame-rate columns (0: not measured).
    if (v.size() < 18 || v.size() > 22) throw Error(tsv.string(), "a row without 22 columns: " + line);
    try {
      Row r;
      r.reference = v[0];
      r.method = v[1];
      r.lobes = v[2];
      r.width = std::stoi(v[3]);
      r.height = std::stoi(v[4]);
      r.levels = std::stoi(v[5]);
      r.cones = std::stoi(v[6]);
      r.voxels = std::stoi(v[7]);
      r.samples = std::stoi(v[8]);
      r.mean_rel = std::stod(v[9]);
      r.rel_l1 = std::stod(v[10]);
      r.bias = std::stod(v[11]);
      r.ssim = std::stod(v[12]);
      r.shadow_mae = std::stod(v[13]);
      r.shadow_pixels = std::stoi(v[14]);
      r.car_pixels = std::stoi(v[15]);
      r.shade_ms = std::stod(v[16]);
      r.total_ms = std::stod(v[17]);
      r.supersample = v.size() > 18 ? std::stoi(v[18]) : 1;
      r.contrast = v.size() > 19 ? std::stod(v[19]) : 0;
      r.frame_shade_ms = v.size() > 20 ? std::stod(v[20]) : 0;
      r.frame_total_ms = v.size() > 21 ? std::stod(v[21]) : 0;
      rows.push_back(r);
    } catch (const std::exception&) {
      throw Error(tsv.string(), "a malformed number in: " + line);
    }
  }
  return rows;
}

std::string F(double v, int digits = 3) { return fmt::format("{:.{}f}", v, digits); }

bool IsDefault(const Row& r, const std::string& lobes, int supersample = 1, double contrast = 0) {
  return r.method == "sg" && r.lobes == lobes && r.levels == kDefaultLevels && r.cones == kDefaultCones &&
         r.voxels == kDefaultVoxels && r.car_pixels > 0 && r.supersample == supersample &&
         (supersample == 1 || r.contrast == contrast);
}

// The sweep's finest configuration for a reference: the most levels, cones and voxels its 1×1
// rows (default lobes) were rendered with, each the largest of its axis — what the renderer gives
// when asked to model the most, beside the default. Chosen by the sweep's extent, not by any
// row's error against the reference. {0, 0, 0} without such a row.
using Config = std::array<int, 3>;  // levels, cones, voxels
Config FinestConfig(const std::vector<Row>& rows, const std::string& reference) {
  Config finest = {0, 0, 0};
  const std::string lobes = DefaultLobes();
  for (const Row& r : rows)
    if (r.reference == reference && r.method == "sg" && r.lobes == lobes && r.supersample == 1 && r.car_pixels > 0)
      finest = {std::max(finest[0], r.levels), std::max(finest[1], r.cones), std::max(finest[2], r.voxels)};
  return finest;
}

bool HasConfig(const Row& r, const Config& c) { return r.levels == c[0] && r.cones == c[1] && r.voxels == c[2]; }

// MC shade ms at a given error, interpolated in log-log between the two MC rows around it;
// `bound` is set when the error lies outside the rows (then the nearest row's ms, a bound).
double McMsAtError(const std::vector<const Row*>& mc, double error, std::string* bound) {
  std::vector<const Row*> s = mc;
  std::sort(s.begin(), s.end(), [](const Row* a, const Row* b) { return a->samples < b->samples; });
  for (std::size_t i = 0; i + 1 < s.size(); ++i) {
    const double e0 = s[i]->mean_rel, e1 = s[i + 1]->mean_rel;
    if ((e0 - error) * (e1 - error) <= 0 && e0 != e1) {
      const double t = (std::log(error) - std::log(e0)) / (std::log(e1) - std::log(e0));
      *bound = "";
      return std::exp(std::log(s[i]->shade_ms) + t * (std::log(s[i + 1]->shade_ms) - std::log(s[i]->shade_ms)));
    }
  }
  double best = 1e300;
  const Row* closest = nullptr;
  for (const Row* r : s)
    if (std::abs(r->mean_rel - error) < best) {
      best = std::abs(r->mean_rel - error);
      closest = r;
    }
  if (!closest) return 0;
  const bool below_all = std::all_of(s.begin(), s.end(), [&](const Row* r) { return r->mean_rel > error; });
  *bound = below_all ? ">" : "<";
  return below_all ? s.back()->shade_ms : s.front()->shade_ms;
}

const Row* MostSamples(const std::vector<const Row*>& mc) {
  const Row* best = nullptr;
  for (const Row* r : mc)
    if (!best || r->samples > best->samples) best = r;
  return best;
}

// The fastest row whose error is at most `error` (nullptr when none is).
const Row* CheapestWithin(const std::vector<const Row*>& candidates, double error) {
  const Row* cheapest = nullptr;
  for (const Row* r : candidates)
    if (r->mean_rel <= error && (!cheapest || r->shade_ms < cheapest->shade_ms)) cheapest = r;
  return cheapest;
}

// The speed at MC's best error: MC's row with the most samples against the cheapest SG row (any
// levels, cones, voxels, samples per pixel) whose error is no larger, as table cells ("–" where
// there is none); `fast`: that speed-up is at least 20×.
struct AtMcsBest {
  std::string mc_best = "–", sg_match = "–", speed = "–";
  bool fast = false;
};
AtMcsBest AtMcsBestError(const std::vector<const Row*>& mc, const std::vector<const Row*>& sg_rows) {
  AtMcsBest out;
  const Row* best = MostSamples(mc);
  if (!best) return out;
  out.mc_best = F(best->mean_rel) + ", " + F(best->shade_ms, 0);
  const Row* cheap = CheapestWithin(sg_rows, best->mean_rel);
  if (!cheap) return out;
  const std::string samples = cheap->supersample == 1 ? ""
                              : cheap->contrast > 0
                                  ? fmt::format(", {}×{} c {}", cheap->supersample, cheap->supersample, cheap->contrast)
                                  : fmt::format(", {}×{}", cheap->supersample, cheap->supersample);
  out.sg_match =
      fmt::format("{}, {} levels, {} cone{}, {}³{}: {}, {}", cheap->lobes, cheap->levels, cheap->cones,
                  cheap->cones == 1 ? "" : "s", cheap->voxels, samples, F(cheap->mean_rel), F(cheap->shade_ms, 0));
  out.fast = best->shade_ms / cheap->shade_ms >= 20;
  out.speed = F(best->shade_ms / cheap->shade_ms, 1) + "×";
  return out;
}

// The rows without a reference (car_pixels 0): a frame's size, its shade and total time, and its
// frame rate, with every layer read back and as the window player draws it.
std::string FrameRateLines(const std::vector<Row>& rows) {
  std::ostringstream md;
  for (const auto& r : rows)
    if (r.car_pixels == 0 && r.method == "sg")
      md << "\n**" << r.width << "×" << r.height << "** (" << r.reference << ", default configuration): shade "
         << F(r.shade_ms, 1) << " ms, total " << F(r.total_ms, 1) << " ms = " << F(1000.0 / r.total_ms, 2)
         << " fps with every layer read back (one render)"
         << (r.frame_total_ms > 0
                 ? "; as the window player draws it (nothing read back but the counts' sums; median of 5 after a "
                   "first render) shade " +
                       F(r.frame_shade_ms, 1) + " ms, total " + F(r.frame_total_ms, 1) +
                       " ms = " + F(1000.0 / r.frame_total_ms, 2) + " fps"
                 : std::string())
         << " (target on a GPU: ≥ 60 fps).\n";
  return md.str();
}

std::string Targets(const std::vector<Row>& rows) {
  std::ostringstream md;
  std::set<std::string> refs;
  for (const auto& r : rows)
    if (r.car_pixels > 0) refs.insert(r.reference);
  const std::string lobes = DefaultLobes();
  md << "\n## Targets, from the rows above\n\n"
     << "Default configuration: " << kDefaultLevels << " levels, " << kDefaultCones << " cones, " << kDefaultVoxels
     << "³ voxels, lobes `" << lobes << "`. Speed: the Monte-Carlo shader's shade ms at the SG renderer's error, "
     << "interpolated (log-log) between its rows; `>` marks an SG error below every MC row (the ratio is then a "
        "lower bound, from MC's largest sample count), `<` one above every MC row (an upper bound). "
        "Where the SG error lies below every MC row that bound says little, so the speed is also taken the "
        "other way round, at MC's best error: MC's row with the most samples against the cheapest SG row "
        "(any levels, cones, voxels) whose error is no larger (the SG row is then at least as accurate: a "
        "speed-up at equal or better error).\n\n"
     << "| reference | mean rel. error | ≤ 10 % | SSIM | shadow MAE | shade ms | MC ms at that error | speed-up "
        "| MC's best: error, ms | cheapest SG row as accurate | speed-up there |\n"
     << "|---|---|---|---|---|---|---|---|---|---|---|\n";
  int supersample = 1;  // the largest k > 1 with rows: its own table below
  for (const auto& r : rows)
    if (r.car_pixels > 0) supersample = std::max(supersample, r.supersample);
  // Its adaptive rows: the largest contrast among them (every sample shaded: 0).
  double contrast = 0;
  for (const auto& r : rows)
    if (r.car_pixels > 0 && r.supersample == supersample) contrast = std::max(contrast, r.contrast);
  std::ostringstream ss_md, fine_md;
  int met = 0, total = 0, fast = 0, fast_total = 0, fast_at_mc = 0, ss_met = 0, ss_total = 0, ss_fast = 0,
      ss_fast_total = 0, ss_fast_at_mc = 0, fine_met = 0, fine_total = 0, fine_fast = 0, fine_fast_total = 0;
  bool finer_than_default = false;
  const Config default_config = {kDefaultLevels, kDefaultCones, kDefaultVoxels};
  for (const auto& name : refs) {
    const Row *sg = nullptr, *sg_ss = nullptr, *sg_every = nullptr, *fine = nullptr, *fine_ss = nullptr;
    std::vector<const Row*> mc, mc_ss, sg_rows;
    const Config finest = FinestConfig(rows, name);
    for (const auto& r : rows) {
      if (r.reference != name || r.car_pixels == 0) continue;
      if (IsDefault(r, lobes)) sg = &r;
      if (supersample > 1 && IsDefault(r, lobes, supersample, contrast)) sg_ss = &r;
      if (supersample > 1 && contrast > 0 && IsDefault(r, lobes, supersample, 0)) sg_every = &r;
      if (r.method == "sg" && r.lobes == lobes && HasConfig(r, finest)) {
        if (r.supersample == 1) fine = &r;
        if (supersample > 1 && r.supersample == supersample && r.contrast == contrast) fine_ss = &r;
      }
      if (r.method == "sg") sg_rows.push_back(&r);
      if (r.method == "mc" && r.voxels == kDefaultVoxels && r.supersample == 1) mc.push_back(&r);
      if (r.method == "mc" && r.voxels == kDefaultVoxels && r.supersample == supersample) mc_ss.push_back(&r);
    }
    // The finest configuration at the most samples per pixel there are rows for.
    if (const Row* judged = supersample > 1 ? fine_ss : fine) {
      finer_than_default |= finest != default_config;
      ++fine_total;
      fine_met += judged->mean_rel <= 0.10;
      std::string bound;
      const double mc_ms = McMsAtError(supersample > 1 ? mc_ss : mc, judged->mean_rel, &bound);
      std::string speed = "–";
      if (mc_ms > 0) {
        ++fine_fast_total;
        fine_fast += mc_ms / judged->shade_ms >= 20 && bound != "<";
        speed = bound + F(mc_ms / judged->shade_ms, 1) + "×";
      }
      fine_md << "| " << name << " | " << finest[0] << ", " << finest[1] << ", " << finest[2] << "³"
              << (finest == default_config ? " (the default)" : "") << " | "
              << (fine ? F(fine->mean_rel) + ", " + F(fine->shade_ms, 0) : "–") << " | "
              << (supersample > 1 ? F(judged->mean_rel) + ", " + F(judged->shade_ms, 0) + " | " : "")
              << (judged->mean_rel <= 0.10 ? "yes" : "no") << " | " << F(judged->ssim) << " | "
              << (mc_ms > 0 ? bound + F(mc_ms, 0) : "–") << " | " << speed << " |\n";
    }
    if (sg_ss) {
      ++ss_total;
      ss_met += sg_ss->mean_rel <= 0.10;
      std::string bound;
      const double mc_ms = McMsAtError(mc_ss, sg_ss->mean_rel, &bound);
      std::string speed = "–";
      if (mc_ms > 0) {
        ++ss_fast_total;
        ss_fast += mc_ms / sg_ss->shade_ms >= 20 && bound != "<";
        speed = bound + F(mc_ms / sg_ss->shade_ms, 1) + "×";
      }
      const AtMcsBest at_best = AtMcsBestError(mc_ss, sg_rows);
      ss_fast_at_mc += at_best.fast;
      ss_md << "| " << name << " | " << (sg ? F(sg->mean_rel) + ", " + F(sg->shade_ms, 0) : "–") << " | "
            << (sg_every ? F(sg_every->mean_rel) + ", " + F(sg_every->shade_ms, 0) : "–") << " | " << F(sg_ss->mean_rel)
            << " | " << (sg_ss->mean_rel <= 0.10 ? "yes" : "no") << " | " << F(sg_ss->ssim) << " | "
            << F(sg_ss->shade_ms, 1) << " | " << (mc_ms > 0 ? bound + F(mc_ms, 0) : "–") << " | " << speed << " | "
            << at_best.mc_best << " | " << at_best.sg_match << " | " << at_best.speed << " |\n";
    }
    if (!sg) continue;
    ++total;
    met += sg->mean_rel <= 0.10;
    std::string bound;
    const double mc_ms = McMsAtError(mc, sg->mean_rel, &bound);
    std::string speed = "–";
    if (mc_ms > 0) {
      ++fast_total;
      fast += mc_ms / sg->shade_ms >= 20 && bound != "<";
      speed = bound + F(mc_ms / sg->shade_ms, 1) + "×";
    }
    const AtMcsBest at_best = AtMcsBestError(mc, sg_rows);
    fast_at_mc += at_best.fast;
    md << "| " << name << " | " << F(sg->mean_rel) << " | " << (sg->mean_rel <= 0.10 ? "yes" : "no") << " | "
       << F(sg->ssim) << " | " << (sg->shadow_mae >= 0 ? F(sg->shadow_mae) : "–") << " | " << F(sg->shade_ms, 1)
       << " | " << (mc_ms > 0 ? bound + F(mc_ms, 0) : "–") << " | " << speed << " | " << at_best.mc_best << " | "
       << at_best.sg_match << " | " << at_best.speed << " |\n";
  }
  md << "\n**Mean relative error ≤ 10 % on car pixels:** " << met << " of " << total
     << " references. **≥ 20× faster than MC at equal error:** " << fast << " of " << fast_total
     << " at the default configuration's error; " << fast_at_mc << " of " << fast_total
     << " at MC's best error (the cheapest SG row as accurate).\n";
  if (ss_total > 0)
    md << "\n**Supersampled, " << supersample << "×" << supersample << " shaded samples per pixel** (the default "
       << "configuration otherwise"
       << (contrast > 0 ? fmt::format("; every sample only where a pixel needs it, contrast {}", contrast)
                        : std::string("; every sample of every pixel"))
       << "; the Monte-Carlo rows likewise, every sample, at samples/" << supersample * supersample
       << " each, the same rays per pixel):\n\n| reference | 1×1: error, ms | every sample: error, ms | error | ≤ 10 % "
          "| "
          "SSIM | shade ms | MC ms at that error | speed-up | MC's best: error, ms | cheapest SG row as accurate | "
          "speed-up there |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|---|\n"
       << ss_md.str() << "\n**Mean relative error ≤ 10 % on car pixels, supersampled:** " << ss_met << " of "
       << ss_total << " references. **≥ 20× faster than MC at equal error** (MC supersampled alike): " << ss_fast
       << " of " << ss_fast_total << " at the supersampled row's error; " << ss_fast_at_mc << " of " << ss_fast_total
       << " at MC's best error (the cheapest SG row as accurate, any samples per pixel).\n";
  if (finer_than_default) {
    const std::string samples = supersample > 1
                                    ? fmt::format("{}×{}", supersample, supersample) +
                                          (contrast > 0 ? fmt::format(" (contrast {})", contrast) : std::string())
                                    : std::string("1×1");
    md << "\n**The sweep's finest configuration**, per reference the most levels, cones and voxels of its sweep "
          "(its extent, not a choice by error), at "
       << samples << ": what the renderer gives when a scene is given the most it models.\n\n"
       << "| reference | levels, cones, voxels | 1×1: error, ms | "
       << (supersample > 1 ? samples + ": error, ms | " : "") << "≤ 10 % | SSIM | MC ms at that error | speed-up |\n"
       << (supersample > 1 ? "|---|---|---|---|---|---|---|---|\n" : "|---|---|---|---|---|---|---|\n") << fine_md.str()
       << "\n**Mean relative error ≤ 10 % on car pixels, finest configuration:** " << fine_met << " of " << fine_total
       << " references. **≥ 20× faster than MC at equal error:** " << fine_fast << " of " << fine_fast_total << ".\n";
  }
  md << FrameRateLines(rows);
  return md.str();
}

void WriteReport(const std::vector<Row>& rows, const BenchRenderOptions& o, const std::string& machine) {
  fs::create_directories(o.out_dir);
  const fs::path tsv = fs::path(o.out_dir) / "render.tsv";
  std::ostringstream t;
  t << "# odvr bench render on " << machine << "\n" << kHeader << "\n";
  for (const auto& r : rows)
    t << r.reference << "\t" << r.method << "\t" << r.lobes << "\t" << r.width << "\t" << r.height << "\t" << r.levels
      << "\t" << r.cones << "\t" << r.voxels << "\t" << r.samples << "\t" << r.mean_rel << "\t" << r.rel_l1 << "\t"
      << r.bias << "\t" << r.ssim << "\t" << r.shadow_mae << "\t" << r.shadow_pixels << "\t" << r.car_pixels << "\t"
      << r.shade_ms << "\t" << r.total_ms << "\t" << r.supersample << "\t" << r.contrast << "\t" << r.frame_shade_ms
      << "\t" << r.frame_total_ms << "\n";
  WriteTextAtomically(tsv, t.str());

  std::ostringstream md;
  md << "# Renderer: error against Cycles, and time\n\n"
     << "Made by `odvr bench render` on " << machine << ". References: `media/reference/` (the demo car under "
     << "three maps × a diffuse and a glossy paint, 320×180, with Cycles' shadow-catcher ratio) and street_a's "
     << "frame 10 relight (its own car paint; the reference holds no shadow). Car pixels: Cycles coverage > 0.99 "
     << "and ours > 0.5. `mean_rel`: mean over car pixels of |Y − Y_ref| / max(Y_ref, 0.05 mean Y_ref) (Y the "
     << "luminance); `rel_l1` = Σ|Y − Y_ref| / ΣY_ref; `bias` = ΣY / ΣY_ref; `ssim`: SSIM (11×11 Gaussian "
     << "window) of the luminance on car pixels, both scaled by Cycles' 99th percentile; `shadow`: mean "
     << "|ratio − ratio_ref| where Cycles' ratio < 0.95 off the car. `sg` rows: the triple-product renderer, "
     << "lobes `iso`/`split` (eq. 4.10's warp / the anisotropic split) × `axis`/`sg` (the cosine at the lobe "
     << "axis / as an SG); `mc` rows: the Monte-Carlo shader on the same G-buffer and voxels; `mc-exact` rows: "
     << "the same with shadow rays against the triangles (the ground's lit fraction still from the voxels). `k`: "
        "shaded samples per pixel along each axis (`RenderOptions::supersample`), resolved with Cycles' pixel "
        "filter (Blackman-Harris reaching ±1.5 px), `c`: every sample only where a pixel needs it "
        "(`RenderOptions::supersample_contrast`); MC `samples` are rays per pixel. Times are one "
     << "render each, after an untimed render of at most 33×33 pixels (sides a power of two where the row's "
        "are: llvmpipe compiles a variant per kind) that compiles the row's shaders, on the device named "
        "above.\n\n"
     << "| reference | method | lobes | levels | cones | voxels | samples | k | mean_rel | rel_l1 | bias | ssim | "
        "shadow | shade ms | total ms |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : rows) {
    if (r.car_pixels == 0) continue;
    md << "| " << r.reference << " | " << r.method << " | " << r.lobes << " | "
       << (r.levels ? std::to_string(r.levels) : "–") << " | " << (r.cones ? std::to_string(r.cones) : "–") << " | "
       << r.voxels << " | " << (r.samples ? std::to_string(r.samples) : "–") << " | "
       << (r.contrast > 0 ? fmt::format("{}, c {}", r.supersample, r.contrast) : std::to_string(r.supersample)) << " | "
       << F(r.mean_rel) << " | " << F(r.rel_l1) << " | " << F(r.bias) << " | " << F(r.ssim) << " | "
       << (r.shadow_mae >= 0 ? F(r.shadow_mae) : "–") << " | " << F(r.shade_ms, 1) << " | " << F(r.total_ms, 1)
       << " |\n";
  }
  md << Targets(rows);
  md << "\nEvery row is in `render.tsv`; `render.png` plots mean_rel against shade ms. Where the error against "
        "Cycles came from and what is left, measured term by term: `../notes/render_accuracy.md`.\n\n![error against "
        "time]"
        "(render.png)\n";
  WriteTextAtomically(fs::path(o.out_dir) / "render.md", md.str());

  std::ostringstream gp;
  const std::string data = "render.tsv";
  gp << "set datafile separator '\\t'\nset logscale xy\nset key outside right\nset grid\n"
     << "set title 'car pixels: mean relative error against Cycles vs shade time'\nset xlabel 'shade ms'\n"
     << "set ylabel 'mean relative error'\nplot '" << data
     << "' using (strcol(2) eq 'sg' && $16 > 0 ? $17 : 1/0):10 with points pt 7 title 'SG triple product', '" << data
     << "' using (strcol(2) eq 'mc' && $16 > 0 ? $17 : 1/0):10 with points pt 5 title 'Monte-Carlo'\n";
  WritePlot(o.out_dir, "render", 1000, 600, gp.str(), "bench render");
}

}  // namespace

int RunBenchRender(BenchRenderOptions o) {
  if (o.report_only) {
    std::string machine = "unknown";
    const auto rows = ReadRows(fs::path(o.out_dir) / "render.tsv", &machine);
    WriteReport(rows, o, machine);
    std::cout << "bench render: report rewritten from " << rows.size() << " rows\n";
    return 0;
  }
  const fs::path repo = fs::path(ODVR_SOURCE_DIR);
  std::vector<Reference> refs;
  if (!o.reference_dir.empty()) {
    const fs::path dir = fs::path(o.reference_dir).is_absolute() ? fs::path(o.reference_dir) : repo / o.reference_dir;
    refs = LoadMediaReferences(dir, repo, o.ground_bounce);
  }
  const fs::path street = o.street_dir.empty() ? repo / ".." / "shared" / "data" / "street_a" : fs::path(o.street_dir);
  if (fs::exists(street / "augment/frame_000010/relight_ref.exr"))
    refs.push_back(LoadStreetFrame10(street, o.ground_bounce));
  if (!o.only.empty())
    std::erase_if(refs,
                  [&](const Reference& r) { return std::find(o.only.begin(), o.only.end(), r.name) == o.only.end(); });
  if (refs.empty()) throw UsageError("bench render", "no reference to run");

  const render::RenderOptions& base = o.switches;
  gl::HeadlessContext context;
  std::string machine = BenchMachineDescription() + ", GL: " + context.Info().renderer;
  for (const std::string& flag : NonDefaultRenderSwitches(base)) machine += "; " + flag;
  // One-at-a-time around the default: every level count, cone count and resolution once.
  std::vector<std::array<int, 3>> configs;
  for (int l : o.levels) configs.push_back({l, kDefaultCones, kDefaultVoxels});
  for (int c : o.cones) configs.push_back({kDefaultLevels, c, kDefaultVoxels});
  for (int v : o.voxels) configs.push_back({kDefaultLevels, kDefaultCones, v});
  std::sort(configs.begin(), configs.end());
  configs.erase(std::unique(configs.begin(), configs.end()), configs.end());
  std::vector<material::LobeOptions> modes = {render::RenderOptions{}.lobes};
  if (o.lobe_modes)
    for (auto warp : {material::WarpMode::kIsotropic, material::WarpMode::kAnisotropicSplit})
      for (auto cosine : {material::CosineTerm::kAtLobeAxis, material::CosineTerm::kAsSg})
        if (!(warp == modes[0].warp && cosine == modes[0].cosine)) modes.push_back({cosine, warp});
  std::vector<Row> rows;
  BenchProgress progress("bench render", static_cast<long>(refs.size()) + (o.hd_row ? 1 : 0));
  for (const auto& ref : refs) {
    for (const auto& c : configs)
      rows.push_back(RenderRow(base, ref, "sg", c[0], c[1], c[2], 0, modes[0], 0, 0, 1, o.images_dir));
    for (std::size_t m = 1; m < modes.size(); ++m)
      rows.push_back(RenderRow(base, ref, "sg", kDefaultLevels, kDefaultCones, kDefaultVoxels, 0, modes[m], 0, 0, 1,
                               o.images_dir));
    for (const char* method : {"mc", "mc-exact"}) {
      if (method == std::string("mc-exact") && !o.mc_exact) continue;
      for (int v : o.mc_voxels)
        for (int n : o.mc_samples)
          rows.push_back(
              RenderRow(base, ref, method, kDefaultLevels, 1, v, n, modes[0], 0, 0, o.mc_seed, o.images_dir));
    }
    // The sweep's finest configuration (FinestConfig), at 1×1 unless swept already, and at each k > 1
    // at the largest contrast, as the report judges it.
    const auto largest = [](const auto& v, auto otherwise) {
      return v.empty() ? otherwise : *std::max_element(v.begin(), v.end());
    };
    const Config finest = {largest(o.levels, kDefaultLevels), largest(o.cones, kDefaultCones),
                           largest(o.voxels, kDefaultVoxels)};
    const bool finest_is_default = finest == Config{kDefaultLevels, kDefaultCones, kDefaultVoxels};
    if (std::find(configs.begin(), configs.end(), finest) == configs.end())
      rows.push_back(RenderRow(base, ref, "sg", finest[0], finest[1], finest[2], 0, modes[0], 0, 0, 1, o.images_dir));
    for (int k : o.supersample) {
      if (k == 1) continue;
      for (double c : o.supersample_contrast)
        rows.push_back(RenderRow(base, ref, "sg", kDefaultLevels, kDefaultCones, kDefaultVoxels, 0, modes[0], 0, 0, 1,
                                 o.images_dir, k, c));
      if (!finest_is_default && !o.supersample_contrast.empty())
        rows.push_back(RenderRow(base, ref, "sg", finest[0], finest[1], finest[2], 0, modes[0], 0, 0, 1, o.images_dir,
                                 k, largest(o.supersample_contrast, 0.0)));
      for (int n : o.mc_samples)
        if (n >= k * k)
          rows.push_back(RenderRow(base, ref, "mc", kDefaultLevels, 1, kDefaultVoxels, n, modes[0], 0, 0, o.mc_seed,
                                   o.images_dir, k));
    }
    progress.Step(ref.name);
  }
  if (o.hd_row) {
    rows.push_back(
        RenderRow(base, refs.front(), "sg", kDefaultLevels, kDefaultCones, kDefaultVoxels, 0, modes[0], 1280, 720));
    progress.Step("1280x720");
  }
  WriteReport(rows, o, machine);
  std::cout << "bench render: " << rows.size() << " rows; wrote " << o.out_dir
            << "/render.md, render.tsv, render.png\n";
  return 0;
}

CommandFn AddBenchRender(CLI::App* sub) {
  auto o = std::make_shared<BenchRenderOptions>();
  // The sweep's own options: --set renders every image at the default configuration (the render
  // switches apply), so it refuses them rather than leave them unused.
  std::vector<CLI::Option*> sweep_only;
  sweep_only.push_back(sub->add_option("--references", o->reference_dir,
                                       "Directory with references.json (relative: to the repository)"));
  sweep_only.push_back(sub->add_option("--street", o->street_dir,
                                       "street_a dataset for its frame-10 reference (default ../shared/data)"));
  sub->add_option("--only", o->only, "Run only these references (by name; with --set: images whose name contains one)")
      ->delimiter(',');
  sweep_only.push_back(sub->add_option("--levels", o->levels, "Lighting levels to sweep")->delimiter(','));
  sweep_only.push_back(sub->add_option("--cones", o->cones, "Cone counts to sweep (1, 7, 19, 37)")->delimiter(','));
  sweep_only.push_back(sub->add_option("--voxels", o->voxels, "Voxel resolutions to sweep")->delimiter(','));
  CLI::Option* mc_samples =
      sub->add_option("--mc-samples", o->mc_samples,
                      "Monte-Carlo samples per pixel, one row each (with --set: the largest, on every image)")
          ->delimiter(',');
  sweep_only.push_back(
      sub->add_option("--mc-voxels", o->mc_voxels, "Voxel resolutions of the Monte-Carlo rows (one row each)")
          ->delimiter(','));
  sub->add_option("--mc-seed", o->mc_seed, "Seed of the Monte-Carlo rows");
  sub->add_flag("--mc-exact", o->mc_exact,
                "Also Monte-Carlo rows with shadow rays against the triangles (method mc-exact): what the voxels cost");
  sweep_only.push_back(
      sub->add_option(
             "--supersample", o->supersample,
             "Shaded samples per pixel along each axis: 1 and, per k > 1, the default SG row, the sweep's finest "
             "configuration and the MC rows again")
          ->delimiter(',')
          ->check(CLI::Range(1, render::kMaxSupersample)));
  sweep_only.push_back(
      sub->add_option("--supersample-contrast", o->supersample_contrast,
                      "Per k > 1, an SG row at each of these contrasts (0: every sample of every pixel)")
          ->delimiter(',')
          ->check(CLI::Range(0.0, 1.0)));
  sub->add_option("--images", o->images_dir,
                  "Also write each scored row's car layer and shadow ratio (linear EXR) here");
  sweep_only.push_back(AddSetFlag(sub, "--no-lobe-modes", &o->lobe_modes, false, "Skip the warp × cosine rows"));
  sweep_only.push_back(AddSetFlag(sub, "--no-hd", &o->hd_row, false, "Skip the 1280x720 timing row"));
  AddSetFlag(sub, "--no-ground-bounce", &o->ground_bounce, false,
             "Light the references from their maps' lower half, not from Cycles' catcher plane");
  AddRenderSwitches(sub, &o->switches);
  sub->add_option("--out", o->out_dir, "Where the table, TSV and plot go (docs/benchmarks: the committed pages)")
      ->capture_default_str();
  sub->add_flag(
      "--report-only", o->report_only,
      "Rewrite the table and plot from the TSV already in --out (with --set: the run's --mc-samples and --mc-exact)");
  auto set = std::make_shared<BenchRenderSetOptions>();
  sub->add_option("--set", set->set_dir,
                  "Instead of the sweep: the default configuration over a generalization set (render_reference.py "
                  "--generalization-set's folder), as distributions by map, model, material, ground and region");
  sub->add_option("--envs", set->envs_dir, "The set's maps (default ../shared/data/env)");
  return [o, set, mc_samples, sweep_only] {
    if (set->set_dir.empty()) return RunBenchRender(*o);
    for (const CLI::Option* option : sweep_only)
      if (option->count() > 0)
        throw UsageError(option->get_name(), "is the sweep's; --set renders every image at the default configuration");
    if (o->report_only && (!o->only.empty() || !o->images_dir.empty()))
      throw UsageError("--report-only", "renders nothing: no --only or --images with it");
    set->report_only = o->report_only;
    set->only = o->only;
    if (mc_samples->count() > 0) set->mc_samples = *std::max_element(o->mc_samples.begin(), o->mc_samples.end());
    if (set->mc_samples > 0 && set->mc_samples < render::kStillSupersample * render::kStillSupersample)
      throw UsageError("--mc-samples", "with --set at least " +
                                           std::to_string(render::kStillSupersample * render::kStillSupersample) +
                                           ": a ray for each of a pixel's samples");
    set->mc_exact = o->mc_exact;
    set->mc_seed = o->mc_seed;
    set->ground_bounce = o->ground_bounce;
    set->switches = o->switches;
    set->out_dir = o->out_dir;
    set->images_dir = o->images_dir;
    return RunBenchRenderSet(*set);
  };
}

}  // namespace odvr::app
