#include "core/atomic_file.h"

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "core/error.h"

namespace odvr {
namespace {

namespace fs = std::filesystem;

std::string ReadAll(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Entries beside `dir` named after it with a temporary's suffix (".NAME.tmpPID", ".NAME.oldPID").
int SiblingTemporaries(const fs::path& dir) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir.parent_path()))
    n += e.path().filename().string().rfind("." + dir.filename().string() + ".", 0) == 0;
  return n;
}

TEST(AtomicFile, ReplacesTheTargetOnlyWhenTheWriteSucceeds) {
  const fs::path dir = fs::temp_directory_path() / ("odvr_atomic_" + std::to_string(::getpid()));
  const fs::path target = dir / "sub" / "out.json";
  WriteTextAtomically(target, "first");
  EXPECT_EQ(ReadAll(target), "first");

  EXPECT_THROW(WriteFileAtomically(target,
                                   [](const fs::path& tmp) {
                                     std::ofstream(tmp) << "half";
                                     throw Error("test", "disk full");
                                   }),
               Error);
  EXPECT_EQ(ReadAll(target), "first");  // the good file survives
  int files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir / "sub")) ++files;
  EXPECT_EQ(files, 1);  // and no temporary is left behind
  fs::remove_all(dir);
}

TEST(AtomicFile, UnwritableDirectoryIsAClearError) {
  try {
    WriteTextAtomically("/proc/odvr_cannot_be_here/x.txt", "x");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/proc/odvr_cannot_be_here"), std::string::npos) << e.what();
  }
}

// Issue: `--out` onto a device, FIFO or link replaced the node with a regular file (as root,
// `--out /dev/null` would destroy /dev/null). Refused, naming the path, the node untouched.
TEST(AtomicFile, ANodeThatIsNotARegularFileIsNeverReplaced) {
  const fs::path dir = fs::temp_directory_path() / ("odvr_atomic_nodes_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path fifo = dir / "fifo.png", link = dir / "link.json", real = dir / "real.json", sub = dir / "sub";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  WriteTextAtomically(real, "kept");
  fs::create_symlink(real, link);
  fs::create_directories(sub);
  for (const auto& [path, what] : std::vector<std::pair<fs::path, std::string>>{
           {fifo, "a FIFO"}, {link, "a symbolic link"}, {sub, "a directory"}, {"/dev/null", "a device"}}) {
    try {
      WriteTextAtomically(path, "x");
      ADD_FAILURE() << "no error for " << path;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(path.string() + ": is " + what + ", not a regular file"), std::string::npos)
          << e.what();
    }
  }
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(ReadAll(real), "kept");
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
  fs::remove_all(dir);
}

TEST(AtomicFile, AWriterThatLeavesNoFileIsAnErrorAndKeepsTheOldOne) {
  const fs::path dir = fs::temp_directory_path() / ("odvr_atomic_nofile_" + std::to_string(::getpid()));
  const fs::path target = dir / "clip.mp4";
  WriteTextAtomically(target, "old");
  try {
    WriteFileAtomically(target, [](const fs::path&) {});
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("the writer produced no file"), std::string::npos) << e.what();
  }
  EXPECT_EQ(ReadAll(target), "old");
  fs::remove_all(dir);
}

// A set of files replaces the old set whole or not at all: one output that cannot be written (a
// directory stands where it goes) leaves every old file as it was and no temporary behind.
TEST(AtomicFile, ASetIsWrittenWholeOrNotAtAll) {
  const fs::path dir = fs::temp_directory_path() / ("odvr_atomic_set_" + std::to_string(::getpid()));
  WriteTextFilesAtomically(dir, {{"a.json", "a1"}, {"b.txt", "b1"}});
  EXPECT_EQ(ReadAll(dir / "a.json"), "a1");
  WriteTextFilesAtomically(dir, {{"a.json", "a2"}, {"b.txt", "b2"}});
  EXPECT_EQ(ReadAll(dir / "b.txt"), "b2");
  fs::create_directories(dir / "c.txt");
  EXPECT_THROW(WriteTextFilesAtomically(dir, {{"a.json", "a3"}, {"b.txt", "b3"}, {"c.txt", "c3"}}), Error);
  EXPECT_EQ(ReadAll(dir / "a.json"), "a2");
  EXPECT_EQ(ReadAll(dir / "b.txt"), "b2");
  int entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++entries;
  EXPECT_EQ(entries, 3) << "a.json, b.txt and the c.txt folder";
  EXPECT_EQ(SiblingTemporaries(dir), 0);
  fs::remove_all(dir);
}

