#pragma once
// Runs the real odvr binary as a user would, for the app tests: exit code, stdout and stderr.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "tests/scratch_dir.h"

namespace odvr::testing {

struct CliRun {
  int exit_code;
  std::string out;  // stdout
  std::string err;  // stderr
};

// `env`: assignments for the command's environment ("XDG_CACHE_HOME=/tmp/x"), shell-quoted.
inline CliRun RunOdvr(const std::string& args, const std::string& env = "") {
  // Per process: ctest runs the app tests in parallel.
  const std::string err_file = ::testing::TempDir() + "odvr_err_" + std::to_string(::getpid()) + ".txt";
  const std::string cmd = (env.empty() ? "" : env + " ") + std::string(ODVR_BINARY) + " " + args + " 2>" + err_file;
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

// A whole text file ("" when it cannot be read: the caller's expectations then fail).
inline std::string ReadText(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

inline int Lines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

// A fresh folder for one test, removed after it.

}  // namespace odvr::testing
