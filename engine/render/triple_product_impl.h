#pragma once
// TripleProductRenderer::Impl: the renderer's model, lighting and GPU objects, and the passes
// that Render runs in order, one role each. Not part of the engine's API. The passes' definitions
// by role:
//   triple_product_renderer.cpp    construction, the setters, Render itself, the counts' sums
//   triple_product_gbuffer.cpp     a render's Frame, the stage timestamps, voxelize, the G-buffer
//   triple_product_shade_gpu.cpp   the GPU shading: its uniforms, the Monte-Carlo pass, the SG
//                                  passes (ground table, ground-lit map, then plain, adaptive or
//                                  half-rate), the resolve
//   triple_product_gpu_output.cpp  the GPU path in order: shade, composite, the stages' GPU
//                                  times, the readback; and SumCountsOnGpu
//   triple_product_cpu_path.cpp    the CPU path: its shading (resolve, flags, fill) and composite
#include <array>
#include <cstddef>
#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <map>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "engine/gl/objects.h"
#include "engine/render/triple_product_internal.h"
#include "engine/render/triple_product_renderer.h"
#include "engine/scene/gltf_scene.h"
#include "engine/visibility/triangle_bvh.h"
#include "engine/visibility/voxelizer_gpu.h"

namespace odvr::render {

struct TripleProductRenderer::Impl {
  // --- the model, the lighting, the GPU objects ---------------------------------------------------

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
  // Per material: the radiance it emits before its emissive texture (glTF emissive factor ×
  // strength; 0 under an override). The G-buffer multiplies in the texture.
  std::vector<glm::vec3> emission;
  gl::Buffer terms_buffer{gl::NoCreate}, ndf_table{gl::NoCreate}, cosine_table{gl::NoCreate};
  std::vector<glm::vec4> ndf_rows;  // ndf_table's contents

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
  gl::Program& ShadeProgram(int lanes);
  gl::Program gbuffer_program{gl::NoCreate}, composite_program{gl::NoCreate}, resolve_program{gl::NoCreate},
      flag_program{gl::NoCreate}, counts_program{gl::NoCreate};
  int fb_width = 0, fb_height = 0, out_width = 0, out_height = 0;
  gl::Framebuffer framebuffer{gl::NoCreate};
  gl::Texture g_position{gl::NoCreate}, g_normal{gl::NoCreate}, g_base{gl::NoCreate}, g_emission{gl::NoCreate},
      g_depth{gl::NoCreate};
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

  // Construction: the model's meshes into the world and onto the GPU, its voxel grid (and BVH),
  // the shaders' tables (the NDF's and the clamped cosine's SG fits, the overlap bins).
  void UploadModel(const scene::GltfScene& model, const glm::dmat4& world_from_model);
  void PlaceVoxelGrid(const scene::GltfScene& model, const RenderOptions& options);
  void UploadShaderTables(const RenderOptions& options);
  const gl::Texture& TextureFor(const scene::GltfScene& model, int image, bool srgb);
  void UploadSheenTable();
  // The G-buffer and the shading at w × h, the output at out_w × out_h (smaller when supersampled).
  void EnsureTargets(int w, int h, int out_w, int out_h);
  // The shading lanes of a GPU render of `camera`'s size (RenderOptions::shade_lanes), their
  // program compiled now.
  int PrepareShading(const RenderOptions& options, const PinholeCamera& camera);

  // --- one render ---------------------------------------------------------------------------------

