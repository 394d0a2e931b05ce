// engine/sphere: area resampling, the step every lighting level and the error evaluator take.
// The counter is what the resampling is for: a sun's energy must survive it.
#include <benchmark/benchmark.h>

#include <cmath>

#include "benchmarks/bench_data.h"
#include "engine/sphere/resample.h"

namespace odvr::bench {
namespace {

// Args: input width, output width (both 2:1). The input is park.exr enlarged to that width.
void BM_ResampleArea(benchmark::State& state) {
  std::string why;
  const EnvMap* park = Park(&why);
  if (!park) {
    state.SkipWithError(why.c_str());
    return;
  }
  const auto& input = ParkFrame(*park, static_cast<int>(state.range(0)));
  const int width = static_cast<int>(state.range(1));
  // ResampleArea averages each output pixel's area in pixel units, not in solid angle, so the
  // energy it keeps is exact only where the solid angle is even across a block's rows: the
  // counter measures how far that is from the truth, against the input's own integral.
  const double before = SphereIntegral(input);
  const double after = SphereIntegral(sphere::ResampleArea(input, width, width / 2));
  for (auto _ : state) {
    auto out = sphere::ResampleArea(input, width, width / 2);
    benchmark::DoNotOptimize(out.rgb.data());
  }
  state.counters["energy_err"] = std::abs(after - before) / before;
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(input.pixel_count()));
}
BENCHMARK(BM_ResampleArea)
    ->ArgNames({"in", "out"})
    ->Args({1024, 256})
    ->Args({2048, 512})
    ->Args({2048, 384})  // a fractional ratio (5⅓): blocks share their edge pixels
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace odvr::bench
