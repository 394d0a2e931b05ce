// odvr bench light: for every equirect map, the residual transform's four errors and
// its time per level count, with and without peaks, on the CPU (and the GPU when asked), beside
// the least-squares optimum on the same SG basis and spherical harmonics of orders 2–16.
// Writes a Markdown table, the raw rows (TSV) and a PNG plot of error against time.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include "app/bench/bench_common.h"
#include "app/bench/bench_light.h"
#include "app/flags/command_flags.h"
#include "app/flags/transform_tuning.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "engine/gl/context.h"
#include "engine/gl/objects.h"
#include "engine/image/image_io.h"
#include "engine/lighting/lighting_builder.h"
#include "engine/lighting/lighting_errors.h"
#include "engine/lighting/peak_detector.h"
#include "engine/lighting/reference_fits.h"
#include "engine/lighting/residual_transform_gpu.h"
#include "engine/sphere/resample.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;
using lighting::LightingErrors;

constexpr int kMaxRuns = 500;

// The ms of `run` over at least o.repeats calls, continued until o.min_time_ms have passed.
template <class Run>
std::vector<double> TimedRuns(const BenchLightOptions& o, Run run) {
  std::vector<double> times;
  double total = 0;
  while (static_cast<int>(times.size()) < o.repeats ||
         (total < o.min_time_ms && static_cast<int>(times.size()) < kMaxRuns)) {
    times.push_back(run());
    total += times.back();
  }
  return times;
}

// Untimed calls of `run` until `ms` have passed, at least one (it builds the overlap lists). A GPU
// left idle through the CPU rows lowers its clocks, and the first calls after pay for it: without
// the warm-up, rows with fewer levels read slower than rows with more.
template <class Run>
void WarmUp(double ms, Run run) {
  const auto start = std::chrono::steady_clock::now();
  do run();
  while (std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count() < ms);
}

struct Row {
  std::string map;
  int width = 0;
  std::string method;  // "sg", "sg+peaks", "least-squares", "least-squares+peaks", "sh"
  std::string device;
  int param = 0;  // levels (SG) or order (SH)
  int coefficients = 0;
  double ms = 0;
  LightingErrors e;
};

std::vector<std::string> DefaultMaps() {
  std::vector<std::string> maps;
  const fs::path dir = fs::path(ODVR_SOURCE_DIR) / ".." / "shared" / "data" / "env";
  if (fs::is_directory(dir))
    for (const auto& entry : fs::directory_iterator(dir))
      if (entry.path().extension() == ".exr") maps.push_back(entry.path().lexically_normal().string());
  std::sort(maps.begin(), maps.end());
  return maps;
}

std::string Fmt(double v) { return fmt::format("{:.4f}", v); }

// LightingBuilder's detection: on the frame area-resampled to the peak grid when it is wider.
lighting::PeakDetection DetectPeaksAsTheBuilderDoes(const sphere::EquirectImage& frame) {
  const lighting::LightingOptions defaults;
  if (frame.width <= defaults.peak_grid_width) return lighting::DetectPeaks(frame, defaults.peaks);
  const int w = defaults.peak_grid_width;
  const int h = static_cast<int>(std::lround(static_cast<double>(frame.height) * w / frame.width));
  return lighting::DetectPeaks(sphere::ResampleArea(frame, w, h), defaults.peaks);
}

// The bench's rows, found by (map, width, method, device, param), and the maps and SG widths
// they cover.
struct RowIndex {
  explicit RowIndex(const std::vector<Row>& all) : rows(all) {
    for (const auto& r : rows) {
      maps.insert(r.map);
      if (r.method == "sg") widths.insert(r.width);
    }
  }
  const Row* Find(const std::string& map, int width, const std::string& method, const std::string& device,
                  int param) const {
    for (const auto& r : rows)
      if (r.map == map && r.width == width && r.method == method && r.device == device && r.param == param) return &r;
    return nullptr;
  }
  int Widest() const { return widths.empty() ? 0 : *widths.rbegin(); }

