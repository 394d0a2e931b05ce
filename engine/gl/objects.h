#pragma once
// Move-only owners of OpenGL objects, after Magnum's GL wrappers: no copies, a NoCreate state for
// members that are made later, wrap()/release() for interop, setters that chain. All use the
// 4.5 direct-state-access entry points, so nothing depends on what happens to be bound.
#include <epoxy/gl.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace odvr::gl {

struct NoCreateT {
  explicit constexpr NoCreateT() = default;
};
inline constexpr NoCreateT NoCreate{};

// Shared move-only ownership of a GLuint name; Deleter frees it.
template <class Derived>
class Object {
 public:
  Object(const Object&) = delete;
  Object& operator=(const Object&) = delete;
  Object(Object&& other) noexcept : id_(std::exchange(other.id_, 0)) {}
  Object& operator=(Object&& other) noexcept {
    std::swap(id_, other.id_);
    return *this;
  }
  ~Object() {
    if (id_) Derived::Delete(id_);
  }
  GLuint id() const { return id_; }
  explicit operator bool() const { return id_ != 0; }
  // Gives up ownership; the caller deletes the name.
  GLuint release() { return std::exchange(id_, 0); }

 protected:
  Object() = default;
  explicit Object(GLuint id) : id_(id) {}
  GLuint id_ = 0;
};

class Buffer : public Object<Buffer> {
 public:
  Buffer();
  explicit Buffer(NoCreateT) {}
  static Buffer wrap(GLuint id) { return Buffer(id, 0); }
  static void Delete(GLuint id) { glDeleteBuffers(1, &id); }

  // Immutable-size storage, readable and writable from the CPU.
  Buffer& Allocate(std::size_t bytes, const void* data = nullptr);
  template <class T>
  Buffer& SetData(std::span<const T> data) {
    return Allocate(data.size_bytes(), data.data());
  }
  template <class T>
  Buffer& SetData(const std::vector<T>& data) {
    return SetData(std::span<const T>(data));
  }
  Buffer& SubData(std::size_t offset, std::size_t bytes, const void* data);
  // Binding changes the context's state, not the object's: const.
  const Buffer& BindBase(GLenum target, GLuint index) const;
  std::size_t size() const { return size_; }

  // Readback for tests and CPU consumers: waits for the GPU.
  void Read(std::size_t offset, std::size_t bytes, void* out) const;
  template <class T>
  std::vector<T> Read(std::size_t count = 0, std::size_t first = 0) const {
    if (count == 0) count = size_ / sizeof(T) - first;
    std::vector<T> out(count);
    Read(first * sizeof(T), count * sizeof(T), out.data());
    return out;
  }

 private:
  Buffer(GLuint id, std::size_t size) : Object(id), size_(size) {}
  std::size_t size_ = 0;
};

class Texture : public Object<Texture> {
 public:
  explicit Texture(NoCreateT) {}
  static Texture wrap(GLuint id, GLenum target) { return Texture(id, target); }
  static void Delete(GLuint id) { glDeleteTextures(1, &id); }

  static Texture Create2D(GLenum internal_format, int width, int height, int levels = 1);
  static Texture Create3D(GLenum internal_format, int width, int height, int depth, int levels = 1);

  Texture& Upload2D(GLenum format, GLenum type, const void* pixels, int level = 0);
  Texture& Upload3D(GLenum format, GLenum type, const void* pixels, int level = 0);
  Texture& SetFilter(GLenum min_filter, GLenum mag_filter);
  Texture& SetWrap(GLenum wrap_s, GLenum wrap_t, GLenum wrap_r = GL_CLAMP_TO_EDGE);
  Texture& GenerateMipmaps();
  const Texture& BindUnit(GLuint unit) const;
  const Texture& BindImage(GLuint unit, GLenum access, int level = 0) const;

  // Whole-level readback (glGetTextureImage): `components` values of T per texel.
  template <class T>
  std::vector<T> Read(GLenum format, GLenum type, int components, int level = 0) const {
    const int w = std::max(1, width_ >> level), h = std::max(1, height_ >> level),
              d = target_ == GL_TEXTURE_3D ? std::max(1, depth_ >> level) : 1;
    std::vector<T> out(static_cast<std::size_t>(w) * h * d * components);
    ReadInto(format, type, level, out.size() * sizeof(T), out.data());
    return out;
  }

