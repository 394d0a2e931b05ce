#pragma once
// Outputs are written atomically: to a temporary file beside the target, then renamed over it,
// so a crash, a full disk or an interrupt never leaves a half-written result where a good one was.
#include <filesystem>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace odvr {

// Calls write(tmp_path) and renames tmp_path to `path` if it returns normally and left a file
// there. The temporary keeps the target's extension so format-sniffing writers (OpenImageIO,
// OpenCV) still work. Throws odvr::Error naming `path` when it exists and is not a regular file
// (a device, FIFO, directory or symbolic link is never replaced by a file: `--out /dev/null` run
// as root must not destroy /dev/null), when the writer leaves nothing, or when the rename fails;
// the temporary is removed then, and by RemoveTemporaryFiles on SIGINT/SIGTERM.
void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(const std::filesystem::path& tmp_path)>& write);

// Convenience for text outputs (JSON, TUM, COLMAP text).
void WriteTextAtomically(const std::filesystem::path& path, const std::string& text);

// A set of text files making up the folder `dir`, replaced as a whole: the set is written into a
// temporary sibling folder, with every other entry of the old folder carried over (hard links),
// and that folder is swapped for the old one, so `dir` is always wholly old or wholly new, after
// a failure or an interrupt too. Interrupts are held off meanwhile (InterruptsDeferred). Throws
// odvr::Error naming `dir` when it is not a folder, or holds the working folder.
void WriteTextFilesAtomically(const std::filesystem::path& dir,
                              const std::vector<std::pair<std::string, std::string>>& name_and_text);

// While one lives, an interrupt (the handler calls DeferInterrupt) does not end the process: it
// is recorded, and the last one to end removes the temporaries and ends the process by that
// signal. Blocking the signal would not do: pthread_sigmask holds it off in one thread only.
class InterruptsDeferred {
 public:
  InterruptsDeferred();
  ~InterruptsDeferred();
  InterruptsDeferred(const InterruptsDeferred&) = delete;
  InterruptsDeferred& operator=(const InterruptsDeferred&) = delete;
};
// For an interrupt handler, async-signal-safe: true when an InterruptsDeferred is alive (the
// signal is recorded, the handler returns and the process goes on), false when the handler is to
// act now.
bool DeferInterrupt(int sig);

// Throws odvr::Error naming `path` when it exists and is not a regular file (see above); for
// outputs written in place or as folders.
void CheckReplaceableOutput(const std::filesystem::path& path);

// Registers `path` as a temporary to remove if the process is interrupted, until released. Up to
// 32 at once; more are simply not cleaned on a signal.
void RegisterTemporaryFile(const std::filesystem::path& path);
void ReleaseTemporaryFile(const std::filesystem::path& path);
// Removes every registered temporary, files first, then folders (emptied by then): only
// unlink and rmdir, async-signal-safe, for a SIGINT/SIGTERM handler.
void RemoveTemporaryFiles();
// What an interrupt does when it is not deferred: RemoveTemporaryFiles, then the signal's default
// action, so the process ends by `sig`. Async-signal-safe.
void EndByInterrupt(int sig);

}  // namespace odvr
