// glTF 2.0 models, binary (.glb) and text (.gltf): engine::scene::LoadGltfScene.
#include "core/error.h"
#include "engine/scene/gltf_scene.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const bool binary = odvr::fuzz::StartsWith(data, size, "glTF");
  const auto path = odvr::fuzz::WriteInput(data, size, binary ? ".glb" : ".gltf");
  // Caps small enough that a mutant claiming millions of triangles is refused before allocating.
  odvr::scene::GltfLoadOptions options;
  options.max_triangles = 200'000;
  options.max_vertices = 300'000;
  options.max_texture_side = 1024;
  try {
    odvr::scene::LoadGltfScene(path, options);
  } catch (const odvr::Error&) {
  }
  return 0;
}
