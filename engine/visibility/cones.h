#pragma once
// Visibility cones for SG lobes (seed §4.3.3, eq. 4.12–4.13; DESIGN.md §5). A cone of
// half-angle α stands for the SG that falls to 1/2 at α: e^{λ(cos α − 1)} = 1/2. A sharp lobe
// is one cone; a broad lobe is subsampled by smaller cones packed over the cap that holds most
// of its mass — a centre cone and hexagonal rings (1, 7, 19, 37 … cones), all of one half-angle
// β, the ring r at 2rβ from the axis: the hexagonal packing of equal circles, laid on the
// sphere. Each cone's weight is the lobe's share that its own SG catches,
//   w_i = ∫ G·V_i / Σ_j ∫ G·V_j   (V_i the cone's SG, eq. 4.7),
// so that Σ w_i v_i (v_i the traced visibility of cone i) estimates the lobe-weighted visible
// fraction ∫ G·V / ∫ G that the triple product needs.
#include <glm/vec3.hpp>
#include <vector>

#include "engine/lighting/sg.h"

namespace odvr::visibility {

struct Cone {
  glm::dvec3 axis{0, 0, 1};  // unit
  double half_angle = 0;     // radians
  double weight = 1;         // the weights of one lobe sum to 1
};

struct ConeSubsampleOptions {
  // A lobe whose half-value angle is at most this is traced as one cone of that angle
  // (a mirror-like lobe: the seed's "specular" case).
  double single_cone_max_half_angle = 0.15;  // radians, ≈ 8.6°
  // Hexagonal rings around the centre cone for a broad lobe: 1 → 7 cones, 2 → 19, 3 → 37.
  int rings = 1;
  // The packed cones cover the cap around the axis that holds this fraction of the lobe's
  // integral (the rest is its thin tail).
  double coverage = 0.9;
  void Check() const;  // throws odvr::Error naming the field
};

// Half-angle of the cap around an SG's axis that holds `fraction` of its integral:
//   ∫_cap / ∫_sphere = (1 − e^{λ(cos θ − 1)}) / (1 − e^{−2λ}).
double CapHalfAngleHolding(double lambda, double fraction);

// The cones that stand for `lobe` (its amplitude is ignored). Throws odvr::Error for a
// non-finite or zero axis or a negative λ.
std::vector<Cone> ConesForLobe(const lighting::Sg& lobe, const ConeSubsampleOptions& options = {});

}  // namespace odvr::visibility
