#pragma once
// Image files in and out, through OpenImageIO: EXR, HDR, PNG, JPEG (and what else it reads).
// In memory everything is linear-light float RGB (DESIGN.md §3): 8- and 16-bit files are taken
// as sRGB and linearized, float files as linear. Bad pixels (NaN, ±Inf, negative: lossy EXR
// compression leaves large negative lobes around bright sources) are clamped to 0 and counted,
// never passed on.
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "engine/sphere/equirect_image.h"

namespace odvr::image {

struct LoadOptions {
  // Wider inputs are box-downsampled while they are read, a block of rows at a time, so a
  // 16k-wide frame never sits in memory at full size: peak memory ≈ output + one block of input
  // (at least `factor` rows) + OpenImageIO's own conversion buffer (up to 64 MB).
  int max_width = 8192;
  bool require_equirect = false;  // width must be 2 × height
  // The input rows read per call (as float RGB(A)). OpenImageIO 2.4 allocates its conversion
  // buffer, up to 64 MB, on every read_scanlines call whatever the range, so reading one row at
  // a time allocates it once per row; one block of the whole frame leaves the cache between the
  // library's copy and ours. 1 MB sits between the two: `BM_LoadImage` measures
  // the block sizes around it.
  std::size_t read_block_bytes = std::size_t{1} << 20;
  // Larger files are refused from their header, before any pixel is read: 2^28 pixels (a 23k x 11k
  // panorama, twice the widest consumer 360° frame) at most, and 65536 wide, which bounds one
  // block of downsampled input rows. A 200 kB compressed file can claim a 16k x 8k image that
  // decodes for a minute; a caller that needs less sets less.
  long long max_pixels = 1LL << 28;
};

struct LoadReport {
  int file_width = 0, file_height = 0, channels = 0;
  int downsample_factor = 1;
  bool linearized_from_srgb = false;
  long nan_or_inf_pixels = 0;
  long negative_pixels = 0;
  std::string format;  // OpenImageIO's format name
};

// Throws odvr::Error naming the file: missing, unreadable, corrupt, empty, too small (1×1) or
// (with require_equirect) not 2:1.
sphere::EquirectImage LoadImage(const std::filesystem::path& path, const LoadOptions& options = {},
                                LoadReport* report = nullptr);

// Why an OpenEXR file's header cannot be read safely; empty when it can, or when the file is not
// OpenEXR. The OpenEXR library allocates and clears the size an attribute declares before it reads
// the value, so a header that claims a 2 GB string in a 3 kB file takes seconds and gigabytes to
// be refused; here every attribute must fit in the bytes that follow it. The library also reads
// some types by their content whatever size is declared (a box2i as 16 bytes, a channel list up
// to its end); there the content must be the declared size, or the library and this check would
// part ways at the next attribute. Reads only the header.
std::string ExrHeaderProblem(const std::filesystem::path& path);

// Replaces NaN, ±Inf and negative values by 0; returns {nan_or_inf, negative} counts (pixels).
std::pair<long, long> SanitizePixels(sphere::EquirectImage* image);

// The alpha channel of an image file (OpenImageIO's "A", else a 4th channel), one float per pixel,
// rows top first; all 1 when there is none. Throws odvr::Error naming the file as LoadImage.
std::vector<float> LoadAlpha(const std::filesystem::path& path, int* width, int* height);

// Written atomically. EXR keeps linear float; PNG/JPEG are sRGB-encoded 8-bit (clamped).
void SaveImage(const std::filesystem::path& path, const sphere::EquirectImage& image);

}  // namespace odvr::image
