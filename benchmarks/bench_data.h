#pragma once
// The real inputs the micro-benchmarks share, loaded once per process (Google Benchmark calls a
// benchmark's function several times while it sizes the iteration count, so anything set up per
// call would be redone): the park map of ../shared/data/env and its enlarged frames, and the
// error evaluator `odvr bench light` judges lighting models with.
#include <filesystem>
#include <memory>
#include <string>

#include "engine/lighting/lighting_errors.h"
#include "engine/sphere/equirect_image.h"

namespace odvr::bench {

struct EnvMap {
  std::filesystem::path path;
  sphere::EquirectImage native;
  // Judges models against the native map, as `odvr bench light` does. Holds a pointer to
  // `native`, so an EnvMap is never moved once made.
  std::unique_ptr<lighting::LightingErrorEvaluator> evaluator;
};

// ../shared/data/env/park.exr beside the source tree; nullptr (and `*why` set) when absent or
// unreadable, so the benchmarks that need it skip with that message.
const EnvMap* Park(std::string* why);

// The park map enlarged bilinearly to width × width/2, as `odvr bench light` makes its frames.
const sphere::EquirectImage& ParkFrame(const EnvMap& park, int width);

// Σ over pixels and channels of value × pixel solid angle: the map's radiant energy (its
// integral over the sphere), in double.
double SphereIntegral(const sphere::EquirectImage& image);

}  // namespace odvr::bench
