// odvr bench render --set: the default configuration over a generalization set. Seven references
// from three maps were enough to tune against and too few to measure with; a set of every map ×
// model × material × ground says where the error lives, as distributions, not as a count.
#include "app/bench/bench_render_set.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <glm/matrix.hpp>
#include <iostream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "app/bench/render_rows.h"
#include "app/flags/render_switches.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/statistics.h"
#include "engine/gl/context.h"
#include "engine/image/image_io.h"

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

// One image of the set: its reference and what it varies.
struct SetImage {
  Reference ref;
  std::string model, map, material, ground;
  double ref_noise = 0;  // the reference's own: render_reference.py's mean_of_seeds_car_mean_rel
};

// A scored image: what it varies, its row and, when asked, the Monte-Carlo baseline's.
struct SetRow {
  std::string model, map, material, ground;
  double ref_noise = 0;
  Row row;
  std::optional<Row> mc;
};

// Which of a SetRow's rows a table reads.
using RowOf = const Row& (*)(const SetRow&);
const Row& SgRow(const SetRow& r) { return r.row; }
const Row& McRow(const SetRow& r) { return *r.mc; }

// One image's reference from its JSON (render_reference.py's Renderer.render). nullopt when its
// map is not in `envs_dir` (a clone without ../shared): left out, with a warning.
std::optional<SetImage> LoadSetImage(const fs::path& dir, const std::string& name, const fs::path& model,
                                     const fs::path& envs_dir, double catcher_albedo, double keep_below_horizon,
                                     bool ground_bounce) {
  const fs::path json_path = dir / (name + ".json");
  const nlohmann::json im = ReadJsonFile(json_path);
  try {
    SetImage s;
    s.model = dir.filename().string();
    s.material = im.at("material").get<std::string>();
    s.ground = im.at("ground").get<std::string>();
    if (im.contains("noise")) s.ref_noise = im.at("noise").value("mean_of_seeds_car_mean_rel", 0.0);
    const fs::path env = envs_dir / im.at("env").get<std::string>();
    s.map = env.stem().string();
    if (!fs::exists(env)) {
      spdlog::warn("bench render --set: {} left out: its map {} is absent", name, env.string());
      return std::nullopt;
    }
    Reference& r = s.ref;
    r.name = s.model + "/" + name;
    r.model = model;
    r.env = image::LoadImage(env, {.max_width = 8192, .require_equirect = true});
    image::SanitizePixels(&r.env);  // Cycles clamps a lossy EXR's negative pixels to 0 too
    if (s.ground != "catcher" && s.ground != "none")
      throw Error(json_path.string(), "ground '" + s.ground + "' is neither 'catcher' nor 'none'");
    r.ground = s.ground == "catcher";
    if (r.ground && ground_bounce) ReplaceLowerHemisphereByGround(&r.env, catcher_albedo, keep_below_horizon);
    const auto& m = im.at("env_world_from_env_odvr");
    for (int row = 0; row < 3; ++row)
      for (int c = 0; c < 3; ++c) r.world_from_env[c][row] = m.at(row).at(c).get<double>();
    const auto& files = im.at("files");
    r.rgb = image::LoadImage(dir / files.at("rgba").get<std::string>());
    // Without the catcher Cycles' shadow pass is empty: no shadow to score.
    if (r.ground) r.shadow = image::LoadImage(dir / files.at("shadow").get<std::string>());
    const sphere::EquirectImage mask = image::LoadImage(dir / files.at("mask").get<std::string>());
    r.mask.resize(static_cast<std::size_t>(mask.width) * mask.height);
    for (std::size_t i = 0; i < r.mask.size(); ++i) r.mask[i] = mask.rgb[3 * i];
    r.camera = CameraFromJson(im.at("camera"));
    // Where the script placed the model (stood on the ground); identity in sets made before it did.
    if (im.contains("world_from_model_odvr")) {
      r.world_from_model = Matrix4(im.at("world_from_model_odvr"));
      const glm::dmat3 linear(r.world_from_model);
      bool finite = true;
      for (int c = 0; c < 4; ++c)
        for (int k = 0; k < 4; ++k) finite = finite && std::isfinite(r.world_from_model[c][k]);
      if (!finite || !(std::abs(glm::determinant(linear)) > 1e-12))
        throw Error(json_path.string(), "world_from_model_odvr is not a finite, invertible placement");
    }
    if (s.material != "as-is") {
      const auto& mp = im.at("material_params");
      render::MaterialOverride paint;
      paint.brdfs = {material::MetallicRoughness{Vec3(mp.at("base_color")), mp.at("metallic").get<double>(),
                                                 mp.at("roughness").get<double>()}};
      try {
        material::CheckBrdf(paint.brdfs[0]);
      } catch (const Error& e) {
        throw Error(json_path.string(), e.what());
      }
      r.materials.push_back(std::move(paint));
    }
    if (r.rgb.width != r.camera.width || r.rgb.height != r.camera.height || r.mask.size() != r.rgb.rgb.size() / 3 ||
        (r.ground && r.shadow.width != r.rgb.width))
      throw Error(json_path.string(), "the image sizes disagree with the camera");
    return s;
  } catch (const nlohmann::json::exception& e) {
    throw Error(json_path.string(), std::string("a field is missing or malformed: ") + e.what());
  }
}