  const std::vector<Row>& rows;
  std::set<std::string> maps;
  std::set<int> widths;
};

// Target 1: through level 4 (levels = 5), each convolved error within 1.5x of the least-squares
// `optimum`, >= 100x faster; per map at the widest width.
void WriteOptimumRatios(const RowIndex& index, const std::string& method, const std::string& optimum,
                        std::ostream& md) {
  md << "| map | diffuse | glossy20 | glossy200 | time ratio (LS / transform) |\n|---|---|---|---|---|\n";
  std::vector<double> worst;
  for (const auto& m : index.maps) {
    const Row* sg = index.Find(m, index.Widest(), method, "cpu", 5);
    // The optimum fitted to the same frame (TSVs from before it had a row per width hold one,
    // fitted to the native map; it stands in then).
    const Row* ls = index.Find(m, index.Widest(), optimum, "cpu", 5);
    for (const auto& r : index.rows)
      if (!ls && r.map == m && r.method == optimum && r.param == 5) ls = &r;
    if (!sg || !ls) continue;
    const double d = sg->e.diffuse / ls->e.diffuse, g20 = sg->e.glossy20 / ls->e.glossy20,
                 g200 = sg->e.glossy200 / ls->e.glossy200;
    worst.push_back(std::max({d, g20, g200}));
    md << "| " << m << " | " << fmt::format("{:.2f}", d) << " | " << fmt::format("{:.2f}", g20) << " | "
       << fmt::format("{:.2f}", g200) << " | " << fmt::format("{:.0f}", ls->ms / sg->ms) << " |\n";
  }
  if (!worst.empty())
    md << "\nMaps with every ratio within 1.5: "
       << std::count_if(worst.begin(), worst.end(), [](double w) { return w <= 1.5; }) << " of " << worst.size()
       << "; median of the worst ratio per map " << fmt::format("{:.2f}", Median(worst)) << ".\n\n";
}

// Target 2, and that no error grows when a level is added.
void WriteDiffuseAndGrowth(const RowIndex& index, std::ostream& md) {
  // 2. Diffuse <= 1 % from level 2 on; no error grows when a level is added. The errors are against
  // the native map, but the transform sees the enlarged frame: a model converging on the frame
  // converges on the frame's own error (the `input` row), so a rise that stays within it is not
  // counted as a growth but told apart.
  struct DiffuseCount {
    int ok = 0, total = 0, optimum_fitted = 0, optimum_over = 0;
  };
  std::map<std::string, DiffuseCount> diffuse;
  int growths = 0, growths_within_input = 0, sequences = 0;
  for (const auto& m : index.maps)
    for (int w : index.widths) {
      const Row* input = index.Find(m, w, "input", "cpu", 0);
      for (const char* method : {"sg", "sg+peaks"}) {
        const Row* previous = nullptr;
        bool grew = false, grew_within_input = false;
        for (int levels = 1; levels <= 6; ++levels) {
          const Row* r = index.Find(m, w, method, "cpu", levels);
          if (!r) continue;
          if (levels >= 3) {
            DiffuseCount& d = diffuse[method];
            ++d.total;
            d.ok += r->e.diffuse <= 0.01;
            const Row* optimum =
                index.Find(m, w, std::string(method) == "sg" ? "least-squares" : "least-squares+peaks", "cpu", levels);
            if (r->e.diffuse > 0.01 && optimum) {
              ++d.optimum_fitted;
              d.optimum_over += optimum->e.diffuse > 0.01;
            }
          }
          if (previous) {
            // A rise ending within the input row's error is the model converging on the frame.
            // Without an input row (an old TSV) every rise counts.
            enum Rise { kNone, kWithinInput, kBeyondInput };
            const auto rise = [&](double now, double before, double input_error) {
              if (now <= before * 1.02 + 1e-5) return kNone;
              return now > input_error ? kBeyondInput : kWithinInput;
            };
            const double none = -std::numeric_limits<double>::infinity();
            const Rise worst =
                std::max({rise(r->e.diffuse, previous->e.diffuse, input ? input->e.diffuse : none),
                          rise(r->e.glossy20, previous->e.glossy20, input ? input->e.glossy20 : none),
                          rise(r->e.glossy200, previous->e.glossy200, input ? input->e.glossy200 : none)});
            grew |= worst == kBeyondInput;
            grew_within_input |= worst == kWithinInput;
          }
          previous = r;
        }
        if (previous) {
          ++sequences;
          growths += grew;
          growths_within_input += !grew && grew_within_input;
        }
      }
    }
  md << "**Diffuse error <= 1 % from level 2 on** (levels >= 3):";
  for (const auto& [method, d] : diffuse)
    md << " `" << method << "` " << d.ok << " of " << d.total << " (map, width, levels) rows"
       << (d.optimum_fitted > 0 ? fmt::format(", the least-squares optimum on the same basis over 1 % too on {} of "
                                              "the {} others it was fitted for",
                                              d.optimum_over, d.optimum_fitted)
                                : "")
       << ";";
  md << " **an error grew by more than 2 % when a level was added** in " << growths << " of " << sequences
     << " level sequences, and in " << growths_within_input
     << " more it rose but stayed within the frame's own error against the native map (the `input` row: the "
        "model converges on the frame it is given).\n\n";
}

