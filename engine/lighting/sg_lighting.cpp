#include "engine/lighting/sg_lighting.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <glm/geometric.hpp>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/atomic_file.h"
#include "core/error.h"
#include "engine/sphere/equirect.h"
#include "engine/sphere/healpix.h"

namespace odvr::lighting {

int SgLighting::sg_count() const {
  int n = (constant.x != 0 || constant.y != 0 || constant.z != 0) ? 1 : 0;
  for (const auto& l : levels) n += static_cast<int>(l.indices.size());
  return n + static_cast<int>(peaks.size());
}

std::vector<RgbSg> SgLighting::ToSgs() const {
  std::vector<RgbSg> out;
  if (constant != glm::vec3(0)) out.push_back({{0, 1, 0}, 0.0, constant});
  for (const auto& l : levels) {
    const auto& hp = sphere::Healpix(l.level);
    for (std::size_t i = 0; i < l.indices.size(); ++i)
      out.push_back({hp.centre(l.indices[i]), l.lambda, l.amplitudes[i]});
  }
  out.insert(out.end(), peaks.begin(), peaks.end());
  return out;
}

glm::vec3 SgLighting::Evaluate(const glm::dvec3& direction) const {
  const glm::dvec3 d = glm::normalize(direction);
  glm::dvec3 sum(constant);
  for (const auto& g : ToSgs()) {
    if (g.lambda == 0) continue;  // the constant, already in
    sum += glm::dvec3(g.amplitude) * std::exp(g.lambda * (glm::dot(d, g.axis) - 1.0));
  }
  return glm::vec3(sum);
}

namespace {
// cos and sin of each column's longitude on a grid `w` wide, as sphere::EquirectDirection computes
// them (the same expressions, so the same bits), made once per width and thread: a pixel's
// direction then costs no trigonometry, where two sincos per pixel were a quarter of `odvr light`.
const std::vector<glm::dvec2>& ColumnLongitudes(int w) {
  thread_local std::vector<glm::dvec2> table;
  thread_local int table_width = 0;
  if (table_width != w) {
    table.resize(static_cast<std::size_t>(w));
    for (int col = 0; col < w; ++col) {
      const double lon = kPi * (1.0 - 2.0 * (col + 0.5) / w);
      table[static_cast<std::size_t>(col)] = {std::cos(lon), std::sin(lon)};
    }
    table_width = w;
  }
  return table;
}
}  // namespace

void AddSgToImage(const RgbSg& g, sphere::EquirectImage* image, double cutoff) {
  const int w = image->width, h = image->height;
  if (g.lambda <= 0) {
    for (std::size_t p = 0; p < image->pixel_count(); ++p)
      for (int k = 0; k < 3; ++k) image->rgb[3 * p + k] += g.amplitude[k];
    return;
  }
  // Cap: exp(λ(cos θ − 1)) > cutoff  ⇔  cos θ > 1 + ln(cutoff)/λ.
  const sphere::EquirectCap cap(g.axis, 1.0 + std::log(cutoff) / g.lambda, w, h);
  const std::vector<glm::dvec2>& longitudes = ColumnLongitudes(w);
  for (int row = cap.first_row(); row <= cap.last_row(); ++row) {
    const double lat = kPi / 2 - kPi * (row + 0.5) / h;
    const double cos_lat = std::cos(lat), sin_lat = std::sin(lat);
    const auto [start, n] = cap.Columns(row);
    for (int k = 0; k < n; ++k) {
      const int col = ((start + k) % w + w) % w;
      const glm::dvec2 lon = longitudes[static_cast<std::size_t>(col)];
      const glm::dvec3 d(cos_lat * lon.x, sin_lat, -cos_lat * lon.y);
      const double v = std::exp(g.lambda * (glm::dot(d, g.axis) - 1.0));
      if (v < cutoff) continue;
      float* p = image->at(col, row);
      for (int ch = 0; ch < 3; ++ch) p[ch] += static_cast<float>(v * g.amplitude[ch]);
    }
  }
}

sphere::EquirectImage SgLighting::Reconstruct(int width, int height) const {
  sphere::EquirectImage image(width, height);
  for (const auto& g : ToSgs()) AddSgToImage(g, &image);
  return image;
}

namespace {
nlohmann::json Vec(const glm::vec3& v) { return {v.x, v.y, v.z}; }
nlohmann::json Vec(const glm::dvec3& v) { return {v.x, v.y, v.z}; }

template <class V>
V ReadVec(const nlohmann::json& j, const std::string& where) {
  if (!j.is_array() || j.size() != 3) throw Error(where, "expected an array of 3 numbers");
  V v;
  for (int k = 0; k < 3; ++k) {
    if (!j[static_cast<std::size_t>(k)].is_number()) throw Error(where, "expected an array of 3 numbers");
    v[k] = j[static_cast<std::size_t>(k)].get<typename V::value_type>();
    if (!std::isfinite(static_cast<double>(v[k]))) throw Error(where, "has a non-finite number");
  }
  return v;
}
}  // namespace

nlohmann::json SgLighting::ToJson() const {
  nlohmann::json j;
  j["format"] = "odvr-sg-lighting";
  j["version"] = 1;
  j["frame"] = "odvr world: +Y up, +X forward, +Z right";
  j["constant"] = Vec(constant);
  j["levels"] = nlohmann::json::array();
  for (const auto& l : levels) {
    nlohmann::json amps = nlohmann::json::array();
    for (const auto& a : l.amplitudes) amps.push_back(Vec(a));
    j["levels"].push_back({{"level", l.level}, {"lambda", l.lambda}, {"indices", l.indices}, {"amplitudes", amps}});
  }
  j["peaks"] = nlohmann::json::array();
  for (const auto& p : peaks)
    j["peaks"].push_back({{"axis", Vec(p.axis)}, {"lambda", p.lambda}, {"amplitude", Vec(p.amplitude)}});
  return j;
}

SgLighting SgLighting::FromJson(const nlohmann::json& j, const std::string& where) {
  try {
    if (!j.is_object() || j.value("format", "") != "odvr-sg-lighting")
      throw Error(where, "not an odvr lighting file (format must be \"odvr-sg-lighting\")");
    if (j.value("version", 0) != 1) throw Error(where, "unsupported version (expected 1)");
    SgLighting m;
    m.constant = ReadVec<glm::vec3>(j.at("constant"), where + ": constant");
    for (const auto& lj : j.at("levels")) {
      SgLevel l;
      l.level = lj.at("level").get<int>();
      if (l.level < 0 || l.level > sphere::kMaxHealpixLevel) throw Error(where, "level out of range");
      l.lambda = lj.at("lambda").get<double>();
      if (!(l.lambda >= 0) || !std::isfinite(l.lambda)) throw Error(where, "lambda must be finite and >= 0");
      l.indices = lj.at("indices").get<std::vector<int>>();
      const int n = sphere::HealpixCount(l.level);
      for (int i : l.indices)
        if (i < 0 || i >= n)
          throw Error(where,
                      "HEALPix index " + std::to_string(i) + " out of range at level " + std::to_string(l.level));
      const auto& amps = lj.at("amplitudes");
      if (!amps.is_array() || amps.size() != l.indices.size())
        throw Error(where, "level " + std::to_string(l.level) + ": indices and amplitudes differ in length");
      for (const auto& a : amps) l.amplitudes.push_back(ReadVec<glm::vec3>(a, where + ": amplitude"));
      m.levels.push_back(std::move(l));
    }
    for (const auto& pj : j.at("peaks")) {
      RgbSg p;
      p.axis = ReadVec<glm::dvec3>(pj.at("axis"), where + ": peak axis");
      const double len = glm::length(p.axis);
      if (!(len > 0.5 && len < 2)) throw Error(where, "peak axis is not a unit vector");
      p.axis /= len;
      p.lambda = pj.at("lambda").get<double>();
      if (!(p.lambda >= 0) || !std::isfinite(p.lambda)) throw Error(where, "peak lambda must be finite and >= 0");
      p.amplitude = ReadVec<glm::vec3>(pj.at("amplitude"), where + ": peak amplitude");
      m.peaks.push_back(p);
    }
    return m;
  } catch (const nlohmann::json::exception& e) {
    throw Error(where, std::string("malformed lighting JSON: ") + e.what());
  }
}

void SgLighting::Save(const std::filesystem::path& path) const { WriteTextAtomically(path, ToJson().dump(1) + "\n"); }

SgLighting SgLighting::Load(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw Error(path.string(), "cannot open");
  nlohmann::json j;
  try {
    in >> j;
  } catch (const nlohmann::json::exception& e) {
    throw Error(path.string(), std::string("not valid JSON: ") + e.what());
  }
  return FromJson(j, path.string());
}

SgLighting SgLighting::Blend(const std::vector<std::pair<const SgLighting*, double>>& weighted) {
  SgLighting out;
  std::map<int, std::map<int, glm::vec3>> per_level;
  std::map<int, double> lambdas;
  for (const auto& [model, w] : weighted) {
    if (!model || w == 0) continue;
    const float wf = static_cast<float>(w);
    out.constant += wf * model->constant;
    for (const auto& l : model->levels) {
      lambdas[l.level] = l.lambda;
      for (std::size_t i = 0; i < l.indices.size(); ++i) per_level[l.level][l.indices[i]] += wf * l.amplitudes[i];
    }
    for (auto p : model->peaks) {
      p.amplitude *= wf;
      out.peaks.push_back(p);
    }
  }
  for (const auto& [level, entries] : per_level) {
    SgLevel l;
    l.level = level;
    l.lambda = lambdas[level];
    for (const auto& [index, amp] : entries) {
      l.indices.push_back(index);
      l.amplitudes.push_back(amp);
    }
    out.levels.push_back(std::move(l));
  }
  return out;
}

}  // namespace odvr::lighting
