#include "capture/stitcher_gpu.h"

#include <array>
#include <chrono>

#include "core/error.h"
#include "core/srgb.h"
#include "core/timing.h"
#include "engine/gl/objects.h"
#include "engine/gl/shader_library.h"
#include "engine/image/image_io.h"

namespace odvr::capture {
namespace {
using Clock = std::chrono::steady_clock;
}  // namespace

struct GpuStitchPipeline::State {
  int width = 0, height = 0, cameras = 0;
  std::vector<std::array<int, 2>> cam_sizes;
  // Per camera: the level it is sampled at, that level's size, and its first vec4 in `linear`.
  std::array<int, kMaxStitchCameras> level{}, base{};
  std::array<int, 2 * kMaxStitchCameras> level_size{};
  int array_w = 0, array_h = 0;
  gl::Buffer offsets, entries, srgb_table, linear;
  gl::Texture images{gl::NoCreate};
  gl::Program linearize{gl::NoCreate}, warp{gl::NoCreate}, pull{gl::NoCreate}, push{gl::NoCreate};
  // Pull-push pyramid: level 0 is the warp output; filled[l] the pushed colour of level l.
  std::vector<std::array<int, 2>> sizes;
  std::vector<gl::Buffer> prem, filled;
  std::array<GLuint, 2> stamps{};  // GL_TIMESTAMP before the first pass and after the last
  ~State() {
    if (stamps[0] != 0) glDeleteQueries(static_cast<GLsizei>(stamps.size()), stamps.data());
  }
};

GpuStitchPipeline::GpuStitchPipeline(const Rig& rig, const StitchLut& lut) : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.width = lut.width;
  s.height = lut.height;
  s.cameras = lut.cameras;
  int total = 0;
  for (int c = 0; c < s.cameras; ++c) {
    const CameraModel& m = rig.cameras[static_cast<std::size_t>(c)].model;
    const auto cu = static_cast<std::size_t>(c);
    s.cam_sizes.push_back({m.width(), m.height()});
    s.array_w = std::max(s.array_w, m.width());
    s.array_h = std::max(s.array_h, m.height());
    s.level[cu] = lut.level[cu];
    s.level_size[2 * cu] = s.level[cu] ? (m.width() + 1) / 2 : m.width();
    s.level_size[2 * cu + 1] = s.level[cu] ? (m.height() + 1) / 2 : m.height();
    s.base[cu] = total;
    total += s.level_size[2 * cu] * s.level_size[2 * cu + 1];
  }
  s.linear.Allocate(sizeof(float) * 4 * static_cast<std::size_t>(total));
  s.offsets.SetData(lut.offsets);
  static_assert(sizeof(StitchLut::Entry) == 16, "matches the std430 Entry struct of stitch_warp.comp");
  if (lut.entries.empty()) {
    s.entries.Allocate(16);  // no camera sees anything: an empty SSBO cannot be bound
  } else {
    s.entries.SetData(lut.entries);
  }
  const std::array<float, 256>& table = Srgb8ToLinearTable();
  s.srgb_table.Allocate(sizeof table, table.data());

  GLuint id = 0;
  glCreateTextures(GL_TEXTURE_2D_ARRAY, 1, &id);
  s.images = gl::Texture::wrap(id, GL_TEXTURE_2D_ARRAY);
  glTextureStorage3D(id, 1, GL_RGBA8, s.array_w, s.array_h, s.cameras);
  glTextureParameteri(id, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(id, GL_TEXTURE_MAG_FILTER, GL_NEAREST);

  glCreateQueries(GL_TIMESTAMP, static_cast<GLsizei>(s.stamps.size()), s.stamps.data());
  s.linearize = gl::ShaderLibrary::Compute("stitch_linearize.comp");
  s.warp = gl::ShaderLibrary::Compute("stitch_warp.comp");
  s.pull = gl::ShaderLibrary::Compute("stitch_pull.comp");
  s.push = gl::ShaderLibrary::Compute("stitch_push.comp");

  s.sizes.push_back({s.width, s.height});
  while (s.sizes.back()[0] > 1 || s.sizes.back()[1] > 1)
    s.sizes.push_back({(s.sizes.back()[0] + 1) / 2, (s.sizes.back()[1] + 1) / 2});
  for (const auto& sz : s.sizes) {
    const std::size_t bytes = sizeof(float) * 4 * static_cast<std::size_t>(sz[0]) * sz[1];
    s.prem.emplace_back().Allocate(bytes);
    s.filled.emplace_back().Allocate(bytes);
  }
}

GpuStitchPipeline::~GpuStitchPipeline() = default;

void GpuStitchPipeline::Run(const std::vector<cv::Mat>& images, const std::vector<bool>& used,
                            const std::vector<double>& gains, bool fill, sphere::EquirectImage* image,
                            std::vector<std::uint8_t>* valid, StitchReport* report) {
  State& s = *state_;
  const auto upload_start = Clock::now();
  GLint alignment = 4;
  glGetIntegerv(GL_UNPACK_ALIGNMENT, &alignment);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  std::array<float, kMaxStitchCameras> g{};
  for (int c = 0; c < s.cameras; ++c) {
    const auto cu = static_cast<std::size_t>(c);
    if (!used[cu] || images[cu].empty()) continue;
    g[cu] = static_cast<float>(gains[cu]);
    const cv::Mat m = images[cu].isContinuous() ? images[cu] : images[cu].clone();
    glTextureSubImage3D(s.images.id(), 0, 0, 0, c, m.cols, m.rows, 1, GL_BGR, GL_UNSIGNED_BYTE, m.data);
  }
  glPixelStorei(GL_UNPACK_ALIGNMENT, alignment);
  report->ms_upload = MsSince(upload_start);

  glQueryCounter(s.stamps[0], GL_TIMESTAMP);
  const GLuint lin = s.linearize.id();
  s.linear.BindBase(GL_SHADER_STORAGE_BUFFER, 0);
  s.srgb_table.BindBase(GL_SHADER_STORAGE_BUFFER, 1);
  s.images.BindUnit(0);
  for (int c = 0; c < s.cameras; ++c) {
    const auto cu = static_cast<std::size_t>(c);
    if (g[cu] == 0) continue;  // never sampled
    glProgramUniform1i(lin, s.linearize.Uniform("uCamera"), c);
    glProgramUniform2i(lin, s.linearize.Uniform("uCamSize"), s.cam_sizes[cu][0], s.cam_sizes[cu][1]);
    glProgramUniform2i(lin, s.linearize.Uniform("uLevelSize"), s.level_size[2 * cu], s.level_size[2 * cu + 1]);
    glProgramUniform1i(lin, s.linearize.Uniform("uLevel"), s.level[cu]);
    glProgramUniform1i(lin, s.linearize.Uniform("uBase"), s.base[cu]);
    s.linearize.DispatchCovering(static_cast<unsigned>(s.level_size[2 * cu]),
                                 static_cast<unsigned>(s.level_size[2 * cu + 1]));
  }
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);

