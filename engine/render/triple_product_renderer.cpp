#include "engine/render/triple_product_renderer.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <chrono>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <glm/matrix.hpp>
#include <map>
#include <optional>
#include <sstream>

#include "core/constants.h"
#include "core/error.h"
#include "core/timing.h"
#include "engine/gl/context.h"
#include "engine/gl/objects.h"
#include "engine/gl/shader_library.h"
#include "engine/render/triple_product_internal.h"
#include "engine/scene/gltf_scene.h"
#include "engine/sphere/equirect.h"
#include "engine/sphere/healpix.h"
#include "engine/visibility/triangle_bvh.h"
#include "engine/visibility/voxelizer_gpu.h"

namespace odvr::render {
namespace {

using Clock = std::chrono::steady_clock;

// render_shade.comp's material-term types (brdf_lobes.glsl).
enum TermType : int {
  kNone = 0,
  kGltf = 1,
  kLambertian = 2,
  kPhong = 3,
  kBlinnPhong = 4,
  kWard = 5,
  kCookTorrance = 6,
  kMetallicRoughness = 7
};

struct GpuTerm {
  glm::ivec4 type{0};
  glm::vec4 color{0};
  glm::vec4 params{0};
};

GpuTerm ToGpuTerm(const material::Brdf& brdf) {
  GpuTerm t;
  std::visit(
      [&](const auto& m) {
        using T = std::decay_t<decltype(m)>;
        if constexpr (std::is_same_v<T, material::Lambertian>) {
          t.type.x = kLambertian;
          t.color = glm::vec4(glm::vec3(m.albedo), 0);
        } else if constexpr (std::is_same_v<T, material::Phong>) {
          t.type.x = kPhong;
          t.color = glm::vec4(glm::vec3(m.ks), 0);
          t.params.x = static_cast<float>(m.exponent);
        } else if constexpr (std::is_same_v<T, material::BlinnPhong>) {
          t.type.x = kBlinnPhong;
          t.color = glm::vec4(glm::vec3(m.ks), 0);
          t.params.x = static_cast<float>(m.exponent);
        } else if constexpr (std::is_same_v<T, material::Ward>) {
          if (std::abs(m.alpha_x - m.alpha_y) > 1e-9 * std::max(m.alpha_x, m.alpha_y))
            throw Error("material override", "the renderer shades isotropic Ward only (alpha_x = alpha_y)");
          t.type.x = kWard;
          t.color = glm::vec4(glm::vec3(m.rho_s), 0);
          t.params.x = static_cast<float>(m.alpha_x);
        } else if constexpr (std::is_same_v<T, material::CookTorrance>) {
          t.type.x = kCookTorrance;
          t.color = glm::vec4(glm::vec3(m.f0), 0);
          t.params.x = static_cast<float>(m.alpha);
          t.params.y = m.ndf == material::Ndf::kBeckmann ? 1.f : 0.f;
        } else {
          t.type.x = kMetallicRoughness;
          t.color = glm::vec4(glm::vec3(m.base_color), 0);
          t.params.x = static_cast<float>(m.metallic);
          t.params.y = static_cast<float>(m.roughness);
        }
      },
      brdf);
  return t;
}

std::string Lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::vector<double> ParseNumbers(const std::string& list, const std::string& where) {
  std::vector<double> out;
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      std::size_t used = 0;
      const double v = std::stod(item, &used);
      if (used != item.size() || !std::isfinite(v)) throw std::invalid_argument(item);
      out.push_back(v);
    } catch (const std::exception&) {
      throw UsageError(where, "'" + item + "' is not a number");
    }
  }
  return out;
}

material::Brdf ParseTerm(const std::string& term, const std::string& where) {
  const auto colon = term.find(':');
  if (colon == std::string::npos) {
    const auto v = ParseNumbers(term, where);
    if (v.size() != 3) throw UsageError(where, "'" + term + "': want KD,KS,N or MODEL:PARAMS");
    throw UsageError(where, "internal: KD,KS,N is two terms");  // handled by the caller
  }
  const std::string model = Lower(term.substr(0, colon));
  const std::string rest = term.substr(colon + 1);
  const bool beckmann = rest.size() > 9 && Lower(rest.substr(rest.size() - 9)) == ",beckmann";
  const auto v = ParseNumbers(beckmann ? rest.substr(0, rest.size() - 9) : rest, where);
  const auto want = [&](std::size_t n, const char* form) {
    if (v.size() != n) throw UsageError(where, "'" + term + "': want " + form);
  };
  const auto in01 = [&](double x, const char* name) {
    if (x < 0 || x > 1) throw UsageError(where, "'" + term + "': " + name + " must be in [0, 1]");
  };
  if (model == "lambert") {
    want(3, "lambert:R,G,B");
    for (double x : v) in01(x, "albedo");
    return material::Lambertian{{v[0], v[1], v[2]}};
  }
  if (model == "phong" || model == "blinn") {
    want(4, model == "phong" ? "phong:R,G,B,N" : "blinn:R,G,B,S");
    for (int i = 0; i < 3; ++i) in01(v[static_cast<std::size_t>(i)], "ks");
    if (v[3] < 0 || v[3] > 1e5) throw UsageError(where, "'" + term + "': exponent must be in [0, 1e5]");
    if (model == "phong") return material::Phong{{v[0], v[1], v[2]}, v[3]};
    return material::BlinnPhong{{v[0], v[1], v[2]}, v[3]};
  }
  if (model == "ward") {
    want(4, "ward:R,G,B,ALPHA");
    for (int i = 0; i < 3; ++i) in01(v[static_cast<std::size_t>(i)], "rho_s");
    if (!(v[3] > 0 && v[3] <= 1)) throw UsageError(where, "'" + term + "': alpha must be in (0, 1]");
    return material::Ward{{v[0], v[1], v[2]}, v[3], v[3]};
  }
  if (model == "ct") {
    want(4, "ct:F0R,F0G,F0B,ALPHA[,beckmann]");
    for (int i = 0; i < 3; ++i) in01(v[static_cast<std::size_t>(i)], "f0");
    if (!(v[3] > 0 && v[3] <= 1)) throw UsageError(where, "'" + term + "': alpha must be in (0, 1]");
    return material::CookTorrance{{v[0], v[1], v[2]}, v[3], beckmann ? material::Ndf::kBeckmann : material::Ndf::kGgx};
  }
  if (model == "mr") {
    want(5, "mr:R,G,B,METALLIC,ROUGHNESS");
    for (double x : v) in01(x, "every value");
    return material::MetallicRoughness{{v[0], v[1], v[2]}, v[3], v[4]};
  }
  throw UsageError(where, "unknown BRDF '" + model + "' (lambert, phong, blinn, ward, ct, mr)");
}

// Everything of the lighting that the shading stage reads, in the world frame.
detail::PreparedLighting Prepare(const lighting::SgLighting& model, const glm::dmat3& world_from_lighting,
                                 int max_levels) {
  detail::PreparedLighting p;
  p.env_from_world = glm::transpose(world_from_lighting);
  p.constant = model.constant;
  p.sg_count = model.constant != glm::vec3(0) ? 1 : 0;
  int deepest = -1;
  for (const auto& l : model.levels)
    if (l.level < max_levels) deepest = std::max(deepest, l.level);
  if (deepest >= 0) {
    p.srbfs.assign(static_cast<std::size_t>(lighting::GlobalSrbfIndex(max_levels, 0)), {});
    for (const auto& l : model.levels) {
      if (l.level >= max_levels) continue;
      const auto& hp = sphere::Healpix(l.level);
      for (std::size_t i = 0; i < l.indices.size(); ++i) {
        auto& s = p.srbfs[static_cast<std::size_t>(lighting::GlobalSrbfIndex(l.level, l.indices[i]))];
        s.axis = world_from_lighting * hp.centre(l.indices[i]);
        s.lambda = l.lambda;
        s.amplitude += l.amplitudes[i];
        ++p.sg_count;
      }
    }
  }
  std::vector<lighting::RgbSg> peaks = model.peaks;
  // Brightest first: ∫G μ summed over the channels.
  std::stable_sort(peaks.begin(), peaks.end(), [](const auto& a, const auto& b) {
    return lighting::Integral({a.axis, a.lambda, 1.0}) * (a.amplitude.x + a.amplitude.y + a.amplitude.z) >
           lighting::Integral({b.axis, b.lambda, 1.0}) * (b.amplitude.x + b.amplitude.y + b.amplitude.z);
  });
  for (auto& pk : peaks) {
    pk.axis = glm::normalize(world_from_lighting * pk.axis);
    p.peaks.push_back(pk);
  }
  p.sg_count += static_cast<int>(p.peaks.size());
  // One pass over the lights for the ground: its irradiance from above (channels summed), of
  // which the traced peaks' shares, and the lighting's cosine-weighted mean radiance below the
  // horizon (E from below / π), the traced peaks' part apart.
  const glm::dvec3 up(0, 1, 0), down(0, -1, 0);
  double total = 0;
  glm::dvec3 e_down(0), e_traced(0);
  std::vector<double> peak_e;
  const auto add = [&](const glm::vec3& amplitude, const glm::dvec3& axis, double lambda, bool traced) {
    const double e_up = material::ClampedCosineIntegral(up, {axis, lambda, 1.0}) *
                        static_cast<double>(amplitude.x + amplitude.y + amplitude.z);
    total += e_up;
    if (traced) peak_e.push_back(e_up);
    (traced ? e_traced : e_down) += glm::dvec3(amplitude) * material::ClampedCosineIntegral(down, {axis, lambda, 1.0});
  };
  add(p.constant, up, 0.0, false);
  for (const auto& s : p.srbfs)
    if (s.amplitude != glm::vec3(0)) add(s.amplitude, s.axis, s.lambda, false);
  for (std::size_t k = 0; k < p.peaks.size(); ++k)
    add(p.peaks[k].amplitude, p.peaks[k].axis, p.peaks[k].lambda, k < TripleProductRenderer::kMaxPeakCones);
  for (double e : peak_e) p.ground_peak_share.push_back(total > 0 ? e / total : 0.0);
  p.ground_radiance = glm::vec3(e_down / 3.14159265358979323846);
  p.ground_radiance_traced_peaks = glm::vec3(e_traced / 3.14159265358979323846);
  return p;
}

// The traced peaks for the ground's lit fraction (detail::GroundLitFraction): axis and cone
// half-angle, and share of the ground's irradiance; none without peak cones.
void SetGroundPeakUniforms(gl::Program& p, const detail::PreparedLighting& l, bool peak_cones) {
  std::vector<float> axes, shares;
  const std::size_t n = peak_cones ? l.ground_peak_share.size() : 0;
  for (std::size_t k = 0; k < n; ++k) {
    const auto& pk = l.peaks[k];
    axes.insert(axes.end(),
                {static_cast<float>(pk.axis.x), static_cast<float>(pk.axis.y), static_cast<float>(pk.axis.z),
                 static_cast<float>(std::min(detail::HalfValueAngle(pk.lambda), visibility::kMaxConeHalfAngle))});
    shares.push_back(static_cast<float>(l.ground_peak_share[k]));
  }
  p.Set("uGroundPeakCount", static_cast<int>(n));
  if (n > 0) {
    glProgramUniform4fv(p.id(), p.Uniform("uGroundPeakAxis"), static_cast<GLsizei>(n), axes.data());
    glProgramUniform1fv(p.id(), p.Uniform("uGroundPeakShare"), static_cast<GLsizei>(n), shares.data());
  }
}