// Every model folder of the set (one with a set.json), in name order.
std::vector<fs::path> ModelFolders(const fs::path& set_dir) {
  if (!fs::is_directory(set_dir)) throw Error(set_dir.string(), "is not a directory");
  std::vector<fs::path> models;
  for (const auto& entry : fs::directory_iterator(set_dir))
    if (fs::exists(entry.path() / "set.json")) models.push_back(entry.path());
  std::sort(models.begin(), models.end());
  return models;
}

std::vector<SetImage> LoadSet(const fs::path& set_dir, const fs::path& envs_dir, bool ground_bounce,
                              const std::vector<std::string>& only) {
  // BenchRenderSetOptions::only, before anything is read: a map is loaded per image.
  const auto wanted = [&](const std::string& name) {
    return only.empty() || std::any_of(only.begin(), only.end(),
                                       [&](const std::string& part) { return name.find(part) != std::string::npos; });
  };
  const std::vector<fs::path> models = ModelFolders(set_dir);
  if (models.empty()) throw Error(set_dir.string(), "holds no model folder with a set.json");
  std::vector<SetImage> images;
  int named = 0;  // images that --only lets through, their maps present or not
  for (const fs::path& dir : models) {
    const fs::path set_json = dir / "set.json";
    const nlohmann::json js = ReadJsonFile(set_json);
    try {
      // A model inside the repository is named relative to it (render_reference.py).
      fs::path model = js.at("model").get<std::string>();
      if (model.is_relative()) model = fs::path(ODVR_SOURCE_DIR) / model;
      if (!fs::exists(model)) throw Error(set_json.string(), "its model " + model.string() + " is absent");
      const double albedo = js.at("catcher").at("albedo_seen_by_the_car").get<double>();
      const auto& box = js.at("model_box_odvr");
      const double keep = KeepBelowHorizon(0.5 * (box.at(0).at(1).get<double>() + box.at(1).at(1).get<double>()));
      for (const auto& entry : js.at("images")) {
        const std::string name = entry.get<std::string>();
        if (!wanted(dir.filename().string() + "/" + name)) continue;
        ++named;
        if (auto image = LoadSetImage(dir, name, model, envs_dir, albedo, keep, ground_bounce))
          images.push_back(std::move(*image));
      }
    } catch (const nlohmann::json::exception& e) {
      throw Error(set_json.string(), std::string("a field is missing or malformed: ") + e.what());
    }
  }
  if (named == 0 && !only.empty()) throw UsageError("--only", "names no image of " + set_dir.string());
  return images;
}

