#include "engine/lighting/residual_transform_gpu.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <glm/vec4.hpp>
#include <string>

#include "engine/core/error.h"
#include "engine/gl/context.h"
#include "engine/gl/shader_library.h"
#include "engine/sphere/equirect.h"

namespace odvr::lighting {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

// Slots of the totals buffer (lighting_stats_total.comp): 8 doubles each.
constexpr int kSlotFrame = 0, kSlotBefore = 1, kSlotAfter = 2, kSlots = 3;
constexpr std::size_t kSlotDoubles = 8;
constexpr std::size_t kPixelBytes = 4 * sizeof(float);  // vec4 per pixel

// One overlap-list entry as the shaders read it: std430 struct { int; float; }.
struct Entry {
  std::int32_t index;
  float value;
};
static_assert(sizeof(Entry) == 8);

// Sums of one image over the sphere, from one slot of the totals buffer.
struct SphereSums {
  glm::dvec3 rgb{0};  // Σ c dA per channel
  double abs = 0;     // Σ (|r|+|g|+|b|) dA
  double sq = 0;      // Σ (r²+g²+b²) dA
  // The same measures as MeanAbsRadiance and RmsRadiance.
  double MeanAbs() const { return abs / 3.0 / (4 * sphere::kPi); }
  double Rms() const { return std::sqrt(sq / 3.0 / (4 * sphere::kPi)); }
};

SphereSums SumsOf(const std::vector<double>& totals, int slot) {
  const double* t = &totals[static_cast<std::size_t>(slot) * kSlotDoubles];
  SphereSums s;
  s.rgb = glm::dvec3(t[0], t[1], t[2]);
  s.abs = t[3];
  s.sq = t[4];
  return s;
}

// Shader writes to storage buffers become visible to later dispatches and buffer commands.
void StorageBarrier() { glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT); }

void SetSize(gl::Program& program, const char* name, int width, int height) {
  glProgramUniform2i(program.id(), program.Uniform(name), width, height);
}

void Bind(const gl::Buffer& buffer, GLuint index) { glBindBufferBase(GL_SHADER_STORAGE_BUFFER, index, buffer.id()); }

gl::Buffer Zeros(std::size_t bytes) {
  gl::Buffer b;
  b.Allocate(bytes);
  glClearNamedBufferData(b.id(), GL_R8UI, GL_RED_INTEGER, GL_UNSIGNED_BYTE, nullptr);
  return b;
}

}  // namespace

struct ResidualTransformGpu::Grid {
  int width = 0, height = 0;
  gl::Buffer image{gl::NoCreate};            // the frame area-resampled to this grid
  gl::Buffer row_solid_angle{gl::NoCreate};  // double per row
  std::size_t pixels() const { return static_cast<std::size_t>(width) * static_cast<std::size_t>(height); }
};

struct ResidualTransformGpu::Tables {
  int srbfs = 0;
  double lambda = 0;
  bool has_projection = false;  // the by-SRBF lists, needed only on the level's own grid
  gl::Buffer srbf_begin{gl::NoCreate}, srbf_entries{gl::NoCreate}, srbf_scale{gl::NoCreate};
  gl::Buffer pixel_begin{gl::NoCreate}, pixel_entries{gl::NoCreate};
};

