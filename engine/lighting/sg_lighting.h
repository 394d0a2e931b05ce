#pragma once
// The lighting model the renderer loads (lighting.json): a constant term (an SG with λ = 0),
// the multiscale SGs of the residual transform (per HEALPix level: which centres were kept and
// their RGB amplitudes) and free-form peak SGs (suns, lamps) with their own axis and sharpness.
// All of it is linear in the amplitudes, so models of neighbouring frames blend by weights.
#include <filesystem>
#include <glm/vec3.hpp>
#include <nlohmann/json_fwd.hpp>
#include <utility>
#include <vector>

#include "engine/lighting/sg.h"
#include "engine/sphere/equirect_image.h"

namespace odvr::lighting {

struct RgbSg {
  glm::dvec3 axis{0, 1, 0};
  double lambda = 0;
  glm::vec3 amplitude{0};
};

struct SgLevel {
  int level = 0;
  double lambda = 0;
  std::vector<int> indices;  // HEALPix nested indices of the kept SRBFs
  std::vector<glm::vec3> amplitudes;
};

struct SgLighting {
  glm::vec3 constant{0};
  std::vector<SgLevel> levels;
  std::vector<RgbSg> peaks;

  int sg_count() const;  // the constant counts as one SG when non-zero
  // Every SG of the model, the constant as λ = 0.
  std::vector<RgbSg> ToSgs() const;
  // Direct evaluation (sums every SG): for tests and spot checks.
  glm::vec3 Evaluate(const glm::dvec3& direction) const;
  // Point-sampled equirect image of the model, each SG added over its cap only (G > 1e-5).
  sphere::EquirectImage Reconstruct(int width, int height) const;

  nlohmann::json ToJson() const;
  // Throws odvr::Error naming `where` when the JSON is not a valid model.
  static SgLighting FromJson(const nlohmann::json& json, const std::string& where);
  void Save(const std::filesystem::path& path) const;  // atomic
  static SgLighting Load(const std::filesystem::path& path);

  // Σ wᵢ · modelᵢ, merging levels index by index.
  static SgLighting Blend(const std::vector<std::pair<const SgLighting*, double>>& weighted);
};

// Adds g to `image` over the pixels where it exceeds `cutoff` of its peak (a cap around its axis).
void AddSgToImage(const RgbSg& g, sphere::EquirectImage* image, double cutoff = 1e-5);

}  // namespace odvr::lighting