// What the set's set.json files say of it: the references' size and samples (render_reference.py's
// settings, one line per distinct kind) and what it left out of each model's images and why
// ("left_out", absent in sets made before it had any).
std::string SetNotes(const fs::path& set_dir) {
  std::map<std::string, std::vector<std::string>> settings;  // description → models
  std::string left_out;
  for (const fs::path& dir : ModelFolders(set_dir)) {
    const fs::path set_json = dir / "set.json";
    const nlohmann::json js = ReadJsonFile(set_json);
    const std::string model = dir.filename().string();
    try {
      if (js.contains("settings")) {
        const auto& g = js.at("settings");
        settings[fmt::format("{}×{} pixels, {} samples per pixel × {} seeds", g.at("size").at(0).get<int>(),
                             g.at("size").at(1).get<int>(), g.at("spp").get<int>(), g.at("seeds").size())]
            .push_back(model);
      }
      if (js.contains("left_out") && js.at("left_out").is_object())
        for (const auto& [kind, why] : js.at("left_out").items())
          left_out += "- " + model + ", " + kind + ": " + why.get<std::string>() + ".\n";
    } catch (const nlohmann::json::exception& e) {
      throw Error(set_json.string(), std::string("a field is missing or malformed: ") + e.what());
    }
  }
  std::string notes;
  for (const auto& [what, names] : settings) {
    std::string list;
    for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
    notes += "The references of " + list + ": " + what + ".\n";
  }
  if (!notes.empty()) notes += "\n";
  if (!left_out.empty())
    notes += "Left out of the set, with the reason `render_reference.py` gave:\n\n" + left_out + "\n";
  return notes;
}

std::string F(double v, int digits = 3) { return fmt::format("{:.{}f}", v, digits); }

// One line of a distribution table: the rows' count, the car's error (median, 90th percentile),
// its bias (median, and the 10th–90th percentile range), and the two regions' median errors.
std::string DistributionLine(const std::string& label, const std::vector<const SetRow*>& rows, RowOf row_of) {
  std::vector<double> err, bias, upper, lower, ms, noise;
  for (const SetRow* r : rows) {
    const Row& row = row_of(*r);
    noise.push_back(r->ref_noise);
    err.push_back(row.mean_rel);
    bias.push_back(row.bias);
    upper.push_back(row.upper_mean_rel);
    lower.push_back(row.lower_mean_rel);
    ms.push_back(row.shade_ms);
  }
  // A TSV written before a column existed reads it as NaN: "–", not a median of what is unknown.
  const auto median = [](const std::vector<double>& v) {
    return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); }) ? F(Median(v)) : "–";
  };
  return fmt::format("| {} | {} | {} | {} | {} | {}–{} | {} | {} | {} | {} |\n", label, rows.size(), F(Median(err)),
                     F(Quantile(err, 0.9)), F(Median(bias)), F(Quantile(bias, 0.1)), F(Quantile(bias, 0.9)),
                     median(upper), F(Median(lower)), F(Median(noise)), F(Median(ms), 1));
}

// A table of the rows grouped by `key`, one line per value and one for all.
std::string GroupTable(const std::string& title, const std::vector<SetRow>& rows,
                       const std::function<std::string(const SetRow&)>& key, RowOf row_of = SgRow) {
  std::map<std::string, std::vector<const SetRow*>> groups;
  for (const SetRow& r : rows) groups[key(r)].push_back(&r);
  std::ostringstream md;
  md << "\n### By " << title << "\n\n| " << title
     << " | images | error median | error p90 | bias median | bias p10–p90 | upper half: error | lower quarter: "
        "error | reference noise | shade ms |\n|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& [value, group] : groups) md << DistributionLine(value, group, row_of);
  return md.str();
}

// The targets over the whole set: the error's median and 90th percentile, and every material's
// median bias, computed from the rows.
std::string SetTargets(const std::vector<SetRow>& rows) {
  std::vector<double> err;
  std::map<std::string, std::vector<double>> bias_by_material;
  for (const SetRow& r : rows) {
    err.push_back(r.row.mean_rel);
    bias_by_material[r.material].push_back(r.row.bias);
  }
  const double median = Median(err), p90 = Quantile(err, 0.9);
  int materials_in = 0;
  std::string biases;
  for (const auto& [material, bias] : bias_by_material) {
    const double b = Median(bias);
    materials_in += b >= 0.97 && b <= 1.03;
    biases += (biases.empty() ? "" : ", ") + material + " " + F(b);
  }
  return fmt::format(
      "\n## Targets, from the rows above\n\n"
      "- Median car-pixel error ≤ 0.08: **{}** ({}).\n"
      "- 90th percentile ≤ 0.12: **{}** ({}).\n"
      "- Every material's median bias within 0.97–1.03: **{}** ({} of {}: {}).\n",
      median <= 0.08 ? "met" : "not met", F(median), p90 <= 0.12 ? "met" : "not met", F(p90),
      materials_in == static_cast<int>(bias_by_material.size()) ? "met" : "not met", materials_in,
      bias_by_material.size(), biases);
}

