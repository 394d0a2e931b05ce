#include <string>

#include "capture/source.h"
#include "core/error.h"

namespace odvr::capture {

void CheckWrittenVideo(const std::filesystem::path& file, const std::string& name, long expected_frames) {
  long frames = 0;
  try {
    auto source = OpenSource(file.string());
    while (source->Next()) ++frames;
  } catch (const Error& e) {
    throw Error(name, std::string("the video written is unreadable (disk full?): ") + e.what());
  }
  if (frames < expected_frames)
    throw Error(name, "the video written holds " + std::to_string(frames) + " of its " +
                          std::to_string(expected_frames) + " frames (disk full?)");
}

}  // namespace odvr::capture