// Target 3: on sunny maps, SG with peaks against SH order 8 of the same frame.
void WriteSunnyAgainstSh8(const RowIndex& index, std::ostream& md) {
  // 3. Sunny maps: SG with peaks against SH order 8, each from the same frame (TSVs written before
  // SH had a row per width hold one SH row per map, from the native map; it stands in then).
  const auto sh8 = [&](const std::string& map, int width) -> const Row* {
    const Row* any = nullptr;
    for (const auto& r : index.rows)
      if (r.map == map && r.method == "sh" && r.param == 8) {
        if (r.width == width) return &r;
        if (!any) any = &r;
      }
    return any;
  };
  const auto beats = [](const Row& a, const Row& b) {
    return a.e.diffuse < b.e.diffuse && a.e.glossy20 < b.e.glossy20 && a.e.glossy200 < b.e.glossy200;
  };
  const char* sunny[] = {"sky", "park", "sunrise", "sunset", "dawn"};
  md << "**Sunny maps: `sg+peaks` (5 levels, widest width) against SH order 8:**\n\n| map | diffuse | glossy20 | "
        "glossy200 | ms (SG / SH) |\n|---|---|---|---|---|\n";
  for (const char* m : sunny) {
    const Row* sg = index.Find(m, index.Widest(), "sg+peaks", "cpu", 5);
    const Row* sh = sh8(m, index.Widest());
    if (!sg || !sh) continue;
    md << "| " << m << " | " << Fmt(sg->e.diffuse) << " / " << Fmt(sh->e.diffuse) << " | " << Fmt(sg->e.glossy20)
       << " / " << Fmt(sh->e.glossy20) << " | " << Fmt(sg->e.glossy200) << " / " << Fmt(sh->e.glossy200) << " | "
       << fmt::format("{:.1f} / {:.1f}", sg->ms, sh->ms) << " |\n";
  }
  // The model is to be only what the scene needs: the cheapest `sg+peaks` (levels,
  // width) that beats SH 8 of the same frame on all three errors, and whether it takes less time.
  md << "\n**Sunny maps: the cheapest `sg+peaks` that beats SH order 8 on all three errors** (over every "
        "levels and width; SH 8 from the same frame, ms from the same run):\n\n| map | levels | width | diffuse "
        "| glossy20 | glossy200 | ms (SG / SH) | less time |\n|---|---|---|---|---|---|---|---|\n";
  int sunny_maps = 0, faster = 0;
  for (const char* m : sunny) {
    const Row* best = nullptr;
    const Row* best_sh = nullptr;
    bool any = false;
    for (const auto& r : index.rows) {
      if (r.map != m || r.method != "sg+peaks" || r.device != "cpu") continue;
      any = true;
      const Row* sh = sh8(m, r.width);
      if (sh && beats(r, *sh) && (!best || r.ms < best->ms)) best = &r, best_sh = sh;
    }
    if (!any) continue;
    ++sunny_maps;
    if (!best) {
      md << "| " << m << " | none beats SH 8 | | | | | | no |\n";
      continue;
    }
    const bool less = best->ms < best_sh->ms;
    faster += less;
    md << "| " << m << " | " << best->param << " | " << best->width << " | " << Fmt(best->e.diffuse) << " / "
       << Fmt(best_sh->e.diffuse) << " | " << Fmt(best->e.glossy20) << " / " << Fmt(best_sh->e.glossy20) << " | "
       << Fmt(best->e.glossy200) << " / " << Fmt(best_sh->e.glossy200) << " | "
       << fmt::format("{:.2f} / {:.2f}", best->ms, best_sh->ms) << " | " << (less ? "yes" : "no") << " |\n";
  }
  if (sunny_maps)
    md << "\nBetter on all three errors at less time than SH 8: " << faster << " of " << sunny_maps << " sunny maps.\n";
}

