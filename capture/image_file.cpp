#include "capture/image_file.h"

#include <OpenImageIO/imageio.h>
#include <algorithm>
#include <fstream>
#include <iterator>

#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <vector>

#include "engine/image/image_io.h"

namespace odvr::capture {
namespace {

namespace OIIO = OIIO_NAMESPACE;

std::vector<unsigned char> ReadBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

bool JpegBytesEndEarly(const std::vector<unsigned char>& bytes) {
  if (bytes.size() < 2 || bytes[0] != 0xFF || bytes[1] != 0xD8) return false;  // not a JPEG
  // In entropy-coded data a 0xFF byte is always followed by 0x00 (stuffing) or a restart marker,
  // so the marker bytes FF DA (start of scan) and FF D9 (end of image) only occur as markers. An
  // EXIF thumbnail carries its own scan and end marker near the start; the main image's last scan
  // is the last FF DA of the file, and a whole file has an FF D9 after it.
  const unsigned char start_of_scan[] = {0xFF, 0xDA}, end_of_image[] = {0xFF, 0xD9};
  const auto last_scan = std::find_end(bytes.begin(), bytes.end(), std::begin(start_of_scan), std::end(start_of_scan));
  if (last_scan == bytes.end()) return true;  // headers only: no image data at all
  return std::search(last_scan, bytes.end(), std::begin(end_of_image), std::end(end_of_image)) == bytes.end();
}

// The width x height a file's header claims, read by OpenImageIO without decoding a pixel; none
// when it cannot tell (OpenCV may still read the file).
std::optional<long long> HeaderPixels(const std::filesystem::path& path) {
  auto in = OIIO::ImageInput::open(path.string());
  if (!in) {
    (void)OIIO::geterror();  // clears the message this thread would otherwise keep
    return std::nullopt;
  }
  const OIIO::ImageSpec& spec = in->spec();
  return static_cast<long long>(spec.width) * spec.height;
}

}  // namespace

bool JpegEndsEarly(const std::filesystem::path& path) { return JpegBytesEndEarly(ReadBytes(path)); }

cv::Mat ReadImageFile(const std::filesystem::path& path, int flags, std::string* problem, long long max_pixels) {
  // OpenImageIO (the header) and OpenCV (the decoder) both read an EXR through the OpenEXR library.
  if (*problem = image::ExrHeaderProblem(path); !problem->empty()) return {};
  if (const auto pixels = HeaderPixels(path); pixels && *pixels > max_pixels) {
    *problem = "its header claims " + std::to_string(*pixels) + " pixels, more than the " + std::to_string(max_pixels) +
               " a frame may have";
    return {};
  }
  // The file is read once: the check and the decoder see the same bytes.
  const std::vector<unsigned char> bytes = ReadBytes(path);
  cv::Mat image = bytes.empty() ? cv::Mat() : cv::imdecode(bytes, flags);
  if (image.empty()) {
    *problem = "unreadable image";
  } else if (JpegBytesEndEarly(bytes)) {
    *problem = "truncated JPEG: the file ends before its end-of-image marker";
    image.release();
  }
  return image;
}

}  // namespace odvr::capture
