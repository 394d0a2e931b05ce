// odvr bench player: the augmented player's frame budget (decode, lighting, render, composite,
// total; medians) on this machine's OpenGL, written to docs/benchmarks/player.md.
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <iterator>
#include <sstream>

#include "app/ar/car_rendering.h"
#include "app/ar/demo_media.h"
#include "app/bench/bench_common.h"
#include "app/bench/bench_player.h"
#include "app/flags/command_flags.h"
#include "app/player/live_player.h"
#include "app/player/player.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/size_text.h"
#include "engine/gl/context.h"
#include "engine/gl/objects.h"

namespace odvr::app {
namespace {

// The live-mode section of the table (RunBenchLive) survives a rerun of the recorded bench, and
// the other way round.
constexpr const char* kLiveHeading = "\n## Live mode\n";

std::string ExistingLiveSection(const std::string& path) {
  std::ifstream in(path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto at = text.find(kLiveHeading);
  return at == std::string::npos ? "" : text.substr(at);
}

}  // namespace

// The --live section of the page; RunBenchPlayer's, named after the GL renderer it ran on.
int RunBenchLive(const BenchPlayerOptions& b, const std::string& gl_renderer);

int RunBenchPlayer(const BenchPlayerOptions& b) {
  std::string gl_renderer;
  {
    gl::HeadlessContext context;
    gl_renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  }
  if (b.live) return RunBenchLive(b, gl_renderer);
  PlayerOptions o;
  std::tie(o.width, o.height) = ParseSize(b.size);
  o.video = DefaultDemoVideo();
  const auto demo = std::filesystem::path(o.video).parent_path();
  o.trajectory = (demo / "trajectory_gt.json").string();
  o.car = (demo / "car.glb").string();
  o.headless = true;
  o.headless_frames = b.frames + 1;  // the first frame also compiles the shaders: not counted
  o.drive = b.drive;
  o.lighting_levels = b.levels;
  o.voxels = b.voxels;
  o.shading_rate = b.shading_rate;
  o.out_dir = (std::filesystem::temp_directory_path() / ("odvr_bench_player_" + std::to_string(::getpid()))).string();
  std::cerr << "bench player: " << o.headless_frames << " frames at " << b.size << " on " << gl_renderer << "\n";
  PlayerReport r = RunAugmentedPlayer(o, /*window=*/false);
  std::filesystem::remove_all(o.out_dir);

  std::ostringstream md;
  md << "# Player frame budget\n\n"
     << "Made by `odvr bench player --size " << b.size << " --frames " << b.frames << " --drive " << b.drive
     << "`: the demo (`media/" << demo.filename().string()
     << "/street.mp4`, its `trajectory_gt.json` and `car.glb`) in augmented mode, "
     << "headless, the car driven by the script; the first frame (shader compilation) is left out. Lighting: "
     << b.levels << " HEALPix levels from the frame, at most " << CarRendering{}.lighting_width
     << " wide (its peaks found there, the rest box-averaged to the transform's grid); visibility: " << b.voxels
     << "³ voxels, 7 cones per broad lobe.\n\n"
     << "Machine: " << BenchMachineDescription() << "; OpenGL renderer: " << gl_renderer
     << (gl::IsSoftwareRenderer(gl_renderer)
             ? ". **No GPU was available this session**: the figures are a CPU rasterizer's, not the target's (25 fps "
               "at 1280×720 on a GPU).\n\n"
             : ". Target: 25 fps at 1280×720 (40 ms per frame).\n\n")
     << "| stage | median ms |\n|---|---:|\n";
  md << "| decode | " << r.median.decode_ms << " |\n"
     << "| lighting | " << r.median.lighting_ms << " |\n"
     << "| render | " << r.median.render_ms << " |\n"
     << "| read-back | " << r.median.readback_ms << " |\n"
     << "| composite | " << r.median.composite_ms << " |\n"
     << "| **total** | " << r.median.total_ms << " |\n\n"
     << "Stages: *decode* = the panoramas the frame needs (the viewer's, the car's light frames) from the "
        "decoder thread, cached; *lighting* = SG models of new light frames (built once each) and their "
        "blend; *render* = voxelize, G-buffer and triple-product shading of the car "
        "(`TripleProductRenderer`); *read-back* = its composite and its counts' sums to the CPU (headless "
        "frames are written as PNG; the window draws the composite where it was rendered and reads back "
        "the sums alone); *composite* = the viewer frame's panorama through the camera, the "
        "shadow and the car over it. Frames: "
     << r.frames_shown << " (" << r.frames_shown - 1 << " timed).\n";
  md << ExistingLiveSection(b.out);
  if (const auto folder = std::filesystem::path(b.out).parent_path(); !folder.empty())
    std::filesystem::create_directories(folder);
  WriteTextAtomically(b.out, md.str());
  std::cout << md.str();
  return 0;
}

// `odvr play --live` on the demo rig replayed live, per size: the stages' medians with the first
// frame (shader compilation) left out, as a section of the same table.
int RunBenchLive(const BenchPlayerOptions& b, const std::string& gl_renderer) {
  const std::string sizes = b.size_option->count() ? b.size : "640x360,1280x720";
  std::string load = "unknown";
  if (std::ifstream loadavg("/proc/loadavg"); loadavg) loadavg >> load;
  struct Column {
    std::string size;
    LiveTimings median;
    double skipped = 0;
  };
  std::vector<Column> columns;
  for (std::size_t start = 0; start < sizes.size();) {
    const std::size_t end = std::min(sizes.find(',', start), sizes.size());
    const std::string size = sizes.substr(start, end - start);
    start = end + 1;
    LivePlayOptions o;
    std::tie(o.player.width, o.player.height) = ParseSize(size);
    const auto root = std::filesystem::path(DefaultDemoVideo()).parent_path().parent_path().parent_path();
    o.rig = (root / "config" / "demo_rig.json").string();
    o.player.car = (root / "media" / "demo" / "car.glb").string();
    o.player.headless = true;
    o.player.headless_frames = b.frames + 1;
    o.player.lighting_levels = b.levels;
    o.player.voxels = b.voxels;
    o.player.shading_rate = b.shading_rate;
    o.player.out_dir =
        (std::filesystem::temp_directory_path() / ("odvr_bench_live_" + std::to_string(::getpid()))).string();
    std::cerr << "bench player --live: " << o.player.headless_frames << " frames at " << size << " on " << gl_renderer
              << "\n";
    const LiveReport r = RunLivePlayer(o);
    std::filesystem::remove_all(o.player.out_dir);
    Column col{size, {}, 0};
    auto median = [&](double LiveTimings::*field) {
      std::vector<double> v;
      for (std::size_t i = 1; i < r.frames.size(); ++i) v.push_back(r.frames[i].ms.*field);
      return Median(v);
    };
    for (auto field : {&LiveTimings::capture_wait, &LiveTimings::stitch, &LiveTimings::lighting, &LiveTimings::render,
                       &LiveTimings::readback, &LiveTimings::composite, &LiveTimings::total})
      col.median.*field = median(field);
    // Sets the cameras delivered between two shown frames and never shown (dropped from the full
    // queue or passed over for a newer one).
    for (std::size_t i = 1; i < r.frames.size(); ++i)
      col.skipped += static_cast<double>(r.frames[i].set_index - r.frames[i - 1].set_index - 1) /
                     static_cast<double>(r.frames.size() - 1);
    columns.push_back(col);
  }

  std::ostringstream md;
  md << std::setprecision(4) << kLiveHeading << "\n"
     << "Made by `odvr bench player --live --frames " << b.frames << "`: `odvr play --live --rig "
     << "config/demo_rig.json` headless, the demo's six 300×400 fisheye cameras replayed live at 25 fps on "
        "capture threads (`replay:`, the rig's `image_dir` folders), stitched on the CPU to 1024×512 and relit "
        "from every new stitched frame ("
     << b.levels << " HEALPix levels from the stitched frame at " << CarRendering{}.lighting_width
     << " wide), the car standing 6 m ahead of the rig (" << b.voxels << "³ voxels); medians over " << b.frames
     << " frames, the first (shader compilation) left out. Machine: " << BenchMachineDescription() << " (load average "
     << load << " at the start: the cores may have been shared); OpenGL renderer: " << gl_renderer << ".\n\n| stage |";
  for (const auto& c : columns) md << " " << c.size << " ms |";
  md << "\n|---|";
  for (std::size_t i = 0; i < columns.size(); ++i) md << "---:|";
  md << "\n";
  const std::pair<const char*, double LiveTimings::*> rows[] = {{"capture wait", &LiveTimings::capture_wait},
                                                                {"stitch", &LiveTimings::stitch},
                                                                {"lighting", &LiveTimings::lighting},
                                                                {"render", &LiveTimings::render},
                                                                {"read-back", &LiveTimings::readback},
                                                                {"composite", &LiveTimings::composite},
                                                                {"**total**", &LiveTimings::total}};
  for (const auto& [name, field] : rows) {
    md << "| " << name << " |";
    for (const auto& c : columns) md << " " << c.median.*field << " |";
    md << "\n";
  }
  md << "| sets not shown per frame (mean) |";
  for (const auto& c : columns) md << " " << c.skipped << " |";
  md << "\n\nStages: *capture wait* = waiting for the next frame set and taking the newest queued; *stitch* = "
        "the set into the 1024×512 panorama (`capture::Stitcher`) and its wrap padding; *lighting* = the SG "
        "model of that panorama (`LightingBuilder`, rebuilt for every new set) handed to the renderer; *render* "
        "and *composite* as above. A set that arrives while a frame is being made waits, and only the newest "
        "waiting set is shown (a live view shows the present); where frames take less than the cameras' 40 ms, "
        "the wait is what paces the loop at their 25 fps.\n";
  std::ifstream in(b.out);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (const auto at = text.find(kLiveHeading); at != std::string::npos) text.resize(at);
  if (const auto folder = std::filesystem::path(b.out).parent_path(); !folder.empty())
    std::filesystem::create_directories(folder);
  WriteTextAtomically(b.out, text + md.str());
  std::cout << md.str();
  return 0;
}

CommandFn AddBenchPlayer(CLI::App* sub) {
  auto b = std::make_shared<BenchPlayerOptions>();
  b->size_option = sub->add_option("--size", b->size, "Frame size WIDTHxHEIGHT (--live: a comma-separated list)")
                       ->capture_default_str();
  sub->add_flag("--live", b->live, "Live mode on the demo rig, at 640x360 and 1280x720 unless --size says");
  sub->add_option("--frames", b->frames, "Timed frames")->capture_default_str()->check(CLI::Range(1, 1000));
  sub->add_option("--drive", b->drive, "Scripted drive")->capture_default_str();
  sub->add_option("--levels", b->levels, "Lighting levels")->capture_default_str();
  sub->add_option("--voxels", b->voxels, "Voxels per side")->capture_default_str();
  sub->add_option("--shading-rate", b->shading_rate, "The car's shading rate (1: every pixel, 2: per smooth 2x2 block)")
      ->check(CLI::IsMember({1, 2}))
      ->capture_default_str();
  sub->add_option("--out", b->out, "Markdown table (docs/benchmarks/player.md: the committed page)")
      ->capture_default_str();
  return [b] { return RunBenchPlayer(*b); };
}

}  // namespace odvr::app
