#include "app/crash_report.h"

#include <gtest/gtest.h>
#include <signal.h>

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

}  // namespace
