// `odvr bench decode` as a user runs it, on two clips ffmpeg makes: an MP4 (an index of its
// frames) and an MPEG transport stream (none), each 40 numbered frames of ffmpeg's test pattern.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
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

std::vector<std::vector<std::string>> TsvRows(const std::string& text) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(text);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::istringstream cells_in(line);
    std::string cell;
    while (std::getline(cells_in, cell, '\t')) cells.push_back(cell);
    rows.push_back(cells);
  }
  return rows;
}

TEST(BenchDecode, EveryFrameDeliveredAndTheSeekLandsOnTheAskedFrame) {
  if (std::system("command -v ffmpeg >/dev/null 2>&1") != 0) GTEST_SKIP() << "ffmpeg is not installed";
  const ScratchDir scratch("odvr_bench_decode");
  const fs::path mp4 = scratch.dir / "pattern.mp4", ts = scratch.dir / "pattern.ts";
  const std::string source =
      "ffmpeg -v error -y -f lavfi -i testsrc=size=128x64:rate=25 -frames:v 40 -c:v libx264 -g 10 ";
  ASSERT_EQ(std::system((source + mp4.string()).c_str()), 0);
  ASSERT_EQ(std::system((source + "-f mpegts " + ts.string()).c_str()), 0);

  const fs::path out = scratch.dir / "report";
  const CliRun r = RunOdvr("bench decode --clips " + mp4.string() + " " + ts.string() + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::printf("%s", r.out.c_str());
  EXPECT_TRUE(fs::exists(out / "decode.md"));
  const auto rows = TsvRows(ReadText(out / "decode.tsv"));
  ASSERT_EQ(rows.size(), 2u);
  for (const auto& row : rows) {
    ASSERT_EQ(row.size(), 8u);
    EXPECT_EQ(row[2], "40") << row[0] << ": libav delivers every frame";
    EXPECT_GT(std::stod(row[3]), 0) << row[0];
    EXPECT_EQ(row[4], "0") << row[0] << ": libav's seek lands on the asked frame";
    EXPECT_GT(std::stol(row[5]), 0) << row[0] << ": OpenCV reads it too";
  }
  EXPECT_EQ(rows[0][1], "40") << "the MP4's index counts its frames";

  const CliRun bad = RunOdvr("bench decode --clips " + (scratch.dir / "none.mp4").string() + " --out " + out.string());
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("none.mp4"), std::string::npos) << bad.err;
}

}  // namespace
