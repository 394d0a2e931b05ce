// `odvr bench reconstruct` run as a user would: our reconstruction alone (--no-colmap) on the first
// four frames of ../shared/data/street_a, the report rewritten from its TSVs, and the errors for a
// missing COLMAP binary, dataset or table.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "tests/app/run_odvr.h"

namespace {

using odvr::testing::CliRun;
using odvr::testing::ReadText;
using odvr::testing::RunOdvr;
using odvr::testing::ScratchDir;

namespace fs = std::filesystem;
const fs::path kStreet = fs::path(ODVR_SHARED_DIR) / "data/street_a";

// Rows of a TSV as column name -> value.
std::vector<std::map<std::string, std::string>> ReadTsv(const fs::path& path) {
  std::ifstream in(path);
  std::string line;
  std::vector<std::string> header;
  std::getline(in, line);
  std::stringstream h(line);
  for (std::string f; std::getline(h, f, '\t');) header.push_back(f);
  std::vector<std::map<std::string, std::string>> rows;
  while (std::getline(in, line)) {
    std::map<std::string, std::string> row;
    std::stringstream s(line);
    std::size_t i = 0;
    for (std::string f; std::getline(s, f, '\t'); ++i)
      if (i < header.size()) row[header[i]] = f;
    EXPECT_GE(i + 1, header.size()) << "a short row in " << path << ": " << line;
    rows.push_back(row);
  }
  return rows;
}

double Number(const std::map<std::string, std::string>& row, const std::string& column) {
  const auto it = row.find(column);
  if (it == row.end()) {
    ADD_FAILURE() << "no column " << column;
    return NAN;
  }
  return it->second == "n/a" ? NAN : std::stod(it->second);
}

// The table lines (from the header row to the last row) of tracking.md.
std::string Table(const std::string& md) {
  const auto begin = md.find("| method | seconds");
  const auto end = md.find("\n\n", begin);
  return begin == std::string::npos ? "" : md.substr(begin, end - begin);
}

TEST(BenchReconstruct, OursAloneWritesFiniteErrorsAndTheTargetsFromTheRows) {
  if (!fs::exists(kStreet / "rig.json")) GTEST_SKIP() << kStreet << " absent (no ../shared data)";
  const ScratchDir t{"odvr_bench_reconstruct"};
  const CliRun r = RunOdvr("bench reconstruct --frames 4 --no-colmap --out " + t.dir.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("bench reconstruct: 1/1"), std::string::npos) << r.err;  // the progress line

  const auto rows = ReadTsv(t.dir / "tracking.tsv");
  ASSERT_EQ(rows.size(), 1u);
  const auto& row = rows[0];
  EXPECT_EQ(row.at("method"), "odvr");
  EXPECT_EQ(row.at("dataset"), "street_a");
  EXPECT_EQ(Number(row, "frames"), 4);
  EXPECT_EQ(Number(row, "frames_posed"), 4) << row.at("note");
  EXPECT_EQ(Number(row, "matched"), 4);
  EXPECT_GT(Number(row, "seconds"), 0);
  // The first four frames cover 1.47 m of the ground truth (0.49 m per frame at 25 fps). Measured:
  // ATE 0.0003 m, rigid ATE 0.0016 m, RPE 0.0016 m / 0.008°, scale 0.9971. A wrong rig pose or an
  // unscaled trajectory errs by decimetres; the bounds leave room for other machines' numerics.
  EXPECT_NEAR(Number(row, "path_length_m"), 1.47, 0.01);
  const double ate = Number(row, "ate_rmse_m");
  EXPECT_TRUE(std::isfinite(ate));
  EXPECT_LT(ate, 0.01);
  EXPECT_NEAR(Number(row, "ate_percent"), 100 * ate / Number(row, "path_length_m"), 0.01);
  EXPECT_LE(ate, Number(row, "ate_max_m"));
  EXPECT_LT(Number(row, "ate_rigid_rmse_m"), 0.02);
  EXPECT_LT(Number(row, "rpe_translation_m"), 0.02);
  EXPECT_LT(Number(row, "rpe_rotation_deg"), 0.2);
  EXPECT_NEAR(Number(row, "scale"), 1.0, 0.03);
  EXPECT_NEAR(Number(row, "scale_error_percent"), 100 * std::abs(Number(row, "scale") - 1), 0.02);
  EXPECT_GT(Number(row, "points"), 100);

  // Stage times: ours, and their sum no more than the total.
  double staged = 0;
  for (const auto& s : ReadTsv(t.dir / "tracking_stages.tsv")) {
    EXPECT_EQ(s.at("method"), "odvr");
    staged += Number(s, "seconds");
  }
  EXPECT_GT(staged, 0);
  EXPECT_NEAR(staged, Number(row, "seconds"), 0.1);
  // The plot's positions: the truth and ours, four frames each, ours within the ATE's reach.
  std::map<std::string, std::map<long, std::array<double, 3>>> paths;
  for (const auto& p : ReadTsv(t.dir / "tracking_paths.tsv"))
    paths[p.at("method")][std::stol(p.at("frame"))] = {Number(p, "x"), Number(p, "y"), Number(p, "z")};
  ASSERT_EQ(paths.size(), 2u);
  ASSERT_EQ(paths["ground truth"].size(), 4u);
  ASSERT_EQ(paths["odvr"].size(), 4u);
  for (const auto& [frame, xyz] : paths["odvr"]) {
    const auto& gt = paths["ground truth"][frame];
    EXPECT_LT(std::hypot(xyz[0] - gt[0], xyz[1] - gt[1], xyz[2] - gt[2]), 0.02) << "frame " << frame;
  }

  const std::string md = ReadText(t.dir / "tracking.md");
  EXPECT_NE(md.find("| odvr | "), std::string::npos) << md;
  EXPECT_EQ(md.find("| colmap | "), std::string::npos) << md;
  EXPECT_NE(md.find(ate <= 0.01 * Number(row, "path_length_m") ? "of the trajectory length: met.**"
                                                               : "of the trajectory length: not met.**"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find(Number(row, "scale_error_percent") <= 3 ? "within 3 % of the truth: met.**"
                                                            : "within 3 % of the truth: not met.**"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("ATE below COLMAP's, in less time: not measured"), std::string::npos) << md;
  EXPECT_TRUE(fs::exists(t.dir / "tracking.gnuplot"));

  // --report-only rebuilds the same table from the TSVs alone.
  const std::string table = Table(md);
  ASSERT_FALSE(table.empty());
  fs::remove(t.dir / "tracking.md");
  const CliRun again = RunOdvr("bench reconstruct --report-only --out " + t.dir.string());
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(Table(ReadText(t.dir / "tracking.md")), table);
}

TEST(BenchReconstruct, MissingColmapDatasetOrTableIsAClearError) {
  const ScratchDir t{"odvr_bench_reconstruct"};
  const CliRun no_dataset =
      RunOdvr("bench reconstruct --no-colmap --dataset " + t.dir.string() + " --out " + t.dir.string());
  EXPECT_NE(no_dataset.exit_code, 0);
  EXPECT_NE(no_dataset.err.find("has no rig.json"), std::string::npos) << no_dataset.err;

  const CliRun no_table = RunOdvr("bench reconstruct --report-only --out " + t.dir.string());
  EXPECT_NE(no_table.exit_code, 0);
  EXPECT_NE(no_table.err.find("tracking.tsv"), std::string::npos) << no_table.err;

  const CliRun both = RunOdvr("bench reconstruct --no-colmap --colmap-only --out " + t.dir.string());
  EXPECT_NE(both.exit_code, 0);
  EXPECT_NE(both.err.find("--no-colmap"), std::string::npos) << both.err;

  if (!fs::exists(kStreet / "rig.json")) return;
  // Checked before our own reconstruction runs, so this fails at once rather than minutes later.
  const CliRun no_colmap =
      RunOdvr("bench reconstruct --frames 4 --colmap " + (t.dir / "colmap").string() + " --out " + t.dir.string());
  EXPECT_NE(no_colmap.exit_code, 0);
  EXPECT_NE(no_colmap.err.find("is not an executable on PATH"), std::string::npos) << no_colmap.err;
  EXPECT_NE(no_colmap.err.find("--no-colmap"), std::string::npos) << no_colmap.err;
  EXPECT_FALSE(fs::exists(t.dir / "tracking.md"));
  EXPECT_FALSE(fs::exists(t.dir / "tracking.tsv"));
}

// --equirect on the first 8 frames, odvr alone: the panoramas and the stitched rig as H.264,
// each with and without the camera height, the rig mode beside them, the real clips, and the long
// clip (the panoramas to and fro) reconstructed at two lengths by odvr reconstruct.
TEST(BenchReconstruct, EquirectRowsForBothVideosAndTheRigWithTheirTargets) {
  if (!fs::exists(kStreet / "rig.json")) GTEST_SKIP() << kStreet << " absent (no ../shared data)";
  const ScratchDir t{"odvr_bench_equirect"};
  const CliRun r = RunOdvr(
      "bench reconstruct --equirect --frames 8 --no-colmap --clip-frames 4 --long-frames 24 "
      "--dataset " +
      kStreet.string() + " --out " + t.dir.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::printf("%s", r.out.c_str());
  const auto rows = ReadTsv(t.dir / "tracking_equirect.tsv");
  std::map<std::string, std::map<std::string, std::string>> by_method;
  for (const auto& row : rows) by_method[row.at("method")] = row;
  for (const char* m : {"odvr, gt H.264", "odvr, gt H.264, no height", "odvr, stitched H.264",
                        "odvr, stitched H.264, no height", "odvr rig"}) {
    ASSERT_TRUE(by_method.count(m)) << m;
    EXPECT_EQ(Number(by_method[m], "frames_posed"), 8) << m;
    EXPECT_LT(Number(by_method[m], "ate_percent"), 1.0) << m;
  }
  EXPECT_TRUE(std::isnan(Number(by_method["odvr, gt H.264, no height"], "scale_error_percent")))
      << "up to scale: no scale error";
  EXPECT_FALSE(std::isnan(Number(by_method["odvr, gt H.264"], "scale_error_percent")));
  const std::string md = ReadText(t.dir / "tracking_equirect.md");
  EXPECT_NE(md.find("## Targets"), std::string::npos);
  EXPECT_NE(md.find("## Real clips"), std::string::npos);
  EXPECT_NE(md.find("scene distance chosen from the frames"), std::string::npos) << "as odvr stitch chooses it";
  EXPECT_NE(md.find("## A long clip"), std::string::npos);
  EXPECT_NE(md.find("| 8 | "), std::string::npos) << "a third of it";
  EXPECT_NE(md.find("| 24/24 | 24 | 1 | "), std::string::npos) << "every frame posed, each a key frame, one chunk";
  EXPECT_TRUE(fs::exists(t.dir / "tracking_equirect_paths.tsv"));

  // The GoPro Fusion (../shared/data/rig_fusion/5_2k) stitched and tracked: its row, the first
  // --clip-frames frames each posed or a reason why not; without the data, a row saying so.
  const std::string fusion = "| rig_fusion/5_2k (stitched) | two fisheyes | ";
  const auto at = md.find(fusion);
  ASSERT_NE(at, std::string::npos) << md;
  const std::string row = md.substr(at, md.find('\n', at) - at);
  if (!fs::is_directory(kStreet.parent_path() / "rig_fusion/5_2k/directory")) {
    EXPECT_NE(row.find("skipped: "), std::string::npos) << row;
    return;
  }
  // Measured: 4/4 posed, RMSE 0.53 px; a walk whose frames do not pose must say why in the note.
  EXPECT_NE(row.find("/4 | "), std::string::npos) << row;
  const bool all_posed = row.find(" | 4/4 | ") != std::string::npos;
  EXPECT_TRUE(all_posed || row.substr(row.rfind(" | ")).size() > 5) << row;
  EXPECT_EQ(row.find("failed: "), std::string::npos) << row;
  EXPECT_NE(r.out.find("rig_fusion/5_2k stitched: scene distance"), std::string::npos) << r.out;
}

}  // namespace