// The figures the targets are set on, computed from the rows (never typed in by hand).
std::string Targets(const std::vector<Row>& rows) {
  const RowIndex index(rows);
  std::ostringstream md;
  md << "\n## Targets, from the rows above\n\n";
  md << "**Against the least-squares optimum, through level 4** (5 levels, 4092 SGs + constant; `sg` = the "
        "transform alone on the same basis; ratio = transform error / optimum error, per map, at the widest "
        "width, the optimum fitted to the same enlarged frame):\n\n";
  WriteOptimumRatios(index, "sg", "least-squares", md);
  if (std::any_of(rows.begin(), rows.end(), [](const Row& r) { return r.method == "least-squares+peaks"; })) {
    md << "**With peaks, against the optimum on the same basis** (`sg+peaks` against `least-squares+peaks`: the "
          "same peaks, detected as the transform's builder detects them, and least-squares amplitudes of the same "
          "SRBFs for what the detector leaves of the frame):\n\n";
    WriteOptimumRatios(index, "sg+peaks", "least-squares+peaks", md);
  }
  WriteDiffuseAndGrowth(index, md);
  WriteSunnyAgainstSh8(index, md);
  // 4. CPU time of a 2048x1024 frame to 5 levels.
  std::vector<double> ms;
  for (const auto& m : index.maps)
    if (const Row* r = index.Find(m, 2048, "sg", "cpu", 5)) ms.push_back(r->ms);
  if (!ms.empty())
    md << "\n**CPU, 2048x1024 to 5 levels (no peaks):** median " << fmt::format("{:.1f}", Median(ms)) << " ms over "
       << ms.size() << " maps (target: under 30 ms).\n";
  return md.str();
}

std::vector<Row> ReadRows(const fs::path& tsv, std::string* machine) {
  std::ifstream in(tsv);
  if (!in) throw Error(tsv.string(), "cannot be read");
  std::vector<Row> rows;
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("# odvr bench light on ", 0) == 0) {
      *machine = line.substr(22);
      continue;
    }
    if (line.empty() || line.rfind("map\t", 0) == 0) continue;
    std::istringstream f(line);
    Row r;
    std::string field;
    std::vector<std::string> v;
    while (std::getline(f, field, '\t')) v.push_back(field);
    if (v.size() != 11) throw Error(tsv.string(), "a row without 11 columns: " + line);
    r.map = v[0];
    r.width = std::stoi(v[1]);
    r.method = v[2];
    r.device = v[3];
    r.param = std::stoi(v[4]);
    r.coefficients = std::stoi(v[5]);
    r.ms = std::stod(v[6]);
    r.e = {std::stod(v[7]), std::stod(v[8]), std::stod(v[9]), std::stod(v[10])};
    rows.push_back(r);
  }
  return rows;
}

