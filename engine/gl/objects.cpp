#include "engine/gl/objects.h"

#include <algorithm>
#include <array>

#include "core/error.h"

namespace odvr::gl {

Buffer::Buffer() { glCreateBuffers(1, &id_); }

Buffer& Buffer::Allocate(std::size_t bytes, const void* data) {
  // Immutable storage cannot be resized: replace the name when the size changes.
  if (size_ != 0) {
    GLuint fresh = 0;
    glCreateBuffers(1, &fresh);
    glDeleteBuffers(1, &id_);
    id_ = fresh;
  }
  size_ = bytes;
  glNamedBufferStorage(id_, static_cast<GLsizeiptr>(std::max<std::size_t>(bytes, 4)), data,
                       GL_DYNAMIC_STORAGE_BIT | GL_MAP_READ_BIT);
  return *this;
}

Buffer& Buffer::SubData(std::size_t offset, std::size_t bytes, const void* data) {
  glNamedBufferSubData(id_, static_cast<GLintptr>(offset), static_cast<GLsizeiptr>(bytes), data);
  return *this;
}

const Buffer& Buffer::BindBase(GLenum target, GLuint index) const {
  glBindBufferBase(target, index, id_);
  return *this;
}

void Buffer::Read(std::size_t offset, std::size_t bytes, void* out) const {
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  glGetNamedBufferSubData(id_, static_cast<GLintptr>(offset), static_cast<GLsizeiptr>(bytes), out);
}

Texture Texture::Create2D(GLenum internal_format, int width, int height, int levels) {
  if (width <= 0 || height <= 0) throw Error("texture", "size must be positive");
  GLuint id = 0;
  glCreateTextures(GL_TEXTURE_2D, 1, &id);
  Texture t(id, GL_TEXTURE_2D);
  t.internal_format_ = internal_format;
  t.width_ = width;
  t.height_ = height;
  t.levels_ = levels;
  glTextureStorage2D(id, levels, internal_format, width, height);
  t.SetFilter(levels > 1 ? GL_LINEAR_MIPMAP_LINEAR : GL_LINEAR, GL_LINEAR);
  return t;
}

Texture Texture::Create3D(GLenum internal_format, int width, int height, int depth, int levels) {
  if (width <= 0 || height <= 0 || depth <= 0) throw Error("texture", "size must be positive");
  GLuint id = 0;
  glCreateTextures(GL_TEXTURE_3D, 1, &id);
  Texture t(id, GL_TEXTURE_3D);
  t.internal_format_ = internal_format;
  t.width_ = width;
  t.height_ = height;
  t.depth_ = depth;
  t.levels_ = levels;
  glTextureStorage3D(id, levels, internal_format, width, height, depth);
  t.SetFilter(levels > 1 ? GL_LINEAR_MIPMAP_LINEAR : GL_LINEAR, GL_LINEAR);
  return t;
}

Texture& Texture::Upload2D(GLenum format, GLenum type, const void* pixels, int level) {
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTextureSubImage2D(id_, level, 0, 0, std::max(1, width_ >> level), std::max(1, height_ >> level), format, type,
                      pixels);
  return *this;
}

Texture& Texture::Upload3D(GLenum format, GLenum type, const void* pixels, int level) {
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTextureSubImage3D(id_, level, 0, 0, 0, std::max(1, width_ >> level), std::max(1, height_ >> level),
                      std::max(1, depth_ >> level), format, type, pixels);
  return *this;
}

Texture& Texture::SetFilter(GLenum min_filter, GLenum mag_filter) {
  glTextureParameteri(id_, GL_TEXTURE_MIN_FILTER, static_cast<GLint>(min_filter));
  glTextureParameteri(id_, GL_TEXTURE_MAG_FILTER, static_cast<GLint>(mag_filter));
  return *this;
}

Texture& Texture::SetWrap(GLenum wrap_s, GLenum wrap_t, GLenum wrap_r) {
  glTextureParameteri(id_, GL_TEXTURE_WRAP_S, static_cast<GLint>(wrap_s));
  glTextureParameteri(id_, GL_TEXTURE_WRAP_T, static_cast<GLint>(wrap_t));
  glTextureParameteri(id_, GL_TEXTURE_WRAP_R, static_cast<GLint>(wrap_r));
  return *this;
}

Texture& Texture::GenerateMipmaps() {
  glGenerateTextureMipmap(id_);
  return *this;
}

const Texture& Texture::BindUnit(GLuint unit) const {
  glBindTextureUnit(unit, id_);
  return *this;
}

const Texture& Texture::BindImage(GLuint unit, GLenum access, int level) const {
  glBindImageTexture(unit, id_, level, target_ == GL_TEXTURE_3D ? GL_TRUE : GL_FALSE, 0, access, internal_format_);
  return *this;
}

void Texture::ReadInto(GLenum format, GLenum type, int level, std::size_t bytes, void* out) const {
  glMemoryBarrier(GL_TEXTURE_UPDATE_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glGetTextureImage(id_, level, format, type, static_cast<GLsizei>(bytes), out);
}

void ReadbackBuffer::Reserve(std::size_t bytes) {
  if (buffer_ && capacity_ >= bytes) return;
  buffer_ = Buffer(NoCreate);  // unmapped by its deletion
  mapped_ = nullptr;
  capacity_ = std::max<std::size_t>(bytes, 4096);
  GLuint id = 0;
  glCreateBuffers(1, &id);
  buffer_ = Buffer::wrap(id);
  const GLbitfield flags = GL_MAP_READ_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
  glNamedBufferStorage(id, static_cast<GLsizeiptr>(capacity_), nullptr, flags | GL_CLIENT_STORAGE_BIT);
  mapped_ = static_cast<const std::byte*>(glMapNamedBufferRange(id, 0, static_cast<GLsizeiptr>(capacity_), flags));
  if (!mapped_) throw Error("read-back buffer", "cannot map " + std::to_string(capacity_) + " bytes");
}

const std::byte* ReadbackBuffer::Wait() {
  // Coherent mapping: once the fence has passed, the copy is visible to the CPU.
  GLsync fence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
  const GLenum status = glClientWaitSync(fence, GL_SYNC_FLUSH_COMMANDS_BIT, 60'000'000'000ull);
  glDeleteSync(fence);
  if (status != GL_ALREADY_SIGNALED && status != GL_CONDITION_SATISFIED)
    throw Error("read-back", "the GPU did not finish the copy within 60 s");
  return mapped_;
}

const std::byte* ReadbackBuffer::Read(const Texture& texture, GLenum format, GLenum type, std::size_t bytes,
                                      int level) {
  Reserve(bytes);
  glMemoryBarrier(GL_TEXTURE_UPDATE_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_PIXEL_BUFFER_BARRIER_BIT);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glBindBuffer(GL_PIXEL_PACK_BUFFER, buffer_.id());
  glGetTextureImage(texture.id(), level, format, type, static_cast<GLsizei>(bytes), nullptr);
  glBindBuffer(GL_PIXEL_PACK_BUFFER, 0);
  return Wait();
}

const std::byte* ReadbackBuffer::Read(const Buffer& buffer, std::size_t offset, std::size_t bytes) {
  Reserve(bytes);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT);
  glCopyNamedBufferSubData(buffer.id(), buffer_.id(), static_cast<GLintptr>(offset), 0, static_cast<GLsizeiptr>(bytes));
  return Wait();
}

Framebuffer::Framebuffer() { glCreateFramebuffers(1, &id_); }

Framebuffer& Framebuffer::AttachColor(const Texture& texture, int index, int level) {
  glNamedFramebufferTexture(id_, GL_COLOR_ATTACHMENT0 + index, texture.id(), level);
  return *this;
}

Framebuffer& Framebuffer::AttachDepth(const Texture& texture, int level) {
  glNamedFramebufferTexture(id_, GL_DEPTH_ATTACHMENT, texture.id(), level);
  return *this;
}

Framebuffer& Framebuffer::CheckComplete() {
  const GLenum status = glCheckNamedFramebufferStatus(id_, GL_DRAW_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "incomplete (status 0x%04X)", status);
    throw Error("framebuffer", buf);
  }
  return *this;
}

Framebuffer& Framebuffer::Bind() {
  glBindFramebuffer(GL_FRAMEBUFFER, id_);
  return *this;
}

std::vector<unsigned char> Framebuffer::ReadRgba8(int x, int y, int width, int height, int index) const {
  std::vector<unsigned char> out(static_cast<std::size_t>(width) * height * 4);
  glNamedFramebufferReadBuffer(id_, GL_COLOR_ATTACHMENT0 + index);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, id_);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(x, y, width, height, GL_RGBA, GL_UNSIGNED_BYTE, out.data());
  return out;
}

