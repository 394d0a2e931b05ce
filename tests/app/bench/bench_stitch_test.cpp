// `odvr bench stitch` run as a user would, on one frame of ../shared/data/street_a at a small size.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "tests/app/run_odvr.h"

namespace {

using odvr::testing::CliRun;
using odvr::testing::Lines;
using odvr::testing::ReadText;
using odvr::testing::RunOdvr;
using odvr::testing::ScratchDir;

namespace fs = std::filesystem;
const fs::path kStreet = fs::path(ODVR_SHARED_DIR) / "data/street_a";

struct TsvRow {
  double ms, psnr_valid, psnr_seams;
};

// method -> row, for the one frame the test asks for.
std::map<std::string, TsvRow> ReadTsv(const fs::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "frame\tmethod\tms\tpsnr_valid_db\tpsnr_seams_db");
  std::map<std::string, TsvRow> rows;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream s(line);
    for (std::string field; std::getline(s, field, '\t');) f.push_back(field);
    if (f.size() != 5) {
      ADD_FAILURE() << "a row without 5 columns: " << line;
      continue;
    }
    EXPECT_EQ(f[0], "0");
    rows[f[1]] = {std::stod(f[2]), std::stod(f[3]), std::stod(f[4])};
  }
  return rows;
}

TEST(BenchStitch, ScoresBothPipelinesAndComputesTheTargetsFromTheRows) {
  if (!fs::exists(kStreet / "rig.json")) GTEST_SKIP() << kStreet << " absent (no ../shared data)";
  const ScratchDir t{"odvr_bench_stitch"};
  const CliRun r = RunOdvr("bench stitch --frames 0 --width 256 --height 128 --repeats 1 --out " + t.dir.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto rows = ReadTsv(t.dir / "stitch.tsv");
  ASSERT_EQ(rows.size(), 2u);
  ASSERT_TRUE(rows.count("odvr cpu") && rows.count("opencv"));
  // Measured at 256x128: 25.8 / 24.9 dB (odvr, valid / seams) and 25.7 / 25.5 dB (OpenCV). A
  // pipeline given the wrong geometry or the wrong channel order scores near 12 dB.
  for (const auto& [method, row] : rows) {
    EXPECT_GT(row.ms, 0) << method;
    EXPECT_GT(row.psnr_valid, 24.0) << method;
    EXPECT_GT(row.psnr_seams, 23.5) << method;
    EXPECT_LT(row.psnr_valid, 40.0) << method;  // the truth's own noise bounds it
  }
  // The target line reports what the rows say, not a typed figure.
  const TsvRow& cpu = rows.at("odvr cpu");
  const TsvRow& cv = rows.at("opencv");
  const std::string md = ReadText(t.dir / "stitch.md");
  EXPECT_NE(md.find("## Targets, from the rows above"), std::string::npos) << md;
  const double speedup = cv.ms / cpu.ms, dv = cpu.psnr_valid - cv.psnr_valid, ds = cpu.psnr_seams - cv.psnr_seams;
  const bool met = speedup >= 5 && dv >= -0.05 && ds >= -0.05;
  EXPECT_NE(md.find(met ? "equal or better PSNR: met.**" : "equal or better PSNR: not met.**"), std::string::npos)
      << md;
  EXPECT_NE(md.find(fmt::format("Speed-up of `odvr cpu` over `opencv`: {:.1f}×", speedup)), std::string::npos) << md;
  EXPECT_NE(md.find(fmt::format("{:+.2f} dB over the valid mask, {:+.2f} dB over the seams", dv, ds)),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("**GPU:** not timed"), std::string::npos) << md;
  EXPECT_TRUE(fs::exists(t.dir / "stitch.gnuplot"));

  // Where the odvr frame's time went: the CPU's stages, none of the GPU's, each within the frame.
  std::vector<std::string> stages;
  {
    std::stringstream text(ReadText(t.dir / "stitch_stages.tsv"));
    for (std::string l; std::getline(text, l);) stages.push_back(l);
  }
  ASSERT_EQ(stages.size(), 2u);
  EXPECT_EQ(stages[0], "frame\tmethod\tprepare_ms\tgains_ms\twarp_ms\tfill_ms\tupload_ms\tgpu_passes_ms\treadback_ms");
  std::vector<std::string> f;
  std::stringstream line(stages[1]);
  for (std::string field; std::getline(line, field, '\t');) f.push_back(field);
  ASSERT_EQ(f.size(), 9u) << stages[1];
  EXPECT_EQ(f[1], "odvr cpu");
  double sum = 0;
  for (int k = 2; k <= 5; ++k) {
    EXPECT_GT(std::stod(f[static_cast<std::size_t>(k)]), 0) << stages[1];
    sum += std::stod(f[static_cast<std::size_t>(k)]);
  }
  EXPECT_LE(sum, cpu.ms * 1.05 + 0.01) << "one run: the stages lie within the frame's time";
  for (int k = 6; k <= 8; ++k) EXPECT_EQ(f[static_cast<std::size_t>(k)], "0.000") << stages[1];
  EXPECT_NE(md.find(fmt::format("| odvr cpu | {:.2f} | {:.2f} | {:.2f} | {:.2f} | 0.00 | 0.00 | 0.00 |",
                                std::stod(f[2]), std::stod(f[3]), std::stod(f[4]), std::stod(f[5]))),
            std::string::npos)
      << md;
}

TEST(BenchStitch, BadInputsEndInOneLine) {
  const ScratchDir t{"odvr_bench_stitch"};
  const CliRun missing = RunOdvr("bench stitch --dataset " + t.dir.string() + " --out " + t.dir.string());
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.err.find("has no rig.json"), std::string::npos) << missing.err;
  const CliRun tiny = RunOdvr("bench stitch --width 3 --out " + t.dir.string());
  EXPECT_NE(tiny.exit_code, 0);
  EXPECT_NE(tiny.err.find("--width"), std::string::npos) << tiny.err;
  if (!fs::exists(kStreet / "rig.json")) return;
  const CliRun absent = RunOdvr("bench stitch --frames 9999 --width 64 --height 32 --out " + t.dir.string());
  EXPECT_NE(absent.exit_code, 0);
  EXPECT_NE(absent.err.find("009999.jpg: cannot read the rig image"), std::string::npos) << absent.err;
  EXPECT_FALSE(fs::exists(t.dir / "stitch.md"));
}

}  // namespace
