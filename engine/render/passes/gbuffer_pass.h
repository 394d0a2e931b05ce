#pragma once
// The G-buffer pass: the model rasterized at the shaded size (render_gbuffer.vert/.frag) into
// RenderTargets' position (and material index + 1), shading normal (and roughness), base colour
// (and metallic) and emission. Internal to engine/render.
#include <glm/mat4x4.hpp>
#include <vector>

#include "engine/gl/objects.h"
#include "engine/render/passes/gpu_model.h"
#include "engine/render/passes/render_targets.h"
#include "engine/render/passes/shade_inputs.h"
#include "engine/render/pinhole_camera.h"

namespace odvr::render {

// The clip transform of `camera` (OpenCV axes, y flipped for GL's rows), its depth range fitted
// to `bounds` (or 0.01–10 m when empty); `camera`'s own size and focal length.
glm::mat4 ClipFromWorld(const PinholeCamera& camera, const scene::Bounds& bounds);

class GBufferPass {
 public:
  GBufferPass();  // compiles its shaders: needs a current OpenGL 4.5 context

  // Clears the G-buffer of fr's shaded size (RenderTargets::Ensure first) and, when fr.geometry,
  // draws the model seen by fr.shaded_camera. A material that an override replaces is drawn as
  // the override's surface: opaque, without its normal map, emitting nothing.
  void Run(const RenderFrame& fr, const GpuModel& model, const GpuMaterials& materials, RenderTargets& targets);

 private:
  void Draw(const GpuModel& model, const GpuModel::Primitive& p, const GpuMaterials& materials);
  gl::Program program_{gl::NoCreate};
};

}  // namespace odvr::render
