#pragma once
// Reading one frame image from a file with OpenCV, refusing what OpenCV would silently accept.

#include <filesystem>
#include <opencv2/core.hpp>
#include <string>

namespace odvr::capture {

// The most pixels a frame file may hold by default: 2^27 (16384 x 8192, beyond the widest consumer
// 360° frames). OpenCV allocates the whole image before it decodes a row, and a 200 kB PNG or EXR
// can claim that many, so the header is checked first.
inline constexpr long long kMaxFramePixels = 1LL << 27;

// The image at `path` (cv::imread with `flags`), or an empty Mat with `*problem` set to why not:
// unreadable, larger than `max_pixels`, or a JPEG that ends before its end-of-image marker.
// libjpeg decodes such a file "successfully" and fills the rows it never read with grey, which a
// tracker follows as texture and a lighting fit takes as light.
cv::Mat ReadImageFile(const std::filesystem::path& path, int flags, std::string* problem,
                      long long max_pixels = kMaxFramePixels);

// Whether `path` is a JPEG whose last scan has no end-of-image marker after it (cut short).
// False for any other file, and for a JPEG that ends properly.
bool JpegEndsEarly(const std::filesystem::path& path);

}  // namespace odvr::capture
