// Runs the real odvr binary, as a user would.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "core/error.h"
#include "tests/app/run_odvr.h"

namespace {

using odvr::testing::CliRun;
using odvr::testing::Lines;
using odvr::testing::RunOdvr;

TEST(Cli, UnknownCommandExitsTwoWithOneLine) {
  const CliRun r = RunOdvr("frobnicate");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(Lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("frobnicate"), std::string::npos);
}

// `odvr clip.mp4` plays the clip, as mpv and VLC users type it.
TEST(Cli, AFileAsTheFirstArgumentIsPlayed) {
  const odvr::testing::ScratchDir d("cli_file");
  const std::string demo = std::string(ODVR_SOURCE_DIR) + "/media/demo/street.mp4";
  const CliRun r = RunOdvr(demo + " --headless --frames 1 --size 32x18 --out " + (d.dir / "frames").string());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("rendered 1 frames to " + (d.dir / "frames").string()), std::string::npos) << r.out;
  const CliRun missing = RunOdvr("/no/such/clip.mp4");
  EXPECT_EQ(missing.exit_code, 2);
  EXPECT_NE(missing.err.find("'/no/such/clip.mp4' is neither a command nor a file to play"), std::string::npos)
      << missing.err;
}

TEST(Cli, BadFlagExitsTwoWithOneLine) {
  const CliRun r = RunOdvr("info --no-such-flag");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(Lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("--no-such-flag"), std::string::npos) << r.err;
}

TEST(Cli, InfoJsonReportsCoreContextAndComputeLimits) {
  const CliRun r = RunOdvr("info --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["gl"]["core_profile"].get<bool>());
  EXPECT_GE(j["gl"]["major"].get<int>() * 10 + j["gl"]["minor"].get<int>(), 45);
  EXPECT_GE(j["gl"]["compute"]["max_invocations"].get<int>(), 1024);
  EXPECT_TRUE(j["libraries"].contains("ceres"));
  EXPECT_TRUE(j["libraries"].contains("libcamera"));
}

TEST(Cli, HelpListsTheCommands) {
  const CliRun r = RunOdvr("--help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("info"), std::string::npos);
  EXPECT_NE(r.out.find("odvr clip.mp4"), std::string::npos) << r.out;  // examples
}

}  // namespace
