#pragma once
// How good is a lighting model, as the image will show it? A sun holds most of a sunny map's energy
// in a few pixels, so the raw relative L2 error stays near 1 for any compact model; what reaches
// the picture is the light convolved with a BRDF lobe. So, besides rel_l2, the input and the model
// are each convolved with a clamped cosine (diffuse_error) and with SG lobes of λ = 20 and λ = 200
// (glossy20_error, glossy200_error), evaluated at the 768 level-3 HEALPix directions:
//   error = ‖conv(I) − conv(R)‖₂ / ‖conv(I)‖₂.
// conv(I) is integrated numerically on an area-resampled grid (512×256 for the smooth kernels,
// 1024×512 for λ = 200), but for pixels over 20× the mean (a sun), which are summed at their own
// directions; conv(R) is exact for the SG kernels (closed-form SG products) and, for
// the cosine, numerical for broad SGs and, for sharp ones (λ ≥ 300), the lobe's energy times its
// mean cosine coth λ − 1/λ times the clamped cosine averaged over the lobe (which differs from
// max(0, n·axis) only within a few σ of the horizon, σ ≤ 3°).
#include <functional>
#include <glm/vec3.hpp>
#include <vector>

#include "engine/lighting/sg_lighting.h"
#include "engine/sphere/equirect_image.h"

namespace odvr::lighting {

struct LightingErrors {
  double rel_l2 = 0;
  double diffuse = 0;
  double glossy20 = 0;
  double glossy200 = 0;
};

// Convolutions of a spherical function at a set of directions, for the three kernels.
struct Convolutions {
  std::vector<glm::dvec3> diffuse, glossy20, glossy200;
};

class LightingErrorEvaluator {
 public:
  explicit LightingErrorEvaluator(const sphere::EquirectImage& input);

  LightingErrors Evaluate(const SgLighting& model) const;
  // For other representations (spherical harmonics): their convolutions and their
  // reconstruction on the input's grid.
  LightingErrors Evaluate(const Convolutions& conv, const sphere::EquirectImage& reconstruction) const;

  const std::vector<glm::dvec3>& directions() const { return directions_; }
  const Convolutions& input_convolutions() const { return input_conv_; }

  // Numerical convolution of an image with the three kernels at the given directions.
  static Convolutions ConvolveImage(const sphere::EquirectImage& image, const std::vector<glm::dvec3>& directions);
  static Convolutions ConvolveModel(const SgLighting& model, const std::vector<glm::dvec3>& directions);

 private:
  LightingErrors Compare(const Convolutions& conv, double rel_l2) const;
  const sphere::EquirectImage* input_;
  std::vector<glm::dvec3> directions_;
  Convolutions input_conv_;
};

// Solid-angle-weighted ‖a − b‖₂ / ‖a‖₂ over all channels (sizes must match).
double RelativeL2(const sphere::EquirectImage& reference, const sphere::EquirectImage& estimate);

}  // namespace odvr::lighting
