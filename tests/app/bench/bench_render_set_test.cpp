// `odvr bench render --set` as a user runs it on the committed generalization set
// (media/reference_set: the demo car under park and hall × its own paint, a glossy and a diffuse
// one × the catcher or none, 96×54): every image is scored, the page's distributions are the
// rows' (recomputed here from the TSV), and a malformed set is refused naming the file.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "core/statistics.h"
#include "tests/app/run_odvr.h"

namespace {

using odvr::testing::CliRun;
using odvr::testing::ReadText;
using odvr::testing::RunOdvr;
using odvr::testing::ScratchDir;

namespace fs = std::filesystem;

const fs::path kSet = fs::path(ODVR_SOURCE_DIR) / "media/reference_set";

std::vector<std::vector<std::string>> TsvRows(const fs::path& tsv) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream text(ReadText(tsv));
  for (std::string line; std::getline(text, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> v;
    std::istringstream cells(line);
    for (std::string c; std::getline(cells, c, '\t');) v.push_back(c);
    rows.push_back(std::move(v));
  }
  return rows;
}

TEST(BenchRenderSetGL, ScoresEveryImageAndReportsTheRowsDistributions) {
  for (const char* map : {"park.exr", "hall.exr"})
    if (!fs::exists(fs::path(ODVR_SHARED_DIR) / "data/env" / map))
      GTEST_SKIP() << "the shared environment maps are absent";
  ScratchDir d("bench_render_set");
  const CliRun r = RunOdvr("bench render --set " + kSet.string() + " --out " + d.dir.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("12 images"), std::string::npos) << r.out;

  const auto rows = TsvRows(d.dir / "render_set.tsv");
  ASSERT_EQ(rows.size(), 12u);
  std::vector<double> err, bias;
  std::map<std::string, int> per_material, per_ground;
  for (const auto& v : rows) {
    ASSERT_EQ(v.size(), 17u);
    const double mean_rel = std::stod(v[4]), b = std::stod(v[6]), upper = std::stod(v[7]), lower = std::stod(v[9]);
    for (double x : {mean_rel, b, upper, lower}) ASSERT_TRUE(std::isfinite(x)) << v[0] << " " << v[1];
    // A render of the right car under the right light: its brightness within a factor of 1.5 of
    // Cycles', each region scored.
    EXPECT_GT(mean_rel, 0) << v[1] << " " << v[2] << " " << v[3];
    EXPECT_LT(mean_rel, 0.5) << v[1] << " " << v[2] << " " << v[3];
    EXPECT_GT(b, 1 / 1.5) << v[1] << " " << v[2] << " " << v[3];
    EXPECT_LT(b, 1.5) << v[1] << " " << v[2] << " " << v[3];
    EXPECT_GT(upper, 0);
    EXPECT_GT(lower, 0);
    EXPECT_GT(std::stod(v[16]), 0) << "the reference's noise";
    err.push_back(mean_rel);
    bias.push_back(b);
    ++per_material[v[2]];
    ++per_ground[v[3]];
  }
  EXPECT_EQ(per_material, (std::map<std::string, int>{{"as-is", 4}, {"diffuse", 4}, {"glossy", 4}}));
  EXPECT_EQ(per_ground, (std::map<std::string, int>{{"catcher", 6}, {"none", 6}}));

  const std::string md = ReadText(d.dir / "render_set.md");
  const auto f3 = [](double x) {
    char s[32];
    std::snprintf(s, sizeof s, "%.3f", x);
    return std::string(s);
  };
  EXPECT_NE(md.find("| all | 12 | " + f3(odvr::Median(err)) + " | " + f3(odvr::Quantile(err, 0.9)) + " | " +
                    f3(odvr::Median(bias)) + " |"),
            std::string::npos)
      << md;
  for (const char* group : {"| as-is | 4 |", "| glossy | 4 |", "| catcher | 6 |", "| none | 6 |", "| car | 12 |",
                            "| park | 6 |", "| hall | 6 |"})
    EXPECT_NE(md.find(group), std::string::npos) << group << "\n" << md;
  EXPECT_NE(md.find("Median car-pixel error ≤ 0.08: **"), std::string::npos) << md;
  EXPECT_NE(md.find("The references of car: 96×54 pixels, 256 samples per pixel × 2 seeds."), std::string::npos) << md;
}

// --only picks images by name before any is read; --mc-samples adds the Monte-Carlo baseline on
// the same images: its columns in the TSV and its section on the page.
TEST(BenchRenderSetGL, OnlyAndTheMonteCarloBaseline) {
  if (!fs::exists(fs::path(ODVR_SHARED_DIR) / "data/env/hall.exr")) GTEST_SKIP() << "the shared maps are absent";
  ScratchDir d("bench_render_set_mc");
  const CliRun r = RunOdvr("bench render --set " + kSet.string() +
                           " --only hall_diffuse --mc-samples 9 --mc-exact --out " + d.dir.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto rows = TsvRows(d.dir / "render_set.tsv");
  ASSERT_EQ(rows.size(), 2u) << "hall × diffuse × two grounds";
  for (const auto& v : rows) {
    ASSERT_EQ(v.size(), 22u);
    EXPECT_EQ(v[1], "hall");
    EXPECT_EQ(v[2], "diffuse");
    const double mc_err = std::stod(v[17]), mc_bias = std::stod(v[18]);
    EXPECT_GT(mc_err, 0);
    EXPECT_LT(mc_err, 1.0) << "9 samples: noisy, not wrong";
    EXPECT_GT(mc_bias, 1 / 1.5);
    EXPECT_LT(mc_bias, 1.5);
  }
  const std::string md = ReadText(d.dir / "render_set.md");
  EXPECT_NE(md.find("## The Monte-Carlo baseline on the same images"), std::string::npos) << md;
  EXPECT_NE(md.find("9 samples per pixel (over every one of its 3×3 samples), seed 1, visibility by shadow rays "
                    "against the triangles"),
            std::string::npos)
      << md;
  // Fewer rays than a pixel has samples: refused before anything is rendered.
  const CliRun few = RunOdvr("bench render --set " + kSet.string() + " --only hall_diffuse --mc-samples 2 --out " +
                             (d.dir / "few").string());
  EXPECT_EQ(few.exit_code, 2) << few.err;
  EXPECT_NE(few.err.find("--mc-samples"), std::string::npos) << few.err;
}

// An image's world_from_model_odvr places the model (render_reference.py stands a model on the
// ground with it): the identity scores as the committed image without it does, and the car
// lifted 100 m shares no pixel with its reference, so nothing is scored. What set.json says was
// left out of a model's images (render_reference.py's "left_out") is on the page, with its reason.
TEST(BenchRenderSetGL, TheImagesModelPlacementIsHonoured) {
  if (!fs::exists(fs::path(ODVR_SHARED_DIR) / "data/env/hall.exr")) GTEST_SKIP() << "the shared maps are absent";
  ScratchDir d("bench_render_set_placed");
  fs::create_directories(d.dir / "car");
  for (const char* f : {"hall_diffuse_none.exr", "hall_diffuse_none_mask.exr", "hall_diffuse_none_shadow.exr"})
    fs::copy_file(kSet / "car" / f, d.dir / "car" / f);
  const std::string set_json = ReadText(kSet / "car/set.json");
  std::ofstream(d.dir / "car/set.json") << "{\"left_out\": {\"as-is\": \"its paint is not what Cycles renders\"}, "
                                        << set_json.substr(set_json.find('{') + 1);
  const std::string json = ReadText(kSet / "car/hall_diffuse_none.json");
  const auto run_lifted = [&](const std::string& lift) {
    std::ofstream(d.dir / "car/hall_diffuse_none.json")
        << "{\"world_from_model_odvr\": [[1, 0, 0, 0], [0, 1, 0, " << lift << "], [0, 0, 1, 0], [0, 0, 0, 1]], "
        << json.substr(json.find('{') + 1);
    return RunOdvr("bench render --set " + d.dir.string() + " --only hall_diffuse_none --out " +
                   (d.dir / ("out" + lift)).string());
  };
  const CliRun committed =
      RunOdvr("bench render --set " + kSet.string() + " --only hall_diffuse_none --out " + (d.dir / "own").string());
  const CliRun identity = run_lifted("0");
  ASSERT_EQ(committed.exit_code, 0) << committed.err;
  ASSERT_EQ(identity.exit_code, 0) << identity.err;
  const auto own = TsvRows(d.dir / "own/render_set.tsv"), placed = TsvRows(d.dir / "out0/render_set.tsv");
  ASSERT_EQ(own.size(), 1u);
  ASSERT_EQ(placed.size(), 1u);
  EXPECT_EQ(placed[0][4], own[0][4]) << "mean_rel";
  const std::string note = "- car, as-is: its paint is not what Cycles renders.";
  EXPECT_NE(ReadText(d.dir / "out0/render_set.md").find(note), std::string::npos);
  EXPECT_EQ(ReadText(d.dir / "own/render_set.md").find("Left out of the set"), std::string::npos);
  const CliRun lifted = run_lifted("100");
  EXPECT_NE(lifted.exit_code, 0);
  EXPECT_NE(lifted.err.find("has no car pixel in common with its reference"), std::string::npos) << lifted.err;
  // A placement that flattens the model is refused, naming the image's file.
  std::string flat = ReadText(d.dir / "car/hall_diffuse_none.json");
  flat.replace(flat.find("[0, 1, 0, 100]"), 14, "[0, 0, 0, 100]");
  std::ofstream(d.dir / "car/hall_diffuse_none.json") << flat;
  const CliRun singular =
      RunOdvr("bench render --set " + d.dir.string() + " --only hall_diffuse_none --out " + (d.dir / "flat").string());
  EXPECT_NE(singular.exit_code, 0);
  EXPECT_NE(singular.err.find((d.dir / "car/hall_diffuse_none.json").string() +
                              ": world_from_model_odvr is not a finite, invertible placement"),
            std::string::npos)
      << singular.err;
}

TEST(BenchRenderSet, AMalformedSetIsRefusedNamingTheFile) {
  ScratchDir d("bench_render_set_bad");
  const CliRun empty = RunOdvr("bench render --set " + d.dir.string() + " --out " + (d.dir / "out").string());
  EXPECT_NE(empty.exit_code, 0);
  EXPECT_NE(empty.err.find("holds no model folder with a set.json"), std::string::npos) << empty.err;

  fs::create_directories(d.dir / "car");
  std::ofstream(d.dir / "car/set.json") << "{\"model\": \"media/demo/car.glb\", \"images\": [";
  const CliRun bad = RunOdvr("bench render --set " + d.dir.string() + " --out " + (d.dir / "out").string());
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find((d.dir / "car/set.json").string() + ": is not JSON"), std::string::npos) << bad.err;

  std::ofstream(d.dir / "car/set.json") << "{\"model\": \"media/demo/car.glb\", \"images\": [\"x\"]}";
  const CliRun missing = RunOdvr("bench render --set " + d.dir.string() + " --out " + (d.dir / "out").string());
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.err.find("a field is missing or malformed"), std::string::npos) << missing.err;
  EXPECT_FALSE(fs::exists(d.dir / "out/render_set.md"));