// The Monte-Carlo baseline on the same images, when it was asked for: its error is the
// reference's noise plus what the renderer's inputs (the map, the materials, the voxels unless
// exact) miss, so SG's error above it is the SG model's own; the shade times give SG's speed-up.
std::string McSection(const std::vector<SetRow>& rows, const BenchRenderSetOptions& o) {
  if (o.mc_samples <= 0) return "";
  std::vector<const SetRow*> all;
  for (const SetRow& r : rows) all.push_back(&r);
  std::ostringstream md;
  md << "\n## The Monte-Carlo baseline on the same images\n\n"
     << o.mc_samples << " samples per pixel (over every one of its " << render::kStillSupersample << "×"
     << render::kStillSupersample << " samples), seed " << o.mc_seed << ", visibility "
     << (o.mc_exact ? "by shadow rays against the triangles" : "through the same voxels as the SG rows")
     << ", the same lighting map.\n\n| set | images | error median | error p90 | bias median | bias p10–p90 | "
        "upper half: error | lower quarter: error | reference noise | shade ms |\n"
        "|---|---|---|---|---|---|---|---|---|---|\n"
     << DistributionLine("all", all, McRow)
     << GroupTable(
            "material", rows, [](const SetRow& r) { return r.material; }, McRow)
     << GroupTable(
            "model", rows, [](const SetRow& r) { return r.model; }, McRow);
  return md.str();
}

void WriteSetReport(const std::vector<SetRow>& rows, const BenchRenderSetOptions& o, const std::string& machine) {
  fs::create_directories(o.out_dir);
  std::ostringstream t;
  t << "# odvr bench render --set on " << machine
    << "\n# model\tmap\tmaterial\tground\tmean_rel\trel_l1\tbias\tupper_mean_rel\tupper_bias\tlower_mean_rel\t"
       "lower_bias\tssim\tshadow_mae\tcar_pixels\tshade_ms\ttotal_ms\tref_noise"
    << (o.mc_samples > 0 ? "\tmc_mean_rel\tmc_bias\tmc_lower_mean_rel\tmc_shade_ms\tmc_upper_mean_rel\n" : "\n");
  for (const SetRow& s : rows) {
    const Row& r = s.row;
    t << s.model << "\t" << s.map << "\t" << s.material << "\t" << s.ground << "\t" << r.mean_rel << "\t" << r.rel_l1
      << "\t" << r.bias << "\t" << r.upper_mean_rel << "\t" << r.upper_bias << "\t" << r.lower_mean_rel << "\t"
      << r.lower_bias << "\t" << r.ssim << "\t" << r.shadow_mae << "\t" << r.car_pixels << "\t" << r.shade_ms << "\t"
      << r.total_ms << "\t" << s.ref_noise;
    if (s.mc)
      t << "\t" << s.mc->mean_rel << "\t" << s.mc->bias << "\t" << s.mc->lower_mean_rel << "\t" << s.mc->shade_ms
        << "\t" << s.mc->upper_mean_rel;
    t << "\n";
  }
  WriteTextAtomically(fs::path(o.out_dir) / "render_set.tsv", t.str());

  std::vector<const SetRow*> all;
  for (const SetRow& r : rows) all.push_back(&r);
  std::ostringstream md;
  md << "# Renderer over a generalization set: error distributions\n\n"
     << "Made by `odvr bench render --set " << o.set_dir
     << (o.mc_samples > 0 ? " --mc-samples " + std::to_string(o.mc_samples) + (o.mc_exact ? " --mc-exact" : "") : "")
     << "` on " << machine << ". The set: "
     << "`tools/blender/render_reference.py --generalization-set` (every map × model × its own materials, a glossy "
        "and a diffuse paint × the catcher under the car or none; the model stood on the ground). Each image rendered "
        "once at the default "
        "configuration ("
     << kDefaultLevels << " levels, " << kDefaultCones << " cones, " << kDefaultVoxels << "³ voxels, lobes `"
     << DefaultLobes() << "`, " << render::kStillSupersample << "×" << render::kStillSupersample
     << " samples where a pixel needs them, contrast " << render::RenderOptions{}.supersample_contrast
     << ", as `odvr render`). Errors as `render.md` defines them, on car pixels: `error` = mean relative "
        "error, `bias` = ΣY / ΣY_ref; the regions split the car's silhouette by image rows: its upper half and "
        "its lower quarter (sills, tyres, the lower bumper). `reference noise`: the reference's own Monte-Carlo noise "
        "as a mean relative error on car pixels "
        "(from its two seeds' renders: |a − b| / √2 per pixel, over √2 for their mean); an error near it is "
        "noise, not the model.\n\n"
     << SetNotes(o.set_dir)
     << "| set | images | error median | error p90 | bias median | bias p10–p90 | upper half: error | lower "
        "quarter: error | reference noise | shade ms |\n|---|---|---|---|---|---|---|---|---|---|\n"
     << DistributionLine("all", all, SgRow) << GroupTable("material", rows, [](const SetRow& r) { return r.material; })
     << GroupTable("ground", rows, [](const SetRow& r) { return r.ground; })
     << GroupTable("model", rows, [](const SetRow& r) { return r.model; })
     << GroupTable("map", rows, [](const SetRow& r) { return r.map; }) << SetTargets(rows) << McSection(rows, o)
     << "\nEvery image's row is in `render_set.tsv`; `render_set.png` plots the error's cumulative distribution "
        "over the whole car and its two regions.\n\n![error distributions](render_set.png)\n";
  WriteTextAtomically(fs::path(o.out_dir) / "render_set.md", md.str());

  std::ostringstream gp;
  // A log axis: most images lie between 0.02 and 0.5, a model the renderer cannot draw (a glass it
  // renders opaque) reaches tens.
  gp << "set datafile separator '\\t'\nset key bottom right\nset grid\nset yrange [0:1]\nset logscale x\n"
     << "set title 'car pixels: share of the set at or under an error'\nset xlabel 'mean relative error'\n"
     << "set ylabel 'share of the images'\nplot 'render_set.tsv' using 5:(1) smooth cnormal lw 2 title 'whole car', "
     << "'' using 8:(1) smooth cnormal lw 2 title 'upper half', '' using 10:(1) smooth cnormal lw 2 title "
        "'lower quarter'\n";
  WritePlot(o.out_dir, "render_set", 900, 560, gp.str(), "bench render --set");
}

