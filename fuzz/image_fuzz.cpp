// Images: engine::image::LoadImage (OpenImageIO: EXR, HDR, PNG, JPEG, TIFF: environment maps and
// frames) and capture::ReadImageFile (OpenCV: a rig's and a clip's frame folders, masks).
#include <opencv2/imgcodecs.hpp>

#include "capture/image_file.h"
#include "core/error.h"
#include "engine/image/image_io.h"
#include "fuzz/fuzz_input.h"

namespace {

constexpr long long kMaxPixels = 1LL << 22;

std::string ExtensionOf(const std::uint8_t* data, std::size_t size) {
  using odvr::fuzz::StartsWith;
  if (StartsWith(data, size, "\xFF\xD8")) return ".jpg";
  if (StartsWith(data, size, "\x89PNG")) return ".png";
  if (StartsWith(data, size, "\x76\x2F\x31\x01")) return ".exr";
  if (StartsWith(data, size, "#?")) return ".hdr";
  if (StartsWith(data, size, "II*") || StartsWith(data, size, "MM\0*")) return ".tif";
  return ".img";
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = odvr::fuzz::WriteInput(data, size, ExtensionOf(data, size));
  try {
    // A small max width keeps each run fast: the downsampling path is the one a big file takes.
    // Few pixels: a small compressed file can legitimately hold a 16k x 8k image, which takes a
    // minute and a GB to decode under ASan; the limit's check is what is fuzzed.
    odvr::image::LoadImage(path, {.max_width = 256, .max_pixels = kMaxPixels});
  } catch (const odvr::Error&) {
  }
  std::string problem;
  odvr::capture::ReadImageFile(path, cv::IMREAD_COLOR, &problem, kMaxPixels);
  return 0;
}