glm::vec4 LightVec(const glm::dvec3& a, double l) { return glm::vec4(glm::vec3(a), static_cast<float>(l)); }

template <class T>
gl::Buffer MakeBuffer(const std::vector<T>& data) {
  gl::Buffer b;
  if (data.empty()) {
    b.Allocate(16);
  } else {
    b.SetData(data);
  }
  return b;
}

// Bilinear look-up with GL's rules (texel centres at +0.5), longitude wrapping, latitude clamped.
glm::vec3 SampleEquirect(const sphere::EquirectImage& img, const glm::dvec3& d) {
  const glm::dvec2 px = sphere::EquirectPixel(d, img.width, img.height);
  const double x = px.x - 0.5, y = std::clamp(px.y - 0.5, 0.0, img.height - 1.0);
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const double fx = x - x0, fy = y - y0;
  const auto at = [&](int c, int r) {
    c = ((c % img.width) + img.width) % img.width;
    r = std::clamp(r, 0, img.height - 1);
    const float* v = img.at(c, r);
    return glm::dvec3(v[0], v[1], v[2]);
  };
  return glm::vec3((1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x0 + 1, y0)) +
                   fy * ((1 - fx) * at(x0, y0 + 1) + fx * at(x0 + 1, y0 + 1)));
}

// The uniforms of cone_trace.glsl, which the SG shader and the Monte-Carlo one both include.
void SetConeTraceUniforms(gl::Program& program, const visibility::VoxelGridSpec& spec, bool has_geometry,
                          const visibility::ConeTraceOptions& trace) {
  program
      .Set("uVoxelOrigin", static_cast<float>(spec.origin.x), static_cast<float>(spec.origin.y),
           static_cast<float>(spec.origin.z))
      .Set("uVoxelSize", static_cast<float>(spec.voxel_size))
      .Set("uVoxelSide", static_cast<float>(spec.side()))
      .Set("uVoxelTopLevel", has_geometry ? spec.levels() - 1 : -1)
      .Set("uConeStartOffset", static_cast<float>(trace.start_offset_voxels))
      .Set("uConeStepScale", static_cast<float>(trace.step_scale))
      .Set("uConeMaxDistance", static_cast<float>(trace.max_distance))
      .Set("uConeOpaque", static_cast<float>(trace.opaque_threshold))
      .Set("uConePartialExponent", static_cast<float>(trace.partial_opacity_exponent));
}

// RenderOptions::shading_rate 2: 1 for each pixel that was shaded (the lower right of every
// 2×2 block, every pixel of a flagged block), 0 for the filled ones.
std::vector<std::uint8_t> HalfRateShaded(const std::vector<std::uint8_t>& block_flags, int w, int h) {
  std::vector<std::uint8_t> shaded(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      shaded[static_cast<std::size_t>(y) * w + x] =
          block_flags[static_cast<std::size_t>(y / 2) * ((w + 1) / 2) + x / 2] || (x % 2 == 1 && y % 2 == 1) ? 1 : 0;
  return shaded;
}

}  // namespace

namespace detail {

CountSums SumCountsOnGpu(gl::Program& program, gl::Buffer& counts, gl::Buffer* pixel_flags, gl::Buffer& group_totals,
                         gl::Texture& sample_car, int samples_width, int samples_height, int pixels) {
  constexpr long long kGroup = 256, kMaxGroups = 256;
  // Enough invocations to fill a GPU, few enough that each sums a stride of samples first.
  const long long covered = std::max<long long>(static_cast<long long>(samples_width) * samples_height, pixels);
  const long long groups = std::clamp<long long>((covered + kGroup - 1) / kGroup, 1, kMaxGroups);
  const std::size_t bytes = static_cast<std::size_t>(kMaxGroups * kCountTotals) * sizeof(std::uint32_t);
  if (!group_totals || group_totals.size() < bytes) {
    group_totals = gl::Buffer();
    group_totals.Allocate(bytes);
  }
  counts.BindBase(GL_SHADER_STORAGE_BUFFER, 0);
  if (pixel_flags) pixel_flags->BindBase(GL_SHADER_STORAGE_BUFFER, 1);
  group_totals.BindBase(GL_SHADER_STORAGE_BUFFER, 2);
  sample_car.BindImage(0, GL_READ_ONLY);
  glProgramUniform2i(program.id(), program.Uniform("uSamplesSize"), samples_width, samples_height);
  program.Set("uPixels", pixels).Set("uHasFlags", pixel_flags ? 1 : 0);
  program.Use().DispatchCovering(static_cast<unsigned>(groups * kGroup));
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  const std::vector<std::uint32_t> t =
      group_totals.Read<std::uint32_t>(static_cast<std::size_t>(groups * kCountTotals));
  CountSums s;
  for (long long g = 0; g < groups; ++g) {
    const std::uint32_t* v = &t[static_cast<std::size_t>(g * kCountTotals)];
    const auto pair = [&](int i) {
      return static_cast<long long>(v[3 + 2 * i] | (static_cast<std::uint64_t>(v[4 + 2 * i]) << 32));
    };
    s.car += v[0];
    s.ground += v[1];
    s.pixels_sampled_fully += v[2];
    s.lobes += pair(0);
    s.cones += pair(1);
    s.sgs += pair(2);
    s.triples += pair(3);
    s.cones_total += pair(4);
    s.triples_total += pair(5);
  }
  return s;
}

GroundLitMapLayout GroundLitMapLayoutFor(const visibility::VoxelGridSpec& spec, const PreparedLighting& l,
                                         bool peak_cones, const glm::dvec2& ground_centre, double ground_half_size,
                                         int max_texels) {
  GroundLitMapLayout layout;
  if (max_texels <= 0) return layout;
  const glm::dvec2 square_lo = ground_centre - ground_half_size, square_hi = ground_centre + ground_half_size;
  const glm::dvec3 lo = spec.origin, hi = spec.origin + spec.side();
  // The up cone: the cube's footprint.
  glm::dvec2 r_lo(lo.x, lo.z), r_hi(hi.x, hi.z);
  for (std::size_t k = 0; peak_cones && k < l.ground_peak_share.size(); ++k) {
    if (l.ground_peak_share[k] <= 0) continue;
    const glm::dvec3 a = glm::normalize(l.peaks[k].axis);
    if (!(a.y > 1e-6)) {  // along or under the horizon: its shadow may reach anywhere
      r_lo = square_lo;
      r_hi = square_hi;
      break;
    }
    // The cube's shadow along the axis: its corners moved down the axis to the ground (a corner
    // under the ground lands on the sun's side, which only widens the rectangle).
    for (int c = 0; c < 8; ++c) {
      const glm::dvec3 corner((c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z);
      const glm::dvec3 q = corner - (corner.y / a.y) * a;
      r_lo = glm::min(r_lo, glm::dvec2(q.x, q.z));
      r_hi = glm::max(r_hi, glm::dvec2(q.x, q.z));
    }
  }
  r_lo = glm::max(r_lo, square_lo);
  r_hi = glm::min(r_hi, square_hi);
  if (!(r_hi.x > r_lo.x && r_hi.y > r_lo.y)) return layout;  // the cube's shadows miss the catcher
  const glm::dvec2 extent = r_hi - r_lo;
  // Two texels beyond the rectangle's interior span: one on each side.
  layout.spacing = std::max(spec.voxel_size, std::max(extent.x, extent.y) / std::max(1, max_texels - 3));
  // The quotient may land a rounding above an integer: not one more texel for it.
  layout.width = static_cast<int>(std::ceil(extent.x / layout.spacing - 1e-9)) + 3;
  layout.height = static_cast<int>(std::ceil(extent.y / layout.spacing - 1e-9)) + 3;
  layout.origin = r_lo - layout.spacing;
  return layout;
}

double SampleGroundLitMap(const GroundLitMapLayout& layout, const std::vector<float>& texels, double x, double z) {
  if (layout.width <= 0) return 1.0;
  const double fx = (x - layout.origin.x) / layout.spacing, fz = (z - layout.origin.y) / layout.spacing;
  if (!(fx >= 0 && fz >= 0 && fx < layout.width - 1 && fz < layout.height - 1)) return 1.0;
  const int i = static_cast<int>(fx), j = static_cast<int>(fz);
  const double tx = fx - i, tz = fz - j;
  const auto at = [&](int di, int dj) {
    return static_cast<double>(texels[static_cast<std::size_t>(j + dj) * static_cast<std::size_t>(layout.width) +
                                      static_cast<std::size_t>(i + di)]);
  };
  return (1 - tz) * ((1 - tx) * at(0, 0) + tx * at(1, 0)) + tz * ((1 - tx) * at(0, 1) + tx * at(1, 1));
}

}  // namespace detail

// --- camera, overrides, options -----------------------------------------------------------------

PinholeCamera PinholeCamera::LookAt(const glm::dvec3& position, const glm::dvec3& target, double vfov_deg, int width,
                                    int height, const glm::dvec3& up) {
  const glm::dvec3 forward = target - position;
  if (!(glm::length(forward) > 1e-9)) throw Error("camera", "target coincides with the position");
  const glm::dvec3 z = glm::normalize(forward);
  const glm::dvec3 side = glm::cross(z, up);
  if (!(glm::length(side) > 1e-9 * glm::length(up))) throw Error("camera", "view direction is parallel to up");
  const glm::dvec3 x = glm::normalize(side);
  PinholeCamera c;
  c.position = position;
  c.world_from_camera = glm::dmat3(x, glm::cross(z, x), z);
  c.vfov_deg = vfov_deg;
  c.width = width;
  c.height = height;
  c.Check();
  return c;
}

double PinholeCamera::focal_px() const { return 0.5 * height / std::tan(0.5 * vfov_deg * kPi / 180.0); }

glm::dvec3 PinholeCamera::Ray(double x, double y) const {
  const double f = focal_px();
  return glm::normalize(world_from_camera * glm::dvec3((x - 0.5 * width) / f, (y - 0.5 * height) / f, 1.0));
}

void PinholeCamera::Check() const {
  if (!(vfov_deg > 0.1 && vfov_deg < 179)) throw Error("camera fov", "must be in (0.1, 179) degrees");
  if (width < 1 || height < 1 || width > kMaxSide || height > kMaxSide)
    throw Error("camera size", "must be 1.." + std::to_string(kMaxSide) + " pixels per side, got " +
                                   std::to_string(width) + "x" + std::to_string(height));
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(position[i])) throw Error("camera position", "must be finite");
}

MaterialOverride ParseMaterialOverride(const std::string& text) {
  const std::string where = "--material " + text;
  MaterialOverride out;
  std::string spec = text;
  if (const auto eq = text.find('='); eq != std::string::npos) {
    out.material = text.substr(0, eq);
    spec = text.substr(eq + 1);
  }
  if (spec.empty()) throw UsageError(where, "no BRDF given");
  if (spec.find(':') == std::string::npos) {
    const auto v = ParseNumbers(spec, where);
    if (v.size() != 3) throw UsageError(where, "want KD,KS,N or MODEL:PARAMS[+MODEL:PARAMS]");
    if (v[0] < 0 || v[0] > 1 || v[1] < 0 || v[1] > 1 || v[0] + v[1] > 1)
      throw UsageError(where, "kd and ks must be in [0, 1] with kd + ks <= 1");
    if (v[2] < 0 || v[2] > 1e5) throw UsageError(where, "the Phong exponent must be in [0, 1e5]");
    out.brdfs = {material::Lambertian{glm::dvec3(v[0])}, material::Phong{glm::dvec3(v[1]), v[2]}};
    return out;
  }
  std::stringstream ss(spec);
  std::string term;
  while (std::getline(ss, term, '+')) out.brdfs.push_back(ParseTerm(term, where));
  if (out.brdfs.empty() || out.brdfs.size() > static_cast<std::size_t>(TripleProductRenderer::kTermsPerMaterial))
    throw UsageError(where, "give one or two BRDF terms");
  return out;
}

