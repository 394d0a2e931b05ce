#include "app/flags/material_flag.h"

#include <cctype>
#include <sstream>
#include <vector>

#include "app/flags/command_flags.h"
#include "core/error.h"
#include "engine/material/brdf.h"

namespace odvr::app {
namespace {

std::string Lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// One MODEL:PARAMS term; its values are checked by the caller.
material::Brdf ParseTerm(const std::string& term, const std::string& where) {
  const auto colon = term.find(':');
  if (colon == std::string::npos) throw UsageError(where, "'" + term + "': want MODEL:PARAMS");
  const std::string model = Lower(term.substr(0, colon));
  const std::string rest = term.substr(colon + 1);
  const bool beckmann = rest.size() > 9 && Lower(rest.substr(rest.size() - 9)) == ",beckmann";
  const auto v = ParseNumberList(beckmann ? rest.substr(0, rest.size() - 9) : rest, where);
  const auto want = [&](std::size_t n, const char* form) {
    if (v.size() != n) throw UsageError(where, "'" + term + "': want " + form);
  };
  if (model == "lambert") {
    want(3, "lambert:R,G,B");
    return material::Lambertian{{v[0], v[1], v[2]}};
  }
  if (model == "phong") {
    want(4, "phong:R,G,B,N");
    return material::Phong{{v[0], v[1], v[2]}, v[3]};
  }
  if (model == "blinn") {
    want(4, "blinn:R,G,B,S");
    return material::BlinnPhong{{v[0], v[1], v[2]}, v[3]};
  }
  if (model == "ward") {
    want(4, "ward:R,G,B,ALPHA");
    return material::Ward{{v[0], v[1], v[2]}, v[3], v[3]};
  }
  if (model == "ct") {
    want(4, "ct:F0R,F0G,F0B,ALPHA[,beckmann]");
    return material::CookTorrance{{v[0], v[1], v[2]}, v[3], beckmann ? material::Ndf::kBeckmann : material::Ndf::kGgx};
  }
  if (model == "mr") {
    want(5, "mr:R,G,B,METALLIC,ROUGHNESS");
    return material::MetallicRoughness{{v[0], v[1], v[2]}, v[3], v[4]};
  }
  throw UsageError(where, "unknown BRDF '" + model + "' (lambert, phong, blinn, ward, ct, mr)");
}

}  // namespace

render::MaterialOverride ParseMaterialOverride(const std::string& text) {
  const std::string where = "--material " + text;
  render::MaterialOverride out;
  std::string spec = text;
  if (const auto eq = text.find('='); eq != std::string::npos) {
    out.material = text.substr(0, eq);
    spec = text.substr(eq + 1);
  }
  if (spec.empty()) throw UsageError(where, "no BRDF given");
  if (spec.find(':') == std::string::npos) {
    const auto v = ParseNumberList(spec, where);
    if (v.size() != 3) throw UsageError(where, "want KD,KS,N or MODEL:PARAMS[+MODEL:PARAMS]");
    // One unit of energy split between the two terms.
    if (!(v[0] + v[1] <= 1)) throw UsageError(where, "kd + ks must be at most 1");
    out.brdfs = {material::Lambertian{glm::dvec3(v[0])}, material::Phong{glm::dvec3(v[1]), v[2]}};
  } else {
    std::stringstream ss(spec);
    std::string term;
    while (std::getline(ss, term, '+')) out.brdfs.push_back(ParseTerm(term, where));
  }
  if (out.brdfs.empty() ||
      out.brdfs.size() > static_cast<std::size_t>(render::TripleProductRenderer::kTermsPerMaterial))
    throw UsageError(where, "give one or two BRDF terms");
  for (const auto& brdf : out.brdfs) {
    try {
      material::CheckBrdf(brdf);
    } catch (const Error& e) {
      throw UsageError(where, e.what());
    }
  }
  return out;
}

}  // namespace odvr::app
