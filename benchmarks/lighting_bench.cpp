// engine/lighting: the per-frame work of turning a video frame into SG lighting (the residual
// transform, the peak detector) and the spherical-harmonics baseline, on a real map. The error
// counters are computed once per configuration, untimed, on the model the timed call produces,
// with the evaluator `odvr bench light` uses (errors of the light convolved with a clamped cosine
// and an SG lobe of λ = 20, against the native map), so they read as that bench's columns.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <tuple>

#include "benchmarks/bench_data.h"
#include "engine/lighting/lighting_builder.h"
#include "engine/lighting/peak_detector.h"
#include "engine/lighting/reference_fits.h"
#include "engine/lighting/residual_transform.h"
#include "engine/lighting/sg.h"
#include "engine/sphere/resample.h"

namespace odvr::bench {
namespace {

const EnvMap* ParkOrSkip(benchmark::State& state) {
  std::string why;
  const EnvMap* park = Park(&why);
  if (!park) state.SkipWithError(why.c_str());
  return park;
}

// Args: frame width, HEALPix levels. Every level is run (no early stop), as `odvr bench light`
// measures each level count; the overlap lists are built by an untimed first call, as playback
// builds them once.
void BM_ResidualTransform(benchmark::State& state) {
  const EnvMap* park = ParkOrSkip(state);
  if (!park) return;
  const int width = static_cast<int>(state.range(0)), levels = static_cast<int>(state.range(1));
  const auto& frame = ParkFrame(*park, width);
  struct Setup {
    std::unique_ptr<lighting::ResidualTransform> transform;
    lighting::LightingErrors errors;
    int sgs = 0;
  };
  static std::map<std::pair<int, int>, Setup> setups;
  Setup& setup = setups[{width, levels}];
  if (!setup.transform) {
    lighting::ResidualTransformOptions options;
    options.levels = levels;
    options.stop_threshold = 0;
    setup.transform = std::make_unique<lighting::ResidualTransform>(options);
    const lighting::SgLighting model = setup.transform->Run(frame);
    setup.errors = park->evaluator->Evaluate(model);
    setup.sgs = model.sg_count();
  }
  for (auto _ : state) {
    lighting::SgLighting model = setup.transform->Run(frame);
    benchmark::DoNotOptimize(model.levels.data());
  }
  state.counters["sgs"] = setup.sgs;
  state.counters["diffuse"] = setup.errors.diffuse;
  state.counters["glossy20"] = setup.errors.glossy20;
}
BENCHMARK(BM_ResidualTransform)
    ->ArgNames({"width", "levels"})
    ->ArgsProduct({{1024, 2048}, {3, 5}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Args: frame width, HEALPix levels, peaks (0/1). The whole frame → model path that `odvr bench
// light` times as its `sg` and `sg+peaks` rows (LightingBuilder::Build): the bad-pixel check, the
// peak detector with its fused box pass, the transform.
void BM_LightingBuilder(benchmark::State& state) {
  const EnvMap* park = ParkOrSkip(state);
  if (!park) return;
  const int width = static_cast<int>(state.range(0)), levels = static_cast<int>(state.range(1));
  const bool peaks = state.range(2) != 0;
  const auto& frame = ParkFrame(*park, width);
  struct Setup {
    std::unique_ptr<lighting::LightingBuilder> builder;
    lighting::LightingErrors errors;
    int sgs = 0;
  };
  static std::map<std::tuple<int, int, bool>, Setup> setups;
  Setup& setup = setups[{width, levels, peaks}];
  if (!setup.builder) {
    lighting::LightingOptions options;
    options.transform.levels = levels;
    options.transform.stop_threshold = 0;
    options.detect_peaks = peaks;
    setup.builder = std::make_unique<lighting::LightingBuilder>(options);
    const lighting::SgLighting model = setup.builder->Build(frame);
    setup.errors = park->evaluator->Evaluate(model);
    setup.sgs = model.sg_count();
  }
  double peaks_ms = 0, prepare_ms = 0, transform_ms = 0, correction_ms = 0;
  std::vector<double> level_ms(static_cast<std::size_t>(levels), 0.0);
  for (auto _ : state) {
    lighting::LightingReport report;
    lighting::SgLighting model = setup.builder->Build(frame, &report);
    benchmark::DoNotOptimize(model.levels.data());
    peaks_ms += report.peaks_ms;
    prepare_ms += report.transform.prepare_ms;
    transform_ms += report.transform.total_ms;
    correction_ms += report.transform.correction_ms;
    for (const auto& l : report.transform.levels)
      if (l.level < levels) level_ms[static_cast<std::size_t>(l.level)] += l.ms;
  }
  // Where the time goes, as means over the iterations.
  const double n = std::max<double>(1, static_cast<double>(state.iterations()));
  state.counters["peaks_ms"] = peaks_ms / n;
  state.counters["prepare_ms"] = prepare_ms / n;
  state.counters["transform_ms"] = transform_ms / n;
  state.counters["correction_ms"] = correction_ms / n;
  for (int l = 0; l < levels; ++l)
    state.counters["level" + std::to_string(l) + "_ms"] = level_ms[static_cast<std::size_t>(l)] / n;
  state.counters["sgs"] = setup.sgs;
  state.counters["diffuse"] = setup.errors.diffuse;
  state.counters["glossy20"] = setup.errors.glossy20;
}
BENCHMARK(BM_LightingBuilder)
    ->ArgNames({"width", "levels", "peaks"})
    ->ArgsProduct({{1024, 2048}, {3, 5}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Arg: frame width. Counters: the peaks found and how well their SGs stand for the light they
// took out of the frame (frame − residue), in energy and in shape (solid-angle-weighted relative
// L2 of the SGs rendered on the frame's grid against it).
void BM_DetectPeaks(benchmark::State& state) {
  const EnvMap* park = ParkOrSkip(state);
  if (!park) return;
  const int width = static_cast<int>(state.range(0));
  const auto& frame = ParkFrame(*park, width);
  struct Setup {
    bool done = false;
    int peaks = 0, sgs = 0;
    double energy_err = 0, shape_l2 = 0;
  };
  static std::map<int, Setup> setups;
  Setup& setup = setups[width];
  if (!setup.done) {
    const lighting::PeakDetection d = lighting::DetectPeaks(frame);
    sphere::EquirectImage removed(frame.width, frame.height), fitted(frame.width, frame.height);
    for (std::size_t i = 0; i < removed.rgb.size(); ++i) removed.rgb[i] = frame.rgb[i] - d.residue.rgb[i];
    double fit_energy = 0;
    for (const auto& peak : d.peaks)
      for (const auto& g : peak.sgs) {
        lighting::AddSgToImage(g, &fitted, 1e-9);
        for (int c = 0; c < 3; ++c) fit_energy += lighting::Integral(lighting::Sg{g.axis, g.lambda, g.amplitude[c]});
        ++setup.sgs;
      }
    setup.peaks = static_cast<int>(d.peaks.size());
    const double removed_energy = SphereIntegral(removed);
    setup.energy_err = removed_energy > 0 ? std::abs(fit_energy - removed_energy) / removed_energy : 0;
    setup.shape_l2 = removed_energy > 0 ? lighting::RelativeL2(removed, fitted) : 0;
    setup.done = true;
  }
  for (auto _ : state) {
    lighting::PeakDetection d = lighting::DetectPeaks(frame);
    benchmark::DoNotOptimize(d.peaks.data());
  }
  state.counters["peaks"] = setup.peaks;
  state.counters["sgs"] = setup.sgs;
  state.counters["energy_err"] = setup.energy_err;
  state.counters["shape_l2"] = setup.shape_l2;
}
BENCHMARK(BM_DetectPeaks)->ArgName("width")->Arg(1024)->Arg(2048)->Unit(benchmark::kMillisecond)->UseRealTime();

// Args: grid width the projection runs on (the 1024-wide frame area-resampled to it, untimed),
// SH order. `odvr bench light` projects on 256 wide.
void BM_ProjectSphericalHarmonics(benchmark::State& state) {
  const EnvMap* park = ParkOrSkip(state);
  if (!park) return;
  const int width = static_cast<int>(state.range(0)), order = static_cast<int>(state.range(1));
  struct Setup {
    sphere::EquirectImage grid;
    lighting::LightingErrors errors;
  };
  static std::map<std::pair<int, int>, Setup> setups;
  Setup& setup = setups[{width, order}];
  if (setup.grid.empty()) {
    const auto& frame = ParkFrame(*park, 1024);
    setup.grid = width == frame.width ? frame : sphere::ResampleArea(frame, width, width / 2);
    const auto recon =
        lighting::ProjectSphericalHarmonics(setup.grid, order).Reconstruct(park->native.width, park->native.height);
    setup.errors = park->evaluator->Evaluate(
        lighting::LightingErrorEvaluator::ConvolveImage(recon, park->evaluator->directions()), recon);
  }
  for (auto _ : state) {
    lighting::ShModel sh = lighting::ProjectSphericalHarmonics(setup.grid, order);
    benchmark::DoNotOptimize(sh.coefficients.data());
  }
  state.counters["diffuse"] = setup.errors.diffuse;
  state.counters["glossy20"] = setup.errors.glossy20;
}
BENCHMARK(BM_ProjectSphericalHarmonics)
    ->ArgNames({"width", "order"})
    ->Args({256, 8})
    ->Args({1024, 8})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace odvr::bench
