// `odvr bench render --report-only` as a user runs it: the report and its targets are computed
// from the TSV rows (here a hand-made TSV whose figures are easy to check), and a malformed TSV
// is rejected naming the file. The full bench renders for minutes; its rows are in
// docs/benchmarks/render.tsv. One reference is run for real.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "tests/app/run_odvr.h"

namespace {

using odvr::testing::CliRun;
using odvr::testing::ReadText;
using odvr::testing::RunOdvr;
using odvr::testing::ScratchDir;

namespace fs = std::filesystem;

// The cells of `tsv`'s `sg` rows of `reference` (a bench's render.tsv), each checked for the
// table's 22 columns.
std::vector<std::vector<std::string>> SgRows(const fs::path& tsv, const std::string& reference) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream text(ReadText(tsv));
  for (std::string line; std::getline(text, line);) {
    if (line.rfind(reference + "\tsg\t", 0) != 0) continue;
    std::vector<std::string> v;
    std::istringstream cells(line);
    for (std::string c; std::getline(cells, c, '\t');) v.push_back(c);
    EXPECT_EQ(v.size(), 22u) << line;
    if (v.size() == 22u) rows.push_back(std::move(v));
  }
  return rows;
}

const char* kHeader =
    "reference\tmethod\tlobes\twidth\theight\tlevels\tcones\tvoxels\tsamples\tmean_rel\trel_l1\tbias\tssim\t"
    "shadow_mae\tshadow_px\tcar_px\tshade_ms\ttotal_ms\n";

