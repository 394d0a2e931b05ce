#pragma once
// Reading one frame image from a file with OpenCV, refusing what OpenCV would silently accept.

#include <filesystem>
#include <opencv2/core.hpp>
#include <string>

namespace odvr::capture {

// The image at `path` (cv::imread with `flags`), or an empty Mat with `*problem` set to why not:
// unreadable, or a JPEG that ends before its end-of-image marker. libjpeg decodes such a file
// "successfully" and fills the rows it never read with grey, which a tracker follows as texture
// and a lighting fit takes as light.
cv::Mat ReadImageFile(const std::filesystem::path& path, int flags, std::string* problem);

// Whether `path` is a JPEG whose last scan has no end-of-image marker after it (cut short).
// False for any other file, and for a JPEG that ends properly.
bool JpegEndsEarly(const std::filesystem::path& path);

}  // namespace odvr::capture
