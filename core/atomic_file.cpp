#include "core/atomic_file.h"

#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <system_error>

#include "core/error.h"

namespace odvr {
namespace {

namespace fs = std::filesystem;

// Registered temporaries: fixed storage, so a signal handler reads them without allocating. A
// slot is claimed by compare-and-swap from 0 to 1 (writing), published as 2 once its path is in.
constexpr std::size_t kSlots = 32, kPathBytes = 1024;
struct Slot {
  std::atomic<int> state{0};
  char path[kPathBytes] = {};
};
std::array<Slot, kSlots> g_slots;

}  // namespace

void RegisterTemporaryFile(const fs::path& path) {
  const std::string s = path.string();
  if (s.size() + 1 > kPathBytes) return;
  for (Slot& slot : g_slots) {
    int expected = 0;
    if (!slot.state.compare_exchange_strong(expected, 1)) continue;
    std::memcpy(slot.path, s.c_str(), s.size() + 1);
    slot.state.store(2);
    return;
  }
}

void ReleaseTemporaryFile(const fs::path& path) {
  const std::string s = path.string();
  for (Slot& slot : g_slots)
    if (slot.state.load() == 2 && s == slot.path) {
      slot.path[0] = '\0';
      slot.state.store(0);
      return;
    }
}

void RemoveTemporaryFiles() {
  // Files first, then the folders they were in (rmdir removes only an empty one).
  for (Slot& slot : g_slots)
    if (slot.state.load() == 2 && slot.path[0] != '\0') ::unlink(slot.path);
  for (Slot& slot : g_slots)
    if (slot.state.load() == 2 && slot.path[0] != '\0') ::rmdir(slot.path);
}

void CheckReplaceableOutput(const fs::path& path) {
  std::error_code ec;
  const fs::file_status s = fs::symlink_status(path, ec);
  if (ec || !fs::exists(s)) return;
  const char* what = fs::is_symlink(s)                                  ? "a symbolic link"
                     : fs::is_directory(s)                              ? "a directory"
                     : fs::is_fifo(s)                                   ? "a FIFO"
                     : fs::is_block_file(s) || fs::is_character_file(s) ? "a device"
                     : fs::is_socket(s)                                 ? "a socket"
                                                                        : nullptr;
  if (what) throw Error(path.string(), std::string("is ") + what + ", not a regular file: refusing to replace it");
}

void WriteFileAtomically(const fs::path& path, const std::function<void(const fs::path&)>& write) {
  CheckReplaceableOutput(path);
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw Error(dir.string(), "cannot create directory: " + ec.message());
  // Built by appending: GCC 12 at -O3 takes `"." + std::string` for an overlapping memcpy
  // (-Wrestrict, a false positive) and a Release build with ODVR_WERROR fails.
  std::string name = ".";
  name += path.stem().string();
  name += ".tmp" + std::to_string(::getpid());
  name += path.extension().string();
  const fs::path tmp = dir / name;
  RegisterTemporaryFile(tmp);
  const auto discard = [&] {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    ReleaseTemporaryFile(tmp);
  };
  try {
    write(tmp);
  } catch (...) {
    discard();
    throw;
  }
  if (!fs::is_regular_file(tmp, ec)) {
    discard();
    throw Error(path.string(), "cannot write: the writer produced no file");
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    const std::string why = ec.message();  // before the clean-up overwrites it
    discard();
    throw Error(path.string(), "cannot write (rename failed): " + why);
  }
  ReleaseTemporaryFile(tmp);
}

namespace {

// The interrupt handler's side of InterruptsDeferred: how many sections are open, and the signal
// that arrived during one (0: none).
std::atomic<int> g_deferring_sections{0};
std::atomic<int> g_deferred_signal{0};

// `dir` as an absolute path without a trailing separator: "out/" and "." name the folder itself.
fs::path FolderPath(const fs::path& dir) {
  fs::path d = fs::absolute(dir).lexically_normal();
  if (!d.has_filename()) d = d.parent_path();
  return d;
}

// Refuses a folder that cannot be swapped for a new one: not a folder (a file, a device), or the
// working folder or one above it (the shell that ran odvr would be left in a removed folder). A
// symbolic link to a folder is followed: the folder it names is replaced, the link kept.
fs::path SwappableFolder(const fs::path& dir) {
  fs::path d = FolderPath(dir);
  std::error_code ec;
  if (fs::is_symlink(fs::symlink_status(d, ec))) {
    d = fs::canonical(d, ec);
    if (ec) throw Error(dir.string(), "cannot follow the link: " + ec.message());
  }
  if (fs::exists(d, ec) && !fs::is_directory(d, ec))
    throw Error(dir.string(), "is not a folder: refusing to replace it with the output folder");
  const fs::path inside =
      fs::weakly_canonical(fs::current_path(ec), ec).lexically_relative(fs::weakly_canonical(d, ec));
  if (!inside.empty() && *inside.begin() != "..")
    throw Error(dir.string(),
                "holds the working folder: the output folder is replaced as a whole, give it one of its own");
  return d;
}

// Writes the set into `tmp` and carries every other entry of `old_dir` (if any) over as a hard
// link (a copy where links cannot be made), so the swap replaces the set and keeps the rest.
void FillNewFolder(const fs::path& tmp, const fs::path& old_dir,
                   const std::vector<std::pair<std::string, std::string>>& files) {
  std::error_code ec;
  fs::create_directory(tmp, ec);
  if (ec) throw Error(tmp.string(), "cannot create the output folder: " + ec.message());
  std::vector<std::string> names;
  for (const auto& [name, text] : files) {
    const fs::path target = old_dir / name;
    CheckReplaceableOutput(target);
    std::ofstream out(tmp / name, std::ios::binary);
    out << text;
    out.close();
    if (!out) throw Error(target.string(), "cannot write (disk full, or no permission?)");
    names.push_back(name);
  }
  if (!fs::is_directory(old_dir, ec)) return;
  for (const auto& entry : fs::directory_iterator(old_dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (std::find(names.begin(), names.end(), name) != names.end()) continue;
    constexpr auto kLink = fs::copy_options::recursive | fs::copy_options::copy_symlinks;
    fs::copy(entry.path(), tmp / name, kLink | fs::copy_options::create_hard_links, ec);
    if (ec) fs::copy(entry.path(), tmp / name, kLink, ec);
    if (ec) throw Error(entry.path().string(), "cannot keep it in the new output folder: " + ec.message());
  }
  if (ec) throw Error(old_dir.string(), "cannot list: " + ec.message());
  fs::permissions(tmp, fs::status(old_dir).permissions(), ec);
}

// Puts the folder `tmp` in the place of `dir`: in one step where the file system swaps two names
// (renameat2 RENAME_EXCHANGE), else the old folder renamed aside, the new one into place and the
// old one back if that fails. The old folder is removed after. Throws naming `dir`.
void SwapFolderIntoPlace(const fs::path& tmp, const fs::path& dir) {
  std::error_code ec;
  if (!fs::exists(dir, ec)) {
    fs::rename(tmp, dir, ec);
    if (ec) throw Error(dir.string(), "cannot write (rename failed): " + ec.message());
    return;
  }
  if (::renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, dir.c_str(), RENAME_EXCHANGE) == 0) {
    fs::remove_all(tmp, ec);  // the old folder, now under the temporary name
    return;
  }
  if (errno != EINVAL && errno != ENOSYS && errno != ENOTSUP)
    throw Error(dir.string(), std::string("cannot write (rename failed): ") + std::strerror(errno));
  std::string aside_name = ".";
  aside_name += dir.filename().string();
  aside_name += ".old" + std::to_string(::getpid());
  const fs::path aside = dir.parent_path() / aside_name;
  fs::rename(dir, aside, ec);
  if (ec) throw Error(dir.string(), "cannot move the old output folder aside: " + ec.message());
  fs::rename(tmp, dir, ec);
  if (ec) {
    const std::string why = ec.message();  // before the restore overwrites it
    fs::rename(aside, dir, ec);
    throw Error(dir.string(), "cannot write (rename failed): " + why);
  }
  fs::remove_all(aside, ec);
}

}  // namespace

InterruptsDeferred::InterruptsDeferred() { g_deferring_sections.fetch_add(1); }

InterruptsDeferred::~InterruptsDeferred() {
  if (g_deferring_sections.fetch_sub(1) != 1) return;
  const int sig = g_deferred_signal.exchange(0);
  if (sig != 0) EndByInterrupt(sig);
}

void EndByInterrupt(int sig) {
  RemoveTemporaryFiles();
  struct sigaction fallback {};
  fallback.sa_handler = SIG_DFL;
  sigemptyset(&fallback.sa_mask);
  sigaction(sig, &fallback, nullptr);
  ::raise(sig);
}

bool DeferInterrupt(int sig) {
  // Recorded first, then the sections counted: a section that closes in between finds the signal.
  g_deferred_signal.store(sig);
  if (g_deferring_sections.load() > 0) return true;
  g_deferred_signal.store(0);
  return false;
}

void WriteTextFilesAtomically(const fs::path& dir, const std::vector<std::pair<std::string, std::string>>& files) {
  const fs::path folder = SwappableFolder(dir);
  std::error_code ec;
  fs::create_directories(folder.parent_path(), ec);
  if (ec) throw Error(folder.parent_path().string(), "cannot create directory: " + ec.message());
  std::string tmp_name = ".";
  tmp_name += folder.filename().string();
  tmp_name += ".tmp" + std::to_string(::getpid());
  const fs::path tmp = folder.parent_path() / tmp_name;
  // Held off from the first file to the swap's end (a second or so), so that an interrupt
  // removes no file of a half-swapped set: it ends the process when the set is whole.
  InterruptsDeferred interrupts_held;
  fs::remove_all(tmp, ec);  // an earlier run's, killed
  try {
    FillNewFolder(tmp, folder, files);
    SwapFolderIntoPlace(tmp, folder);
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

void WriteTextAtomically(const fs::path& path, const std::string& text) {
  WriteFileAtomically(path, [&](const fs::path& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    out << text;
    out.close();
    if (!out) throw Error(path.string(), "cannot write (disk full, or no permission?)");
  });
}

}  // namespace odvr
