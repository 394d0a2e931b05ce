#include "benchmarks/bench_data.h"

#include <map>
#include <mutex>

#include "core/error.h"
#include "engine/image/image_io.h"
#include "engine/sphere/equirect.h"
#include "engine/sphere/resample.h"

namespace odvr::bench {

const EnvMap* Park(std::string* why) {
  static std::once_flag once;
  static std::unique_ptr<EnvMap> park;
  static std::string error;
  std::call_once(once, [] {
    const auto path =
        (std::filesystem::path(ODVR_SOURCE_DIR) / ".." / "shared" / "data" / "env" / "park.exr").lexically_normal();
    if (!std::filesystem::is_regular_file(path)) {
      error = path.string() + " is absent (the shared data set sits beside the source tree)";
      return;
    }
    try {
      auto p = std::make_unique<EnvMap>();
      p->path = path;
      p->native = image::LoadImage(path, {.max_width = 8192, .require_equirect = true});
      p->evaluator = std::make_unique<lighting::LightingErrorEvaluator>(p->native);
      park = std::move(p);
    } catch (const Error& e) {
      error = e.what();
    }
  });
  if (!park && why) *why = error;
  return park.get();
}

const sphere::EquirectImage& ParkFrame(const EnvMap& park, int width) {
  static std::mutex mutex;
  static std::map<int, sphere::EquirectImage> frames;
  const std::lock_guard lock(mutex);
  auto it = frames.find(width);
  if (it == frames.end())
    it = frames
             .emplace(width, width == park.native.width ? park.native
                                                        : sphere::UpsampleBilinear(park.native, width, width / 2))
             .first;
  return it->second;
}

double SphereIntegral(const sphere::EquirectImage& image) {
  double total = 0;
  for (int row = 0; row < image.height; ++row) {
    double sum = 0;
    const float* p = image.at(0, row);
    for (int i = 0; i < 3 * image.width; ++i) sum += p[i];
    total += sum * sphere::EquirectPixelSolidAngle(row, image.width, image.height);
  }
  return total;
}

}  // namespace odvr::bench