TEST(BenchRender, ReportOnlyComputesTheTargetsFromTheRows) {
  ScratchDir d("bench_render");
  {
    std::ofstream tsv(d.dir / "render.tsv");
    tsv << "# odvr bench render on a test machine\n" << kHeader;
    // The default configuration (5 levels, 7 cones, 128³, split-axis) at 0.2 error in 100 ms.
    tsv << "car\tsg\tsplit-axis\t320\t180\t5\t7\t128\t0\t0.2\t0.2\t0.9\t0.8\t0.05\t100\t1000\t100\t120\n";
    tsv << "car\tsg\tsplit-axis\t320\t180\t2\t7\t128\t0\t0.3\t0.3\t0.9\t0.7\t0.05\t100\t1000\t50\t70\n";
    // MC: 0.4 at 200 ms, 0.1 at 800 ms; log-log interpolation puts 0.2 at 400 ms, 4× the SG time.
    tsv << "car\tmc\texact\t320\t180\t0\t0\t128\t4\t0.4\t0.4\t0.9\t0.3\t0.1\t100\t1000\t200\t220\n";
    tsv << "car\tmc\texact\t320\t180\t0\t0\t128\t16\t0.1\t0.1\t0.9\t0.6\t0.05\t100\t1000\t800\t820\n";
    // Rows the speed target must not read: exact visibility (--mc-exact) and another resolution.
    tsv << "car\tmc-exact\texact\t320\t180\t0\t0\t128\t16\t0.05\t0.05\t0.9\t0.7\t0.02\t100\t1000\t300\t320\n";
    tsv << "car\tmc\texact\t320\t180\t0\t0\t256\t16\t0.08\t0.08\t0.9\t0.7\t0.04\t100\t1000\t900\t920\n";
    // A reference whose SG error meets the target and lies below every MC row: a lower bound.
    tsv << "paint\tsg\tsplit-axis\t320\t180\t5\t7\t128\t0\t0.08\t0.08\t1.0\t0.9\t-1\t0\t900\t50\t60\n";
    tsv << "paint\tsg\tsplit-axis\t320\t180\t2\t7\t128\t0\t0.25\t0.25\t1.0\t0.8\t-1\t0\t900\t20\t30\n";
    // Supersampled adaptively at 0.15 in 30 ms: the cheapest SG row at MC's best error (0.2).
    tsv << "paint\tsg\tsplit-axis\t320\t180\t5\t7\t128\t0\t0.15\t0.15\t1.0\t0.9\t-1\t0\t900\t30\t40\t2\t0.1\n";
    tsv << "paint\tmc\texact\t320\t180\t0\t0\t128\t4\t0.5\t0.5\t1.0\t0.2\t-1\t0\t900\t100\t110\n";
    tsv << "paint\tmc\texact\t320\t180\t0\t0\t128\t64\t0.2\t0.2\t1.0\t0.5\t-1\t0\t900\t2000\t2010\n";
    // Supersampled 2×2 (a 19th column; the rows above, written before it, are 1×1), every sample
    // shaded (no 20th column: contrast 0) at 0.12 in 10 ms, and adaptively (contrast 0.1) at 0.12
    // in 6 ms; MC at 0.36 in 100 ms and 0.04 in 900 ms puts 0.12 at 300 ms, 50× the adaptive time.
    tsv << "car\tsg\tsplit-axis\t320\t180\t5\t7\t128\t0\t0.12\t0.1\t0.9\t0.85\t0.05\t100\t1000\t10\t20\t2\n";
    tsv << "car\tsg\tsplit-axis\t320\t180\t5\t7\t128\t0\t0.12\t0.1\t0.9\t0.84\t0.05\t100\t1000\t6\t16\t2\t0.1\n";
    tsv << "car\tmc\texact\t320\t180\t0\t0\t128\t4\t0.36\t0.3\t0.9\t0.3\t0.1\t100\t1000\t100\t120\t2\n";
    tsv << "car\tmc\texact\t320\t180\t0\t0\t128\t64\t0.04\t0.04\t0.9\t0.6\t0.05\t100\t1000\t900\t920\t2\n";
    // A reference the default configuration leaves above 10 % and the sweep's finest (the most
    // levels, cones and voxels its 1×1 rows were rendered with: 5, 19, 256³, whatever their errors)
    // takes below it at 2×2 (contrast 0.1, the largest), under every supersampled MC row: a bound.
    tsv << "glossy\tsg\tsplit-axis\t320\t180\t5\t7\t128\t0\t0.12\t0.1\t0.98\t0.9\t-1\t0\t800\t150\t160\n";
    tsv << "glossy\tsg\tsplit-axis\t320\t180\t5\t19\t128\t0\t0.11\t0.1\t0.98\t0.9\t-1\t0\t800\t200\t210\n";
    tsv << "glossy\tsg\tsplit-axis\t320\t180\t5\t7\t256\t0\t0.115\t0.1\t0.98\t0.9\t-1\t0\t800\t180\t190\n";
    tsv << "glossy\tsg\tsplit-axis\t320\t180\t5\t19\t256\t0\t0.105\t0.1\t0.98\t0.9\t-1\t0\t800\t300\t310\n";
    tsv << "glossy\tmc\texact\t320\t180\t0\t0\t128\t4\t0.5\t0.5\t1.0\t0.2\t-1\t0\t800\t100\t110\n";
    tsv << "glossy\tmc\texact\t320\t180\t0\t0\t128\t64\t0.2\t0.2\t1.0\t0.5\t-1\t0\t800\t2000\t2010\n";
    tsv << "glossy\tsg\tsplit-axis\t320\t180\t5\t7\t128\t0\t0.104\t0.1\t0.99\t0.95\t-1\t0\t800\t600\t610\t2\t0.1\n";
    tsv << "glossy\tsg\tsplit-axis\t320\t180\t5\t19\t256\t0\t0.098\t0.09\t0.99\t0.96\t-1\t0\t800\t1000\t1010\t2\t0."
           "1\n";
    tsv << "glossy\tmc\texact\t320\t180\t0\t0\t128\t4\t0.5\t0.5\t1.0\t0.2\t-1\t0\t800\t100\t110\t2\n";
    tsv << "glossy\tmc\texact\t320\t180\t0\t0\t128\t64\t0.2\t0.2\t1.0\t0.5\t-1\t0\t800\t2000\t2010\t2\n";
    // The timing-only row at 1280×720: 250 ms in all is 4 fps; as the window player renders it
    // (nothing read back), 40 ms is 25 fps.
    tsv << "car\tsg\tsplit-axis\t1280\t720\t5\t7\t128\t0\t0\t0\t0\t0\t-1\t0\t0\t200\t250\t1\t0\t30\t40\n";
  }
  const CliRun r = RunOdvr("bench render --report-only --out " + d.dir.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("26 rows"), std::string::npos) << r.out;
  const std::string md = ReadText(d.dir / "render.md");
  EXPECT_NE(md.find("a test machine"), std::string::npos);
  // car: no SG row reaches MC's best error (0.1 at 16 samples); paint: MC's best is 0.2 at 2000
  // ms, and the cheapest SG row at or below it is the supersampled one at 30 ms (the 2-level one
  // at 0.25 is cheaper but less accurate), named with its samples.
  EXPECT_NE(md.find("| car | 0.200 | no | 0.800 | 0.050 | 100.0 | 400 | 4.0× | 0.100, 800 | – | – |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| paint | 0.080 | yes | 0.900 | – | 50.0 | >2000 | >40.0× | 0.200, 2000 | split-axis, 5 levels, "
                    "7 cones, 128³, 2×2 c 0.1: 0.150, 30 | 66.7× |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("≤ 10 % on car pixels:** 1 of 3"), std::string::npos) << md;
  EXPECT_NE(md.find("at equal error:** 1 of 3 at the default configuration's error; 1 of 3 at MC's best error"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("= 4.00 fps"), std::string::npos) << md;
  EXPECT_NE(md.find("shade 30.0 ms, total 40.0 ms = 25.00 fps"), std::string::npos) << md;
  // The supersampled rows: their own table, the adaptive row against the supersampled MC rows only,
  // beside the 1×1 and every-sample rows.
  EXPECT_NE(md.find("| car | 0.200, 100 | 0.120, 10 | 0.120 | no | 0.840 | 6.0 | 300 | 50.0× | 0.040, 900 | – | – |"),
            std::string::npos)
      << md;
  // At supersampled MC's best error (glossy: 0.2 in 2000 ms) the cheapest SG row as accurate is
  // any row, here the 1×1 default (0.12 in 150 ms): 13.3×.
  EXPECT_NE(md.find("| glossy | 0.120, 150 | – | 0.104 | no | 0.950 | 600.0 | >2000 | >3.3× | 0.200, 2000 | "
                    "split-axis, 5 levels, 7 cones, 128³: 0.120, 150 | 13.3× |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("contrast 0.1"), std::string::npos) << md;
  EXPECT_NE(md.find("| paint | 0.080, 50 | – | 0.150 | no | 0.900 | 30.0 | – | – | – | – | – |"), std::string::npos)
      << md;
  EXPECT_NE(md.find("supersampled:** 0 of 3 references. **≥ 20× faster than MC at equal error** (MC supersampled "
                    "alike): 1 of 2 at the supersampled row's error; 0 of 2 at MC's best error"),
            std::string::npos)
      << md;
  // The sweep's finest configuration per reference at 2×2 (contrast 0.1): car's and paint's are
  // the default (their rows above), glossy's its 5 levels, 19 cones and 256³ at 1×1 and 2×2.
  EXPECT_NE(md.find("| car | 5, 7, 128³ (the default) | 0.200, 100 | 0.120, 6 | no | 0.840 | 300 | 50.0× |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| paint | 5, 7, 128³ (the default) | 0.080, 50 | 0.150, 30 | no | 0.900 | – | – |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| glossy | 5, 19, 256³ | 0.105, 300 | 0.098, 1000 | yes | 0.960 | >2000 | >2.0× |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("finest configuration:** 1 of 3 references. **≥ 20× faster than MC at equal error:** 1 of 2"),
            std::string::npos)
      << md;
  // The plot is drawn, and its script names its files relative to itself (a copy in
  // docs/benchmarks redraws there).
  EXPECT_TRUE(fs::exists(d.dir / "render.png"));
  EXPECT_EQ(ReadText(d.dir / "render.gnuplot").find(d.dir.string()), std::string::npos);
  // The TSV is read back unchanged.
  EXPECT_NE(ReadText(d.dir / "render.tsv").find("paint\tmc\texact"), std::string::npos);
}

// The real bench on one media reference, as its targets are measured: studio_diffuse, the
// demo car in a diffuse paint under studio.exr, against its committed Cycles render. Measured
// 0.090 (bias 1.000) since the stand-in for Cycles' catcher keeps the map where the car's rays
// pass beyond it; 0.117 (0.962) before, 0.154 (0.937) with the ground's shadow on every SG's
// share (docs/notes/render_accuracy.md); 0.085 with 2×2 samples per pixel. The target
// is 0.10.
TEST(BenchRenderGL, StudioDiffuseIsWithinTenPercentOfCycles) {
  if (!fs::exists(fs::path(ODVR_SHARED_DIR) / "data/env/studio.exr"))
    GTEST_SKIP() << "needs ../shared/data/env/studio.exr (the reference's environment map): absent";
  ScratchDir d("bench_render_studio");
  const CliRun r = RunOdvr(
      "bench render --only studio_diffuse --levels 5 --cones 7 --voxels 128 --mc-samples 4 "
      "--no-lobe-modes --no-hd --out " +
      d.dir.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  bool found = false;
  for (const auto& v : SgRows(d.dir / "render.tsv", "studio_diffuse")) {
    const double mean_rel = std::stod(v[9]), bias = std::stod(v[11]);
    std::printf("studio_diffuse against Cycles, %s×%s samples per pixel (contrast %s): mean relative %.4f, bias %.4f\n",
                v[18].c_str(), v[18].c_str(), v[19].c_str(), mean_rel, bias);
    EXPECT_LT(mean_rel, 0.10);
    EXPECT_GT(bias, 0.97);
    EXPECT_LT(bias, 1.03);
    found = true;
  }
  EXPECT_TRUE(found) << "no sg row in render.tsv";
}

// street_a's frame-10 reference stands on Cycles' catcher, whose albedo the dataset does not state
// (0.2, recovered by rendering the reference again in Cycles: app/bench/bench_render.cpp). Seen from the
// car below the horizon that plane, not the panorama's road, is what Cycles lit it with; the bench
// gives the renderer the same (the default) or the road (--no-ground-bounce). Measured at the
// default configuration: 0.099 (bias 0.989) against 0.108 (0.955).
TEST(BenchRenderGL, StreetFrameIsLitByTheCatcherItsReferenceStandsOn) {
  const fs::path street = fs::path(ODVR_SHARED_DIR) / "data" / "street_a";
  if (!fs::exists(street / "augment/frame_000010/relight_ref.exr"))
    GTEST_SKIP() << "needs ../shared/data/street_a (its Cycles reference): absent";
  ScratchDir d("bench_render_street");
  const auto run = [&](const std::string& extra) {
    const fs::path out = d.dir / (extra.empty() ? "catcher" : "road");
    const CliRun r = RunOdvr("bench render --only street_a_f10 --street " + street.string() +
                             " --levels 5 --cones 7 --voxels 128 --supersample 1 --mc-samples 4 --no-lobe-modes "
                             "--no-hd " +
                             extra + " --out " + out.string());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    const auto rows = SgRows(out / "render.tsv", "street_a_f10");
    if (rows.size() == 1) return std::pair(std::stod(rows[0][9]), std::stod(rows[0][11]));
    ADD_FAILURE() << rows.size() << " sg rows of street_a_f10 in " << out / "render.tsv"
                  << ", not 1";
    return std::pair(1.0, 0.0);
  };
  const auto [catcher_error, catcher_bias] = run("");
  const auto [road_error, road_bias] = run("--no-ground-bounce");
  std::printf(
      "street_a_f10 against Cycles: mean relative %.4f (bias %.4f) lit by the catcher, %.4f (%.4f) by the road\n",
      catcher_error, catcher_bias, road_error, road_bias);
  EXPECT_LT(catcher_error, 0.10);
  EXPECT_LT(catcher_error, road_error);
  EXPECT_LT(std::abs(catcher_bias - 1), std::abs(road_bias - 1));
  EXPECT_GT(catcher_bias, 0.97);
  EXPECT_LT(catcher_bias, 1.03);
}

TEST(BenchRender, ReportOnlyRejectsAMalformedTable) {
  ScratchDir d("bench_render");
  {
    std::ofstream tsv(d.dir / "render.tsv");
    tsv << kHeader << "car\tsg\tsplit-axis\t320\t180\t5\t7\n";
  }
  const CliRun r = RunOdvr("bench render --report-only --out " + d.dir.string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("render.tsv"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("22 columns"), std::string::npos) << r.err;
  const CliRun missing = RunOdvr("bench render --report-only --out " + (d.dir / "nowhere").string());
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.err.find("cannot be read"), std::string::npos) << missing.err;
}

}  // namespace
