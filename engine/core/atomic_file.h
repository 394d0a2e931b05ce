#pragma once
// Outputs are written atomically: to a temporary file beside the target, then renamed over it,
// so a crash or a full disk never leaves a half-written result where a good one was.
#include <filesystem>
#include <functional>
#include <string>

namespace odvr {

// Calls write(tmp_path) and renames tmp_path to `path` if it returns normally. The temporary
// keeps the target's extension so format-sniffing writers (OpenImageIO, OpenCV) still work.
void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(const std::filesystem::path& tmp_path)>& write);

// Convenience for text outputs (JSON, TUM, COLMAP text).
void WriteTextAtomically(const std::filesystem::path& path, const std::string& text);

}  // namespace odvr
