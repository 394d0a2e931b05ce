#include "app/ar/car_rendering.h"

#include <string>

#include "core/error.h"

namespace odvr::app {

void CarRendering::Check() const {
  if (lighting_levels < 1 || lighting_levels > 6) throw UsageError("--levels", "must be 1..6");
  if (lighting_width < 16 || lighting_width % 2) throw UsageError("lighting width", "must be even and at least 16");
  if (voxel_resolution != 64 && voxel_resolution != 128 && voxel_resolution != 256)
    throw UsageError("--voxels", "must be 64, 128 or 256");
  // No player takes a cone count on its command line: named as the setting, not as an option.
  if (cone_rings < 0 || cone_rings > 3) throw UsageError("cone rings", "must be 0..3 (1, 7, 19 or 37 cones)");
  if (supersample < 1 || supersample > render::kMaxSupersample)
    throw UsageError("--supersample", "must be 1.." + std::to_string(render::kMaxSupersample));
  if (shading_rate != 1 && shading_rate != 2) throw UsageError("--shading-rate", "must be 1 or 2");
}

lighting::LightingOptions CarRendering::Lighting() const {
  lighting::LightingOptions o;
  o.transform.levels = lighting_levels;
  o.peak_grid_width = lighting_width;
  return o;
}

render::RenderOptions CarRendering::Render() const {
  render::RenderOptions o;
  o.lighting_levels = lighting_levels;
  o.voxel_resolution = voxel_resolution;
  o.cone_rings = cone_rings;
  o.supersample = supersample;
  o.shading_rate = supersample > 1 ? 1 : shading_rate;
  o.read_layers = false;
  o.read_composite = !composite_on_gpu;
  return o;
}

}  // namespace odvr::app