// The rows of a render_set.tsv that WriteSetReport wrote, and its machine line: 17 columns, 22
// with the Monte-Carlo baseline's (21 before its upper-half error was written: NaN here).
std::vector<SetRow> ReadSetRows(const fs::path& tsv, bool* with_mc, std::string* machine) {
  std::ifstream in(tsv);
  if (!in) throw Error(tsv.string(), "cannot be read");
  const std::string tag = "# odvr bench render --set on ";
  std::vector<SetRow> rows;
  *with_mc = false;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(tag, 0) == 0) *machine = line.substr(tag.size());
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> v;
    std::istringstream fields(line);
    for (std::string f; std::getline(fields, f, '\t');) v.push_back(f);
    if (v.size() != 17 && v.size() != 21 && v.size() != 22)
      throw Error(tsv.string(), "a row without 17, 21 or 22 columns: " + line);
    if (!rows.empty() && (v.size() > 17) != *with_mc) throw Error(tsv.string(), "rows with and without the MC columns");
    *with_mc = v.size() > 17;
    try {
      SetRow s{v[0], v[1], v[2], v[3], std::stod(v[16]), {}, std::nullopt};
      Row& r = s.row;
      r.mean_rel = std::stod(v[4]);
      r.rel_l1 = std::stod(v[5]);
      r.bias = std::stod(v[6]);
      r.upper_mean_rel = std::stod(v[7]);
      r.upper_bias = std::stod(v[8]);
      r.lower_mean_rel = std::stod(v[9]);
      r.lower_bias = std::stod(v[10]);
      r.ssim = std::stod(v[11]);
      r.shadow_mae = std::stod(v[12]);
      r.car_pixels = std::stoi(v[13]);
      r.shade_ms = std::stod(v[14]);
      r.total_ms = std::stod(v[15]);
      if (*with_mc) {
        Row mc;
        mc.mean_rel = std::stod(v[17]);
        mc.bias = std::stod(v[18]);
        mc.lower_mean_rel = std::stod(v[19]);
        mc.shade_ms = std::stod(v[20]);
        mc.upper_mean_rel = v.size() > 21 ? std::stod(v[21]) : std::numeric_limits<double>::quiet_NaN();
        s.mc = mc;
      }
      // Only the MC rows' upper-half error may be unknown (NaN, from an older TSV): a median over a
      // NaN would be garbage on the page.
      for (double x : {r.mean_rel, r.rel_l1, r.bias, r.upper_mean_rel, r.lower_mean_rel, r.shade_ms, s.ref_noise})
        if (!std::isfinite(x)) throw Error(tsv.string(), "a value that is not a finite number in: " + line);
      if (s.mc && !(std::isfinite(s.mc->mean_rel) && std::isfinite(s.mc->bias) && std::isfinite(s.mc->shade_ms)))
        throw Error(tsv.string(), "a value that is not a finite number in: " + line);
      rows.push_back(std::move(s));
    } catch (const Error&) {
      throw;
    } catch (const std::exception&) {
      throw Error(tsv.string(), "a number that does not parse in: " + line);
    }
  }
  if (rows.empty()) throw Error(tsv.string(), "holds no row");
  return rows;
}

}  // namespace