ResidualTransformGpu::ResidualTransformGpu(ResidualTransformOptions options)
    : options_(options), pool_(std::make_unique<ThreadPool>(options.threads)) {
  options_.Check();
  gl::RequireCurrentGl45("lighting gpu");
  // Work-group sizes of the reduction passes. A GPU wants at least a warp or wavefront per
  // group. Mesa's llvmpipe runs a group's invocations as SIMD loops on one CPU thread, where
  // each barrier() of the tree costs a switch per SIMD chunk: there, groups of 16 (projection)
  // and 32 (row sums) made level 4 of a 1024×512 frame about 2× faster than 128 and 256.
  const char* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  const bool software = renderer && std::string(renderer).find("llvmpipe") != std::string::npos;
  auto group = [](int n) { return "#define GROUP_SIZE " + std::to_string(n) + "\n"; };
  project_ = gl::ShaderLibrary::Compute("lighting_project.comp", group(software ? 16 : 64));
  stats_ = gl::ShaderLibrary::Compute("lighting_stats.comp", group(software ? 32 : 256));
  stats_total_ = gl::ShaderLibrary::Compute("lighting_stats_total.comp", group(software ? 32 : 256));
  resample_texture_ = gl::ShaderLibrary::Compute("lighting_resample.comp", "#define SOURCE_TEXTURE 1\n");
  resample_ = gl::ShaderLibrary::Compute("lighting_resample.comp");
  upsample_ = gl::ShaderLibrary::Compute("lighting_upsample.comp");
  reconstruct_ = gl::ShaderLibrary::Compute("lighting_reconstruct.comp");
  keep_ = gl::ShaderLibrary::Compute("lighting_keep.comp");
  totals_ = Zeros(sizeof(double) * kSlotDoubles * kSlots);
  flags_ = Zeros(2 * sizeof(std::uint32_t));
  counters_ = Zeros(2 * sizeof(std::uint32_t));
}

ResidualTransformGpu::~ResidualTransformGpu() = default;

const ResidualTransformGpu::Tables& ResidualTransformGpu::TablesFor(int level, int width, int height, bool projection) {
  auto& slot = tables_[{level, width, height}];
  if (slot && (slot->has_projection || !projection)) return *slot;
  const auto start = Clock::now();
  const LevelTables t = BuildLevelTables(level, width, height, RegionCutoffOf(options_, level), pool_.get());
  auto g = std::make_unique<Tables>();
  g->srbfs = static_cast<int>(t.inv_weight_sum.size());
  g->lambda = t.lambda;
  g->pixel_begin = gl::Buffer();
  g->pixel_begin.SetData(t.pixel_begin);
  std::vector<Entry> entries(t.pixel_srbf.size());
  for (std::size_t e = 0; e < entries.size(); ++e) entries[e] = {t.pixel_srbf[e], t.pixel_g[e]};
  g->pixel_entries = gl::Buffer();
  g->pixel_entries.SetData(entries);
  if (projection) {
    const std::vector<float>& weights =
        options_.normalization == Normalization::kPartition ? t.srbf_partition_weight : t.srbf_weight;
    for (std::size_t e = 0; e < entries.size(); ++e) entries[e] = {t.srbf_pixel[e], weights[e]};
    std::vector<float> scale(t.inv_weight_sum.size());
    for (std::size_t c = 0; c < scale.size(); ++c) {
      double s = t.inv_weight_sum[c];
      if (options_.normalization == Normalization::kLocalSum) s /= t.local_sum[c];
      scale[c] = static_cast<float>(s);
    }
    g->srbf_begin = gl::Buffer();
    g->srbf_begin.SetData(t.srbf_begin);
    g->srbf_entries = gl::Buffer();
    g->srbf_entries.SetData(entries);
    g->srbf_scale = gl::Buffer();
    g->srbf_scale.SetData(scale);
    g->has_projection = true;
  }
  spdlog::debug("lighting gpu: overlap lists of level {} on {}x{} built and uploaded in {:.1f} ms ({:.1f} MiB)", level,
                width, height, MsSince(start),
                (projection ? 2.0 : 1.0) * static_cast<double>(entries.size() * sizeof(Entry)) / 1048576.0);
  slot = std::move(g);
  return *slot;
}

void ResidualTransformGpu::PrepareGrids(int input_width, int input_height) {
  if (input_width == grids_input_width_ && input_height == grids_input_height_) return;
  grids_.clear();
  std::size_t finest = 0;
  for (int s = 0; s < options_.levels; ++s) {
    auto g = std::make_unique<Grid>();
    std::tie(g->width, g->height) = WorkingGrid(options_, s, input_width, input_height);
    g->image = gl::Buffer();
    g->image.Allocate(g->pixels() * kPixelBytes);
    std::vector<double> solid_angle(static_cast<std::size_t>(g->height));
    for (int row = 0; row < g->height; ++row)
      solid_angle[static_cast<std::size_t>(row)] = sphere::EquirectPixelSolidAngle(row, g->width, g->height);
    g->row_solid_angle = gl::Buffer();
    g->row_solid_angle.SetData(solid_angle);
    finest = std::max(finest, g->pixels());
    grids_.push_back(std::move(g));
  }
  for (auto& b : recon_) b.Allocate(finest * kPixelBytes);
  residue_.Allocate(finest * kPixelBytes);
  remaining_.Allocate(finest * kPixelBytes);
  row_sums_.Allocate(static_cast<std::size_t>(grids_.back()->height) * 2 * kPixelBytes);
  const std::size_t srbfs = static_cast<std::size_t>(12) << (2 * (options_.levels - 1));
  for (auto& b : mu_) b.Allocate(srbfs * kPixelBytes);
  grids_input_width_ = input_width;
  grids_input_height_ = input_height;
}