std::vector<float> Framebuffer::ReadRgba32f(int x, int y, int width, int height, int index) const {
  std::vector<float> out(static_cast<std::size_t>(width) * height * 4);
  glNamedFramebufferReadBuffer(id_, GL_COLOR_ATTACHMENT0 + index);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, id_);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(x, y, width, height, GL_RGBA, GL_FLOAT, out.data());
  return out;
}

VertexArray::VertexArray() { glCreateVertexArrays(1, &id_); }

VertexArray& VertexArray::AddFloatAttribute(GLuint location, const Buffer& buffer, GLuint binding, int components,
                                            std::size_t offset, std::size_t stride) {
  glVertexArrayVertexBuffer(id_, binding, buffer.id(), 0, static_cast<GLsizei>(stride));
  glEnableVertexArrayAttrib(id_, location);
  glVertexArrayAttribFormat(id_, location, components, GL_FLOAT, GL_FALSE, static_cast<GLuint>(offset));
  glVertexArrayAttribBinding(id_, location, binding);
  return *this;
}

VertexArray& VertexArray::SetIndexBuffer(const Buffer& buffer) {
  glVertexArrayElementBuffer(id_, buffer.id());
  return *this;
}

const VertexArray& VertexArray::Bind() const {
  glBindVertexArray(id_);
  return *this;
}

