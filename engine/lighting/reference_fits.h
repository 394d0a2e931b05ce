#pragma once
// The references `odvr bench light` holds the residual transform against:
// - the least-squares optimum on the same SG basis: the amplitudes of the constant and of every
//   SRBF of levels 0..L−1 that minimise ∫ (I − Σ μ_j B_j)² dω, the best any choice of amplitudes
//   can do in L2. The Gram matrix ∫ B_i B_j is closed-form (eq. 4.7) and sparse (entries below
//   1e-9 of the diagonal's geometric mean are dropped); the right side ∫ I B_i is summed over the
//   pixels of each SRBF's cap. A dense solve of 4093 unknowns is what the seed's real-time
//   transform avoids; here it is sparse Cholesky (Eigen), still seconds, not milliseconds.
// - spherical harmonics projected to order (band) L: (L+1)² real SH coefficients, separable per
//   row (associated Legendre in latitude, cos/sin mφ in longitude).
#include <vector>

#include "engine/lighting/sg_lighting.h"
#include "engine/sphere/equirect_image.h"

namespace odvr::lighting {

struct LeastSquaresReport {
  int unknowns = 0;
  long gram_nonzeros = 0;
  double ms = 0;
};

// `levels`: HEALPix levels 0..levels−1 (1..6) plus the constant. Every SRBF is kept.
SgLighting LeastSquaresSgFit(const sphere::EquirectImage& image, int levels, LeastSquaresReport* report = nullptr);

struct ShModel {
  int order = 0;                        // bands 0..order
  std::vector<glm::vec3> coefficients;  // (order+1)², index l(l+1)+m
  // Point-sampled reconstruction on an equirect grid.
  sphere::EquirectImage Reconstruct(int width, int height) const;
  glm::vec3 Evaluate(const glm::dvec3& direction) const;
};

ShModel ProjectSphericalHarmonics(const sphere::EquirectImage& image, int order);

}  // namespace odvr::lighting
