#include "app/cli/crash_report.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

namespace {

// The report names the signal and lists frames, and the process still dies of that signal.
TEST(CrashReport, FatalSignalPrintsItsNameAndTheStackThenEndsWithIt) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        odvr::app::InstallCrashReport();
        raise(SIGSEGV);
      },
      testing::KilledBySignal(SIGSEGV), "odvr: fatal signal 11 \\(SIGSEGV\\); stack[^\n]*\n.*\\(\\+0x[0-9a-f]+\\)");
  EXPECT_EXIT(
      {
        odvr::app::InstallCrashReport();
        raise(SIGFPE);
      },
      testing::KilledBySignal(SIGFPE), "odvr: fatal signal 8 \\(SIGFPE\\)");
}

// SIGTERM while an output is being written: odvr's handler removes the temporary, and the process
// ends by the signal. The export is long (400 frames); the command is stopped five seconds in (a SIGKILL there leaves
// .clip.tmp<pid>.mp4).
TEST(CrashReportGL, AnInterruptedExportLeavesNoTemporaryBehind) {
  const std::filesystem::path demo = std::filesystem::path(ODVR_SOURCE_DIR) / "media/demo";
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("odvr_interrupted_export_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string cmd = "timeout -s TERM 5 " + std::string(ODVR_BINARY) + " export --video " +
                          (demo / "street.mp4").string() + " --trajectory " + (demo / "trajectory_gt.json").string() +
                          " --car " + (demo / "car.glb").string() + " --frames 400 --size 96x54 --out " +
                          (dir / "clip.mp4").string() + " 2>/dev/null";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 124) << "timeout stopped it (a 400-frame export takes far longer)";
  std::vector<std::string> left;
  for (const auto& e : std::filesystem::directory_iterator(dir)) left.push_back(e.path().filename().string());
  EXPECT_TRUE(left.empty()) << left.size() << " files left, the first " << left.front();
  std::filesystem::remove_all(dir);
}

}  // namespace