void WriteReport(const std::vector<Row>& rows, const BenchLightOptions& o, const std::string& machine) {
  fs::create_directories(o.out_dir);
  const fs::path tsv = fs::path(o.out_dir) / "lighting.tsv";
  std::ostringstream t;
  t << "# odvr bench light on " << machine << "\n";
  t << "map\twidth\tmethod\tdevice\tparam\tcoefficients\tms\trel_l2\tdiffuse\tglossy20\tglossy200\n";
  for (const auto& r : rows)
    t << r.map << "\t" << r.width << "\t" << r.method << "\t" << r.device << "\t" << r.param << "\t" << r.coefficients
      << "\t" << r.ms << "\t" << r.e.rel_l2 << "\t" << r.e.diffuse << "\t" << r.e.glossy20 << "\t" << r.e.glossy200
      << "\n";
  WriteTextAtomically(tsv, t.str());

  // Medians over the maps, per (width, method, device, param): the table a reader wants first.
  std::map<std::tuple<int, std::string, std::string, int>, std::vector<const Row*>> groups;
  for (const auto& r : rows) groups[{r.width, r.method, r.device, r.param}].push_back(&r);
  std::ostringstream md;
  md << "# Lighting: speed against error\n\n"
     << "Made by `odvr bench light` on " << machine
     << ". Medians over the maps (the HDR maps of `../shared/data/env/`, bilinearly enlarged to each width). "
     << "Errors: `rel_l2` is the solid-angle-weighted ‖I − R‖₂/‖I‖₂; `diffuse`, `glossy20` and "
     << "`glossy200` compare the input and the model convolved with a clamped cosine and with SG lobes of "
     << "λ = 20 and 200 at the 768 level-3 HEALPix directions. `sg` is the residual transform alone, "
     << "`sg+peaks` takes suns out as free-form SGs first; `least-squares` is the optimum on the same SG basis "
     << "(sparse Cholesky, every SRBF kept), fitted to the same enlarged frame, and `least-squares+peaks` the "
     << "optimum on `sg+peaks`' basis (its peaks, the SRBFs fitted to what the detector leaves; its time is the "
     << "fit's); `input` is that frame's own "
     << "error against the native map (the enlargement blurs a sun: no model made from the frame does better); `sh` is "
        "spherical harmonics of that order, projected from the same "
     << "frame area-resampled to " << o.sh_width << " wide (the resampling is in its time). Device `gpu` takes "
     << "the frame from the CPU (its upload, or its resampling to the transform's finest grid on the CPU's "
     << "threads, is in the time); `gpu-resident` runs `sg` from the frame already in a GPU texture (as a GPU "
     << "stitcher hands it), resampled on the GPU. Time is the median of " << o.repeats << " or more runs (until "
     << o.min_time_ms << " ms have passed, at most " << kMaxRuns
     << ") on one frame, each a warm call as playback makes it every frame (one untimed call first builds "
     << "the transform's overlap lists and the builder's scratch grid; before a GPU row, untimed calls for "
     << o.gpu_warm_up_ms << " ms, so that a GPU idle through the CPU rows has its clocks up).\n\n"
     << "| width | method | device | levels/order | coefficients | ms | rel_l2 | diffuse | glossy20 | glossy200 |\n"
     << "|---|---|---|---|---|---|---|---|---|---|\n";
  const auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v[v.size() / 2];
  };
  for (const auto& [key, group] : groups) {
    std::vector<double> ms, c, l2, d, g20, g200;
    for (const Row* r : group) {
      ms.push_back(r->ms);
      c.push_back(r->coefficients);
      l2.push_back(r->e.rel_l2);
      d.push_back(r->e.diffuse);
      g20.push_back(r->e.glossy20);
      g200.push_back(r->e.glossy200);
    }
    md << "| " << std::get<0>(key) << " | " << std::get<1>(key) << " | " << std::get<2>(key) << " | "
       << std::get<3>(key) << " | " << median(c) << " | " << fmt::format("{:.2f}", median(ms)) << " | "
       << Fmt(median(l2)) << " | " << Fmt(median(d)) << " | " << Fmt(median(g20)) << " | " << Fmt(median(g200))
       << " |\n";
  }
  md << Targets(rows);
  md << "\nEvery row of every map is in `lighting.tsv`; the plot `lighting.png` shows the diffuse and "
        "glossy200 errors of each map against time.\n\n![error against time](lighting.png)\n";
  WriteTextAtomically(fs::path(o.out_dir) / "lighting.md", md.str());

  // The plot: gnuplot reads the TSV directly.
  std::ostringstream gp;
  gp << "set datafile separator '\\t'\nset logscale xy\nset key outside bottom center horizontal\nset grid\n"
     << "set multiplot layout 1,2\n";
  for (const char* col : {"diffuse", "glossy200"}) {
    const int index = std::string(col) == "diffuse" ? 9 : 11;
    gp << "set title '" << col << " error against time (all maps, widths)'\nset xlabel 'ms'\nset ylabel '" << col
       << " error'\nplot ";
    bool first = true;
    // The GPU path's rows apart: on llvmpipe its times are a CPU rasterizer's, not a GPU's.
    const bool any_gpu = std::any_of(rows.begin(), rows.end(), [](const Row& r) { return r.device == "gpu"; });
    for (const char* m : {"sg", "sg+peaks", "least-squares", "least-squares+peaks", "sh"})
      for (const char* device : {"cpu", "gpu"}) {
        if (std::string_view(device) == "gpu" && (!any_gpu || std::string_view(m).substr(0, 2) != "sg")) continue;
        gp << (first ? "" : ", ") << "'lighting.tsv' using (strcol(3) eq '" << m << "' && strcol(4) eq '" << device
           << "' ? $7 : 1/0):" << index << " with points title '" << m
           << (std::string_view(device) == "gpu" ? " (gpu)" : "") << "'";
        first = false;
      }
    gp << "\n";
  }
  gp << "unset multiplot\n";
  WritePlot(o.out_dir, "lighting", 1200, 520, gp.str(), "bench light");
}

}  // namespace