long long detail::FirstShadingPassPixels(const RenderOptions& options, int width, int height) {
  const long long w = width, h = height, k = options.supersample;
  if (options.shading_rate == 2) return ((w + 1) / 2) * ((h + 1) / 2);
  if (k > 1 && options.supersample_contrast > 0 && options.monte_carlo_samples == 0) return w * h;
  return k * w * k * h;
}

int ShadeLanesFor(long long first_pass_pixels, bool software_renderer) {
  return !software_renderer && first_pass_pixels <= kAutoShadeLanesMaxPixels ? 4 : 1;
}

void RenderOptions::Check() const {
  if (lighting_levels < 1 || lighting_levels > 6) throw Error("render levels", "must be in 1..6");
  if (!read_composite && read_layers)
    throw Error("render read_composite", "can be off only with read_layers off (the layers include it)");
  if (cone_rings < 0 || cone_rings > 3) throw Error("render cones", "rings must be in 0..3 (1, 7, 19 or 37 cones)");
  if (shade_lanes != 0 && shade_lanes != 1 && shade_lanes != 2 && shade_lanes != 4)
    throw Error("render shade_lanes", "must be 0 (each render picks), 1, 2 or 4, got " + std::to_string(shade_lanes));
  if (voxel_resolution < 64 || voxel_resolution > 512 || (voxel_resolution & (voxel_resolution - 1)) != 0)
    throw Error("render voxels", "must be a power of two in 64..512, got " + std::to_string(voxel_resolution));
  if (!(ground_half_size > 0)) throw Error("render ground_half_size", "must be positive");
  if (!(surface_offset_voxels >= 0 && surface_offset_voxels <= 8))
    throw Error("render surface_offset_voxels", "must be in [0, 8]");
  if (!(bounce_step_voxels > 0 && bounce_step_voxels <= 16))
    throw Error("render bounce_step_voxels", "must be in (0, 16]");
  if (bounce_steps < 1 || bounce_steps > 1024) throw Error("render bounce_steps", "must be in 1..1024");
  if (!(bounce_thickness_voxels > 0 && bounce_thickness_voxels <= 64))
    throw Error("render bounce_thickness_voxels", "must be in (0, 64]");
  if (!(overlap_min_retention > 0 && overlap_min_retention < 1))
    throw Error("render overlap_min_retention", "must be in (0, 1)");
  if (!(overlap_cutoff > 0 && overlap_cutoff < 1)) throw Error("render overlap_cutoff", "must be in (0, 1)");
  if (ground_lit_map_texels != 0 && (ground_lit_map_texels < 8 || ground_lit_map_texels > 1024))
    throw Error("render ground_lit_map_texels", "must be 0 (trace per cone) or in [8, 1024]");
  for (const auto& m : materials)
    if (m.brdfs.empty() || m.brdfs.size() > static_cast<std::size_t>(TripleProductRenderer::kTermsPerMaterial))
      throw Error("render material override", "needs one or two BRDF terms");
  if (monte_carlo_samples < 0 || monte_carlo_samples > 1 << 20)
    throw Error("render monte_carlo_samples", "must be in 0..2^20");
  if (supersample < 1 || supersample > kMaxSupersample)
    throw Error("render supersample",
                "must be in 1.." + std::to_string(kMaxSupersample) + ", got " + std::to_string(supersample));
  if (!(supersample_contrast >= 0 && supersample_contrast <= 1))
    throw Error("render supersample_contrast", "must be in [0, 1]");
  if (shading_rate != 1 && shading_rate != 2)
    throw Error("render shading_rate", "must be 1 or 2, got " + std::to_string(shading_rate));
  if (shading_rate == 2 && supersample > 1)
    throw Error("render shading_rate", "2 (a pixel per 2x2 block) and supersample > 1 exclude each other");
  if (shading_rate == 2 && monte_carlo_samples > 0)
    throw Error("render shading_rate", "2 is for the SG shader: the Monte-Carlo baseline shades every pixel");
  visibility::ConeSubsampleOptions c = cones;
  c.rings = cone_rings;
  c.Check();
  trace.Check();
}

// --- the renderer ---------------------------------------------------------------------------------

struct TripleProductRenderer::Impl {
  struct Primitive {
    gl::VertexArray vao;
    gl::Buffer positions, normals, uv0, uv1, tangents, indices;
    GLsizei index_count = 0;
    int material = 0;
  };
  std::vector<Primitive> primitives;
  std::vector<scene::PbrMaterial> materials;
  std::map<std::pair<int, bool>, gl::Texture> textures;  // (image, sRGB)
  gl::Texture white{gl::NoCreate};
  detail::MaterialTerms material_terms;
  std::vector<glm::vec3> emission;  // per material: the radiance it emits (glTF emissive)
  gl::Buffer terms_buffer{gl::NoCreate}, ndf_table{gl::NoCreate}, cosine_table{gl::NoCreate};

  std::vector<glm::vec3> triangles;  // world
  scene::Bounds bounds;
  visibility::VoxelGridSpec spec;
  bool has_geometry = false;
  std::unique_ptr<visibility::VoxelizerGpu> voxelizer;
  gl::Buffer triangle_buffer{gl::NoCreate};
  std::unique_ptr<visibility::VoxelGrid> cpu_grid;

  std::shared_ptr<const lighting::OverlapBins> bins;
  gl::Buffer bin_levels{gl::NoCreate}, bin_begin{gl::NoCreate}, bin_srbfs{gl::NoCreate};
  detail::PreparedLighting lighting;
  gl::Buffer srbf_buffer{gl::NoCreate}, peak_buffer{gl::NoCreate};

  sphere::EquirectImage environment, background_image;
  gl::Texture environment_texture{gl::NoCreate};
  bool background_is_image = false;
  // Set by SetBackgroundRotation: the environment's own rotation for the background, apart from
  // the lighting's (a player shows one frame's panorama and lights the car by another's).
  std::optional<glm::dmat3> background_from_world;
  // The Monte-Carlo baseline's sampling tables of `environment` (render_mc.comp).
  gl::Buffer env_row_cdf{gl::NoCreate}, env_col_cdf{gl::NoCreate}, env_texel_prob{gl::NoCreate};
  gl::Texture mc_environment{gl::NoCreate};
  gl::Program mc_program{gl::NoCreate};
  // RenderOptions::monte_carlo_exact_visibility: the BVH's nodes and triangles.
  std::unique_ptr<visibility::TriangleBvh> bvh;  // the CPU reference's
  gl::Buffer bvh_nodes{gl::NoCreate}, bvh_triangles{gl::NoCreate};
  int bvh_triangle_count = 0;

  // render_shade.comp per lane count (1, 2, 4), compiled when a render first asks for it.
  std::array<gl::Program, 3> shade_programs{gl::Program(gl::NoCreate), gl::Program(gl::NoCreate),
                                            gl::Program(gl::NoCreate)};
  int cone_rings = 0;
  bool software_renderer = false;
  gl::Program& ShadeProgram(int lanes) {
    gl::Program& p = shade_programs[static_cast<std::size_t>(lanes == 4 ? 2 : lanes == 2 ? 1 : 0)];
    if (!p)
      p = gl::ShaderLibrary::Compute("render_shade.comp", "#define CONE_RINGS " + std::to_string(cone_rings) +
                                                              "\n#define SHADE_LANES " + std::to_string(lanes) + "\n");
    return p;
  }
  gl::Program gbuffer_program{gl::NoCreate}, composite_program{gl::NoCreate}, resolve_program{gl::NoCreate},
      flag_program{gl::NoCreate}, counts_program{gl::NoCreate};
  int fb_width = 0, fb_height = 0, out_width = 0, out_height = 0;
  gl::Framebuffer framebuffer{gl::NoCreate};
  gl::Texture g_position{gl::NoCreate}, g_normal{gl::NoCreate}, g_base{gl::NoCreate}, g_depth{gl::NoCreate};
  gl::Texture car_layer{gl::NoCreate}, shadow_layer{gl::NoCreate}, composite_layer{gl::NoCreate},
      background_layer{gl::NoCreate};
  // RenderOptions::supersample > 1: the shading's car and shadow layers at the G-buffer's size,
  // resolved into car_layer and shadow_layer at the output's.
  gl::Texture shaded_car{gl::NoCreate}, shaded_shadow{gl::NoCreate};
  // RenderOptions::supersample_contrast: per output pixel, and the flagged ones listed (a count,
  // then the pixels' indices).
  gl::Buffer pixel_flags{gl::NoCreate}, flagged_list{gl::NoCreate};
  gl::Buffer counts{gl::NoCreate};
  // render_shade.comp's GroundTable: per cone of the ground's lobe, per traced peak, and the
  // unshadowed sum, the lighting the ground sees through it (one vec4 each).
  gl::Buffer ground_table{gl::NoCreate};
  gl::Buffer ground_lit_map{gl::NoCreate};  // render_shade.comp's GroundLitMap (RenderOptions::ground_lit_map_texels)
  // RenderOptions::shading_rate 2: per 2×2 block its flag, and the flagged ones listed (a count,
  // then the blocks' indices), as pixel_flags and flagged_list are for supersampling.
  gl::Buffer block_flags{gl::NoCreate}, block_list{gl::NoCreate};
  // render_list_args.comp's output: the listed pass's work groups (x, y, z).
  gl::Buffer list_args{gl::NoCreate};
  gl::Program list_args_program{gl::NoCreate};
  gl::Program fill_program{gl::NoCreate};  // render_fill.comp (shading_rate 2)
  gl::Buffer count_totals{gl::NoCreate};   // RenderOptions::read_layers off: render_counts.comp's group sums
  gl::ReadbackBuffer readback;             // the layers and counts on their way to the CPU
  std::array<GLuint, 5> stage_queries{};   // GL timestamps between the GPU path's stages

  Impl() = default;
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
  ~Impl() {
    if (stage_queries[0] != 0) glDeleteQueries(static_cast<GLsizei>(stage_queries.size()), stage_queries.data());
  }

  const gl::Texture& TextureFor(const scene::GltfScene& model, int image, bool srgb) {
    auto key = std::make_pair(image, srgb);
    auto it = textures.find(key);
    if (it != textures.end()) return it->second;
    const auto& img = model.images.at(static_cast<std::size_t>(image));
    const int levels = 1 + static_cast<int>(std::floor(std::log2(std::max(img.width, img.height))));
    gl::Texture t = gl::Texture::Create2D(srgb ? GL_SRGB8_ALPHA8 : GL_RGBA8, img.width, img.height, levels);
    t.Upload2D(GL_RGBA, GL_UNSIGNED_BYTE, img.rgba.data()).GenerateMipmaps();
    t.SetWrap(GL_REPEAT, GL_REPEAT).SetFilter(GL_LINEAR_MIPMAP_LINEAR, GL_LINEAR);
    return textures.emplace(key, std::move(t)).first->second;
  }

