// odvr bench player: the augmented player's frame budget (decode, lighting, render, composite,
// total; medians) on this machine's OpenGL, written to docs/benchmarks/player.md.
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>

#include "app/bench_common.h"
#include "app/commands.h"
#include "app/player.h"
#include "engine/core/atomic_file.h"
#include "engine/core/error.h"
#include "engine/gl/context.h"
#include "engine/gl/objects.h"

namespace odvr::app {
namespace {

struct BenchPlayerOptions {
  std::string size = "1280x720";
  int frames = 8;
  std::string drive = "W:2s,A:1s";
  std::string out = "docs/benchmarks/player.md";
  int levels = 4, voxels = 64;
};

int RunBenchPlayer(const BenchPlayerOptions& b) {
  std::string gl_renderer;
  {
    gl::HeadlessContext context;
    gl_renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  }
  PlayerOptions o;
  int w = 0, h = 0;
  char x = 0;
  if (std::sscanf(b.size.c_str(), "%d%c%d", &w, &x, &h) != 3 || x != 'x')
    throw UsageError("--size", "expects WIDTHxHEIGHT, got '" + b.size + "'");
  o.width = w;
  o.height = h;
  o.video = DefaultDemoVideo();
  const auto demo = std::filesystem::path(o.video).parent_path();
  o.trajectory = (demo / "trajectory_gt.json").string();
  o.car = (demo / "car.glb").string();
  o.headless = true;
  o.headless_frames = b.frames + 1;  // the first frame also compiles the shaders: not counted
  o.drive = b.drive;
  o.lighting_levels = b.levels;
  o.voxels = b.voxels;
  o.out_dir = (std::filesystem::temp_directory_path() / ("odvr_bench_player_" + std::to_string(::getpid()))).string();
  std::cerr << "bench player: " << o.headless_frames << " frames at " << b.size << " on " << gl_renderer << "\n";
  PlayerReport r = RunAugmentedHeadless(o);
  std::filesystem::remove_all(o.out_dir);

  std::ostringstream md;
  md << "# Player frame budget\n\n"
     << "Made by `odvr bench player --size " << b.size << " --frames " << b.frames << " --drive " << b.drive
     << "`: the demo (`media/demo/street.mp4`, its `trajectory_gt.json` and `car.glb`) in augmented mode, "
     << "headless, the car driven by the script; the first frame (shader compilation) is left out. Lighting: "
     << b.levels << " HEALPix levels from the frame area-resampled to 256×128; visibility: " << b.voxels
     << "³ voxels, 7 cones per broad lobe.\n\n"
     << "Machine: " << BenchMachineDescription() << "; OpenGL renderer: " << gl_renderer
     << ". **No GPU was available this session**: the figures are llvmpipe's (Mesa's CPU rasterizer), "
        "not the target's (25 fps at 1280×720 on a GPU).\n\n"
     << "| stage | median ms |\n|---|---:|\n";
  md << "| decode | " << r.median.decode_ms << " |\n"
     << "| lighting | " << r.median.lighting_ms << " |\n"
     << "| render | " << r.median.render_ms << " |\n"
     << "| composite | " << r.median.composite_ms << " |\n"
     << "| **total** | " << r.median.total_ms << " |\n\n"
     << "Stages: *decode* = the panoramas the frame needs (the viewer's, the car's light frames) from the "
        "decoder thread, cached; *lighting* = SG models of new light frames (built once each) and their "
        "blend; *render* = voxelize, G-buffer and triple-product shading of the car "
        "(`TripleProductRenderer`); *composite* = the viewer frame's panorama through the camera, the "
        "shadow and the car over it. Frames: "
     << r.frames_shown << " (" << r.frames_shown - 1 << " timed).\n";
  WriteTextAtomically(b.out, md.str());
  std::cout << md.str();
  return 0;
}

}  // namespace

CommandFn AddBenchPlayer(CLI::App* sub) {
  auto b = std::make_shared<BenchPlayerOptions>();
  sub->add_option("--size", b->size, "Frame size WIDTHxHEIGHT")->capture_default_str();
  sub->add_option("--frames", b->frames, "Timed frames")->capture_default_str()->check(CLI::Range(1, 1000));
  sub->add_option("--drive", b->drive, "Scripted drive")->capture_default_str();
  sub->add_option("--levels", b->levels, "Lighting levels")->capture_default_str();
  sub->add_option("--voxels", b->voxels, "Voxels per side")->capture_default_str();
  sub->add_option("--out", b->out, "Markdown table")->capture_default_str();
  return [b] { return RunBenchPlayer(*b); };
}

}  // namespace odvr::app
