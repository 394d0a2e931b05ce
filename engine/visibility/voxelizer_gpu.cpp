#include "engine/visibility/voxelizer_gpu.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec4.hpp>
#include <string>

#include "core/error.h"
#include "engine/gl/context.h"
#include "engine/gl/shader_library.h"

namespace odvr::visibility {
namespace {

void Set3(gl::Program& p, const char* name, const glm::dvec3& v) {
  p.Set(name, static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z));
}

// Grows `buffer` to hold at least `bytes` (immutable storage cannot be resized in place).
void Reserve(gl::Buffer& buffer, std::size_t bytes) {
  if (buffer && buffer.size() >= bytes) return;
  buffer = gl::Buffer();
  buffer.Allocate(std::max<std::size_t>(bytes, 256));
}

}  // namespace

VoxelizerGpu::VoxelizerGpu(const VoxelGridSpec& spec) : spec_(spec) {
  spec_.Check();
  gl::RequireCurrentGl45("voxelizer gpu");
  voxelize_ = gl::ShaderLibrary::Compute("voxelize.comp");
  mip_ = gl::ShaderLibrary::Compute("voxel_mip.comp");
  trace_ = gl::ShaderLibrary::Compute("cone_trace.comp");
  const int r = spec_.resolution;
  volume_ = gl::Texture::Create3D(GL_RGBA8, r, r, r, spec_.levels());
  // Outside the cube is empty space: the border (default colour 0) rather than the edge voxel.
  volume_.SetWrap(GL_CLAMP_TO_BORDER, GL_CLAMP_TO_BORDER, GL_CLAMP_TO_BORDER);
  volume_.SetFilter(GL_LINEAR_MIPMAP_LINEAR, GL_LINEAR);
  const float zero[4] = {0, 0, 0, 0};
  glTextureParameterfv(volume_.id(), GL_TEXTURE_BORDER_COLOR, zero);
}

void VoxelizerGpu::Voxelize(std::span<const glm::vec3> vertices) {
  if (vertices.size() % 3 != 0)
    throw Error("voxelize", std::to_string(vertices.size()) + " vertices is not a whole number of triangles");
  std::vector<glm::vec4> padded(vertices.size());
  for (std::size_t i = 0; i < vertices.size(); ++i) padded[i] = glm::vec4(vertices[i], 1.f);
  Reserve(vertices_, padded.size() * sizeof(glm::vec4));
  if (!padded.empty()) vertices_.SubData(0, padded.size() * sizeof(glm::vec4), padded.data());
  Voxelize(vertices_, vertices.size() / 3);
}

void VoxelizerGpu::Voxelize(const gl::Buffer& vertices, std::size_t count) {
  if (count * 3 * sizeof(glm::vec4) > vertices.size())
    throw Error("voxelize", "the vertex buffer holds fewer than " + std::to_string(count) + " triangles");
  const std::uint8_t zero[4] = {0, 0, 0, 0};
  glClearTexImage(volume_.id(), 0, GL_RGBA, GL_UNSIGNED_BYTE, zero);
  glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_TEXTURE_UPDATE_BARRIER_BIT);
  if (count > 0) {
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, vertices.id());
    volume_.BindImage(0, GL_WRITE_ONLY, 0);
    Set3(voxelize_, "uOrigin", spec_.origin);
    voxelize_.Set("uInvVoxel", static_cast<float>(1.0 / spec_.voxel_size))
        .Set("uResolution", spec_.resolution)
        .Set("uTriangles", static_cast<unsigned>(count))
        .Use()
        .DispatchCovering(static_cast<unsigned>(count));
  }
  BuildMips();
}

void VoxelizerGpu::BuildMips() {
  mip_.Use();
  for (int l = 1; l < levels(); ++l) {
    glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
    volume_.BindImage(0, GL_READ_ONLY, l - 1);
    volume_.BindImage(1, GL_WRITE_ONLY, l);
    const unsigned size = static_cast<unsigned>(spec_.resolution >> l);
    mip_.Set("uSize", static_cast<int>(size)).DispatchCovering(size, size, size);
  }
  glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT | GL_TEXTURE_UPDATE_BARRIER_BIT);
}

std::vector<float> VoxelizerGpu::TraceCones(std::span<const ConeQuery> queries, const ConeTraceOptions& options) {
  options.Check();
  if (queries.empty()) return {};
  std::vector<glm::vec4> packed(2 * queries.size());
  for (std::size_t i = 0; i < queries.size(); ++i) {
    const ConeQuery& q = queries[i];
    const glm::dvec3 o(q.origin), d(q.direction);
    const bool finite = std::isfinite(o.x) && std::isfinite(o.y) && std::isfinite(o.z) && std::isfinite(d.x) &&
                        std::isfinite(d.y) && std::isfinite(d.z);
    if (!finite || !(glm::length(d) > 0))
      throw Error("cone query", "origin and direction must be finite, the direction non-zero");
    if (!(q.half_angle >= 0 && q.half_angle <= kMaxConeHalfAngle))
      throw Error("cone half_angle",
                  "must be in [0, " + std::to_string(kMaxConeHalfAngle) + "] rad, got " + std::to_string(q.half_angle));
    packed[2 * i] = glm::vec4(q.origin, q.half_angle);
    packed[2 * i + 1] = glm::vec4(q.direction, 0.f);
  }
  Reserve(queries_, packed.size() * sizeof(glm::vec4));
  queries_.SubData(0, packed.size() * sizeof(glm::vec4), packed.data());
  Reserve(results_, queries.size() * sizeof(float));
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, queries_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, results_.id());
  volume_.BindUnit(0);
  Set3(trace_, "uOrigin", spec_.origin);
  trace_.Set("uVoxelSize", static_cast<float>(spec_.voxel_size))
      .Set("uSide", static_cast<float>(spec_.side()))
      .Set("uTopLevel", levels() - 1)
      .Set("uStartOffset", static_cast<float>(options.start_offset_voxels))
      .Set("uStepScale", static_cast<float>(options.step_scale))
      .Set("uMaxDistance", static_cast<float>(options.max_distance))
      .Set("uOpaque", static_cast<float>(options.opaque_threshold))
      .Set("uPartialExponent", static_cast<float>(options.partial_opacity_exponent))
      .Set("uCount", static_cast<unsigned>(queries.size()))
      .Use()
      .DispatchCovering(static_cast<unsigned>(queries.size()));
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  return results_.Read<float>(queries.size());
}

std::vector<std::uint8_t> VoxelizerGpu::ReadLevel(int level) const {
  if (level < 0 || level >= levels()) throw Error("voxel level", "out of range: " + std::to_string(level));
  return volume_.Read<std::uint8_t>(GL_RED, GL_UNSIGNED_BYTE, 1, level);
}

std::vector<std::uint8_t> VoxelizerGpu::ReadOpacity(int level) const {
  if (level < 0 || level >= levels()) throw Error("voxel level", "out of range: " + std::to_string(level));
  const auto rgba = volume_.Read<std::uint8_t>(GL_RGBA, GL_UNSIGNED_BYTE, 4, level);
  std::vector<std::uint8_t> out(rgba.size() / 4 * 3);
  for (std::size_t i = 0; i < rgba.size() / 4; ++i)
    for (std::size_t k = 0; k < 3; ++k) out[3 * i + k] = rgba[4 * i + 1 + k];
  return out;
}

}  // namespace odvr::visibility