int RunBenchRenderSet(const BenchRenderSetOptions& o) {
  if (o.report_only) {
    bool with_mc = false;
    std::string machine = "unknown";
    const std::vector<SetRow> rows = ReadSetRows(fs::path(o.out_dir) / "render_set.tsv", &with_mc, &machine);
    // The page names the run's command and its Monte-Carlo settings: they must be the TSV's.
    if (with_mc != (o.mc_samples > 0))
      throw UsageError("--report-only", with_mc ? "the TSV has the Monte-Carlo columns: give the run's --mc-samples"
                                                : "the TSV has no Monte-Carlo columns: drop --mc-samples");
    WriteSetReport(rows, o, machine);
    std::cout << "bench render --set: report rewritten from " << rows.size() << " rows\n";
    return 0;
  }
  const fs::path envs =
      o.envs_dir.empty() ? fs::path(ODVR_SOURCE_DIR) / ".." / "shared" / "data" / "env" : fs::path(o.envs_dir);
  const std::vector<SetImage> images = LoadSet(o.set_dir, envs, o.ground_bounce, o.only);
  if (images.empty()) throw UsageError("--set " + o.set_dir, "no image of the set has its map in " + envs.string());
  gl::HeadlessContext context;
  std::string machine = BenchMachineDescription() + ", GL: " + context.Info().renderer;
  for (const std::string& flag : NonDefaultRenderSwitches(o.switches)) machine += "; " + flag;
  const material::LobeOptions lobes = render::RenderOptions{}.lobes;
  // The still's sampling, adaptive at the renderer's contrast; the Monte-Carlo rows spread the
  // same rays per pixel over every sample.
  const double contrast = render::RenderOptions{}.supersample_contrast;
  std::vector<SetRow> rows;
  BenchProgress progress("bench render --set", static_cast<long>(images.size()));
  for (const SetImage& s : images) {
    SetRow r{s.model, s.map, s.material, s.ground, s.ref_noise, {}, std::nullopt};
    r.row = RenderRow(o.switches, s.ref, "sg", kDefaultLevels, kDefaultCones, kDefaultVoxels, 0, lobes, 0, 0, 1,
                      o.images_dir, render::kStillSupersample, contrast);
    if (o.mc_samples > 0)
      r.mc = RenderRow(o.switches, s.ref, o.mc_exact ? "mc-exact" : "mc", kDefaultLevels, 1, kDefaultVoxels,
                       o.mc_samples, lobes, 0, 0, o.mc_seed, o.images_dir, render::kStillSupersample, contrast);
    if (r.row.car_pixels == 0) {
      spdlog::warn("bench render --set: {} has no car pixel in common with its reference: left out", s.ref.name);
    } else {
      rows.push_back(std::move(r));
    }
    progress.Step(s.ref.name);
  }
  if (rows.empty()) throw Error("--set " + o.set_dir, "no image could be scored");
  WriteSetReport(rows, o, machine);
  std::cout << "bench render --set: " << rows.size() << " images; wrote " << o.out_dir
            << "/render_set.md, render_set.tsv, render_set.png\n";
  return 0;
}

}  // namespace odvr::app