Program& Program::Use() {
  glUseProgram(id_);
  return *this;
}

GLint Program::Uniform(const char* name) const { return glGetUniformLocation(id_, name); }

// Unknown uniform names are ignored (location -1), as GL does: a shader variant may not use them.
Program& Program::Set(const char* name, int v) {
  glProgramUniform1i(id_, Uniform(name), v);
  return *this;
}
Program& Program::Set(const char* name, unsigned v) {
  glProgramUniform1ui(id_, Uniform(name), v);
  return *this;
}
Program& Program::Set(const char* name, float v) {
  glProgramUniform1f(id_, Uniform(name), v);
  return *this;
}
Program& Program::Set(const char* name, float x, float y) {
  glProgramUniform2f(id_, Uniform(name), x, y);
  return *this;
}
Program& Program::Set(const char* name, float x, float y, float z) {
  glProgramUniform3f(id_, Uniform(name), x, y, z);
  return *this;
}
Program& Program::Set(const char* name, float x, float y, float z, float w) {
  glProgramUniform4f(id_, Uniform(name), x, y, z, w);
  return *this;
}
Program& Program::SetMat4(const char* name, const float* m) {
  glProgramUniformMatrix4fv(id_, Uniform(name), 1, GL_FALSE, m);
  return *this;
}
Program& Program::SetMat3(const char* name, const float* m) {
  glProgramUniformMatrix3fv(id_, Uniform(name), 1, GL_FALSE, m);
  return *this;
}

std::array<int, 3> Program::LocalSize() const {
  std::array<int, 3> size{1, 1, 1};
  glGetProgramiv(id_, GL_COMPUTE_WORK_GROUP_SIZE, size.data());
  return size;
}

Program& Program::DispatchCovering(unsigned x, unsigned y, unsigned z) {
  const auto local = LocalSize();
  auto groups = [](unsigned n, int l) { return (n + static_cast<unsigned>(l) - 1) / static_cast<unsigned>(l); };
  Use();
  glDispatchCompute(groups(x, local[0]), groups(y, local[1]), groups(z, local[2]));
  return *this;
}

void Finish() { glFinish(); }

}  // namespace odvr::gl