  const GLuint warp = s.warp.id();
  glProgramUniform2i(warp, s.warp.Uniform("uSize"), s.width, s.height);
  glProgramUniform1fv(warp, s.warp.Uniform("uGain"), s.cameras, g.data());
  glProgramUniform2iv(warp, s.warp.Uniform("uLevelSize"), s.cameras, s.level_size.data());
  glProgramUniform1iv(warp, s.warp.Uniform("uLevel"), s.cameras, s.level.data());
  glProgramUniform1iv(warp, s.warp.Uniform("uBase"), s.cameras, s.base.data());
  s.offsets.BindBase(GL_SHADER_STORAGE_BUFFER, 0);
  s.entries.BindBase(GL_SHADER_STORAGE_BUFFER, 1);
  s.prem[0].BindBase(GL_SHADER_STORAGE_BUFFER, 2);
  s.linear.BindBase(GL_SHADER_STORAGE_BUFFER, 3);
  s.warp.DispatchCovering(static_cast<unsigned>(s.width), static_cast<unsigned>(s.height));
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);

  const gl::Buffer* result = &s.prem[0];
  if (fill) {
    for (std::size_t l = 0; l + 1 < s.sizes.size(); ++l) {
      glProgramUniform2i(s.pull.id(), s.pull.Uniform("uFineSize"), s.sizes[l][0], s.sizes[l][1]);
      glProgramUniform2i(s.pull.id(), s.pull.Uniform("uCoarseSize"), s.sizes[l + 1][0], s.sizes[l + 1][1]);
      s.prem[l].BindBase(GL_SHADER_STORAGE_BUFFER, 0);
      s.prem[l + 1].BindBase(GL_SHADER_STORAGE_BUFFER, 1);
      s.pull.DispatchCovering(static_cast<unsigned>(s.sizes[l + 1][0]), static_cast<unsigned>(s.sizes[l + 1][1]));
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    }
    const std::size_t top = s.sizes.size() - 1;
    for (std::size_t l = top; l-- > 0;) {
      glProgramUniform2i(s.push.id(), s.push.Uniform("uSize"), s.sizes[l][0], s.sizes[l][1]);
      glProgramUniform2i(s.push.id(), s.push.Uniform("uCoarseSize"), s.sizes[l + 1][0], s.sizes[l + 1][1]);
      glProgramUniform1i(s.push.id(), s.push.Uniform("uCoarsePremultiplied"), l + 1 == top ? 1 : 0);
      s.prem[l].BindBase(GL_SHADER_STORAGE_BUFFER, 0);
      (l + 1 == top ? s.prem[l + 1] : s.filled[l + 1]).BindBase(GL_SHADER_STORAGE_BUFFER, 1);
      s.filled[l].BindBase(GL_SHADER_STORAGE_BUFFER, 2);
      s.push.DispatchCovering(static_cast<unsigned>(s.sizes[l][0]), static_cast<unsigned>(s.sizes[l][1]));
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    }
    if (top > 0) result = &s.filled[0];
  }
  glQueryCounter(s.stamps[1], GL_TIMESTAMP);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  const auto readback_start = Clock::now();
  const std::vector<float> out = result->Read<float>();
  *image = sphere::EquirectImage(s.width, s.height);
  valid->assign(image->pixel_count(), 0);
  for (std::size_t p = 0; p < image->pixel_count(); ++p) {
    for (int k = 0; k < 3; ++k) image->rgb[3 * p + k] = out[4 * p + k];
    (*valid)[p] = out[4 * p + 3] > 0.5f ? 1 : 0;
  }
  report->ms_readback = MsSince(readback_start);
  // Both stamps are done: the read-back waited for the last pass.
  GLuint64 stamps[2] = {0, 0};
  for (int i = 0; i < 2; ++i) glGetQueryObjectui64v(s.stamps[static_cast<std::size_t>(i)], GL_QUERY_RESULT, &stamps[i]);
  report->ms_gpu_passes = static_cast<double>(stamps[1] - stamps[0]) * 1e-6;
}

}  // namespace odvr::capture