// The set's folder is swapped for a new one as a whole: the new set in it, every other entry of
// the old folder (a note, a folder of images) kept, nothing left beside it. The working folder is
// refused (the shell that ran odvr would be left in a removed folder).
TEST(AtomicFile, AnOutputFolderIsSwappedWholeKeepingItsOtherEntries) {
  const fs::path dir = fs::temp_directory_path() / ("odvr_atomic_swap_" + std::to_string(::getpid()));
  WriteTextFilesAtomically(dir, {{"a.json", "a1"}, {"b.txt", "b1"}});
  std::ofstream(dir / "notes.md") << "mine";
  fs::create_directories(dir / "images");
  std::ofstream(dir / "images" / "0.png") << "png";
  WriteTextFilesAtomically(dir.string() + "/", {{"a.json", "a2"}, {"b.txt", "b2"}});
  EXPECT_EQ(ReadAll(dir / "a.json"), "a2");
  EXPECT_EQ(ReadAll(dir / "b.txt"), "b2");
  EXPECT_EQ(ReadAll(dir / "notes.md"), "mine");
  EXPECT_EQ(ReadAll(dir / "images" / "0.png"), "png");
  EXPECT_EQ(SiblingTemporaries(dir), 0);
  const fs::path cwd = fs::current_path();
  fs::current_path(dir / "images");
  try {
    WriteTextFilesAtomically(dir, {{"a.json", "a3"}});
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("holds the working folder"), std::string::npos) << e.what();
  }
  fs::current_path(cwd);
  EXPECT_EQ(ReadAll(dir / "a.json"), "a2");
  fs::remove_all(dir);
}

// A write that fails part-way (a full disk, stood in for by a file size limit with SIGXFSZ
// ignored, in a child process) leaves the whole old set and no temporary folder.
TEST(AtomicFile, ASetThatFailsPartWayLeavesTheWholeOldSet) {
  GTEST_FLAG_SET(death_test_style, "fast");  // forked here: the child writes this test's files
  const fs::path dir = fs::temp_directory_path() / ("odvr_atomic_full_" + std::to_string(::getpid()));
  WriteTextFilesAtomically(dir, {{"trajectory.json", "t1"}, {"summary.json", "s1"}, {"points3D.txt", "p1"}});
  // Built outside EXPECT_EXIT: the macro splits its argument at the braces' commas.
  const std::vector<std::pair<std::string, std::string>> new_set = {
      {"trajectory.json", "t2"}, {"summary.json", "s2"}, {"points3D.txt", std::string(8192, 'p')}};
  EXPECT_EXIT(
      {
        ::signal(SIGXFSZ, SIG_IGN);
        rlimit limit;
        limit.rlim_cur = limit.rlim_max = 4096;
        ::setrlimit(RLIMIT_FSIZE, &limit);
        try {
          WriteTextFilesAtomically(dir, new_set);
        } catch (const Error& e) {
          std::fprintf(stderr, "%s\n", e.what());
          std::_Exit(3);
        }
        std::_Exit(0);
      },
      ::testing::ExitedWithCode(3), "points3D.txt: cannot write");
  EXPECT_EQ(ReadAll(dir / "trajectory.json"), "t1");
  EXPECT_EQ(ReadAll(dir / "summary.json"), "s1");
  EXPECT_EQ(ReadAll(dir / "points3D.txt"), "p1");
  EXPECT_EQ(SiblingTemporaries(dir), 0);
  fs::remove_all(dir);
}

// A signal sent to the process (any thread may take it) while a set is being swapped is held:
// the process goes on to the section's end, then removes the temporaries and ends by the signal.
TEST(AtomicFile, AnInterruptDuringASwapEndsTheProcessWhenTheSwapIsDone) {
  GTEST_FLAG_SET(death_test_style, "fast");  // forked here: the child writes this test's files
  const fs::path tmp = fs::temp_directory_path() / (".odvr_deferred.tmp" + std::to_string(::getpid()));
  std::ofstream(tmp) << "half";
  EXPECT_EXIT(
      {
        ::signal(SIGTERM, [](int sig) {
          if (DeferInterrupt(sig)) return;
          RemoveTemporaryFiles();
          ::signal(sig, SIG_DFL);
          ::raise(sig);
        });
        RegisterTemporaryFile(tmp);
        {
          InterruptsDeferred held;
          std::thread([] { ::kill(::getpid(), SIGTERM); }).join();
          std::fprintf(stderr, "alive after the signal\n");
        }
        std::_Exit(0);
      },
      ::testing::KilledBySignal(SIGTERM), "alive after the signal");
  EXPECT_FALSE(fs::exists(tmp));
}

// SIGTERM in the middle of a write: the handler removes the registered temporaries before the
// process ends by the signal. A child process stands in for odvr (which installs the handler in
// app/cli/crash_report.cpp).
TEST(AtomicFile, RegisteredTemporariesAreRemovedByTheSignalHandler) {
  const fs::path dir = fs::temp_directory_path() / ("odvr_atomic_signal_" + std::to_string(::getpid()));
  fs::create_directories(dir / "set.tmp");
  const fs::path file = dir / ".out.tmp1.png", inner = dir / "set.tmp" / "summary.json";
  std::ofstream(file) << "half";
  std::ofstream(inner) << "half";
  const pid_t child = ::fork();
  if (child == 0) {
    RegisterTemporaryFile(file);
    RegisterTemporaryFile(dir / "set.tmp");
    RegisterTemporaryFile(inner);
    ::signal(SIGTERM, [](int sig) {
      RemoveTemporaryFiles();
      ::signal(sig, SIG_DFL);
      ::raise(sig);
    });
    ::raise(SIGTERM);
    ::_exit(0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM);
  EXPECT_FALSE(fs::exists(file));
  EXPECT_FALSE(fs::exists(dir / "set.tmp")) << "the folder, emptied";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace odvr
