#pragma once
// Versions of the libraries each module links, for `odvr info` and bug reports.
#include <string>
#include <utility>
#include <vector>

namespace odvr {
using LibraryVersions = std::vector<std::pair<std::string, std::string>>;
LibraryVersions EngineLibraryVersions();
}  // namespace odvr
