#include "app/flags/render_switches.h"

#include "app/flags/command_flags.h"

namespace odvr::app {

void AddRenderSwitches(CLI::App* sub, render::RenderOptions* options) {
  AddSetFlag(sub, "--bin-depth", &options->depth_per_lobe, false,
             "Light each lobe with every level its overlap bin lists, not only those its own λ needs");
  sub->add_option("--overlap-cutoff", options->overlap_cutoff,
                  "An SRBF lights a lobe where their product's integral is at least this fraction of its aligned value")
      ->check(CLI::Range(1e-6, 0.5));
  sub->add_option("--ground-lit-map", options->ground_lit_map_texels,
                  "Texels per side at most of the grid the ground's lit fraction is read from under the car "
                  "(0: traced from every point a cone meets the ground)")
      ->check(CLI::Range(0, 1024) & !CLI::Range(1, 7));
  AddSetFlag(sub, "--exact-peak-shadows", &options->exact_peak_shadows, true,
             "Shadow each peak (a sun, a lamp) by a ray against the triangles (the default)");
  AddSetFlag(sub, "--peak-cone-shadows", &options->exact_peak_shadows, false,
             "Shadow each peak by its cone through the voxels instead");
  AddSetFlag(sub, "--valid-reflection-normals", &options->valid_reflection_normals, true,
             "Tilt a shading normal whose mirrored view would dive below its triangle, as Cycles does (the default)");
  AddSetFlag(sub, "--raw-normals", &options->valid_reflection_normals, false, "Keep the interpolated normals instead");
  AddSetFlag(sub, "--specular-bounce", &options->specular_bounce, true,
             "One bounce of the car's specular light on itself, found by a ray against the triangles (along the "
             "G-buffer with --peak-cone-shadows; the default)");
  AddSetFlag(sub, "--no-specular-bounce", &options->specular_bounce, false, "No bounce of the car's light on itself");
  AddSetFlag(sub, "--ambient-bounce", &options->ambient_bounce, true,
             "Where the car hides the light from its own diffuse surfaces, they see the car lit like an average "
             "surface instead of black (the default)");
  AddSetFlag(sub, "--no-ambient-bounce", &options->ambient_bounce, false,
             "Diffuse surfaces see black where the car hides the light");
  sub->add_option("--shading-rate", options->shading_rate,
                  "2: shade one pixel of each 2x2 block, every pixel only of blocks that are not smooth (by "
                  "--supersample-contrast), and fill the rest between the shaded pixels")
      ->check(CLI::IsMember({1, 2}));
}

std::vector<std::string> NonDefaultRenderSwitches(const render::RenderOptions& o) {
  const render::RenderOptions d;
  std::vector<std::string> out;
  if (!o.depth_per_lobe) out.push_back("--bin-depth");  // on by default: the flag only turns it off
  if (o.overlap_cutoff != d.overlap_cutoff) out.push_back("--overlap-cutoff " + std::to_string(o.overlap_cutoff));
  if (o.ground_lit_map_texels != d.ground_lit_map_texels)
    out.push_back("--ground-lit-map " + std::to_string(o.ground_lit_map_texels));
  if (o.exact_peak_shadows != d.exact_peak_shadows)
    out.push_back(o.exact_peak_shadows ? "--exact-peak-shadows" : "--peak-cone-shadows");
  if (o.valid_reflection_normals != d.valid_reflection_normals)
    out.push_back(o.valid_reflection_normals ? "--valid-reflection-normals" : "--raw-normals");
  if (o.specular_bounce != d.specular_bounce)
    out.push_back(o.specular_bounce ? "--specular-bounce" : "--no-specular-bounce");
  if (o.ambient_bounce != d.ambient_bounce)
    out.push_back(o.ambient_bounce ? "--ambient-bounce" : "--no-ambient-bounce");
  if (o.shading_rate != d.shading_rate) out.push_back("--shading-rate " + std::to_string(o.shading_rate));
  return out;
}

nlohmann::json RenderSwitchesJson(const render::RenderOptions& o) {
  return {{"depth_per_lobe", o.depth_per_lobe},
          {"overlap_cutoff", o.overlap_cutoff},
          {"ground_lit_map_texels", o.ground_lit_map_texels},
          {"exact_peak_shadows", o.exact_peak_shadows},
          {"valid_reflection_normals", o.valid_reflection_normals},
          {"specular_bounce", o.specular_bounce},
          {"ambient_bounce", o.ambient_bounce},
          {"shading_rate", o.shading_rate}};
}

}  // namespace odvr::app