int RunBenchLight(BenchLightOptions o) {
  if (o.report_only) {
    std::string machine = "unknown";
    const auto rows = ReadRows(fs::path(o.out_dir) / "lighting.tsv", &machine);
    WriteReport(rows, o, machine);
    std::cout << "bench light: report rewritten from " << rows.size() << " rows\n";
    return 0;
  }
  if (o.maps.empty()) o.maps = DefaultMaps();
  if (o.maps.empty()) throw UsageError("bench light", "no maps given and ../shared/data/env/ is absent");
  std::unique_ptr<gl::HeadlessContext> context;
  std::unique_ptr<lighting::ResidualTransformGpu> gpu;
  std::string machine = BenchMachineDescription();
  if (o.gpu) {
    context = std::make_unique<gl::HeadlessContext>();
    machine += ", GPU: " + context->Info().renderer;
  }
  std::vector<Row> rows;
  BenchProgress progress("bench light", static_cast<long>(o.maps.size() * o.widths.size()));
  for (const auto& path : o.maps) {
    const sphere::EquirectImage native = image::LoadImage(path, {.max_width = 8192, .require_equirect = true});
    const std::string name = fs::path(path).stem().string();
    const lighting::LightingErrorEvaluator evaluator(native);
    for (int width : o.widths) {
      if (width < native.width)
        throw UsageError("--widths", std::to_string(width) + " is narrower than " + path + " (" +
                                         std::to_string(native.width) +
                                         " wide): the bench enlarges maps, and judges every model against the map");
      const sphere::EquirectImage frame =
          width == native.width ? native : sphere::UpsampleBilinear(native, width, width / 2);
      // Every method is judged against the native map, but an enlarged frame is not the native
      // map (bilinear interpolation blurs a sun over a native pixel): its own error is the floor
      // of any model made from it, and the least-squares optimum is fitted to it too, so that
      // the transform and the optimum see the same light. The fit runs on the frame
      // area-resampled to the native grid (its SGs are 2+ native pixels per σ, so the grid
      // changes the optimum by less than the frames differ, and the solve stays one size).
      const sphere::EquirectImage fit_grid =
          width == native.width ? native : sphere::ResampleArea(frame, native.width, native.height);
      rows.push_back({name, width, "input", "cpu", 0, 0, 0.0,
                      evaluator.Evaluate(lighting::LightingErrorEvaluator::ConvolveImage(frame, evaluator.directions()),
                                         fit_grid)});
      if (o.least_squares) {
        // The sg+peaks model's basis: its peaks, found as LightingBuilder finds them, and the
        // SRBFs fitted to what the detector leaves (the residue, on the same grid as the frame's fit).
        sphere::EquirectImage peak_residue;
        std::vector<lighting::RgbSg> peaks;
        if (!o.skip_peaks) {
          lighting::PeakDetection d = DetectPeaksAsTheBuilderDoes(frame);
          for (const auto& p : d.peaks) peaks.insert(peaks.end(), p.sgs.begin(), p.sgs.end());
          peak_residue = sphere::ResampleArea(d.residue, native.width, native.height);
        }
        for (int levels = 1; levels <= std::min(o.max_levels, 5); ++levels) {
          if (o.only_levels && levels != o.only_levels) continue;
          lighting::LeastSquaresReport ls;
          const auto model = lighting::LeastSquaresSgFit(fit_grid, levels, &ls);
          rows.push_back({name, width, "least-squares", "cpu", levels, ls.unknowns, ls.ms, evaluator.Evaluate(model)});
          if (o.skip_peaks) continue;
          auto with_peaks = lighting::LeastSquaresSgFit(peak_residue, levels, &ls);
          with_peaks.peaks = peaks;
          rows.push_back({name, width, "least-squares+peaks", "cpu", levels, with_peaks.sg_count(), ls.ms,
                          evaluator.Evaluate(with_peaks)});
        }
      }
      // SH from the same frame the transform gets, resampled to its own grid inside the timing.
      for (int order : {2, 4, 8, 16}) {
        lighting::ShModel sh;
        const int sh_width = std::min(o.sh_width, frame.width);
        const auto project = [&] {
          const auto t0 = std::chrono::steady_clock::now();
          sh = lighting::ProjectSphericalHarmonics(sphere::ResampleArea(frame, sh_width, sh_width / 2), order);
          return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        };
        project();  // warm-up, as the transform gets one
        const std::vector<double> times = TimedRuns(o, project);
        const auto recon = sh.Reconstruct(native.width, native.height);
        const LightingErrors e =
            evaluator.Evaluate(lighting::LightingErrorEvaluator::ConvolveImage(recon, evaluator.directions()), recon);
        rows.push_back({name, width, "sh", "cpu", order, (order + 1) * (order + 1), Median(times), e});
      }
      for (const std::string_view device : {"cpu", "gpu"}) {
        if (device == "gpu" && !o.gpu) continue;
        for (bool peaks : {false, true})
          for (int levels = 1; levels <= o.max_levels; ++levels) {
            if ((o.only_levels && levels != o.only_levels) || (peaks && o.skip_peaks)) continue;
            lighting::LightingOptions lo;
            lo.transform = o.transform;
            lo.transform.levels = levels;
            lo.transform.stop_threshold = 0;  // the bench measures each level count as asked
            lo.detect_peaks = peaks;
            lighting::LightingBuilder builder(lo);
            if (device == "gpu") gpu = std::make_unique<lighting::ResidualTransformGpu>(lo.transform);
            lighting::SgLighting model;
            WarmUp(device == "gpu" ? o.gpu_warm_up_ms : 0, [&] { model = builder.Build(frame, nullptr, gpu.get()); });
            const std::vector<double> times = TimedRuns(o, [&] {
              lighting::LightingReport report;
              model = builder.Build(frame, &report, device == "gpu" ? gpu.get() : nullptr);
              return report.total_ms;
            });
            rows.push_back({name, width, peaks ? "sg+peaks" : "sg", std::string(device), levels, model.sg_count(),
                            Median(times), evaluator.Evaluate(model)});
            if (device == "gpu" && !peaks) {
              // The frame already in a GPU texture, as a GPU stitcher or decoder hands it: the
              // transform alone, without the upload and the CPU resampling that `gpu` includes.
              gl::Texture texture = gl::Texture::Create2D(GL_RGB32F, frame.width, frame.height);
              texture.Upload2D(GL_RGB, GL_FLOAT, frame.rgb.data());
              lighting::SgLighting resident;
              WarmUp(o.gpu_warm_up_ms, [&] { resident = gpu->Run(texture); });  // and this grid's lists
              const std::vector<double> resident_times = TimedRuns(o, [&] {
                lighting::TransformReport report;
                resident = gpu->Run(texture, &report);
                return report.total_ms;
              });
              rows.push_back({name, width, "sg", "gpu-resident", levels, resident.sg_count(), Median(resident_times),
                              evaluator.Evaluate(resident)});
            }
          }
        gpu.reset();
      }
      progress.Step(name + " @" + std::to_string(width));
    }
  }
  WriteReport(rows, o, machine);
  std::cout << "bench light: " << rows.size() << " rows; wrote " << o.out_dir << "/lighting.md, lighting.tsv, "
            << "lighting.png\n";
  return 0;
}

