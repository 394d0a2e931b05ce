// engine/image: loading a frame, the first step of `odvr light`, `odvr render` and the benches.
// Args: the file (0: env/sunset.exr, half-float EXR 512x256; 1: street_a's float PXR24 EXR
// 1024x512; 2: street_a's 8-bit PNG of the same frame) and the rows per read
// (LoadOptions::read_block_bytes in KB; 0: one row, as LoadImage read them before OpenImageIO's
// per-call 64 MB buffer was found to dominate). The counter is the largest difference between
// the pixels of a block read and a row-by-row read: the blocks must change nothing.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "engine/image/image_io.h"

namespace odvr::bench {
namespace {

const char* const kFiles[] = {"data/env/sunset.exr", "data/street_a/pano_hdr/000010.exr",
                              "data/street_a/pano/000010.png"};

void BM_LoadImage(benchmark::State& state) {
  const std::filesystem::path path =
      std::filesystem::path(ODVR_SOURCE_DIR) / "../shared" / kFiles[static_cast<std::size_t>(state.range(0))];
  if (!std::filesystem::exists(path)) {
    state.SkipWithError((path.string() + " is absent (the shared data)").c_str());
    return;
  }
  image::LoadOptions block, row;
  row.read_block_bytes = 1;  // at least one row per read
  const sphere::EquirectImage by_block = image::LoadImage(path, block), by_row = image::LoadImage(path, row);
  double max_diff = 0;
  for (std::size_t i = 0; i < by_block.rgb.size(); ++i)
    max_diff = std::max(max_diff, static_cast<double>(std::abs(by_block.rgb[i] - by_row.rgb[i])));
  image::LoadOptions options;
  options.read_block_bytes = state.range(1) == 0 ? 1 : static_cast<std::size_t>(state.range(1)) << 10;
  for (auto _ : state) {
    auto image = image::LoadImage(path, options);
    benchmark::DoNotOptimize(image.rgb.data());
  }
  state.counters["max_diff"] = max_diff;
  state.counters["width"] = by_block.width;
}
BENCHMARK(BM_LoadImage)
    ->ArgNames({"file", "block"})
    ->ArgsProduct({{0, 1, 2}, {0, 256, 1024, 4096, 32768}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace odvr::bench