  // The G-buffer and the shading at w × h, the output at out_w × out_h (smaller when supersampled).
  void EnsureTargets(int w, int h, int out_w, int out_h) {
    if (w == fb_width && h == fb_height && out_w == out_width && out_h == out_height) return;
    fb_width = w;
    fb_height = h;
    out_width = out_w;
    out_height = out_h;
    const auto rgba32 = [&](int tw, int th) {
      gl::Texture t = gl::Texture::Create2D(GL_RGBA32F, tw, th);
      t.SetFilter(GL_NEAREST, GL_NEAREST);
      return t;
    };
    g_position = rgba32(w, h);
    g_normal = rgba32(w, h);
    g_base = rgba32(w, h);
    car_layer = rgba32(out_w, out_h);
    shadow_layer = rgba32(out_w, out_h);
    composite_layer = rgba32(out_w, out_h);
    background_layer = rgba32(out_w, out_h);
    const bool supersampled = w != out_w || h != out_h;
    shaded_car = supersampled ? rgba32(w, h) : gl::Texture(gl::NoCreate);
    shaded_shadow = supersampled ? rgba32(w, h) : gl::Texture(gl::NoCreate);
    pixel_flags = gl::Buffer(gl::NoCreate);
    flagged_list = gl::Buffer(gl::NoCreate);
    if (supersampled) {
      pixel_flags = gl::Buffer();
      pixel_flags.Allocate(static_cast<std::size_t>(out_w) * out_h * 4);
      flagged_list = gl::Buffer();
      flagged_list.Allocate(4 + static_cast<std::size_t>(out_w) * out_h * 4);
    }
    g_depth = gl::Texture::Create2D(GL_DEPTH_COMPONENT32F, w, h);
    framebuffer = gl::Framebuffer();
    framebuffer.AttachColor(g_position, 0).AttachColor(g_normal, 1).AttachColor(g_base, 2).AttachDepth(g_depth);
    const GLenum draw[3] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2};
    glNamedFramebufferDrawBuffers(framebuffer.id(), 3, draw);
    framebuffer.CheckComplete();
    counts = gl::Buffer();
    counts.Allocate(static_cast<std::size_t>(w) * h * 16);
  }
};

TripleProductRenderer::TripleProductRenderer(const scene::GltfScene& model, const glm::dmat4& world_from_model,
                                             RenderOptions options)
    : options_(std::move(options)), impl_(std::make_unique<Impl>()) {
  options_.Check();
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      if (!std::isfinite(world_from_model[i][j])) throw Error("world_from_model", "must be finite");
  const glm::dmat3 linear(world_from_model);
  if (!(std::abs(glm::determinant(linear)) > 1e-12)) throw Error("world_from_model", "is singular");
  gl::RequireCurrentGl45("triple-product renderer");
  Impl& im = *impl_;
  im.gbuffer_program = gl::ShaderLibrary::Graphics("render_gbuffer.vert", "render_gbuffer.frag");
  im.cone_rings = options_.cone_rings;
  im.software_renderer = gl::CurrentRendererIsSoftware();
  if (options_.shade_lanes != 0) im.ShadeProgram(options_.shade_lanes);
  im.composite_program = gl::ShaderLibrary::Compute("render_composite.comp");
  {
    const int cones = 1 + 3 * options_.cone_rings * (options_.cone_rings + 1);  // render_shade.comp's kMaxCones
    im.ground_table = gl::Buffer();
    im.ground_table.Allocate(static_cast<std::size_t>(cones + 1 + kMaxPeakCones) * 4 * sizeof(float));
  }
  if (!options_.read_layers) im.counts_program = gl::ShaderLibrary::Compute("render_counts.comp");
  if (options_.supersample > 1) {
    im.resolve_program = gl::ShaderLibrary::Compute("render_resolve.comp");
    im.flag_program = gl::ShaderLibrary::Compute("render_flag.comp");
  }
  if (options_.shading_rate == 2) {
    im.flag_program = gl::ShaderLibrary::Compute("render_flag.comp");
    im.fill_program = gl::ShaderLibrary::Compute("render_fill.comp");
  }
  if (options_.supersample > 1 || options_.shading_rate == 2) {
    im.list_args_program = gl::ShaderLibrary::Compute("render_list_args.comp");
    im.list_args = gl::Buffer();
    im.list_args.Allocate(3 * sizeof(std::uint32_t));
  }
  if (options_.monte_carlo_samples > 0) im.mc_program = gl::ShaderLibrary::Compute("render_mc.comp");
  im.white = gl::Texture::Create2D(GL_RGBA8, 1, 1);
  const std::uint8_t white[4] = {255, 255, 255, 255};
  im.white.Upload2D(GL_RGBA, GL_UNSIGNED_BYTE, white);

  // Geometry into the world once; the voxelizer and the G-buffer share it.
  const glm::dmat3 normal_matrix = glm::transpose(glm::inverse(linear));
  const bool flips = glm::determinant(linear) < 0;
  im.materials = model.materials;
  if (im.materials.empty()) im.materials.emplace_back();
  for (const auto& prim : model.primitives) {
    if (prim.indices.empty() || prim.positions.empty()) continue;
    const std::size_t n = prim.positions.size();
    std::vector<glm::vec3> pos(n), nor(n);
    std::vector<glm::vec2> uv0(n, glm::vec2(0)), uv1(n, glm::vec2(0));
    std::vector<glm::vec4> tan(n, glm::vec4(0));
    for (std::size_t i = 0; i < n; ++i) {
      pos[i] = glm::vec3(world_from_model * glm::dvec4(glm::dvec3(prim.positions[i]), 1.0));
      const glm::dvec3 nn = normal_matrix * glm::dvec3(i < prim.normals.size() ? prim.normals[i] : glm::vec3(0));
      nor[i] = glm::length(nn) > 0 ? glm::vec3(glm::normalize(nn)) : glm::vec3(0);
      if (i < prim.uv0.size()) uv0[i] = prim.uv0[i];
      if (i < prim.uv1.size()) uv1[i] = prim.uv1[i];
      if (i < prim.tangents.size()) {
        const glm::dvec3 t = linear * glm::dvec3(glm::vec3(prim.tangents[i]));
        tan[i] = glm::vec4(glm::length(t) > 0 ? glm::vec3(glm::normalize(t)) : glm::vec3(0),
                           prim.tangents[i].w * (flips ? -1.f : 1.f));
      }
      im.bounds.Extend(pos[i]);
    }
    std::vector<std::uint32_t> idx = prim.indices;
    if (flips)
      for (std::size_t t = 0; t + 2 < idx.size(); t += 3) std::swap(idx[t + 1], idx[t + 2]);
    for (std::uint32_t k : idx) im.triangles.push_back(pos[k]);
    Impl::Primitive p;
    p.positions.SetData(pos);
    p.normals.SetData(nor);
    p.uv0.SetData(uv0);
    p.uv1.SetData(uv1);
    p.tangents.SetData(tan);
    p.indices.SetData(idx);
    p.index_count = static_cast<GLsizei>(idx.size());
    p.material = std::clamp(prim.material, 0, static_cast<int>(im.materials.size()) - 1);
    p.vao.AddFloatAttribute(0, p.positions, 0, 3, 0, sizeof(glm::vec3))
        .AddFloatAttribute(1, p.normals, 1, 3, 0, sizeof(glm::vec3))
        .AddFloatAttribute(2, p.uv0, 2, 2, 0, sizeof(glm::vec2))
        .AddFloatAttribute(3, p.uv1, 3, 2, 0, sizeof(glm::vec2))
        .AddFloatAttribute(4, p.tangents, 4, 4, 0, sizeof(glm::vec4))
        .SetIndexBuffer(p.indices);
    const auto& mat = im.materials[static_cast<std::size_t>(p.material)];
    if (mat.base_color_texture.valid()) im.TextureFor(model, mat.base_color_texture.image, true);
    if (mat.metallic_roughness_texture.valid()) im.TextureFor(model, mat.metallic_roughness_texture.image, false);
    if (mat.normal_texture.valid()) im.TextureFor(model, mat.normal_texture.image, false);
    im.primitives.push_back(std::move(p));
  }
  im.has_geometry = !im.triangles.empty();
  if (im.has_geometry) {
    // The loader bounds the model in its own frame; a model matrix can still scale it past what a
    // float voxel grid can hold. Say which model and how large, not "voxel size: inf".
    const glm::dvec3 extent = glm::dvec3(im.bounds.max) - glm::dvec3(im.bounds.min);
    // The largest model taken: the loader's bound on a vertex's distance from the origin, across.
    const double max_extent_m = 2 * scene::GltfLoadOptions{}.max_coordinate_m;
    const double largest = std::max({extent.x, extent.y, extent.z});
    if (!std::isfinite(largest) || largest > max_extent_m)
      throw Error(model.source.string(), "placed by its model matrix it spans " + std::to_string(largest) +
                                             " m, more than the " + std::to_string(int(max_extent_m)) +
                                             " m a car's voxel grid can hold");
    im.spec = visibility::VoxelGridSpec::Covering(glm::dvec3(im.bounds.min), glm::dvec3(im.bounds.max),
                                                  options_.voxel_resolution);
    im.voxelizer = std::make_unique<visibility::VoxelizerGpu>(im.spec);
    std::vector<glm::vec4> padded(im.triangles.size());
    for (std::size_t i = 0; i < padded.size(); ++i) padded[i] = glm::vec4(im.triangles[i], 1.f);
    im.triangle_buffer = MakeBuffer(padded);
    if ((options_.monte_carlo_samples > 0 && options_.monte_carlo_exact_visibility) || options_.exact_peak_shadows) {
      im.bvh = std::make_unique<visibility::TriangleBvh>(im.triangles);
      im.bvh_nodes = MakeBuffer(im.bvh->nodes());
      im.bvh_triangles = MakeBuffer(im.bvh->triangles());
      im.bvh_triangle_count = static_cast<int>(im.bvh->triangle_count());
    }
  } else {
    im.spec = visibility::VoxelGridSpec::Covering(glm::dvec3(-1), glm::dvec3(1), options_.voxel_resolution);
  }

  SetMaterials(options_.materials);
  // Per α ∈ [kMinAlpha, 1]: λα² of the NDF's one-SG fit, then GGX's two SGs (λ_k α², μ_k π α²);
  // brdf_lobes.glsl interpolates them.
  std::vector<glm::vec4> table(2 * 512);
  for (std::size_t i = 0; i < table.size() / 2; ++i) {
    const double a =
        material::kMinAlpha + (1.0 - material::kMinAlpha) * static_cast<double>(i) / (table.size() / 2 - 1);
    const double a2 = a * a;
    const material::GgxSgFit fit = material::GgxSg(a);
    table[2 * i] = glm::vec4(static_cast<float>(material::NdfSgLambda(a) * a2), 0, 0, 0);
    table[2 * i + 1] =
        glm::vec4(static_cast<float>(fit.lambda[0] * a2), static_cast<float>(fit.lambda[1] * a2),
                  static_cast<float>(fit.amplitude[0] * kPi * a2), static_cast<float>(fit.amplitude[1] * kPi * a2));
  }
  im.ndf_table = MakeBuffer(table);
  // The clamped cosine's two tables interleaved, so that the shader reads both with one vec2.
  const std::vector<double>& cosine = material::ClampedCosineTable();
  const std::size_t block = cosine.size() / 2;
  std::vector<glm::vec2> interleaved(block);
  for (std::size_t i = 0; i < block; ++i)
    interleaved[i] = glm::vec2(static_cast<float>(cosine[i]), static_cast<float>(cosine[block + i]));
  im.cosine_table = MakeBuffer(interleaved);

  // Overlap bins for the levels used, flattened for the shader.
  lighting::OverlapBinOptions bo;
  bo.lighting_levels = options_.lighting_levels;
  bo.min_retention = options_.overlap_min_retention;
  bo.cutoff = options_.overlap_cutoff;
  im.bins = lighting::OverlapBins::Shared(bo);
  std::vector<glm::vec4> levels;
  std::vector<int> begin, srbfs;
  for (const auto& l : im.bins->levels()) {
    levels.push_back(
        glm::vec4(static_cast<float>(l.lambda), static_cast<float>(l.n), static_cast<float>(begin.size()), 0));
    const int base = static_cast<int>(srbfs.size());
    for (int b : l.begin) begin.push_back(base + b);
    srbfs.insert(srbfs.end(), l.srbfs.begin(), l.srbfs.end());
  }
  im.bin_levels = MakeBuffer(levels);
  im.bin_begin = MakeBuffer(begin);
  im.bin_srbfs = MakeBuffer(srbfs);
  SetLighting(lighting::SgLighting{});
}

