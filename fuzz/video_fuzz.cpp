// Video containers and streams through libav (MP4, MOV, MKV, MPEG-TS, AVI; H.264, HEVC, MJPEG):
// capture::ProbeVideo and capture::LibavVideoReader, reading the first frames, seeking back and
// reading on, as the player does.
#include "capture/libav_video.h"
#include "core/error.h"
#include "fuzz/fuzz_input.h"

namespace {

std::string ExtensionOf(const std::uint8_t* data, std::size_t size) {
  using odvr::fuzz::StartsWith;
  if (StartsWith(data, size, "ftyp", 4)) return ".mp4";
  if (StartsWith(data, size, "\x1A\x45\xDF\xA3")) return ".mkv";
  if (StartsWith(data, size, "RIFF")) return ".avi";
  if (size > 0 && data[0] == 0x47) return ".ts";
  return ".bin";
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = odvr::fuzz::WriteInput(data, size, ExtensionOf(data, size)).string();
  try {
    odvr::capture::ProbeVideo(path);
    odvr::capture::LibavVideoReader reader(path);
    for (int i = 0; i < 4 && reader.Next(); ++i) {
    }
    if (reader.Seek(1)) reader.Next();
  } catch (const odvr::Error&) {
  }
  return 0;
}
