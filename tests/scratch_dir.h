#pragma once
// A folder of its own for one test: named by a prefix, the process and the running test (ctest
// runs test binaries in parallel), created empty, removed with everything in it at scope exit.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

namespace odvr::testing {

struct ScratchDir {
  explicit ScratchDir(const std::string& prefix) {
    dir = std::filesystem::temp_directory_path() / (prefix + "_" + std::to_string(::getpid()) + "_" +
                                                    ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
  }
  ~ScratchDir() { std::filesystem::remove_all(dir); }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  std::filesystem::path dir;
};

}  // namespace odvr::testing
