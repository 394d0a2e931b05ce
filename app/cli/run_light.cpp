// odvr light: one equirect frame → the lighting model the renderer loads, with what each level
// cost and what it bought (the convolved errors of the model truncated after that level).
#include <spdlog/spdlog.h>

#include <glm/geometric.hpp>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "app/cli/commands.h"
#include "app/flags/transform_tuning.h"
#include "core/error.h"
#include "engine/gl/context.h"
#include "engine/image/image_io.h"
#include "engine/lighting/lighting_builder.h"
#include "engine/lighting/lighting_errors.h"
#include "engine/lighting/residual_transform_gpu.h"

namespace odvr::app {
namespace {

struct LightOptions {
  std::string input;
  int levels = 5;
  double threshold = 0.01;
  lighting::ResidualTransformOptions transform;  // the tuning flags (AddTransformTuning)
  bool no_peaks = false;
  std::string device = "cpu";
  std::string out;
  std::string preview;
  bool json = false;
};

nlohmann::json ErrorsJson(const lighting::LightingErrors& e) {
  return {{"rel_l2_error", e.rel_l2},
          {"diffuse_error", e.diffuse},
          {"glossy20_error", e.glossy20},
          {"glossy200_error", e.glossy200}};
}

int RunLight(const LightOptions& o) {
  const sphere::EquirectImage frame = image::LoadImage(o.input, {.max_width = 8192, .require_equirect = true});
  lighting::LightingOptions options;
  options.transform = o.transform;
  options.transform.levels = o.levels;
  options.transform.stop_threshold = o.threshold;
  options.detect_peaks = !o.no_peaks;

  // The GPU path needs a context for as long as the transform lives.
  std::unique_ptr<gl::HeadlessContext> context;
  std::unique_ptr<lighting::ResidualTransformGpu> gpu;
  if (o.device == "gpu") {
    context = std::make_unique<gl::HeadlessContext>();
    gpu = std::make_unique<lighting::ResidualTransformGpu>(options.transform);
  }
  lighting::LightingBuilder builder(options);
  // The first build makes what every later frame reuses (each level's overlap lists; on the GPU
  // its programs and buffers): 0.7 s of start-up where a frame of sky.exr then takes 10 ms, and
  // on the GPU the shaders' compilation. The frame is built again and that build's times are
  // the ones reported, as a player meets them every frame; the first's total is `first_total_ms`.
  lighting::LightingReport first;
  builder.Build(frame, &first, gpu.get());
  lighting::LightingReport report;
  const lighting::SgLighting model = builder.Build(frame, &report, gpu.get());

  if (!o.out.empty()) model.Save(o.out);
  if (!o.preview.empty()) image::SaveImage(o.preview, model.Reconstruct(frame.width, frame.height));

  // Errors after each level: the model truncated there (peaks and constant always in).
  const lighting::LightingErrorEvaluator evaluator(frame);
  nlohmann::json levels = nlohmann::json::array();
  lighting::SgLighting prefix = model;
  prefix.levels.clear();
  std::size_t next_kept = 0;
  for (const auto& lr : report.transform.levels) {
    if (next_kept < model.levels.size() && model.levels[next_kept].level == lr.level)
      prefix.levels.push_back(model.levels[next_kept++]);
    nlohmann::json l = {
        {"level", lr.level}, {"srbfs_total", lr.srbfs_total}, {"srbfs_kept", lr.srbfs_kept},      {"lambda", lr.lambda},
        {"ms", lr.ms},       {"grid", {lr.width, lr.height}}, {"residue_after", lr.residue_after}};
    l.update(ErrorsJson(evaluator.Evaluate(prefix)));
    levels.push_back(l);
  }
  const lighting::LightingErrors final_errors = evaluator.Evaluate(model);

  nlohmann::json peaks = {{"count", model.peaks.size()}, {"ms", report.peaks_ms}, {"sgs", nlohmann::json::array()}};
  for (const auto& p : model.peaks)
    peaks["sgs"].push_back({{"direction", {p.axis.x, p.axis.y, p.axis.z}},
                            {"lambda", p.lambda},
                            {"amplitude", {p.amplitude.x, p.amplitude.y, p.amplitude.z}}});
  if (report.peak_detection.ldr) {
    peaks["ldr_clipped_estimate"] = true;
    peaks["ldr_glow"] = {report.peak_detection.ldr_glow.x, report.peak_detection.ldr_glow.y};
  }

  if (o.json) {
    nlohmann::json out = {{"input", o.input},
                          {"size", {frame.width, frame.height}},
                          {"device", report.transform.device},
                          {"levels", levels},
                          {"peaks", peaks},
                          {"constant", {model.constant.x, model.constant.y, model.constant.z}},
                          {"sg_count", model.sg_count()},
                          {"stop_reason", report.transform.stop_reason},
                          {"correction_ms", report.transform.correction_ms},
                          {"total_ms", report.total_ms},
                          {"first_total_ms", first.total_ms}};
    out.update(ErrorsJson(final_errors));
    std::cout << out.dump(2) << "\n";
  } else {
    std::cout << o.input << ": " << frame.width << "x" << frame.height << ", " << model.sg_count() << " SGs ("
              << model.peaks.size() << " peak SGs) in " << report.total_ms << " ms on " << report.transform.device
              << " (the first build, which makes what later frames reuse, " << first.total_ms << " ms); "
              << report.transform.stop_reason << "\n";
    // An LDR frame's suns are clipped: their energy is a prior's estimate, not a measurement, and
    // the errors below count it against the clipped pixels.
    if (report.peak_detection.ldr)
      std::cout << "LDR frame (no value above 1): "
                << (model.peaks.empty() ? std::string("no clipped region looks like a sun")
                                        : std::to_string(model.peaks.size()) +
                                              " peak SGs estimated from clipped pixels by the sky-to-sun prior "
                                              "(their energy is a guess; the errors below count it against the "
                                              "clipped frame)")
                << "\n";
    std::cout << "level  kept/total     lambda      ms   diffuse  glossy20 glossy200   rel_l2\n";
    for (const auto& l : levels)
      std::cout << fmt::format("{:5d} {:5d}/{:<5d} {:9.2f} {:7.2f} {:8.4f} {:9.4f} {:9.4f} {:8.4f}\n",
                               l["level"].get<int>(), l["srbfs_kept"].get<int>(), l["srbfs_total"].get<int>(),
                               l["lambda"].get<double>(), l["ms"].get<double>(), l["diffuse_error"].get<double>(),
                               l["glossy20_error"].get<double>(), l["glossy200_error"].get<double>(),
                               l["rel_l2_error"].get<double>());
    if (!o.out.empty()) std::cout << "lighting model written to " << o.out << "\n";
    if (!o.preview.empty()) std::cout << "reconstruction written to " << o.preview << "\n";
  }
  return 0;
}

}  // namespace

CommandFn AddLight(CLI::App* sub) {
  auto o = std::make_shared<LightOptions>();
  sub->add_option("input", o->input, "Equirect frame (EXR, HDR, PNG, JPEG)")->required();
  sub->add_option("--levels", o->levels, "HEALPix levels to fit at most (1..6)")
      ->check(CLI::Range(1, 6))
      ->capture_default_str();
  sub->add_option("--threshold", o->threshold, "Stop when the mean |residue| falls below this × mean radiance")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  AddTransformTuning(sub, &o->transform);
  sub->add_flag("--no-peaks", o->no_peaks, "Do not take suns and lamps out as free-form SGs first");
  sub->add_option("--device", o->device, "Where the residual transform runs")
      ->check(CLI::IsMember({"cpu", "gpu"}))
      ->capture_default_str();
  sub->add_option("--out", o->out, "Write the lighting model (lighting.json)");
  sub->add_option("--preview", o->preview, "Write the model's reconstruction as an image (EXR keeps HDR)");
  sub->add_flag("--json", o->json, "Print one JSON object");
  return [o] { return RunLight(*o); };
}

}  // namespace odvr::app