  // What one render shares between its passes: Render's arguments and the sizes and modes they
  // and the options give, fixed before the first pass.
  struct Frame {
    explicit Frame(const RenderOptions& o) : options(o) {}
    const RenderOptions& options;
    ShadeDevice device = ShadeDevice::kGpu;
    PinholeCamera camera;         // the output's
    PinholeCamera shaded_camera;  // the G-buffer's and the shading's: k× the output's size
    int w = 0, h = 0;             // the output
    int k = 1;                    // RenderOptions::supersample
    int sw = 0, sh = 0;           // the shaded samples: k × w by k × h
    int bw = 0, bh = 0;           // shading_rate 2's 2×2 blocks: a block cut by an odd edge is shaded whole
    // Without the model: nothing voxelized, drawn or occluding, so the composite is the background.
    bool geometry = false;
    bool monte_carlo = false;
    // Adaptive supersampling (RenderOptions::supersample_contrast) in the SG shader only.
    bool adaptive = false;
    // RenderOptions::shading_rate 2: a pixel of each 2×2 block, then every pixel of the blocks
    // that need it, the rest filled.
    bool half_rate = false;
    bool gpu_stages = false;  // GL timestamps around the stages: the GPU path
    double f = 0, sf = 0;     // focal lengths in pixels: the output's, the shaded samples'
    glm::dvec2 ground_centre{0};
    std::size_t pixels = 0, samples = 0;  // w × h, sw × sh
  };
  // What a render's counts are summed from (SumCounts).
  struct Tally {
    std::vector<detail::PixelCounts> counts;    // per shaded sample, read back or the CPU's
    std::optional<detail::CountSums> gpu_sums;  // RenderOptions::read_layers off: summed on the GPU
    // The car's coverage per shaded sample when supersampled (the output's car_alpha otherwise).
    std::vector<float> sample_alpha;
  };

  // Render's checks (they throw before any GL call), then the frame.
  Frame MakeFrame(const RenderOptions& options, const PinholeCamera& camera, ShadeDevice device, bool draw_model) const;
  // GL timestamp `stage` (0..4) of the GPU path, between its stages; nothing on the CPU path.
  void Stamp(const Frame& fr, int stage);
  void Voxelize(const Frame& fr, RenderTimings* ms);
  // The G-buffer at the shaded size: position, shading normal, base colour, metallic, roughness.
  void RasterizeGBuffer(const Frame& fr, RenderTimings* ms);
  glm::mat4 ClipFromWorld(const Frame& fr) const;
  void DrawGBufferPrimitive(gl::Program& gp, Primitive& p);

  // The GPU path: shade, resolve, composite, read back.
  void RenderOnGpu(const Frame& fr, RenderResult* out, Tally* tally);
  void SetShadeUniforms(const Frame& fr, gl::Program& sp);
  void BindShadeInputs(const Frame& fr);
  void ShadeMonteCarlo(const Frame& fr);
  void ShadeSg(const Frame& fr, gl::Program& sp, int lanes);
  void DispatchGroundLitMap(const Frame& fr, gl::Program& sp, int lanes);
  void ShadeHalfRate(const Frame& fr, gl::Program& sp, int lanes);
  void ShadeAdaptive(const Frame& fr, gl::Program& sp, int lanes);
  // render_flag.comp over flag_w × flag_h pixels (blocks, at shading_rate 2) of factor² samples
  // each, their flags into `flags` and the flagged ones into `list`; then render_shade.comp shades
  // the listed ones' other samples into car and shadow.
  void FlagAndShadeListed(const Frame& fr, gl::Program& sp, gl::Buffer& flags, gl::Buffer& list, int flag_w, int flag_h,
                          int factor, gl::Texture& car, gl::Texture& shadow, bool neighbour_reps);
  void Resolve(const Frame& fr);
  long long HalfRateShadedPixels(const Frame& fr);
  void CompositeOnGpu(const Frame& fr, RenderTimings* ms);
  void ReadStageTimes(RenderTimings* ms);
  void ReadBack(const Frame& fr, long long half_rate_shaded, RenderResult* out, Tally* tally);

  // The CPU path: the CPU reference shades the read-back G-buffer, then the composite.
  void RenderOnCpu(const Frame& fr, RenderResult* out, Tally* tally);
  void ShadeOnCpu(const Frame& fr, const detail::GBuffer& g, RenderResult* out, Tally* tally);
  void CompositeOnCpu(const Frame& fr, RenderResult* out) const;

  // RenderCounts from the tally.
  void SumCounts(const Frame& fr, const Tally& tally, RenderResult* out) const;
};

}  // namespace odvr::render
