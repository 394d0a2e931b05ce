// odvr bench …: benchmark programs that print speed beside error (never timed tests).
#include "app/bench/bench_decode.h"
#include "app/bench/bench_light.h"
#include "app/bench/bench_player.h"
#include "app/bench/bench_reconstruct.h"
#include "app/bench/bench_render.h"
#include "app/bench/bench_stitch.h"
#include "app/cli/commands.h"

namespace odvr::app {

CommandFn AddBench(CLI::App* sub) {
  sub->require_subcommand(1, 1);
  struct Kind {
    const char* name;
    const char* summary;
    CommandFn (*add)(CLI::App*);
  };
  static const Kind kinds[] = {
      {"light", "Lighting transform: errors and time per level, against least squares and SH", AddBenchLight},
      {"stitch", "Stitching: time and PSNR against the street ground truth, beside OpenCV's pipeline", AddBenchStitch},
      {"reconstruct", "Structure from motion: ATE, RPE, scale error and time against the ground truth, beside COLMAP",
       AddBenchReconstruct},
      {"player", "Player: the augmented frame budget (decode, lighting, render, composite) on the demo",
       AddBenchPlayer},
      {"render", "Renderer: error and SSIM against Cycles and time, beside a Monte-Carlo shader", AddBenchRender},
      {"decode", "Video decoding: frames delivered, time per frame and where a seek lands, libav beside OpenCV",
       AddBenchDecode},
  };
  auto runners = std::make_shared<std::vector<std::pair<CLI::App*, CommandFn>>>();
  for (const auto& k : kinds) {
    CLI::App* s = sub->add_subcommand(k.name, k.summary);
    runners->emplace_back(s, k.add(s));
  }
  return [runners] {
    for (auto& [s, run] : *runners)
      if (s->parsed()) return run();
    return 2;
  };
}

}  // namespace odvr::app