TripleProductRenderer::~TripleProductRenderer() = default;

const std::vector<glm::vec3>& TripleProductRenderer::world_triangles() const { return impl_->triangles; }
const visibility::VoxelGridSpec& TripleProductRenderer::voxel_spec() const { return impl_->spec; }
const gl::Texture& TripleProductRenderer::composite_texture() const { return impl_->composite_layer; }

int TripleProductRenderer::peaks_without_cone() const {
  return std::max(0, static_cast<int>(impl_->lighting.peaks.size()) - kMaxPeakCones);
}

int TripleProductRenderer::PrepareShading(const PinholeCamera& camera) {
  const int lanes = options_.shade_lanes != 0
                        ? options_.shade_lanes
                        : ShadeLanesFor(detail::FirstShadingPassPixels(options_, camera.width, camera.height),
                                        impl_->software_renderer);
  impl_->ShadeProgram(lanes);
  return lanes;
}

void TripleProductRenderer::SetMaterials(std::vector<MaterialOverride> overrides) {
  Impl& im = *impl_;
  // Material terms: the glTF metallic-roughness unless an override names the material. Each
  // material's row in the buffer: its kTermsPerMaterial terms, then one whose colour is the
  // radiance it emits: the glTF material's, none under an override, which replaces the whole
  // material (as the Cycles references' paint overrides do: bench render's paints cover the lamps).
  std::vector<GpuTerm> gpu_terms;
  detail::MaterialTerms material_terms;
  im.emission.clear();
  for (const auto& mat : im.materials) {
    std::vector<material::Brdf> terms;
    for (const auto& o : overrides)
      if (o.material.empty() || Lower(mat.name).find(Lower(o.material)) != std::string::npos) terms = o.brdfs;
    if (terms.size() > static_cast<std::size_t>(kTermsPerMaterial))
      throw Error("material override", "at most " + std::to_string(kTermsPerMaterial) + " BRDF terms");
    std::vector<GpuTerm> row(kTermsPerMaterial + 1);
    if (terms.empty()) {
      row[0].type.x = kGltf;
    } else {
      for (std::size_t k = 0; k < terms.size(); ++k) row[k] = ToGpuTerm(terms[k]);
    }
    im.emission.push_back(terms.empty() ? mat.emission() : glm::vec3(0));
    row.back().color = glm::vec4(im.emission.back(), 0);
    gpu_terms.insert(gpu_terms.end(), row.begin(), row.end());
    material_terms.push_back(std::move(terms));
  }
  im.terms_buffer = MakeBuffer(gpu_terms);
  im.material_terms = std::move(material_terms);
  options_.materials = std::move(overrides);
}

void TripleProductRenderer::SetLighting(const lighting::SgLighting& model, const glm::dmat3& world_from_lighting) {
  Impl& im = *impl_;
  im.lighting = Prepare(model, world_from_lighting, options_.lighting_levels);
  std::vector<glm::vec4> srbfs;
  for (const auto& s : im.lighting.srbfs) {
    srbfs.push_back(LightVec(s.axis, s.lambda));
    srbfs.push_back(glm::vec4(s.amplitude, 0));
  }
  std::vector<glm::vec4> peaks;
  for (const auto& s : im.lighting.peaks) {
    peaks.push_back(LightVec(s.axis, s.lambda));
    peaks.push_back(glm::vec4(s.amplitude, 0));
  }
  im.srbf_buffer = MakeBuffer(srbfs);
  im.peak_buffer = MakeBuffer(peaks);
}

void TripleProductRenderer::SetBackgroundEquirect(const sphere::EquirectImage& equirect) {
  if (equirect.empty()) throw Error("background", "empty image");
  Impl& im = *impl_;
  im.environment = equirect;
  im.background_is_image = false;
  im.environment_texture = gl::Texture::Create2D(GL_RGB32F, equirect.width, equirect.height);
  im.environment_texture.Upload2D(GL_RGB, GL_FLOAT, equirect.rgb.data());
  im.environment_texture.SetWrap(GL_REPEAT, GL_CLAMP_TO_EDGE).SetFilter(GL_LINEAR, GL_LINEAR);
}

void TripleProductRenderer::SetBackgroundRotation(const glm::dmat3& world_from_background) {
  impl_->background_from_world = glm::transpose(world_from_background);
}

void TripleProductRenderer::SetEnvironment(const sphere::EquirectImage& equirect) {
  SetBackgroundEquirect(equirect);
  Impl& im = *impl_;
  im.background_from_world.reset();
  if (options_.monte_carlo_samples > 0) {
    // Texel probabilities ∝ (luminance + a floor) × solid angle; the floor (1e-3 of the mean)
    // keeps every direction reachable by this strategy alone.
    const int w = equirect.width, h = equirect.height;
    std::vector<double> lum(static_cast<std::size_t>(w) * h);
    double mean = 0;
    for (std::size_t i = 0; i < lum.size(); ++i) {
      const float* c = &equirect.rgb[3 * i];
      lum[i] = std::max(0.0, 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]);
      mean += lum[i] / static_cast<double>(lum.size());
    }
    const double floor_value = std::max(1e-3 * mean, 1e-12);
    std::vector<double> weight(lum.size());
    double total = 0;
    for (int y = 0; y < h; ++y) {
      const double sin_theta = std::sin(3.14159265358979323846 * (y + 0.5) / h);
      for (int x = 0; x < w; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        weight[i] = (lum[i] + floor_value) * sin_theta;
        total += weight[i];
      }
    }
    std::vector<float> prob(lum.size()), rows(static_cast<std::size_t>(h) + 1, 0.f),
        cols(static_cast<std::size_t>(h) * (w + 1), 0.f);
    double row_acc = 0;
    for (int y = 0; y < h; ++y) {
      double row_sum = 0;
      for (int x = 0; x < w; ++x) row_sum += weight[static_cast<std::size_t>(y) * w + x];
      double acc = 0;
      for (int x = 0; x < w; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        prob[i] = static_cast<float>(weight[i] / total);
        acc += weight[i];
        cols[static_cast<std::size_t>(y) * (w + 1) + x + 1] = static_cast<float>(acc / row_sum);
      }
      cols[static_cast<std::size_t>(y) * (w + 1) + w] = 1.f;
      row_acc += row_sum;
      rows[static_cast<std::size_t>(y) + 1] = static_cast<float>(row_acc / total);
    }
    rows[static_cast<std::size_t>(h)] = 1.f;
    im.env_row_cdf = MakeBuffer(rows);
    im.env_col_cdf = MakeBuffer(cols);
    im.env_texel_prob = MakeBuffer(prob);
    im.mc_environment = gl::Texture::Create2D(GL_RGB32F, w, h);
    im.mc_environment.Upload2D(GL_RGB, GL_FLOAT, equirect.rgb.data());
    im.mc_environment.SetFilter(GL_NEAREST, GL_NEAREST);
  }
}

void TripleProductRenderer::SetBackgroundImage(const sphere::EquirectImage& image) {
  if (image.empty()) throw Error("background", "empty image");
  Impl& im = *impl_;
  im.background_image = image;
  im.background_is_image = true;
  im.environment_texture = gl::Texture::Create2D(GL_RGB32F, image.width, image.height);
  im.environment_texture.Upload2D(GL_RGB, GL_FLOAT, image.rgb.data());
  im.environment_texture.SetFilter(GL_NEAREST, GL_NEAREST);
}