  const CliRun none =
      RunOdvr("bench render --set " + kSet.string() + " --only no_such_image --out " + (d.dir / "out").string());
  EXPECT_EQ(none.exit_code, 2) << none.err;
  EXPECT_NE(none.err.find("--only: names no image of " + kSet.string()), std::string::npos) << none.err;

  // The sweep's options are refused, not left unused: the set renders at the default configuration.
  for (const std::string option : {"--supersample 2", "--levels 3", "--no-hd"}) {
    const CliRun sweep =
        RunOdvr("bench render --set " + kSet.string() + " " + option + " --out " + (d.dir / "out").string());
    EXPECT_EQ(sweep.exit_code, 2) << option << ": " << sweep.err;
    EXPECT_NE(sweep.err.find(option.substr(0, option.find(' ')) + ": is the sweep's"), std::string::npos) << sweep.err;
    EXPECT_FALSE(fs::exists(d.dir / "out/render_set.md"));
  }
}

// --report-only rewrites the page from the TSV a run wrote, renders nothing (no GL), reads the
// set only for what it left out, and refuses a TSV that does not match its flags or parse.
TEST(BenchRenderSet, ReportOnlyRewritesThePageFromTheTsv) {
  ScratchDir d("bench_render_set_report");
  fs::create_directories(d.dir / "set/police");
  std::ofstream(d.dir / "set/police/set.json") << "{\"left_out\": {\"as-is\": \"a reason\"}}";
  const auto write_tsv = [&](const std::string& extra) {
    std::ofstream(d.dir / "render_set.tsv")
        << "# odvr bench render --set on a test machine\n# model\tmap\t...\n"
        << "police\tsky\tglossy\tnone\t0.1\t0.1\t0.9\t0.1\t0.9\t0.2\t0.8\t0.8\t-1\t1000\t10\t12\t0.03" << extra
        << "\npolice\tcity\tdiffuse\tcatcher\t0.3\t0.2\t1.1\t0.2\t1\t0.4\t1.2\t0.7\t0.02\t900\t20\t22\t0.04" << extra
        << "\n";
  };
  const std::string run = "bench render --set " + (d.dir / "set").string() + " --out " + d.dir.string();
  write_tsv("");
  const CliRun r = RunOdvr(run + " --report-only");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("report rewritten from 2 rows"), std::string::npos) << r.out;
  const std::string md = ReadText(d.dir / "render_set.md");
  EXPECT_NE(md.find("on a test machine"), std::string::npos) << md;
  EXPECT_NE(md.find("| all | 2 | 0.200 | "), std::string::npos) << md;
  EXPECT_NE(md.find("- police, as-is: a reason."), std::string::npos) << md;
  EXPECT_EQ(TsvRows(d.dir / "render_set.tsv").size(), 2u);

  // Monte-Carlo columns need the run's --mc-samples, and their absence refuses it.
  const CliRun extra = RunOdvr(run + " --report-only --mc-samples 64");
  EXPECT_EQ(extra.exit_code, 2) << extra.err;
  write_tsv("\t0.2\t0.9\t0.3\t30");
  const CliRun missing = RunOdvr(run + " --report-only");
  EXPECT_EQ(missing.exit_code, 2) << missing.err;
  EXPECT_NE(missing.err.find("give the run's --mc-samples"), std::string::npos) << missing.err;
  const CliRun mc = RunOdvr(run + " --report-only --mc-samples 64 --mc-exact");
  ASSERT_EQ(mc.exit_code, 0) << mc.err;
  EXPECT_NE(ReadText(d.dir / "render_set.md").find("## The Monte-Carlo baseline on the same images"),
            std::string::npos);
  EXPECT_EQ(RunOdvr(run + " --report-only --mc-samples 64 --only sky").exit_code, 2);

  write_tsv("");
  std::string nan_row = ReadText(d.dir / "render_set.tsv");
  nan_row.replace(nan_row.find("0.1\t0.1\t0.9"), 3, "nan");
  std::ofstream(d.dir / "render_set.tsv") << nan_row;
  const CliRun nan = RunOdvr(run + " --report-only");
  EXPECT_NE(nan.exit_code, 0);
  EXPECT_NE(nan.err.find("a value that is not a finite number"), std::string::npos) << nan.err;

  std::ofstream(d.dir / "render_set.tsv") << "police\tsky\tglossy\tnone\tx\n";
  const CliRun bad = RunOdvr(run + " --report-only");
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find((d.dir / "render_set.tsv").string() + ": a row without 17, 21 or 22 columns"),
            std::string::npos)
      << bad.err;
}

}  // namespace