void ResidualTransformGpu::Sums(const gl::Buffer& image, const Grid& grid, int slot) {
  Bind(image, 0);
  Bind(row_sums_, 1);
  SetSize(stats_, "uSize", grid.width, grid.height);
  stats_.Use();
  glDispatchCompute(static_cast<GLuint>(grid.height), 1, 1);
  StorageBarrier();
  Bind(row_sums_, 0);
  Bind(grid.row_solid_angle, 1);
  Bind(totals_, 2);
  stats_total_.Set("uRows", grid.height).Set("uSlot", slot).Use();
  glDispatchCompute(1, 1, 1);
  StorageBarrier();
}

void ResidualTransformGpu::Reconstruct(const Tables* tables, const gl::Buffer& mu, const gl::Buffer& base,
                                       const gl::Buffer& out, float sign, const Grid& grid, bool write_residue,
                                       bool only_if_dropped) {
  Bind(base, 0);
  Bind(out, 1);
  // Unused bindings still get a valid buffer: the shader never touches them then.
  Bind(tables ? tables->pixel_begin : flags_, 2);
  Bind(tables ? tables->pixel_entries : flags_, 3);
  Bind(mu, 4);
  Bind(grid.image, 5);
  Bind(write_residue ? residue_ : remaining_, 6);
  Bind(flags_, 7);
  reconstruct_.Set("uCount", static_cast<int>(grid.pixels()))
      .Set("uSign", sign)
      .Set("uUseLists", tables ? 1 : 0)
      .Set("uWriteResidue", write_residue ? 1 : 0)
      .Set("uOnlyIfDropped", only_if_dropped ? 1 : 0)
      .DispatchCovering(static_cast<unsigned>(grid.pixels()));
  StorageBarrier();
}

void ResidualTransformGpu::Project(const Tables& tables, const gl::Buffer& residue, const gl::Buffer& mu,
                                   bool accumulate, float step) {
  Bind(residue, 0);
  Bind(tables.srbf_begin, 1);
  Bind(tables.srbf_entries, 2);
  Bind(tables.srbf_scale, 3);
  Bind(mu, 4);
  project_.Set("uAccumulate", accumulate ? 1 : 0).Set("uStep", step).Use();
  glDispatchCompute(static_cast<GLuint>(tables.srbfs), 1, 1);
  StorageBarrier();
}

void ResidualTransformGpu::CorrectCoarserLevels(const gl::Buffer& leftover, int leftover_grid, float keep,
                                                SgLighting* model) {
  const int finest = static_cast<int>(model->levels.size()) - 1;
  const int upper = finest - 1, lower = std::max(0, finest - 2);
  const Grid &source = *grids_[static_cast<std::size_t>(leftover_grid)],
             &grid = *grids_[static_cast<std::size_t>(upper)];
  // The residue on the upper level's grid, in whichever scratch buffer `leftover` is not.
  const gl::Buffer* residue = &leftover;
  if (source.width != grid.width || source.height != grid.height) {
    residue = &leftover == &residue_ ? &remaining_ : &residue_;
    Bind(leftover, 0);
    Bind(*residue, 1);
    SetSize(resample_, "uSourceSize", source.width, source.height);
    SetSize(resample_, "uTargetSize", grid.width, grid.height);
    resample_.DispatchCovering(static_cast<unsigned>(grid.width), static_cast<unsigned>(grid.height));
    StorageBarrier();
  }
  // Each refit level's amplitudes in its own buffer (mu_[0] the upper, mu_[1] the lower), read
  // back together at the end: one wait for the GPU instead of one per level.
  for (int l = upper; l >= lower; --l) {
    const gl::Buffer& delta = mu_[upper - l];
    const Tables& t = TablesFor(l, grid.width, grid.height, true);
    // μ = 0 + step · projection: the step applied before the residue is updated, as on the CPU.
    glClearNamedBufferData(delta.id(), GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, nullptr);
    Project(t, *residue, delta, true, kCoarseCorrectionStep);
    if (l > lower) Reconstruct(&t, delta, *residue, *residue, -1.f, grid, false, false);
  }
  for (int l = upper; l >= lower; --l) {
    const std::vector<glm::vec4> delta4 =
        mu_[upper - l].Read<glm::vec4>(static_cast<std::size_t>(TablesFor(l, grid.width, grid.height, true).srbfs));
    AddRefit(std::vector<glm::vec3>(delta4.begin(), delta4.end()), keep, &model->levels[static_cast<std::size_t>(l)]);
  }
}

