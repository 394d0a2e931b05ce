#pragma once
// `--material`: a BRDF override written on the command line, as `odvr render` and
// `odvr bench render` take it.
#include <string>

#include "engine/render/triple_product_renderer.h"

namespace odvr::app {

// Parses "[NAME=]TERM[+TERM]" with TERM one of
//   lambert:R,G,B | phong:R,G,B,N | blinn:R,G,B,S | ward:R,G,B,ALPHA | ct:F0R,F0G,F0B,ALPHA[,beckmann]
//   | mr:R,G,B,METALLIC,ROUGHNESS | KD,KS,N (Lambertian kd grey + Phong ks grey, exponent N).
// The values' ranges are material::CheckBrdf's. Throws odvr::UsageError naming the text and
// what is wrong.
render::MaterialOverride ParseMaterialOverride(const std::string& text);

}  // namespace odvr::app
