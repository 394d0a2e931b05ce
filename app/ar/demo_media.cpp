#include "app/ar/demo_media.h"

#include <filesystem>

#include "core/error.h"

namespace odvr::app {

std::string DefaultDemoVideo() {
  for (const char* folder : {"drive", "demo"})
    for (const std::filesystem::path& base :
         {std::filesystem::path(ODVR_SOURCE_DIR), std::filesystem::current_path()}) {
      const auto path = base / "media" / folder / "street.mp4";
      if (std::filesystem::exists(path)) return path.string();
    }
  throw Error("media/drive/street.mp4", "the default demo is missing (regenerate it: see media/README.md)");
}

}  // namespace odvr::app