RenderResult TripleProductRenderer::Render(const PinholeCamera& camera, ShadeDevice device, bool draw_model) {
  camera.Check();
  Impl& im = *impl_;
  const int w = camera.width, h = camera.height;
  if (im.background_is_image && (im.background_image.width != w || im.background_image.height != h))
    throw Error("background", "image is " + std::to_string(im.background_image.width) + "x" +
                                  std::to_string(im.background_image.height) + ", the output " + std::to_string(w) +
                                  "x" + std::to_string(h));
  const bool monte_carlo = options_.monte_carlo_samples > 0;
  if (monte_carlo && device != ShadeDevice::kGpu)
    throw Error("render", "the Monte-Carlo baseline runs on the GPU only");
  if (monte_carlo && !im.mc_environment) throw Error("render", "the Monte-Carlo baseline needs SetEnvironment");
  RenderResult out;
  const auto t_total = Clock::now();
  // Without the model: nothing voxelized, drawn or occluding, so the composite is the background.
  const bool geometry = im.has_geometry && draw_model;
  static std::vector<Impl::Primitive> no_primitives;
  gl::Finish();

  // Voxelize. GL timestamps around the GPU path's stages, read once the composite is done.
  const bool gpu_stages = device == ShadeDevice::kGpu;
  if (gpu_stages && im.stage_queries[0] == 0)
    glCreateQueries(GL_TIMESTAMP, static_cast<GLsizei>(im.stage_queries.size()), im.stage_queries.data());
  const auto stamp = [&](int i) {
    if (gpu_stages) glQueryCounter(im.stage_queries[static_cast<std::size_t>(i)], GL_TIMESTAMP);
  };
  stamp(0);
  auto t0 = Clock::now();
  if (geometry) {
    if (device == ShadeDevice::kGpu) {
      im.voxelizer->Voxelize(im.triangle_buffer, im.triangles.size() / 3);
      gl::Finish();
    } else {
      im.cpu_grid = std::make_unique<visibility::VoxelGrid>(im.spec);
      im.cpu_grid->Voxelize(im.triangles);
      im.cpu_grid->BuildMips();
    }
  }
  out.ms.voxelize = MsSince(t0);
  stamp(1);

  // G-buffer, at the shaded size (RenderOptions::supersample).
  t0 = Clock::now();
  const int k = options_.supersample;
  PinholeCamera shaded_camera = camera;
  shaded_camera.width = k * w;
  shaded_camera.height = k * h;
  const int sw = shaded_camera.width, sh = shaded_camera.height;
  // Adaptive supersampling (RenderOptions::supersample_contrast) in the SG shader only.
  const bool adaptive = k > 1 && options_.supersample_contrast > 0 && !monte_carlo;
  // RenderOptions::shading_rate 2: a pixel of each 2×2 block, then every pixel of the blocks that
  // need it, the rest filled.
  const bool half_rate = options_.shading_rate == 2;
  const int bw = (w + 1) / 2, bh = (h + 1) / 2;  // a block cut by an odd edge is shaded whole
  long long half_rate_shaded = 0;                // pixels shaded, the rest filled
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (sw > max_size || sh > max_size)
    throw Error("render supersample", std::to_string(k) + "x" + std::to_string(k) + " samples of " + std::to_string(w) +
                                          "x" + std::to_string(h) + " make " + std::to_string(sw) + "x" +
                                          std::to_string(sh) + ", beyond the GPU's textures (" +
                                          std::to_string(max_size) + ")");
  im.EnsureTargets(sw, sh, w, h);
  const glm::dmat3 camera_from_world = glm::transpose(camera.world_from_camera);
  const double f = camera.focal_px(), sf = shaded_camera.focal_px();
  double near = 0.01, far = 10;
  if (geometry) {
    double dmin = 1e300, dmax = 0;
    for (int c = 0; c < 8; ++c) {
      const glm::dvec3 corner((c & 1) ? im.bounds.max.x : im.bounds.min.x, (c & 2) ? im.bounds.max.y : im.bounds.min.y,
                              (c & 4) ? im.bounds.max.z : im.bounds.min.z);
      const double z = (camera_from_world * (corner - camera.position)).z;
      dmin = std::min(dmin, z);
      dmax = std::max(dmax, z);
    }
    far = std::max(dmax * 1.01 + 0.01, 0.02);
    near = std::clamp(dmin * 0.99, far * 1e-6, far * 0.5);
    if (dmin <= 0) near = std::max(far * 1e-6, 1e-3);
  }
  glm::dmat4 clip(0.0);  // column-major: clip[col][row]
  clip[0][0] = 2 * sf / sw;
  clip[1][1] = 2 * sf / sh;
  clip[2][2] = (far + near) / (far - near);
  clip[3][2] = -2 * far * near / (far - near);
  clip[2][3] = 1;
  glm::dmat4 view(camera_from_world);
  view[3] = glm::dvec4(-(camera_from_world * camera.position), 1.0);
  const glm::mat4 clip_from_world(clip * view);

  im.framebuffer.Bind();
  glViewport(0, 0, sw, sh);
  const float zero[4] = {0, 0, 0, 0};
  for (int i = 0; i < 3; ++i) glClearNamedFramebufferfv(im.framebuffer.id(), GL_COLOR, i, zero);
  const float one = 1.f;
  glClearNamedFramebufferfv(im.framebuffer.id(), GL_DEPTH, 0, &one);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  // The clip transform flips y (image rows grow downward), which turns CCW faces CW on screen.
  glFrontFace(GL_CW);
  gl::Program& gp = im.gbuffer_program;
  gp.SetMat4("uClipFromWorld", glm::value_ptr(clip_from_world))
      .Set("uCameraPosition", static_cast<float>(camera.position.x), static_cast<float>(camera.position.y),
           static_cast<float>(camera.position.z))
      .Set("uValidReflectionNormals", options_.valid_reflection_normals ? 1 : 0);
  for (auto& p : geometry ? im.primitives : no_primitives) {
    const auto& m = im.materials[static_cast<std::size_t>(p.material)];
    gp.Set("uMaterialId", static_cast<float>(p.material + 1))
        .Set("uBaseColorFactor", m.base_color_factor.x, m.base_color_factor.y, m.base_color_factor.z,
             m.base_color_factor.w)
        .Set("uMetallicFactor", m.metallic_factor)
        .Set("uRoughnessFactor", m.roughness_factor)
        .Set("uNormalScale", m.normal_scale)
        .Set("uAlphaCutoff", m.alpha_mode == scene::PbrMaterial::AlphaMode::kMask ? m.alpha_cutoff : -1.f);
    const scene::TextureRef* refs[3] = {&m.base_color_texture, &m.metallic_roughness_texture, &m.normal_texture};
    for (int k = 0; k < 3; ++k) {
      const auto& r = *refs[k];
      const std::string s = std::to_string(k);
      glProgramUniform2i(gp.id(), gp.Uniform(("uTexUse[" + s + "]").c_str()), r.valid() ? 1 : 0, r.texcoord);
      gp.Set(("uTexOffsetScale[" + s + "]").c_str(), r.offset.x, r.offset.y, r.scale.x, r.scale.y)
          .Set(("uTexRotation[" + s + "]").c_str(), r.rotation);
      if (r.valid()) {
        const auto it = im.textures.find({r.image, k == 0});
        if (it != im.textures.end()) {
          it->second.BindUnit(static_cast<GLuint>(k));
          continue;
        }
      }
      im.white.BindUnit(static_cast<GLuint>(k));
    }
    gp.Use();
    p.vao.Bind();
    glDrawElements(GL_TRIANGLES, p.index_count, GL_UNSIGNED_INT, nullptr);
  }
  glFrontFace(GL_CCW);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  gl::Finish();
  out.ms.gbuffer = MsSince(t0);
  stamp(2);

  const glm::dvec2 ground_centre(im.bounds.empty() ? 0.0 : im.bounds.center().x,
                                 im.bounds.empty() ? 0.0 : im.bounds.center().z);
  const glm::vec3 ground_radiance = im.lighting.GroundRadiance(options_.peak_cones);
  const std::size_t pixels = static_cast<std::size_t>(w) * h;
  const std::size_t samples = static_cast<std::size_t>(sw) * sh;
  std::vector<detail::PixelCounts> counts;
  std::optional<detail::CountSums> gpu_sums;  // RenderOptions::read_layers off
  // The car's coverage per shaded sample, for the counts: the output's own when not supersampled.
  std::vector<float> sample_alpha_storage;
  const std::vector<float>* sample_alpha = &out.car_alpha;

  // Shade.
  t0 = Clock::now();
  if (device == ShadeDevice::kGpu) {
    const int lanes = PrepareShading(camera);
    out.counts.shade_lanes = lanes;
    gl::Program& sp = im.ShadeProgram(lanes);
    const glm::mat3 wfc(camera.world_from_camera), efw(im.lighting.env_from_world);
    glProgramUniform2i(sp.id(), sp.Uniform("uSize"), sw, sh);
    sp.Set("uCameraPosition", static_cast<float>(camera.position.x), static_cast<float>(camera.position.y),
           static_cast<float>(camera.position.z))
        .SetMat3("uWorldFromCamera", glm::value_ptr(wfc))
        .Set("uFocal", static_cast<float>(sf))
        .SetMat3("uEnvFromWorld", glm::value_ptr(efw))
        .Set("uConstant", im.lighting.constant.x, im.lighting.constant.y, im.lighting.constant.z)
        .Set("uPeakCount", static_cast<int>(im.lighting.peaks.size()))
        .Set("uPeakCones", options_.peak_cones ? 1 : 0)
        .Set("uBinLevelCount", im.lighting.srbfs.empty() ? 0 : static_cast<int>(im.bins->levels().size()))
        .Set("uSingleConeMaxHalfAngle", static_cast<float>(options_.cones.single_cone_max_half_angle))
        .Set("uConeCoverage", static_cast<float>(options_.cones.coverage))
        .Set("uMaxConeHalfAngle", static_cast<float>(visibility::kMaxConeHalfAngle))
        .Set("uTermsPerMaterial", kTermsPerMaterial)
        .Set("uMaterialCount", static_cast<int>(im.materials.size()))
        .Set("uSurfaceOffset", static_cast<float>(options_.surface_offset_voxels * im.spec.voxel_size))
        .Set("uExactTriangles", options_.exact_peak_shadows && geometry ? im.bvh_triangle_count : 0)
        .Set("uExactRayOffset", detail::kExactRayOffset)
        .Set("uBounce", options_.specular_bounce && geometry ? 1 : 0)
        .Set("uBounceStep", static_cast<float>(options_.bounce_step_voxels * im.spec.voxel_size))
        .Set("uBounceSteps", options_.bounce_steps)
        .Set("uBounceThickness", static_cast<float>(options_.bounce_thickness_voxels * im.spec.voxel_size))
        .Set("uBounceSrbfs", detail::BounceSrbfCount(im.lighting))
        .Set("uGround", options_.ground ? 1 : 0)
        .Set("uWarpSplit", options_.lobes.warp == material::WarpMode::kAnisotropicSplit ? 1 : 0)
        .Set("uCosineAsSg", options_.lobes.cosine == material::CosineTerm::kAsSg ? 1 : 0)
        .Set("uGroundCenter", static_cast<float>(ground_centre.x), static_cast<float>(ground_centre.y))
        .Set("uGroundHalfSize", static_cast<float>(options_.ground_half_size))
        .Set("uGroundShadowsBounce", options_.ground && options_.ground_shadows_bounce ? 1 : 0)
        .Set("uGroundLitHalfAngle", static_cast<float>(kGroundLitHalfAngle))
        .Set("uGroundRadiance", ground_radiance.x, ground_radiance.y, ground_radiance.z);
    {
      std::array<float, 6> level_lambda;
      level_lambda.fill(3e38f);  // beyond the levels used: never deep enough
      for (int s = 0; s < options_.lighting_levels; ++s)
        level_lambda[static_cast<std::size_t>(s)] = static_cast<float>(sphere::Healpix(s).Lambda());
      glProgramUniform1fv(sp.id(), sp.Uniform("uLevelLambda"), 6, level_lambda.data());
      sp.Set("uMinRetention", static_cast<float>(options_.overlap_min_retention))
          .Set("uLobeDepth", options_.depth_per_lobe ? 1 : 0);
    }
    SetGroundPeakUniforms(sp, im.lighting, options_.peak_cones);
    SetConeTraceUniforms(sp, im.spec, geometry, options_.trace);
    if (geometry) glBindTextureUnit(0, im.voxelizer->texture().id());
    im.g_position.BindImage(0, GL_READ_ONLY);
    im.g_normal.BindImage(1, GL_READ_ONLY);
    im.g_base.BindImage(2, GL_READ_ONLY);
    (k > 1 ? im.shaded_car : im.car_layer).BindImage(3, GL_WRITE_ONLY);
    (k > 1 ? im.shaded_shadow : im.shadow_layer).BindImage(4, GL_WRITE_ONLY);
    im.srbf_buffer.BindBase(GL_SHADER_STORAGE_BUFFER, 0);
    im.peak_buffer.BindBase(GL_SHADER_STORAGE_BUFFER, 1);
    im.bin_levels.BindBase(GL_SHADER_STORAGE_BUFFER, 2);
    im.bin_begin.BindBase(GL_SHADER_STORAGE_BUFFER, 3);
    im.bin_srbfs.BindBase(GL_SHADER_STORAGE_BUFFER, 4);
    im.terms_buffer.BindBase(GL_SHADER_STORAGE_BUFFER, 5);
    im.counts.BindBase(GL_SHADER_STORAGE_BUFFER, 6);
    im.ndf_table.BindBase(GL_SHADER_STORAGE_BUFFER, 7);
    glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_FRAMEBUFFER_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT);
    if (monte_carlo) {
      gl::Program& mp = im.mc_program;
      glProgramUniform2i(mp.id(), mp.Uniform("uSize"), sw, sh);
      glProgramUniform1ui(mp.id(), mp.Uniform("uSeed"), options_.monte_carlo_seed);
      mp.Set("uCameraPosition", static_cast<float>(camera.position.x), static_cast<float>(camera.position.y),
             static_cast<float>(camera.position.z))
          .SetMat3("uWorldFromCamera", glm::value_ptr(wfc))
          .Set("uFocal", static_cast<float>(sf))
          .SetMat3("uEnvFromWorld", glm::value_ptr(efw))
          .Set("uTermsPerMaterial", kTermsPerMaterial)
          .Set("uMaterialCount", static_cast<int>(im.materials.size()))
          .Set("uSurfaceOffset", static_cast<float>(options_.surface_offset_voxels * im.spec.voxel_size))
          .Set("uGround", options_.ground ? 1 : 0)
          .Set("uGroundCenter", static_cast<float>(ground_centre.x), static_cast<float>(ground_centre.y))
          .Set("uGroundHalfSize", static_cast<float>(options_.ground_half_size))
          .Set("uGroundShadowsBounce", options_.ground && options_.ground_shadows_bounce ? 1 : 0)
          .Set("uGroundLitHalfAngle", static_cast<float>(kGroundLitHalfAngle))
          .Set("uSamples", options_.monte_carlo_samples)
          // A ray of a voxel's width: level 0 all along (cone_trace.glsl clamps the diameter).
          .Set("uShadowRayHalfAngle", 1e-4f)
          .Set("uExactTriangles", geometry ? im.bvh_triangle_count : 0)
          // Off the surface by a millimetre: the G-buffer's positions are interpolated in float.
          .Set("uExactRayOffset", detail::kExactRayOffset)
          .Set("uExactVisibility", options_.monte_carlo_exact_visibility ? 1 : 0);
      if (options_.monte_carlo_exact_visibility) {
        // The ground's unshadowed irradiance from the map's upper half (world up), which the
        // exact ground lit fraction divides by (render_mc.comp's groundLitExact).
        const sphere::EquirectImage& env = im.environment;
        const glm::dmat3 world_from_env = glm::transpose(im.lighting.env_from_world);
        glm::dvec3 e(0);
        for (int y = 0; y < env.height; ++y) {
          const double lat = 0.5 * kPi - kPi * (y + 0.5) / env.height;
          const double d_omega = (2 * kPi / env.width) * (kPi / env.height) * std::cos(lat);
          for (int x = 0; x < env.width; ++x) {
            const double lon = kPi * (1 - 2 * (x + 0.5) / env.width);
            const glm::dvec3 d = world_from_env * glm::dvec3(std::cos(lat) * std::cos(lon), std::sin(lat),
                                                             -std::cos(lat) * std::sin(lon));
            if (d.y <= 0) continue;
            for (int c = 0; c < 3; ++c) e[c] += env.at(x, y)[c] * d.y * d_omega;
          }
        }
        mp.Set("uGroundIrradiance", static_cast<float>(e.x), static_cast<float>(e.y), static_cast<float>(e.z));
      }
      SetGroundPeakUniforms(mp, im.lighting, options_.peak_cones);
      SetConeTraceUniforms(mp, im.spec, geometry, options_.trace);
      im.mc_environment.BindUnit(1);
      im.env_row_cdf.BindBase(GL_SHADER_STORAGE_BUFFER, 8);
      im.env_col_cdf.BindBase(GL_SHADER_STORAGE_BUFFER, 9);
      im.env_texel_prob.BindBase(GL_SHADER_STORAGE_BUFFER, 10);
      if (im.bvh_triangle_count > 0) {
        im.bvh_nodes.BindBase(GL_SHADER_STORAGE_BUFFER, 11);
        im.bvh_triangles.BindBase(GL_SHADER_STORAGE_BUFFER, 12);
      }
      mp.Use().DispatchCovering(static_cast<unsigned>(sw), static_cast<unsigned>(sh));
    } else {
      im.cosine_table.BindBase(GL_SHADER_STORAGE_BUFFER, 8);
      im.ground_table.BindBase(GL_SHADER_STORAGE_BUFFER, 11);
      if (options_.exact_peak_shadows && im.bvh_triangle_count > 0) {
        im.bvh_nodes.BindBase(GL_SHADER_STORAGE_BUFFER, 14);
        im.bvh_triangles.BindBase(GL_SHADER_STORAGE_BUFFER, 15);
      }
      if (options_.ground) {
        sp.Set("uGroundTablePass", 1).Use();
        glDispatchCompute(1, 1, 1);
        glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      }
      const detail::GroundLitMapLayout map =
          options_.ground && options_.ground_shadows_bounce && geometry
              ? detail::GroundLitMapLayoutFor(im.spec, im.lighting, options_.peak_cones, ground_centre,
                                              options_.ground_half_size, options_.ground_lit_map_texels)
              : detail::GroundLitMapLayout{};
      const std::size_t map_bytes = std::max<std::size_t>(map.texels(), 1) * sizeof(float);
      if (!im.ground_lit_map || im.ground_lit_map.size() < map_bytes) {
        im.ground_lit_map = gl::Buffer();
        im.ground_lit_map.Allocate(map_bytes);
      }
      im.ground_lit_map.BindBase(GL_SHADER_STORAGE_BUFFER, 12);
      glProgramUniform2i(sp.id(), sp.Uniform("uGroundLitMapSize"), map.width, map.height);
      sp.Set("uGroundLitMapOrigin", static_cast<float>(map.origin.x), static_cast<float>(map.origin.y))
          .Set("uGroundLitMapSpacing", static_cast<float>(map.spacing));
      if (map.width > 0) {
        spdlog::debug("render: the ground's lit fraction on {}x{} texels {:.3f} m apart", map.width, map.height,
                      map.spacing);
        sp.Set("uGroundTablePass", 2)
            .Use()
            .DispatchCovering(static_cast<unsigned>(map.width), static_cast<unsigned>(map.height),
                              static_cast<unsigned>(lanes));
        glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      }
      // render_flag.comp over flag_w × flag_h pixels (blocks, at shading_rate 2) of factor²
      // samples each, their flags into `flags` and the flagged ones into `list`; then
      // render_shade.comp shades the listed ones' other samples into car and shadow.
      const auto flag_and_shade_listed = [&](gl::Buffer& flags, gl::Buffer& list, int flag_w, int flag_h, int factor,
                                             gl::Texture& car, gl::Texture& shadow, bool neighbour_reps) {
        gl::Program& fp = im.flag_program;
        glProgramUniform2i(fp.id(), fp.Uniform("uSize"), flag_w, flag_h);
        fp.Set("uFactor", factor)
            .Set("uContrast", static_cast<float>(options_.supersample_contrast))
            .Set("uNormalCos", detail::kSupersampleNormalCos)
            .Set("uNeighbourReps", neighbour_reps ? 1 : 0);
        im.g_position.BindImage(0, GL_READ_ONLY);
        im.g_normal.BindImage(1, GL_READ_ONLY);
        car.BindImage(2, GL_READ_ONLY);
        shadow.BindImage(3, GL_READ_ONLY);
        flags.BindBase(GL_SHADER_STORAGE_BUFFER, 9);
        list.BindBase(GL_SHADER_STORAGE_BUFFER, 10);
        const std::uint32_t zero = 0;
        list.SubData(0, 4, &zero);
        fp.Use().DispatchCovering(static_cast<unsigned>(flag_w), static_cast<unsigned>(flag_h));
        glMemoryBarrier(GL_ALL_BARRIER_BITS);
        // The second pass sized on the GPU from the list's count: no wait for the flags here.
        constexpr int kListPitch = 256;
        gl::Program& ap = im.list_args_program;
        ap.Set("uFactor", factor).Set("uListPitch", kListPitch);
        im.list_args.BindBase(GL_SHADER_STORAGE_BUFFER, 13);
        ap.Use();
        glDispatchCompute(1, 1, 1);
        glMemoryBarrier(GL_COMMAND_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT);
        im.g_position.BindImage(0, GL_READ_ONLY);
        im.g_normal.BindImage(1, GL_READ_ONLY);
        im.g_base.BindImage(2, GL_READ_ONLY);
        car.BindImage(3, GL_WRITE_ONLY);
        shadow.BindImage(4, GL_WRITE_ONLY);
        sp.Set("uAdaptivePass", 1).Set("uListPitch", kListPitch).Set("uSampleStride", 1).Set("uSamplePhase", 0).Use();
        glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, im.list_args.id());
        glDispatchComputeIndirect(0);
        glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, 0);
      };
      sp.Set("uGroundTablePass", 0).Set("uOutWidth", w).Set("uFactor", k).Set("uAdaptivePass", 0);
      if (half_rate) {
        const std::size_t blocks = static_cast<std::size_t>(bw) * static_cast<std::size_t>(bh);
        if (!im.block_flags || im.block_flags.size() < blocks * 4) {
          im.block_flags = gl::Buffer();
          im.block_flags.Allocate(blocks * 4);
          im.block_list = gl::Buffer();
          im.block_list.Allocate(4 + blocks * 4);
        }
        // The pixels the passes leave unshaded read as empty in the counts until they are filled.
        glClearNamedBufferData(im.counts.id(), GL_RGBA32UI, GL_RGBA_INTEGER, GL_UNSIGNED_INT, nullptr);
        glMemoryBarrier(GL_ALL_BARRIER_BITS);
        sp.Set("uOutWidth", bw)
            .Set("uFactor", 2)
            .Set("uSampleStride", 2)
            .Set("uSamplePhase", 1)
            .Use()
            .DispatchCovering(static_cast<unsigned>(bw), static_cast<unsigned>(bh), static_cast<unsigned>(lanes));
        glMemoryBarrier(GL_ALL_BARRIER_BITS);
        flag_and_shade_listed(im.block_flags, im.block_list, bw, bh, 2, im.car_layer, im.shadow_layer, true);
        glMemoryBarrier(GL_ALL_BARRIER_BITS);
        gl::Program& fill = im.fill_program;
        glProgramUniform2i(fill.id(), fill.Uniform("uBlocks"), bw, bh);
        glProgramUniform2i(fill.id(), fill.Uniform("uSize"), w, h);
        im.car_layer.BindImage(0, GL_READ_WRITE);
        im.shadow_layer.BindImage(1, GL_READ_WRITE);
        im.block_flags.BindBase(GL_SHADER_STORAGE_BUFFER, 9);
        fill.Use().DispatchCovering(static_cast<unsigned>(w), static_cast<unsigned>(h));
      } else if (adaptive) {
        // The samples a pass leaves unshaded must read as empty in the counts and the coverage.
        glClearNamedBufferData(im.counts.id(), GL_RGBA32UI, GL_RGBA_INTEGER, GL_UNSIGNED_INT, nullptr);
        glClearTexImage(im.shaded_car.id(), 0, GL_RGBA, GL_FLOAT, nullptr);
        glMemoryBarrier(GL_ALL_BARRIER_BITS);
        im.flagged_list.BindBase(GL_SHADER_STORAGE_BUFFER, 10);
        sp.Set("uSampleStride", k)
            .Set("uSamplePhase", k / 2)
            .Use()
            .DispatchCovering(static_cast<unsigned>(w), static_cast<unsigned>(h), static_cast<unsigned>(lanes));
        glMemoryBarrier(GL_ALL_BARRIER_BITS);
        flag_and_shade_listed(im.pixel_flags, im.flagged_list, w, h, k, im.shaded_car, im.shaded_shadow, false);
      } else {
        sp.Set("uSampleStride", 1)
            .Set("uSamplePhase", 0)
            .Use()
            .DispatchCovering(static_cast<unsigned>(sw), static_cast<unsigned>(sh), static_cast<unsigned>(lanes));
      }
    }
    glMemoryBarrier(GL_ALL_BARRIER_BITS);
    if (k > 1) {
      gl::Program& rp = im.resolve_program;
      const std::vector<float> weights = detail::SupersampleWeights(k);
      glProgramUniform2i(rp.id(), rp.Uniform("uSize"), w, h);
      glProgramUniform2i(rp.id(), rp.Uniform("uShadedSize"), sw, sh);
      rp.Set("uFactor", k).Set("uAdaptive", adaptive ? 1 : 0);
      if (adaptive) im.pixel_flags.BindBase(GL_SHADER_STORAGE_BUFFER, 9);
      glProgramUniform1fv(rp.id(), rp.Uniform("uWeights"), static_cast<GLsizei>(weights.size()), weights.data());
      im.shaded_car.BindImage(0, GL_READ_ONLY);
      im.shaded_shadow.BindImage(1, GL_READ_ONLY);
      im.car_layer.BindImage(2, GL_WRITE_ONLY);
      im.shadow_layer.BindImage(3, GL_WRITE_ONLY);
      rp.Use().DispatchCovering(static_cast<unsigned>(w), static_cast<unsigned>(h));
      glMemoryBarrier(GL_ALL_BARRIER_BITS);
    }
    gl::Finish();
    out.ms.shade = MsSince(t0);
    stamp(3);
    if (half_rate) {
      // Every block once, three more pixels of each flagged whole block, and every pixel of the
      // blocks an odd edge cuts (all flagged); the count read now that the GPU is done.
      std::uint32_t listed = 0;
      im.block_list.Read(0, 4, &listed);
      const long long blocks = static_cast<long long>(bw) * bh, whole = static_cast<long long>(w / 2) * (h / 2);
      half_rate_shaded = whole + 3LL * (listed - (blocks - whole)) + (static_cast<long long>(pixels) - 4 * whole);
    }

    // Composite.
    t0 = Clock::now();
    gl::Program& cp = im.composite_program;
    const glm::mat3 background_efw(im.background_from_world.value_or(im.lighting.env_from_world));
    cp.Set("uBackgroundIsImage", im.background_is_image ? 1 : 0)
        .Set("uCameraPosition", static_cast<float>(camera.position.x), static_cast<float>(camera.position.y),
             static_cast<float>(camera.position.z))
        .SetMat3("uWorldFromCamera", glm::value_ptr(wfc))
        .Set("uFocal", static_cast<float>(f))
        .SetMat3("uEnvFromWorld", glm::value_ptr(background_efw));
    glProgramUniform2i(cp.id(), cp.Uniform("uSize"), w, h);
    if (im.environment_texture) {
      im.environment_texture.BindUnit(0);
    } else {
      static const float black[3] = {0, 0, 0};
      im.environment_texture = gl::Texture::Create2D(GL_RGB32F, 1, 1);
      im.environment_texture.Upload2D(GL_RGB, GL_FLOAT, black);
      im.environment_texture.BindUnit(0);
    }
    im.car_layer.BindImage(0, GL_READ_ONLY);
    im.shadow_layer.BindImage(1, GL_READ_ONLY);
    im.composite_layer.BindImage(2, GL_WRITE_ONLY);
    im.background_layer.BindImage(3, GL_WRITE_ONLY);
    cp.Use().DispatchCovering(static_cast<unsigned>(w), static_cast<unsigned>(h));
    glMemoryBarrier(GL_ALL_BARRIER_BITS);
    gl::Finish();
    out.ms.composite = MsSince(t0);
    stamp(4);
    std::array<GLuint64, 5> ns{};
    for (std::size_t i = 0; i < ns.size(); ++i) glGetQueryObjectui64v(im.stage_queries[i], GL_QUERY_RESULT, &ns[i]);
    const auto between = [&](int a, int b) {
      return static_cast<double>(ns[static_cast<std::size_t>(b)] - ns[static_cast<std::size_t>(a)]) * 1e-6;
    };
    out.ms.gpu_voxelize = between(0, 1);
    out.ms.gpu_gbuffer = between(1, 2);
    out.ms.gpu_shade = between(2, 3);
    out.ms.gpu_composite = between(3, 4);

    // Read back.
    t0 = Clock::now();
    // Each layer through the mapped staging buffer, split into RGB and alpha as it is read.
    const auto rgba = [&](const gl::Texture& t) {
      const std::size_t texels = static_cast<std::size_t>(t.width()) * t.height();
      return reinterpret_cast<const float*>(im.readback.Read(t, GL_RGBA, GL_FLOAT, texels * 4 * sizeof(float)));
    };
    const auto to_rgb = [&](const float* v, std::vector<float>* alpha) {
      sphere::EquirectImage img(w, h);
      if (alpha) alpha->resize(pixels);
      for (std::size_t i = 0; i < pixels; ++i) {
        for (int c = 0; c < 3; ++c) img.rgb[3 * i + c] = v[4 * i + c];
        if (alpha) (*alpha)[i] = v[4 * i + 3];
      }
      return img;
    };
    if (options_.read_composite) out.composite = to_rgb(rgba(im.composite_layer), nullptr);
    if (!options_.read_layers) {
      gpu_sums =
          detail::SumCountsOnGpu(im.counts_program, im.counts, adaptive ? &im.pixel_flags : nullptr, im.count_totals,
                                 k > 1 ? im.shaded_car : im.car_layer, sw, sh, static_cast<int>(pixels));
      if (k > 1 && !adaptive) gpu_sums->pixels_sampled_fully = static_cast<long long>(pixels);
      if (half_rate) gpu_sums->pixels_sampled_fully = half_rate_shaded;
    } else {
      out.car = to_rgb(rgba(im.car_layer), &out.car_alpha);
      out.shadow = to_rgb(rgba(im.shadow_layer), &out.ground_mask);
      out.background = to_rgb(rgba(im.background_layer), nullptr);
      const auto* raw =
          reinterpret_cast<const std::uint32_t*>(im.readback.Read(im.counts, 0, samples * 4 * sizeof(std::uint32_t)));
      counts.resize(samples);
      for (std::size_t i = 0; i < samples; ++i)
        counts[i] = {raw[4 * i], raw[4 * i + 1], raw[4 * i + 2], raw[4 * i + 3]};
      if (adaptive) {
        const auto flags = im.pixel_flags.Read<std::uint32_t>(pixels);
        out.sampled_fully.assign(flags.begin(), flags.end());
      } else if (half_rate) {
        const auto flags = im.block_flags.Read<std::uint32_t>(static_cast<std::size_t>(bw) * bh);
        std::vector<std::uint8_t> block(flags.begin(), flags.end());
        out.sampled_fully = HalfRateShaded(block, w, h);
      } else if (k > 1) {
        out.sampled_fully.assign(pixels, 1);
      }
      if (k > 1) {
        const float* car = rgba(im.shaded_car);
        sample_alpha_storage.resize(samples);
        for (std::size_t i = 0; i < samples; ++i) sample_alpha_storage[i] = car[4 * i + 3];
        sample_alpha = &sample_alpha_storage;
      }
    }
    out.ms.readback = MsSince(t0);
  } else {
    detail::GBuffer g;
    g.width = sw;
    g.height = sh;
    g.position = im.g_position.Read<float>(GL_RGBA, GL_FLOAT, 4);
    g.normal = im.g_normal.Read<float>(GL_RGBA, GL_FLOAT, 4);
    g.base = im.g_base.Read<float>(GL_RGBA, GL_FLOAT, 4);
    t0 = Clock::now();  // the shading stage alone, as on the GPU
    detail::ReferenceInputs in;
    in.gbuffer = &g;
    in.camera = shaded_camera;
    in.materials = &im.material_terms;
    in.emission = &im.emission;
    in.lighting = &im.lighting;
    in.bins = im.bins.get();
    in.grid = geometry ? im.cpu_grid.get() : nullptr;
    in.bvh = geometry && options_.exact_peak_shadows ? im.bvh.get() : nullptr;
    in.options = options_;
    in.ground_centre = ground_centre;
    if (k > 1) {
      RenderResult shaded;
      detail::ShadeReference(in, &shaded, &counts);
      if (adaptive) {
        // Every sample is shaded here; the ones the GPU would not shade are left out of the
        // result, the counts and the coverage alike.
        out.sampled_fully = detail::FlagPixels(g, shaded, k, w, h, static_cast<float>(options_.supersample_contrast));
        for (int y = 0; y < sh; ++y)
          for (int x = 0; x < sw; ++x) {
            const std::size_t s = static_cast<std::size_t>(y) * sw + x;
            if (!out.sampled_fully[static_cast<std::size_t>(y / k) * w + x / k] && (x % k != k / 2 || y % k != k / 2)) {
              counts[s] = {};
              shaded.car_alpha[s] = 0;
            }
          }
        detail::ResolveSupersampled(shaded, k, w, h, &out, &out.sampled_fully);
      } else {
        out.sampled_fully.assign(pixels, 1);
        detail::ResolveSupersampled(shaded, k, w, h, &out);
      }
      sample_alpha_storage = std::move(shaded.car_alpha);
      sample_alpha = &sample_alpha_storage;
    } else if (half_rate) {
      // Every pixel is shaded here; the flags pick the blocks the GPU shades whole, and the other
      // blocks' pixels are filled as render_fill.comp fills them, out of the counts.
      detail::ShadeReference(in, &out, &counts);
      const std::vector<std::uint8_t> block =
          detail::FlagPixels(g, out, 2, bw, bh, static_cast<float>(options_.supersample_contrast), true);
      detail::FillHalfRate(block, &out);
      out.sampled_fully = HalfRateShaded(block, w, h);
      for (std::size_t i = 0; i < pixels; ++i)
        if (!out.sampled_fully[i]) counts[i] = {};
    } else {
      detail::ShadeReference(in, &out, &counts);
    }
    out.ms.shade = MsSince(t0);

    t0 = Clock::now();
    out.background = sphere::EquirectImage(w, h, 0.f);
    out.composite = sphere::EquirectImage(w, h, 0.f);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        glm::vec3 bg(0);
        if (im.background_is_image) {
          const float* b = im.background_image.at(x, y);
          bg = glm::vec3(b[0], b[1], b[2]);
        } else if (!im.environment.empty()) {
          bg = SampleEquirect(im.environment, im.background_from_world.value_or(im.lighting.env_from_world) *
                                                  camera.Ray(x + 0.5, y + 0.5));
        }
        const float a = out.car_alpha[i];
        for (int c = 0; c < 3; ++c) {
          out.background.rgb[3 * i + c] = bg[c];
          out.composite.rgb[3 * i + c] = (1 - a) * bg[c] * out.shadow.rgb[3 * i + c] + a * out.car.rgb[3 * i + c];
        }
      }
    out.ms.composite = MsSince(t0);
  }

  // Counts.
  detail::CountSums sums;
  if (gpu_sums) {
    sums = *gpu_sums;
  } else {
    for (std::size_t i = 0; i < samples; ++i) {
      sums.cones_total += counts[i].cones;
      sums.triples_total += counts[i].triples;
      if ((*sample_alpha)[i] > 0) {
        ++sums.car;
        sums.lobes += counts[i].lobes;
        sums.cones += counts[i].cones;
        sums.sgs += counts[i].sgs;
        sums.triples += counts[i].triples;
      } else if (counts[i].lobes > 0) {
        ++sums.ground;
      }
    }
    sums.pixels_sampled_fully = std::count(out.sampled_fully.begin(), out.sampled_fully.end(), 1);
  }
  RenderCounts& c = out.counts;
  c.lighting_sgs = im.lighting.sg_count;
  c.peaks = static_cast<int>(im.lighting.peaks.size());
  c.car_pixels = static_cast<int>(sums.car);
  c.ground_pixels = static_cast<int>(sums.ground);
  c.pixels_sampled_fully = static_cast<int>(sums.pixels_sampled_fully);
  c.cones_total = sums.cones_total;
  c.triples_total = sums.triples_total;
  if (c.car_pixels > 0) {
    c.lobes_per_car_pixel = static_cast<double>(sums.lobes) / c.car_pixels;
    c.cones_per_car_pixel = static_cast<double>(sums.cones) / c.car_pixels;
    c.sgs_per_car_pixel = static_cast<double>(sums.sgs) / c.car_pixels;
    c.triples_per_car_pixel = static_cast<double>(sums.triples) / c.car_pixels;
  }
  out.ms.total = MsSince(t_total);
  return out;
}

}  // namespace odvr::render