SgLighting ResidualTransformGpu::Run(const sphere::EquirectImage& input, TransformReport* report) {
  const auto start = Clock::now();
  CheckTransformInput(input.width, input.height);
  if (input.rgb.size() != input.pixel_count() * 3)
    throw Error("lighting input", "holds " + std::to_string(input.rgb.size()) + " values, not " +
                                      std::to_string(input.pixel_count() * 3));
  if (!upload_ || upload_.width() != input.width || upload_.height() != input.height)
    upload_ = gl::Texture::Create2D(GL_RGB32F, input.width, input.height);
  upload_.Upload2D(GL_RGB, GL_FLOAT, input.rgb.data());
  return RunOnTexture(upload_.id(), input.width, input.height, start, report);
}

SgLighting ResidualTransformGpu::Run(const gl::Texture& frame, TransformReport* report) {
  const auto start = Clock::now();
  if (!frame || frame.target() != GL_TEXTURE_2D) throw Error("lighting input texture", "must be a 2D texture");
  // Ask GL, not the wrapper: a wrapped texture carries no size.
  GLint width = 0, height = 0;
  glGetTextureLevelParameteriv(frame.id(), 0, GL_TEXTURE_WIDTH, &width);
  glGetTextureLevelParameteriv(frame.id(), 0, GL_TEXTURE_HEIGHT, &height);
  CheckTransformInput(width, height);
  return RunOnTexture(frame.id(), width, height, start, report);
}

