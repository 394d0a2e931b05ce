// The light bench's report on rows written by hand: the sunny-map tables pick, per map, the
// cheapest `sg+peaks` row that beats SH order 8 of the same width on all three convolved errors,
// and say honestly whether it took less time.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "app/bench/bench_light.h"
#include "tests/app/run_odvr.h"

namespace {

using odvr::testing::ReadText;
using odvr::testing::RunOdvr;
using odvr::testing::ScratchDir;

const char* kHeader =
    "# odvr bench light on a test\n"
    "map\twidth\tmethod\tdevice\tparam\tcoefficients\tms\trel_l2\tdiffuse\tglossy20\tglossy200\n";

// The bench's report alone (`odvr bench light --report-only`, called as the library it is) on these
// TSV rows (after the header); the lighting.md it writes.
std::string ReportFrom(const std::string& name, const std::string& rows) {
  ScratchDir scratch(name);
  std::ofstream(scratch.dir / "lighting.tsv") << kHeader << rows;
  odvr::app::BenchLightOptions options;
  options.report_only = true;
  options.out_dir = scratch.dir.string();
  EXPECT_EQ(odvr::app::RunBenchLight(options), 0);
  return ReadText(scratch.dir / "lighting.md");
}

TEST(BenchLight, ReportPicksTheCheapestSgWithPeaksThatBeatsSh8OfTheSameWidth) {
  const std::string md =
      ReportFrom("bench_light",
                 // sky: level 1 fails on diffuse; level 2 beats SH 8 at 1024 and is faster; 2048 slower.
                 "sky\t1024\tsh\tcpu\t8\t81\t3.0\t0.9\t0.010\t0.10\t0.80\n"
                 "sky\t1024\tsg+peaks\tcpu\t1\t14\t2.0\t0.5\t0.020\t0.05\t0.05\n"
                 "sky\t1024\tsg+peaks\tcpu\t2\t62\t2.5\t0.5\t0.005\t0.02\t0.03\n"
                 "sky\t1024\tsg+peaks\tcpu\t3\t254\t4.0\t0.5\t0.002\t0.01\t0.02\n"
                 "sky\t2048\tsh\tcpu\t8\t81\t5.0\t0.9\t0.010\t0.10\t0.80\n"
                 "sky\t2048\tsg+peaks\tcpu\t2\t62\t6.0\t0.5\t0.005\t0.02\t0.03\n"
                 // park: beats SH 8 only at 5 levels, slower than it. An SH 8 row of another width, far
                 // worse, must not be compared with.
                 "park\t1024\tsh\tcpu\t8\t81\t2.0\t0.9\t0.010\t0.10\t0.80\n"
                 "park\t512\tsh\tcpu\t8\t81\t0.5\t0.9\t0.900\t0.90\t0.90\n"
                 "park\t1024\tsg+peaks\tcpu\t4\t1024\t5.0\t0.5\t0.020\t0.01\t0.01\n"
                 "park\t1024\tsg+peaks\tcpu\t5\t4094\t9.0\t0.5\t0.005\t0.01\t0.01\n"
                 // dawn: never beats SH 8.
                 "dawn\t1024\tsh\tcpu\t8\t81\t2.0\t0.9\t0.001\t0.01\t0.10\n"
                 "dawn\t1024\tsg+peaks\tcpu\t5\t4090\t9.0\t0.5\t0.002\t0.005\t0.05\n");
  EXPECT_NE(md.find("| sky | 2 | 1024 | 0.0050 / 0.0100 | 0.0200 / 0.1000 | 0.0300 / 0.8000 | 2.50 / 3.00 | yes |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| park | 5 | 1024 | 0.0050 / 0.0100 | 0.0100 / 0.1000 | 0.0100 / 0.8000 | 9.00 / 2.00 | no |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| dawn | none beats SH 8 |"), std::string::npos) << md;
  EXPECT_NE(md.find("at less time than SH 8: 1 of 3 sunny maps."), std::string::npos) << md;
}

// The ratio to least squares takes the optimum fitted to the same enlarged frame the transform
// got (a row of that width), not the one fitted to the sharper native map; an old TSV with only a
// native row still gets a ratio from it.
TEST(BenchLight, ReportComparesWithTheLeastSquaresFitOfTheSameWidth) {
  const std::string md = ReportFrom("bench_light_ls",
                                    "bridge\t2048\tleast-squares\tcpu\t5\t4093\t2400\t0.5\t0.002\t0.0020\t0.004\n"
                                    "bridge\t512\tleast-squares\tcpu\t5\t4093\t2000\t0.5\t0.001\t0.0002\t0.003\n"
                                    "bridge\t2048\tsg\tcpu\t5\t4092\t30\t0.5\t0.001\t0.0030\t0.006\n"
                                    "city\t512\tleast-squares\tcpu\t5\t4093\t1500\t0.5\t0.001\t0.0010\t0.002\n"
                                    "city\t2048\tsg\tcpu\t5\t4092\t30\t0.5\t0.001\t0.0010\t0.004\n");
  EXPECT_NE(md.find("| bridge | 0.50 | 1.50 | 1.50 | 80 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| city | 1.00 | 1.00 | 2.00 | 50 |"), std::string::npos) << md;
  EXPECT_NE(md.find("Maps with every ratio within 1.5: 1 of 2"), std::string::npos) << md;
  // No least-squares+peaks rows: no table for them.
  EXPECT_EQ(md.find("With peaks, against the optimum"), std::string::npos) << md;
}

// sg+peaks is compared with the optimum on its own basis (its peaks, the SRBFs fitted to what the
// detector leaves), in a second table beside the first; the plain rows keep theirs.
TEST(BenchLight, ReportComparesSgWithPeaksWithTheOptimumOnItsBasis) {
  const std::string md = ReportFrom("bench_light_ls_peaks",
                                    "park\t2048\tleast-squares\tcpu\t5\t4093\t2400\t0.5\t0.002\t0.0020\t0.004\n"
                                    "park\t2048\tleast-squares+peaks\tcpu\t5\t4094\t2000\t0.5\t0.001\t0.0010\t0.002\n"
                                    "park\t2048\tsg\tcpu\t5\t4092\t30\t0.5\t0.001\t0.0060\t0.006\n"
                                    "park\t2048\tsg+peaks\tcpu\t5\t4093\t40\t0.5\t0.001\t0.0012\t0.002\n");
  const std::size_t with_peaks = md.find("With peaks, against the optimum");
  ASSERT_NE(with_peaks, std::string::npos) << md;
  // Before it, sg against least-squares: 0.5, 3.0, 1.5 and 2400 / 30 ms.
  EXPECT_LT(md.find("| park | 0.50 | 3.00 | 1.50 | 80 |"), with_peaks) << md;
  // After it, sg+peaks against least-squares+peaks: 1.0, 1.2, 1.0 and 2000 / 40 ms.
  const std::size_t row = md.find("| park | 1.00 | 1.20 | 1.00 | 50 |");
  EXPECT_NE(row, std::string::npos) << md;
  EXPECT_GT(row, with_peaks) << md;
  EXPECT_NE(md.find("Maps with every ratio within 1.5: 1 of 1", with_peaks), std::string::npos) << md;
}

// A level that raises an error counts as a growth, unless the raised error stays within the
// frame's own error against the native map (the `input` row): the model converges on the frame.
// The diffuse line is per method, beside the optimum's own diffuse error on the failing rows.
TEST(BenchLight, ReportCountsGrowthsBeyondTheFramesOwnError) {
  const std::string md = ReportFrom("bench_light_growth",
                                    // bridge: level 5 raises diffuse, but to under the input row's.
                                    "bridge\t2048\tinput\tcpu\t0\t0\t0\t0.1\t0.0006\t0.0008\t0.0011\n"
                                    "bridge\t2048\tsg\tcpu\t3\t253\t1\t0.9\t0.0040\t0.0500\t0.4400\n"
                                    "bridge\t2048\tsg\tcpu\t5\t4091\t7\t0.6\t0.0004\t0.0007\t0.0038\n"
                                    "bridge\t2048\tsg\tcpu\t6\t16310\t27\t0.4\t0.0005\t0.0007\t0.0010\n"
                                    // venice: level 5 raises glossy20 beyond the input row's.
                                    "venice\t2048\tinput\tcpu\t0\t0\t0\t0.1\t0.0001\t0.0001\t0.0003\n"
                                    "venice\t2048\tsg\tcpu\t5\t4091\t7\t0.1\t0.0002\t0.0002\t0.0007\n"
                                    "venice\t2048\tsg\tcpu\t6\t16359\t27\t0.1\t0.0002\t0.0004\t0.0003\n"
                                    // sky: 2 % diffuse at level 2, its optimum 1.1 %.
                                    "sky\t2048\tsg\tcpu\t3\t253\t1\t0.9\t0.0200\t0.0500\t0.4000\n"
                                    "sky\t2048\tleast-squares\tcpu\t3\t253\t190\t0.9\t0.0110\t0.0300\t0.3000\n"
                                    "sky\t2048\tsg+peaks\tcpu\t3\t254\t2\t0.6\t0.0005\t0.0300\t0.2000\n");
  EXPECT_NE(md.find("`sg` 5 of 6 (map, width, levels) rows, the least-squares optimum on the same basis over 1 % "
                    "too on 1 of the 1 others it was fitted for; `sg+peaks` 1 of 1 (map, width, levels) rows;"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("when a level was added** in 1 of 4 level sequences, and in 1 more it rose but stayed within"),
            std::string::npos)
      << md;
}

}  // namespace

namespace {

// The real bench with --gpu on one small map: besides `sg` from a CPU frame, `gpu-resident` runs
// the transform from the frame already in a GPU texture, and fits the same model (the same errors
// within rounding: the finest grid is area-resampled on the GPU there, on the CPU in `gpu`).
TEST(BenchLightGL, GpuResidentRowsFitTheSameModel) {
  const std::string map = std::string(ODVR_SHARED_DIR) + "/data/env/park.exr";
  if (!std::filesystem::exists(map)) GTEST_SKIP() << "the shared environment maps are absent";
  ScratchDir scratch("bench_light_gpu");
  const auto run = RunOdvr(
      "bench light --gpu --widths 512 --max-levels 2 --no-least-squares --skip-peaks "
      "--repeats 1 --min-time-ms 0 --out " +
      scratch.dir.string() + " " + map);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  std::map<std::pair<std::string, int>, std::vector<double>> errors;  // (device, levels) → errors
  std::ifstream tsv(scratch.dir / "lighting.tsv");
  for (std::string line; std::getline(tsv, line);) {
    std::vector<std::string> v;
    std::istringstream cells(line);
    for (std::string c; std::getline(cells, c, '\t');) v.push_back(c);
    if (v.size() < 11 || v[2] != "sg") continue;
    errors[{v[3], std::stoi(v[4])}] = {std::stod(v[7]), std::stod(v[8]), std::stod(v[9]), std::stod(v[10])};
  }
  for (int levels : {1, 2}) {
    ASSERT_TRUE(errors.count({"gpu", levels}) && errors.count({"gpu-resident", levels})) << levels;
    const auto &a = errors[{"gpu", levels}], &b = errors[{"gpu-resident", levels}];
    for (std::size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(b[i], a[i], 1e-3 + 1e-2 * a[i]) << levels << " " << i;
  }
  EXPECT_NE(ReadText(scratch.dir / "lighting.md").find("| 512 | sg | gpu-resident | 2 |"), std::string::npos);
  // A width below the map's is a usage error that says so (the bench only enlarges maps).
  const auto narrow = RunOdvr("bench light --widths 256 --max-levels 1 --out " + scratch.dir.string() + " " + map);
  EXPECT_EQ(narrow.exit_code, 2);
  EXPECT_NE(narrow.err.find("narrower than"), std::string::npos) << narrow.err;
}

}  // namespace
