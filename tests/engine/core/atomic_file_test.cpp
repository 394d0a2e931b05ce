#include "engine/core/atomic_file.h"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "engine/core/error.h"

namespace odvr {
namespace {

namespace fs = std::filesystem;

std::string ReadAll(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
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

}  // namespace
}  // namespace odvr
