// `odvr bench player --live` as a user runs it, at a tiny size: the live section carries every
// stage with a real figure, and it replaces only itself in a table the recorded bench wrote.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "tests/app/run_odvr.h"

namespace {

using odvr::testing::ReadText;
using odvr::testing::RunOdvr;
using odvr::testing::ScratchDir;

TEST(BenchPlayerGL, LiveSectionReplacesOnlyItself) {
  ScratchDir d("bench_player_live");
  const auto md = d.dir / "player.md";
  std::ofstream(md) << "# Player frame budget\n\nrecorded table\n\n## Live mode\n\nan older live section\n";
  const auto r = RunOdvr("bench player --live --size 48x27,64x36 --frames 1 --levels 3 --out " + md.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string text = ReadText(md);
  EXPECT_EQ(text.rfind("# Player frame budget\n\nrecorded table\n", 0), 0u) << text;
  EXPECT_EQ(text.find("an older live section"), std::string::npos) << text;
  EXPECT_NE(text.find("| stage | 48x27 ms | 64x36 ms |"), std::string::npos) << text;
  for (const char* stage :
       {"| capture wait |", "| stitch |", "| lighting |", "| render |", "| composite |", "| **total** |"}) {
    const auto at = text.find(stage);
    ASSERT_NE(at, std::string::npos) << stage;
    // Two columns of positive milliseconds (a wait may be below a microsecond, never negative).
    double a = -1, b = -1;
    ASSERT_EQ(std::sscanf(text.c_str() + at + std::string(stage).size(), " %lf | %lf |", &a, &b), 2) << stage;
    EXPECT_GE(a, 0) << stage;
    EXPECT_GE(b, 0) << stage;
    if (std::string(stage) != "| capture wait |") {
      EXPECT_GT(a, 0) << stage;
      EXPECT_GT(b, 0) << stage;
    }
  }
}

}  // namespace
