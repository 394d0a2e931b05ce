#include "engine/lighting/residual_transform_gpu.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <glm/vec4.hpp>
#include <string>

#include "core/error.h"
#include "core/timing.h"
#include "engine/gl/context.h"
#include "engine/gl/shader_library.h"
#include "engine/sphere/equirect.h"

namespace odvr::lighting {
namespace {

using Clock = std::chrono::steady_clock;
// Slots of the totals buffer (lighting_stats_total.comp): 8 doubles each; the frame's, then per
// level the residue entering it and the one it leaves.
constexpr int kMaxLevels = 6;
constexpr int kSlotFrame = 0, kSlots = 1 + 2 * kMaxLevels;
int SlotBefore(int level) { return 1 + 2 * level; }
int SlotAfter(int level) { return 2 + 2 * level; }
constexpr std::size_t kSlotDoubles = 8;
constexpr std::size_t kFlagsBytes = kMaxLevels * sizeof(std::uint32_t);  // per level: SRBFs kept
constexpr std::size_t kGateBytes = 2 * sizeof(std::uint32_t);            // closed, levels run
constexpr std::size_t kPixelBytes = 4 * sizeof(float);                   // vec4 per pixel

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
  double MeanAbs() const { return abs / 3.0 / (4 * kPi); }
  double Rms() const { return std::sqrt(sq / 3.0 / (4 * kPi)); }
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
  // With the projection on the level's own grid, where it refits (SweepsOf > 1): its LevelGram.
  bool has_gram = false;
  gl::Buffer gram_begin{gl::NoCreate}, gram_entries{gl::NoCreate};
};

struct ResidualTransformGpu::Readback {
  std::vector<std::uint8_t> bytes;     // results_: the totals, flags and gate, then every level's μ
  std::vector<std::size_t> mu_offset;  // level s's amplitudes in `bytes`
  std::vector<double> totals;          // kSlots slots of kSlotDoubles
  std::vector<std::uint32_t> flags;    // per level: the SRBFs its keep rule kept
  int levels_run = 0;
  std::vector<double> level_ms;
};

ResidualTransformGpu::ResidualTransformGpu(ResidualTransformOptions options)
    : options_(options), pool_(std::make_unique<ThreadPool>(options.threads)) {
  options_.Check();
  gl::RequireCurrentGl45("lighting gpu");
  // Work-group sizes of the reduction passes. A GPU wants at least a warp or wavefront per
  // group. Mesa's llvmpipe runs a group's invocations as SIMD loops on one CPU thread, where
  // each barrier() of the tree costs a switch per SIMD chunk: there, groups of 16 (projection)
  // and 32 (row sums) made level 4 of a 1024×512 frame about 2× faster than 128 and 256.
  const bool software = gl::CurrentRendererIsSoftware();
  auto group = [](int n) { return "#define GROUP_SIZE " + std::to_string(n) + "\n"; };
  project_ = gl::ShaderLibrary::Compute("lighting_project.comp", group(software ? 16 : 64));
  stats_ = gl::ShaderLibrary::Compute("lighting_stats.comp", group(software ? 32 : 256));
  stats_total_ = gl::ShaderLibrary::Compute("lighting_stats_total.comp", group(software ? 32 : 256));
  resample_texture_ = gl::ShaderLibrary::Compute("lighting_resample.comp", "#define SOURCE_TEXTURE 1\n");
  resample_ = gl::ShaderLibrary::Compute("lighting_resample.comp");
  upsample_ = gl::ShaderLibrary::Compute("lighting_upsample.comp");
  reconstruct_ = gl::ShaderLibrary::Compute("lighting_reconstruct.comp");
  keep_ = gl::ShaderLibrary::Compute("lighting_keep.comp");
  gram_ = gl::ShaderLibrary::Compute("lighting_gram.comp");
  gate_program_ = gl::ShaderLibrary::Compute("lighting_gate.comp");
  totals_ = Zeros(sizeof(double) * kSlotDoubles * kSlots);
  flags_ = Zeros(kFlagsBytes);
  counters_ = Zeros(2 * sizeof(std::uint32_t));
  gate_ = Zeros(2 * sizeof(std::uint32_t));  // closed, levels run (lighting_gate.comp)
  level_queries_.assign(static_cast<std::size_t>(kMaxLevels) + 1, 0);
  glCreateQueries(GL_TIMESTAMP, static_cast<GLsizei>(level_queries_.size()), level_queries_.data());
}

ResidualTransformGpu::~ResidualTransformGpu() {
  glDeleteQueries(static_cast<GLsizei>(level_queries_.size()), level_queries_.data());
}

const ResidualTransformGpu::Tables& ResidualTransformGpu::TablesFor(int level, int width, int height, bool projection) {
  auto& slot = tables_[{level, width, height}];
  // The refits' LevelGram only where the level projects on its own grid: the coarse correction
  // also projects a level on the grid above its own, and never refits there. A grid can be both
  // for different input sizes, so a slot built without it is rebuilt when it is needed.
  const Grid& own = *grids_[static_cast<std::size_t>(level)];
  const bool gram = projection && SweepsOf(options_, level) > 1 && own.width == width && own.height == height;
  if (slot && (slot->has_projection || !projection) && (slot->has_gram || !gram)) return *slot;
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
    if (gram) {
      const LevelGram m = BuildLevelGram(t, options_.normalization, pool_.get());
      std::vector<Entry> rows(m.column.size());
      for (std::size_t k = 0; k < rows.size(); ++k) rows[k] = {m.column[k], m.value[k]};
      g->gram_begin = gl::Buffer();
      g->gram_begin.SetData(m.row_begin);
      g->gram_entries = gl::Buffer();
      g->gram_entries.SetData(rows);
      g->has_gram = true;
    }
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
  correction_.Allocate(finest * kPixelBytes);
  level_residue_.clear();
  level_remaining_.clear();
  level_mu_.clear();
  std::size_t all_srbfs = 0;
  for (int s = 0; s < options_.levels; ++s) {
    const std::size_t pixels = grids_[static_cast<std::size_t>(s)]->pixels();
    const std::size_t srbfs = static_cast<std::size_t>(12) << (2 * s);
    level_residue_.emplace_back().Allocate(pixels * kPixelBytes);
    level_remaining_.emplace_back().Allocate(pixels * kPixelBytes);
    level_mu_.emplace_back().Allocate(srbfs * kPixelBytes);
    all_srbfs += srbfs;
  }
  results_.Allocate(sizeof(double) * kSlotDoubles * kSlots + kFlagsBytes + kGateBytes + all_srbfs * kPixelBytes);
  row_sums_.Allocate(static_cast<std::size_t>(grids_.back()->height) * 2 * kPixelBytes);
  const std::size_t srbfs = static_cast<std::size_t>(12) << (2 * (options_.levels - 1));
  for (auto& b : mu_) b.Allocate(srbfs * kPixelBytes);
  for (auto& b : sweep_mu_) b.Allocate(srbfs * kPixelBytes);
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
                                       const gl::Buffer& out, float sign, const Grid& grid, const gl::Buffer* residue) {
  Bind(base, 0);
  Bind(out, 1);
  // Unused bindings still get a valid buffer: the shader never touches them then.
  Bind(tables ? tables->pixel_begin : flags_, 2);
  Bind(tables ? tables->pixel_entries : flags_, 3);
  Bind(mu, 4);
  Bind(grid.image, 5);
  Bind(residue ? *residue : out, 6);
  reconstruct_.Set("uCount", static_cast<int>(grid.pixels()))
      .Set("uSign", sign)
      .Set("uUseLists", tables ? 1 : 0)
      .Set("uWriteResidue", residue ? 1 : 0)
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
  // The residue on the upper level's grid: `leftover` itself, or restricted into the scratch.
  const gl::Buffer* residue = &leftover;
  if (source.width != grid.width || source.height != grid.height) {
    residue = &correction_;
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
    if (l > lower) Reconstruct(&t, delta, *residue, *residue, -1.f, grid, nullptr);
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
  // The gate open (the level passes and the sums read it at binding 9), and whatever wrote the
  // frame (an upload, a stitching pass) landed before it is sampled.
  glClearNamedBufferData(gate_.id(), GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, nullptr);
  Bind(gate_, 9);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);

  ResampleIntoGrids(frame, input_width, input_height);
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
  if (options_.constant_term) model.constant = glm::vec3(frame_sums.rgb / (4 * kPi));

  const float keep = static_cast<float>(options_.keep_threshold * report.mean_radiance);
  // The stop rule's mean |residue| < threshold × mean radiance, as a bound on Σ (|r|+|g|+|b|) dA,
  // so that the gate on the GPU and the replay below compare the same doubles.
  const double abs_limit = options_.stop_threshold * report.mean_radiance * 3.0 * (4 * kPi);
  glClearNamedBufferData(flags_.id(), GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, nullptr);
  const std::size_t totals_bytes = sizeof(double) * kSlotDoubles * kSlots;
  std::vector<std::size_t> mu_offset;  // each level's amplitudes in results_
  std::size_t offset = totals_bytes + kFlagsBytes + kGateBytes;

  // Every level queued at once (see the header), each one's amplitudes copied into results_.
  int recon = 0;
  for (int s = 0; s < options_.levels; ++s) {
    const std::size_t mu_bytes =
        static_cast<std::size_t>(QueueLevel(s, model.constant, keep, abs_limit, &recon)) * kPixelBytes;
    mu_offset.push_back(offset);
    glCopyNamedBufferSubData(level_mu_[static_cast<std::size_t>(s)].id(), results_.id(), 0,
                             static_cast<GLintptr>(offset), static_cast<GLsizeiptr>(mu_bytes));
    offset += mu_bytes;
  }
  const Readback queued = ReadQueued(std::move(mu_offset), offset);
  report.gpu_levels_run = queued.levels_run;
  glClearNamedBufferData(gate_.id(), GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT,
                         nullptr);  // the correction's passes run

  const gl::Buffer* leftover = nullptr;  // what every kept level left, for the coarse correction
  int leftover_grid = 0;
  const bool converged = PickLevels(queued, abs_limit, &model, &report, &leftover, &leftover_grid);
  if (report.stop_reason.empty()) report.stop_reason = "maximum level reached";
  if (leftover && CoarseCorrectionApplies(options_, static_cast<int>(model.levels.size()), converged)) {
    const auto correction_start = Clock::now();
    CorrectCoarserLevels(*leftover, leftover_grid, keep, &model);
    report.correction_ms = MsSince(correction_start);
  }
  report.total_ms = MsSince(start);
  if (report_out) *report_out = report;
  return model;
}

// The residue's pyramid: working grids, finest first, each area-resampled from the next finer
// one; the finest from the frame, with NaN/Inf/negative channels clamped to 0 (and counted in
// counters_) on the way.
void ResidualTransformGpu::ResampleIntoGrids(GLuint frame, int input_width, int input_height) {
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
}

// Level s queued: R_{<s} on its grid and the residue r_s = I_s − R_{<s}; its amplitudes (eq.
// 4.17), refitted by the extra sweeps; the keep rule; the residue it leaves (eq. 4.18); and the
// gate, which closes once a level stops the transform. Returns the level's SRBF count (its
// amplitudes in level_mu_[s]). *recon_index is the scratch
// reconstruction (of recon_) that holds R_{<s}; a magnified one moves it to the other.
int ResidualTransformGpu::QueueLevel(int s, const glm::vec3& constant, float keep, double abs_limit, int* recon_index) {
  int& recon = *recon_index;
  const auto level = static_cast<std::size_t>(s);
  glQueryCounter(level_queries_[level], GL_TIMESTAMP);
  const Grid& grid = *grids_[level];
  const gl::Buffer &residue = level_residue_[level], &remaining = level_remaining_[level], &mu = level_mu_[level];
  // R_{<s} on this grid and the residue r_s = I_s − R_{<s}: at level 0 the constant; then every
  // coarser level evaluated here, or (exact_reconstruction off) the coarser reconstruction
  // magnified plus the previous level evaluated here.
  if (s == 0 || options_.exact_reconstruction) {
    const float fill[4] = {constant.x, constant.y, constant.z, 0.f};
    glClearNamedBufferSubData(recon_[recon].id(), GL_RGBA32F, 0, grid.pixels() * kPixelBytes, GL_RGBA, GL_FLOAT, fill);
    if (s == 0) Reconstruct(nullptr, mu, recon_[recon], recon_[recon], 1.f, grid, &residue);
    for (int l = 0; l < s; ++l)
      Reconstruct(&TablesFor(l, grid.width, grid.height, false), level_mu_[static_cast<std::size_t>(l)], recon_[recon],
                  recon_[recon], 1.f, grid, l == s - 1 ? &residue : nullptr);
  } else {
    const Grid& coarser = *grids_[level - 1];
    Bind(recon_[recon], 0);
    Bind(recon_[1 - recon], 1);
    SetSize(upsample_, "uSourceSize", coarser.width, coarser.height);
    SetSize(upsample_, "uTargetSize", grid.width, grid.height);
    upsample_.DispatchCovering(static_cast<unsigned>(grid.width), static_cast<unsigned>(grid.height));
    StorageBarrier();
    recon = 1 - recon;
    Reconstruct(&TablesFor(s - 1, grid.width, grid.height, false), level_mu_[level - 1], recon_[recon], recon_[recon],
                1.f, grid, &residue);
  }
  Sums(residue, grid, SlotBefore(s));

  // The level's amplitudes (eq. 4.17) and the residue they leave (eq. 4.18), refitted by the
  // extra sweeps, then the keep rule.
  const Tables& t = TablesFor(s, grid.width, grid.height, true);
  Project(t, residue, mu, false);
  RefitSweeps(t, mu, s);
  Bind(mu, 0);
  Bind(flags_, 1);
  keep_.Set("uCount", t.srbfs).Set("uKeep", keep).Set("uFlagsSlot", s).DispatchCovering(static_cast<unsigned>(t.srbfs));
  StorageBarrier();
  Reconstruct(&t, mu, residue, remaining, -1.f, grid, nullptr);
  Sums(remaining, grid, SlotAfter(s));
  Bind(totals_, 0);
  Bind(flags_, 1);
  gate_program_.Set("uLevel", s).Set("uBeforeSlot", SlotBefore(s)).Set("uAfterSlot", SlotAfter(s));
  glProgramUniform1d(gate_program_.id(), gate_program_.Uniform("uAbsLimit"), abs_limit);
  gate_program_.Use();
  glDispatchCompute(1, 1, 1);
  StorageBarrier();
  return t.srbfs;
}

// The refits on the amplitudes (lighting_gram.comp), as the CPU path makes them: sweep_mu_[0]
// keeps P(r), each sweep writes sweep_mu_[1] and copies it back into μ.
void ResidualTransformGpu::RefitSweeps(const Tables& t, const gl::Buffer& mu, int s) {
  if (SweepsOf(options_, s) <= 1) return;
  const auto bytes = static_cast<GLsizeiptr>(static_cast<std::size_t>(t.srbfs) * kPixelBytes);
  glCopyNamedBufferSubData(mu.id(), sweep_mu_[0].id(), 0, 0, bytes);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  for (int sweep = 1; sweep < SweepsOf(options_, s); ++sweep) {
    Bind(sweep_mu_[0], 0);
    Bind(t.gram_begin, 1);
    Bind(t.gram_entries, 2);
    Bind(mu, 3);
    Bind(sweep_mu_[1], 4);
    gram_.Set("uCount", t.srbfs)
        .Set("uStep", RelaxationOf(options_, s))
        .DispatchCovering(static_cast<unsigned>(t.srbfs));
    StorageBarrier();
    glCopyNamedBufferSubData(sweep_mu_[1].id(), mu.id(), 0, 0, bytes);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
  }
}

ResidualTransformGpu::Readback ResidualTransformGpu::ReadQueued(std::vector<std::size_t> mu_offset, std::size_t end) {
  const int levels = options_.levels;
  const std::size_t totals_bytes = sizeof(double) * kSlotDoubles * kSlots;
  glQueryCounter(level_queries_[static_cast<std::size_t>(levels)], GL_TIMESTAMP);
  glCopyNamedBufferSubData(totals_.id(), results_.id(), 0, 0, static_cast<GLsizeiptr>(totals_bytes));
  glCopyNamedBufferSubData(flags_.id(), results_.id(), 0, static_cast<GLintptr>(totals_bytes),
                           static_cast<GLsizeiptr>(kFlagsBytes));
  glCopyNamedBufferSubData(gate_.id(), results_.id(), 0, static_cast<GLintptr>(totals_bytes + kFlagsBytes),
                           static_cast<GLsizeiptr>(kGateBytes));
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  Readback r;
  r.bytes = results_.Read<std::uint8_t>(end);
  r.mu_offset = std::move(mu_offset);
  r.totals.resize(kSlotDoubles * kSlots);
  std::memcpy(r.totals.data(), r.bytes.data(), totals_bytes);
  r.flags.resize(kMaxLevels);
  std::memcpy(r.flags.data(), r.bytes.data() + totals_bytes, kFlagsBytes);
  std::uint32_t gate[2];
  std::memcpy(gate, r.bytes.data() + totals_bytes + kFlagsBytes, kGateBytes);
  r.levels_run = static_cast<int>(gate[1]);
  std::vector<GLuint64> stamps(static_cast<std::size_t>(levels) + 1);
  for (std::size_t i = 0; i < stamps.size(); ++i) glGetQueryObjectui64v(level_queries_[i], GL_QUERY_RESULT, &stamps[i]);
  r.level_ms.assign(static_cast<std::size_t>(levels), 0.0);
  for (std::size_t i = 0; i < r.level_ms.size(); ++i)
    r.level_ms[i] = static_cast<double>(stamps[i + 1] - stamps[i]) * 1e-6;
  return r;
}

bool ResidualTransformGpu::PickLevels(const Readback& r, double abs_limit, SgLighting* model, TransformReport* report,
                                      const gl::Buffer** leftover, int* leftover_grid) {
  for (int s = 0; s < options_.levels; ++s) {
    const auto level = static_cast<std::size_t>(s);
    const SphereSums before_sums = SumsOf(r.totals, SlotBefore(s)), after_sums = SumsOf(r.totals, SlotAfter(s));
    if (s > 0 && before_sums.abs < abs_limit) {
      report->stop_reason = "residue below threshold before level " + std::to_string(s);
      return true;
    }
    const Grid& grid = *grids_[level];
    const Tables& t = TablesFor(s, grid.width, grid.height, true);
    const int kept = static_cast<int>(r.flags[level]);
    LevelReport lr;
    lr.level = s;
    lr.srbfs_total = t.srbfs;
    lr.srbfs_kept = kept;
    lr.lambda = t.lambda;
    lr.width = grid.width;
    lr.height = grid.height;
    lr.residue_before = before_sums.MeanAbs() / report->mean_radiance;
    lr.ms = r.level_ms[level];
    if (!(after_sums.sq < before_sums.sq && kept > 0)) {  // LevelReducesResidue on the squares
      lr.srbfs_kept = 0;
      lr.residue_after = lr.residue_before;
      report->levels.push_back(lr);
      report->stop_reason = "level " + std::to_string(s) + " does not reduce the residue";
      *leftover = &level_residue_[level];
      *leftover_grid = s;
      return false;
    }
    lr.residue_after = after_sums.MeanAbs() / report->mean_radiance;
    std::vector<glm::vec4> amplitudes(static_cast<std::size_t>(t.srbfs));
    std::memcpy(amplitudes.data(), r.bytes.data() + r.mu_offset[level], amplitudes.size() * sizeof(glm::vec4));
    SgLevel kept_level;
    kept_level.level = s;
    kept_level.lambda = t.lambda;
    for (std::size_t c = 0; c < amplitudes.size(); ++c) {
      const glm::vec3 m(amplitudes[c]);
      if (m == glm::vec3(0)) continue;
      kept_level.indices.push_back(static_cast<int>(c));
      kept_level.amplitudes.push_back(m);
    }
    model->levels.push_back(std::move(kept_level));
    *leftover = &level_remaining_[level];
    *leftover_grid = s;
    report->levels.push_back(lr);
    if (after_sums.abs < abs_limit) {
      report->stop_reason = "residue below threshold after level " + std::to_string(s);
      break;
    }
  }
  return false;
}

}  // namespace odvr::lighting
