#include "app/ar/car_look.h"

#include "core/error.h"

namespace odvr::app {

void CarLook::Check() const {
  for (const float c : colour)
    if (!(c >= 0 && c <= 1)) throw UsageError("car colour", "components must be in [0, 1]");
  if (!(ks >= 0 && ks <= 1)) throw UsageError("car ks", "must be in [0, 1]");
  if (!(phong_n >= 0 && phong_n <= 1e5)) throw UsageError("car Phong n", "must be in [0, 1e5]");
  if (!(roughness >= 0.01 && roughness <= 1)) throw UsageError("car roughness", "must be in [0.01, 1]");
  if (!(fresnel_f0 >= 0 && fresnel_f0 <= 1)) throw UsageError("car Fresnel F0", "must be in [0, 1]");
}

std::vector<render::MaterialOverride> MaterialOverrides(const CarLook& look) {
  look.Check();
  if (look.model == CarLook::Model::kGltf) return {};
  const glm::dvec3 diffuse = (1 - look.ks) * glm::dvec3(look.colour[0], look.colour[1], look.colour[2]);
  render::MaterialOverride o;  // no name: every material
  o.brdfs.push_back(material::Lambertian{diffuse});
  if (look.model == CarLook::Model::kPhong)
    o.brdfs.push_back(material::Phong{glm::dvec3(look.ks), look.phong_n});
  else
    o.brdfs.push_back(material::CookTorrance{glm::dvec3(look.ks * look.fresnel_f0), look.roughness});
  return {o};
}

lighting::SgLighting ApplyLightToggles(lighting::SgLighting light, const CarLook& look) {
  for (auto& level : light.levels)
    if (level.level >= 0 && level.level < static_cast<int>(look.levels.size()) &&
        !look.levels[static_cast<std::size_t>(level.level)]) {
      level.indices.clear();
      level.amplitudes.clear();
    }
  if (!look.peaks) light.peaks.clear();
  return light;
}

}  // namespace odvr::app
