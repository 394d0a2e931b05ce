#include "app/cli/crash_report.h"

#include <errno.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "core/atomic_file.h"

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

// SIGHUP (the terminal closed) and SIGQUIT remove the temporaries as SIGINT and SIGTERM do, and the
// process still ends by the signal.
TEST(CrashReport, HangUpAndQuitRemoveTheTemporaries) {
  // Forked here (not re-run, as "threadsafe" would, under another pid): the child sees these paths.
  GTEST_FLAG_SET(death_test_style, "fast");
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("odvr_hangup_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  for (int sig : {SIGHUP, SIGQUIT}) {
    const std::filesystem::path tmp = dir / (".out.tmp" + std::to_string(sig) + ".png");
    std::ofstream(tmp) << "half";
    EXPECT_EXIT(
        {
          rlimit no_core;  // SIGQUIT's default action dumps core: not into the test's folder
          no_core.rlim_cur = no_core.rlim_max = 0;
          setrlimit(RLIMIT_CORE, &no_core);
          odvr::app::InstallInterruptCleanup();
          odvr::RegisterTemporaryFile(tmp);
          raise(sig);
        },
        testing::KilledBySignal(sig), "");
    EXPECT_FALSE(std::filesystem::exists(tmp)) << strsignal(sig);
  }
  std::filesystem::remove_all(dir);
}

// A write past the file size limit (ulimit -f) fails with EFBIG instead of killing the process by
// SIGXFSZ (which left the temporary behind), so the writer's error path runs.
TEST(CrashReport, AWritePastTheFileSizeLimitFailsInsteadOfKilling) {
  GTEST_FLAG_SET(death_test_style, "fast");  // forked here: the child writes this test's file
  const std::filesystem::path file =
      std::filesystem::temp_directory_path() / ("odvr_fsize_" + std::to_string(::getpid()));
  EXPECT_EXIT(
      {
        odvr::app::InstallInterruptCleanup();
        rlimit limit;
        limit.rlim_cur = limit.rlim_max = 4096;
        setrlimit(RLIMIT_FSIZE, &limit);
        const int fd = open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
        const std::vector<char> bytes(8192, 'x');
        const ssize_t first = write(fd, bytes.data(), bytes.size());  // short: up to the limit
        const ssize_t second = write(fd, bytes.data(), bytes.size());
        std::fprintf(stderr, "wrote %zd then %zd (%s)\n", first, second, second < 0 ? strerror(errno) : "");
        std::_Exit(second < 0 && errno == EFBIG ? 3 : 4);
      },
      testing::ExitedWithCode(3), "wrote 4096 then -1");
  std::filesystem::remove(file);
}

// A full disk as a user meets it, stood in for by `ulimit -f`: render --out x.png over a good
// x.png exits 1 naming it, and the good file and no temporary remain (the PNG writer reported
// success after a short write, and SIGXFSZ killed odvr with its temporary left).
TEST(CrashReportGL, ARenderPastTheFileSizeLimitFailsAndKeepsTheOldImage) {
  const std::string street = std::string(ODVR_SHARED_DIR) + "/data/street_a";
  if (!std::filesystem::exists(street + "/car.glb")) GTEST_SKIP() << "street_a is absent (the shared test data)";
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("odvr_render_fsize_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string render = std::string(ODVR_BINARY) + " render --model " + street + "/car.glb --env " + street +
                             "/pano_hdr/000010.exr --camera -7,2.06,0.1,0,0.7,0,43 --levels 2 --out " +
                             (dir / "x.png").string();
  ASSERT_EQ(std::system((render + " --size 64x32 >/dev/null 2>&1").c_str()), 0);
  const auto size = std::filesystem::file_size(dir / "x.png");
  // 8 blocks (4 or 8 KiB, as the shell counts them): the 512x256 image is several times that.
  const std::string limited = "ulimit -f 8; " + render + " --size 512x256 >/dev/null 2>" + (dir / "err").string();
  const int status = std::system(("sh -c '" + limited + "'").c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
  std::ifstream err(dir / "err");
  const std::string said((std::istreambuf_iterator<char>(err)), std::istreambuf_iterator<char>());
  EXPECT_NE(said.find((dir / "x.png").string() + ": cannot write"), std::string::npos) << said;
  EXPECT_EQ(std::filesystem::file_size(dir / "x.png"), size) << "the good image was replaced";
  int entries = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++entries;
  EXPECT_EQ(entries, 2) << "x.png and err: no temporary left";
  std::filesystem::remove_all(dir);
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