SgLighting ResidualTransformGpu::RunOnTexture(GLuint frame, int input_width, int input_height, Clock::time_point start,
                                              TransformReport* report_out) {
  TransformReport report;
  report.device = "gpu";
  SgLighting model;
  PrepareGrids(input_width, input_height);
  // Whatever wrote the frame (an upload, a stitching pass) lands before it is sampled.
  glMemoryBarrier(GL_ALL_BARRIER_BITS);

  // Working grids, finest first, each area-resampled from the next finer one; the finest from
  // the frame, with NaN/Inf/negative channels clamped to 0 on the way.
  const int levels = options_.levels;
  glClearNamedBufferData(counters_.id(), GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, nullptr);
  {
    const Grid& g = *grids_.back();
    glBindTextureUnit(0, frame);
    Bind(g.image, 1);
    Bind(counters_, 2);
    SetSize(resample_texture_, "uSourceSize", input_width, input_height);
    SetSize(resample_texture_, "uTargetSize", g.width, g.height);
    resample_texture_.DispatchCovering(static_cast<unsigned>(g.width), static_cast<unsigned>(g.height));
    StorageBarrier();
  }
  for (int s = levels - 2; s >= 0; --s) {
    const Grid &finer = *grids_[static_cast<std::size_t>(s) + 1], &g = *grids_[static_cast<std::size_t>(s)];
    Bind(finer.image, 0);
    Bind(g.image, 1);
    SetSize(resample_, "uSourceSize", finer.width, finer.height);
    SetSize(resample_, "uTargetSize", g.width, g.height);
    resample_.DispatchCovering(static_cast<unsigned>(g.width), static_cast<unsigned>(g.height));
    StorageBarrier();
  }
  const Grid& finest = *grids_.back();
  Sums(finest.image, finest, kSlotFrame);
  const SphereSums frame_sums = SumsOf(totals_.Read<double>(), kSlotFrame);
  const auto counters = counters_.Read<std::uint32_t>();
  if (counters[0] || counters[1])
    spdlog::warn("lighting input: clamped {} NaN/Inf and {} negative pixels to 0", counters[0], counters[1]);
  report.prepare_ms = MsSince(start);
  report.input_width = input_width;
  report.input_height = input_height;

  report.mean_radiance = frame_sums.MeanAbs();
  if (!(report.mean_radiance > 0)) {
    report.stop_reason = "the frame is black";
    report.total_ms = MsSince(start);
    if (report_out) *report_out = report;
    return model;
  }
  // The constant term: the solid-angle-weighted mean (an SG with λ = 0).
  if (options_.constant_term) model.constant = glm::vec3(frame_sums.rgb / (4 * sphere::kPi));

  const float keep = static_cast<float>(options_.keep_threshold * report.mean_radiance);
  int recon = 0, mu = 0;  // which of the two buffers holds the current reconstruction / amplitudes
  int previous_level = -1;
  // What every kept level left, for the coarse correction: remaining_ on the last kept level's
  // grid, or residue_ on the grid of a rejected level (what the CPU path's `leftover` holds).
  bool converged = false, leftover_in_residue = false;
  int leftover_grid = 0;
  for (int s = 0; s < levels; ++s) {
    const auto level_start = Clock::now();
    const Grid& grid = *grids_[static_cast<std::size_t>(s)];
    // R_{<s} on this grid and the residue r_s = I_s − R_{<s}: at level 0 the constant; then every
    // coarser level evaluated here, or (exact_reconstruction off) the coarser reconstruction
    // magnified plus the previous level evaluated here.
    if (s == 0) {
      const float fill[4] = {model.constant.x, model.constant.y, model.constant.z, 0.f};
      glClearNamedBufferSubData(recon_[recon].id(), GL_RGBA32F, 0, grid.pixels() * kPixelBytes, GL_RGBA, GL_FLOAT,
                                fill);
      Reconstruct(nullptr, mu_[mu], recon_[recon], recon_[recon], 1.f, grid, true, false);
    } else if (options_.exact_reconstruction) {
      // Every accepted coarser level evaluated on this grid, as the CPU path does.
      const float fill[4] = {model.constant.x, model.constant.y, model.constant.z, 0.f};
      glClearNamedBufferSubData(recon_[recon].id(), GL_RGBA32F, 0, grid.pixels() * kPixelBytes, GL_RGBA, GL_FLOAT,
                                fill);
      for (int l = 0; l < s; ++l)
        Reconstruct(&TablesFor(l, grid.width, grid.height, false), level_mu_[static_cast<std::size_t>(l)],
                    recon_[recon], recon_[recon], 1.f, grid, l == s - 1, false);
    } else {
      const Grid& coarser = *grids_[static_cast<std::size_t>(s) - 1];
      Bind(recon_[recon], 0);
      Bind(recon_[1 - recon], 1);
      SetSize(upsample_, "uSourceSize", coarser.width, coarser.height);
      SetSize(upsample_, "uTargetSize", grid.width, grid.height);
      upsample_.DispatchCovering(static_cast<unsigned>(grid.width), static_cast<unsigned>(grid.height));
      StorageBarrier();
      recon = 1 - recon;
      const Tables& previous = TablesFor(previous_level, grid.width, grid.height, false);
      Reconstruct(&previous, mu_[1 - mu], recon_[recon], recon_[recon], 1.f, grid, true, false);
    }
    Sums(residue_, grid, kSlotBefore);

    // The level's amplitudes (eq. 4.17) and the residue they leave (eq. 4.18), refitted by the
    // extra sweeps, then the keep rule; all without a readback. The stop rule's "before" sum is
    // read together with the level's result: if it says the transform had already converged,
    // this level's work is discarded, which costs one level once per frame instead of one more
    // GPU round trip per level.
    const Tables& t = TablesFor(s, grid.width, grid.height, true);
    Project(t, residue_, mu_[mu], false);
    Reconstruct(&t, mu_[mu], residue_, remaining_, -1.f, grid, false, false);
    for (int sweep = 1; sweep < SweepsOf(options_, s); ++sweep) {
      Project(t, remaining_, mu_[mu], true, RelaxationOf(options_, s));
      Reconstruct(&t, mu_[mu], residue_, remaining_, -1.f, grid, false, false);
    }
    glClearNamedBufferData(flags_.id(), GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, nullptr);
    Bind(mu_[mu], 0);
    Bind(flags_, 1);
    keep_.Set("uCount", t.srbfs).Set("uKeep", keep).DispatchCovering(static_cast<unsigned>(t.srbfs));
    StorageBarrier();
    Reconstruct(&t, mu_[mu], residue_, remaining_, -1.f, grid, false, true);
    Sums(remaining_, grid, kSlotAfter);

    const std::vector<double> totals = totals_.Read<double>();
    const int kept = static_cast<int>(flags_.Read<std::uint32_t>()[0]);
    const SphereSums before_sums = SumsOf(totals, kSlotBefore), after_sums = SumsOf(totals, kSlotAfter);
    const double before = before_sums.MeanAbs() / report.mean_radiance;
    if (before < options_.stop_threshold && s > 0) {
      report.stop_reason = "residue below threshold before level " + std::to_string(s);
      converged = true;
      break;
    }
    const double after = after_sums.MeanAbs() / report.mean_radiance;
    LevelReport lr;
    lr.level = s;
    lr.srbfs_total = t.srbfs;
    lr.srbfs_kept = kept;
    lr.lambda = t.lambda;
    lr.width = grid.width;
    lr.height = grid.height;
    lr.residue_before = before;
    if (!LevelReducesResidue(before_sums.Rms(), after_sums.Rms(), kept)) {
      lr.srbfs_kept = 0;
      lr.residue_after = before;
      lr.ms = MsSince(level_start);
      report.levels.push_back(lr);
      report.stop_reason = "level " + std::to_string(s) + " does not reduce the residue";
      leftover_in_residue = true;
      leftover_grid = s;
      break;
    }
    lr.residue_after = after;
    const std::vector<glm::vec4> amplitudes = mu_[mu].Read<glm::vec4>(static_cast<std::size_t>(t.srbfs));
    SgLevel level;
    level.level = s;
    level.lambda = t.lambda;
    for (std::size_t c = 0; c < amplitudes.size(); ++c) {
      const glm::vec3 m(amplitudes[c]);
      if (m == glm::vec3(0)) continue;
      level.indices.push_back(static_cast<int>(c));
      level.amplitudes.push_back(m);
    }
    model.levels.push_back(std::move(level));
    if (options_.exact_reconstruction) {
      const std::size_t bytes = static_cast<std::size_t>(t.srbfs) * kPixelBytes;
      if (level_mu_.size() <= static_cast<std::size_t>(s)) level_mu_.resize(static_cast<std::size_t>(s) + 1);
      gl::Buffer& kept_mu = level_mu_[static_cast<std::size_t>(s)];
      if (kept_mu.size() < bytes) {
        kept_mu = gl::Buffer();
        kept_mu.Allocate(bytes);
      }
      glCopyNamedBufferSubData(mu_[mu].id(), kept_mu.id(), 0, 0, static_cast<GLsizeiptr>(bytes));
    }
    mu = 1 - mu;  // the accepted amplitudes stay on the GPU for the next level's reconstruction
    previous_level = s;
    leftover_grid = s;
    lr.ms = MsSince(level_start);
    report.levels.push_back(lr);
    if (after < options_.stop_threshold) {
      report.stop_reason = "residue below threshold after level " + std::to_string(s);
      break;
    }
  }
  if (report.stop_reason.empty()) report.stop_reason = "maximum level reached";
  if (CoarseCorrectionApplies(options_, static_cast<int>(model.levels.size()), converged)) {
    const auto correction_start = Clock::now();
    CorrectCoarserLevels(leftover_in_residue ? residue_ : remaining_, leftover_grid, keep, &model);
    report.correction_ms = MsSince(correction_start);
  }
  report.total_ms = MsSince(start);
  if (report_out) *report_out = report;
  return model;
}

}  // namespace odvr::lighting