  GLenum target() const { return target_; }
  GLenum internal_format() const { return internal_format_; }
  int width() const { return width_; }
  int height() const { return height_; }
  int depth() const { return depth_; }
  int levels() const { return levels_; }

 private:
  Texture(GLuint id, GLenum target) : Object(id), target_(target) {}
  void ReadInto(GLenum format, GLenum type, int level, std::size_t bytes, void* out) const;
  GLenum target_ = GL_TEXTURE_2D;
  GLenum internal_format_ = 0;
  int width_ = 0, height_ = 0, depth_ = 1, levels_ = 1;
};

// GPU-to-CPU copies through a persistently mapped buffer in host memory: the GPU writes the
// texture or buffer there itself (glGetTextureImage into a pixel-pack buffer, or a buffer copy)
// and the CPU reads the mapping once a fence says it is done, where a read straight into client
// memory let the driver copy on its own terms, far below the bus's rate.
// The pointers returned stay valid until the next call.
class ReadbackBuffer {
 public:
  const std::byte* Read(const Texture& texture, GLenum format, GLenum type, std::size_t bytes, int level = 0);
  const std::byte* Read(const Buffer& buffer, std::size_t offset, std::size_t bytes);

 private:
  void Reserve(std::size_t bytes);
  const std::byte* Wait();
  Buffer buffer_{NoCreate};
  std::size_t capacity_ = 0;
  const std::byte* mapped_ = nullptr;
};

class Framebuffer : public Object<Framebuffer> {
 public:
  Framebuffer();
  explicit Framebuffer(NoCreateT) {}
  static void Delete(GLuint id) { glDeleteFramebuffers(1, &id); }

  Framebuffer& AttachColor(const Texture& texture, int index = 0, int level = 0);
  Framebuffer& AttachDepth(const Texture& texture, int level = 0);
  // Throws odvr::Error naming the status if the framebuffer cannot be drawn to.
  Framebuffer& CheckComplete();
  Framebuffer& Bind();
  // RGBA8 readback of colour attachment `index`, rows bottom-up as GL stores them.
  std::vector<unsigned char> ReadRgba8(int x, int y, int width, int height, int index = 0) const;
  std::vector<float> ReadRgba32f(int x, int y, int width, int height, int index = 0) const;
};

class VertexArray : public Object<VertexArray> {
 public:
  VertexArray();
  explicit VertexArray(NoCreateT) {}
  static void Delete(GLuint id) { glDeleteVertexArrays(1, &id); }

  // Binds `buffer` at `binding` and describes float attribute `location` within it.
  VertexArray& AddFloatAttribute(GLuint location, const Buffer& buffer, GLuint binding, int components,
                                 std::size_t offset, std::size_t stride);
  VertexArray& SetIndexBuffer(const Buffer& buffer);
  const VertexArray& Bind() const;
};

class Program : public Object<Program> {
 public:
  explicit Program(NoCreateT) {}
  static Program wrap(GLuint id) { return Program(id); }
  static void Delete(GLuint id) { glDeleteProgram(id); }

  Program& Use();
  GLint Uniform(const char* name) const;
  Program& Set(const char* name, int v);
  Program& Set(const char* name, unsigned v);
  Program& Set(const char* name, float v);
  Program& Set(const char* name, float x, float y);
  Program& Set(const char* name, float x, float y, float z);
  Program& Set(const char* name, float x, float y, float z, float w);
  Program& SetMat4(const char* name, const float* column_major);
  Program& SetMat3(const char* name, const float* column_major);
  // Dispatches enough groups of the shader's local size to cover (x, y, z) invocations.
  Program& DispatchCovering(unsigned x, unsigned y = 1, unsigned z = 1);
  std::array<int, 3> LocalSize() const;

 private:
  friend class ShaderLibrary;
  explicit Program(GLuint id) : Object(id) {}
};

// Waits until every GL command issued so far has completed (timing and readback).
void Finish();

}  // namespace odvr::gl