CommandFn AddBenchLight(CLI::App* sub) {
  auto o = std::make_shared<BenchLightOptions>();
  sub->add_option("maps", o->maps, "Equirect maps (default: ../shared/data/env/*.exr)");
  sub->add_option("--widths", o->widths, "Frame widths to run the transform at")->delimiter(',');
  sub->add_option("--max-levels", o->max_levels, "Levels 0..N−1 at most")->check(CLI::Range(1, 6));
  sub->add_option("--only-levels", o->only_levels,
                  "Run only this level count (and its least-squares fit): a quick check of one configuration")
      ->check(CLI::Range(1, 6));
  sub->add_flag("--skip-peaks", o->skip_peaks, "Leave out the sg+peaks rows");
  sub->add_option(
         "--gpu-warm-up-ms", o->gpu_warm_up_ms,
         "Before each GPU row, untimed calls for this long (a GPU idle through the CPU rows lowers its clocks)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--min-time-ms", o->min_time_ms, "Time runs until this much time has passed (>= --repeats runs)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--repeats", o->repeats, "Timed runs per configuration (the median is kept)")
      ->check(CLI::Range(1, 100));
  sub->add_flag("--gpu", o->gpu, "Also time the GPU path (needs an OpenGL 4.5 context)");
  AddSetFlag(sub, "--no-least-squares", &o->least_squares, false, "Skip the least-squares optimum (slow)");
  sub->add_option("--sh-width", o->sh_width, "Width of the grid SH projects the frame on (resampled, timed)")
      ->check(CLI::Range(16, 8192));
  sub->add_option("--out", o->out_dir, "Where the table, TSV and plot go (docs/benchmarks: the committed pages)")
      ->capture_default_str();
  AddTransformTuning(sub, &o->transform);
  sub->add_flag("--report-only", o->report_only, "Rewrite the table and plot from the TSV already in --out");
  return [o] { return RunBenchLight(*o); };
}

}  // namespace odvr::app
