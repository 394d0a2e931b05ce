// Runs the real odvr binary, as a user would.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

namespace {

struct CliRun {
  int exit_code;
  std::string out;  // stdout
  std::string err;  // stderr
};

CliRun RunOdvr(const std::string& args) {
  const std::string err_file = ::testing::TempDir() + "odvr_cli_err.txt";
  const std::string cmd = std::string(ODVR_BINARY) + " " + args + " 2>" + err_file;
  CliRun run{-1, "", ""};
  FILE* pipe = ::popen(cmd.c_str(), "r");
  std::array<char, 4096> buf{};
  std::size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), pipe)) > 0) run.out.append(buf.data(), n);
  const int status = ::pclose(pipe);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (FILE* f = std::fopen(err_file.c_str(), "r")) {
    while ((n = std::fread(buf.data(), 1, buf.size(), f)) > 0) run.err.append(buf.data(), n);
    std::fclose(f);
  }
  return run;
}

int Lines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

TEST(Cli, UnknownCommandExitsTwoWithOneLine) {
  const CliRun r = RunOdvr("frobnicate");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(Lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("frobnicate"), std::string::npos);
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
}

}  // namespace
