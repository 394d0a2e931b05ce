#include "engine/image/image_io.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <utility>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/srgb.h"

namespace odvr::image {

namespace OIIO = OIIO_NAMESPACE;

namespace {
// The widest file read (LoadOptions::max_pixels says why there is a limit).
constexpr int kMaxWidth = 65536;
}  // namespace

std::pair<long, long> SanitizePixels(sphere::EquirectImage* image) {
  long bad = 0, negative = 0;
  for (std::size_t p = 0; p < image->pixel_count(); ++p) {
    float* c = &image->rgb[3 * p];
    bool is_bad = false, is_negative = false;
    for (int k = 0; k < 3; ++k) {
      if (!std::isfinite(c[k])) {
        c[k] = 0;
        is_bad = true;
      } else if (c[k] < 0) {
        c[k] = 0;
        is_negative = true;
      }
    }
    bad += is_bad;
    negative += is_negative && !is_bad;
  }
  return {bad, negative};
}

// Some readers (libjpeg through OpenImageIO) decode a file that ends early without failing: they
// fill the missing rows with grey and leave only a message behind. Grey moves the lighting's
// constant term, so a file that ended early is refused; any other message the reader left (a
// camera's stray bytes before a marker, harmless) is passed on as a warning naming the file.
void CheckReaderMessages(OIIO::ImageInput* in, const std::string& name) {
  std::string message = in->geterror();
  if (message.empty()) return;
  std::replace(message.begin(), message.end(), '\n', ' ');
  std::string lower = message;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  if (lower.find("premature end") != std::string::npos || lower.find("truncated") != std::string::npos)
    throw Error(name, "truncated: the file ends before its last row (" + message + ")");
  spdlog::warn("{}: {}", name, message);
}

namespace {

// A NUL-terminated name of at most `max_length` characters; false when the file ends first or the
// name is longer.
bool ReadExrName(std::ifstream& in, std::size_t max_length, std::string* name) {
  name->clear();
  for (char c; in.get(c);) {
    if (c == '\0') return true;
    if (name->size() == max_length) return false;
    name->push_back(c);
  }
  return false;
}

// The value size OpenEXR reads for a fixed-size attribute type whatever size the attribute
// declares (its TypedAttribute<T>::readValueFrom reads sizeof(T) bytes); -1 for other types. A
// header whose declared size differs is parsed differently by the library than by a reader that
// trusts the size: the next "attribute" it sees starts inside this one's value, with any size.
int ExrFixedValueSize(const std::string& type) {
  static const std::pair<const char*, int> kSizes[] = {{"box2i", 16},
                                                       {"box2f", 16},
                                                       {"chromaticities", 32},
                                                       {"compression", 1},
                                                       {"deepImageState", 1},
                                                       {"double", 8},
                                                       {"envmap", 1},
                                                       {"float", 4},
                                                       {"int", 4},
                                                       {"keycode", 28},
                                                       {"lineOrder", 1},
                                                       {"m33f", 36},
                                                       {"m33d", 72},
                                                       {"m44f", 64},
                                                       {"m44d", 128},
                                                       {"rational", 8},
                                                       {"tiledesc", 9},
                                                       {"timecode", 8},
                                                       {"v2i", 8},
                                                       {"v2f", 8},
                                                       {"v2d", 16},
                                                       {"v3i", 12},
                                                       {"v3f", 12},
                                                       {"v3d", 24}};
  for (const auto& [name, size] : kSizes)
    if (type == name) return size;
  return -1;
}

std::int32_t LittleEndian32(const unsigned char* b) {
  return static_cast<std::int32_t>(b[0] | b[1] << 8 | b[2] << 16 | static_cast<std::uint32_t>(b[3]) << 24);
}

// The variable-size types OpenEXR reads by their content rather than as the declared bytes (the
// others, "string" and unknown ones, are read as declared): a "chlist" up to its empty channel
// name (each channel: name NUL, then 16 bytes), a "stringvector" as (int32 length, bytes) pairs,
// each allocated at its own length, a "preview" as int32 width and height, then width x height
// RGBA allocated at once. (A "floatvector", size / 4 floats, needs only its size checked.)
bool ExrReadsByContent(const std::string& type) {
  return type == "chlist" || type == "stringvector" || type == "preview";
}

// Why OpenEXR would read `value`, of a type ExrReadsByContent names, other than as exactly its
// bytes; empty when it would not.
std::string ExrValueProblem(const std::string& type, const std::vector<unsigned char>& value) {
  if (type == "preview") {
    if (value.size() < 8) return "is shorter than a preview's size";
    const unsigned long long width = static_cast<std::uint32_t>(LittleEndian32(&value[0]));
    const unsigned long long height = static_cast<std::uint32_t>(LittleEndian32(&value[4]));
    const unsigned long long pixel_bytes = value.size() - 8, pixels = pixel_bytes / 4;
    // width x height == pixels by division: the product of two 32-bit sizes could overflow.
    const bool fits = pixel_bytes % 4 == 0 &&
                      (width == 0 || height == 0 ? pixels == 0 : pixels % width == 0 && pixels / width == height);
    if (!fits)
      return "claims a preview of " + std::to_string(width) + "x" + std::to_string(height) + " in " +
             std::to_string(value.size()) + " bytes";
    return {};
  }
  std::size_t at = 0;
  if (type == "chlist") {
    for (;;) {
      const auto name_end = std::find(value.begin() + static_cast<std::ptrdiff_t>(at), value.end(), 0);
      if (name_end == value.end()) return "ends inside a channel name";
      const std::size_t name_length = static_cast<std::size_t>(name_end - value.begin()) - at;
      at += name_length + 1;
      if (name_length == 0) break;
      if (value.size() - at < 16) return "ends inside a channel";
      at += 16;
    }
    return at == value.size()
               ? ""
               : "holds its channels in " + std::to_string(at) + " of its " + std::to_string(value.size()) + " bytes";
  }
  while (at < value.size()) {  // stringvector
    if (value.size() - at < 4) return "ends inside a string's length";
    const std::int32_t length = LittleEndian32(&value[at]);
    at += 4;
    if (length < 0 || static_cast<std::size_t>(length) > value.size() - at)
      return "has a string of " + std::to_string(length) + " bytes";
    at += static_cast<std::size_t>(length);
  }
  return {};
}

}  // namespace

// The header layout (OpenEXR's file layout document): magic 76 2f 31 01, a version word whose bit
// 10 allows names of 255 characters instead of 31 and whose bit 12 marks a multi-part file, then
// attributes (name NUL, type NUL, int32 size, value) up to an empty name; a multi-part file has
// one such header per part and an empty one after the last.
std::string ExrHeaderProblem(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char start[8];
  if (!in.read(reinterpret_cast<char*>(start), sizeof start)) return {};
  if (start[0] != 0x76 || start[1] != 0x2f || start[2] != 0x31 || start[3] != 0x01) return {};
  std::error_code error;
  const auto file_size = static_cast<long long>(std::filesystem::file_size(path, error));
  if (error) return {};
  const bool long_names = start[5] & 0x04, multi_part = start[5] & 0x10;
  const std::size_t max_length = long_names ? 255 : 31;
  for (std::string name, type;;) {
    if (!ReadExrName(in, max_length, &name)) return "its OpenEXR header ends early or has an over-long name";
    if (name.empty()) {  // the end of one part's header
      if (!multi_part || in.peek() == 0 || in.peek() == std::ifstream::traits_type::eof()) return {};
      continue;
    }
    std::uint8_t size_bytes[4];
    if (!ReadExrName(in, max_length, &type) || !in.read(reinterpret_cast<char*>(size_bytes), sizeof size_bytes))
      return "its OpenEXR header ends early in attribute '" + name + "'";
    const std::int32_t size = LittleEndian32(size_bytes);
    const long long left = file_size - static_cast<long long>(in.tellg());
    if (size < 0 || size > left)
      return "its OpenEXR header's attribute '" + name + "' claims " + std::to_string(size) + " bytes, but " +
             std::to_string(left) + " are left in the file";
    if (const int fixed = ExrFixedValueSize(type); fixed >= 0 && size != fixed)
      return "its OpenEXR header's attribute '" + name + "' of type " + type + " claims " + std::to_string(size) +
             " bytes, where the type has " + std::to_string(fixed);
    if (type == "floatvector" && size % 4 != 0)
      return "its OpenEXR header's attribute '" + name + "' is not a whole number of floats";
    if (!ExrReadsByContent(type)) {
      in.seekg(size, std::ios::cur);
      continue;
    }
    std::vector<unsigned char> value(static_cast<std::size_t>(size));
    if (!in.read(reinterpret_cast<char*>(value.data()), size))
      return "its OpenEXR header ends early in attribute '" + name + "'";
    if (const std::string problem = ExrValueProblem(type, value); !problem.empty())
      return "its OpenEXR header's attribute '" + name + "' " + problem;
  }
}

sphere::EquirectImage LoadImage(const std::filesystem::path& path, const LoadOptions& options, LoadReport* report) {
  const std::string name = path.string();
  if (!std::filesystem::exists(path)) throw Error(name, "no such file");
  if (std::filesystem::is_directory(path)) throw Error(name, "is a directory, not an image");
  if (const std::string problem = ExrHeaderProblem(path); !problem.empty()) throw Error(name, problem);
  auto in = OIIO::ImageInput::open(name);
  if (!in) {
    std::string why = OIIO::geterror();
    if (why.empty()) why = "not an image OpenImageIO can read";
    std::replace(why.begin(), why.end(), '\n', ' ');
    throw Error(name, "cannot read: " + why);
  }
  const OIIO::ImageSpec& spec = in->spec();
  LoadReport r;
  r.file_width = spec.width;
  r.file_height = spec.height;
  r.channels = spec.nchannels;
  r.format = in->format_name();
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0) throw Error(name, "empty image");
  if (spec.width < 2 || spec.height < 2)
    throw Error(name,
                "is " + std::to_string(spec.width) + "x" + std::to_string(spec.height) + ": too small for a frame");
  if (options.require_equirect && spec.width != 2 * spec.height)
    throw Error(name, "is " + std::to_string(spec.width) + "x" + std::to_string(spec.height) +
                          ": an equirectangular frame must be twice as wide as high");
  const std::string size = std::to_string(spec.width) + "x" + std::to_string(spec.height);
  if (static_cast<long long>(spec.width) * spec.height > options.max_pixels)
    throw Error(name,
                "is " + size + ": more than the " + std::to_string(options.max_pixels) + " pixels an image may have");
  if (spec.width > kMaxWidth)
    throw Error(name, "is " + size + ": wider than the " + std::to_string(kMaxWidth) + " pixels an image may be");

  int factor = 1;
  while (spec.width / factor > options.max_width) factor *= 2;
  if (spec.width % factor || spec.height % factor)
    throw Error(name, "size " + std::to_string(spec.width) + "x" + std::to_string(spec.height) +
                          " cannot be downsampled by " + std::to_string(factor) + " to fit max width " +
                          std::to_string(options.max_width));
  r.downsample_factor = factor;
  const bool is_float = spec.format.basetype == OIIO::TypeDesc::FLOAT || spec.format.basetype == OIIO::TypeDesc::HALF ||
                        spec.format.basetype == OIIO::TypeDesc::DOUBLE;
  const std::string colorspace = spec.get_string_attribute("oiio:ColorSpace");
  r.linearized_from_srgb = !is_float && colorspace != "Linear" && colorspace != "linear";

  sphere::EquirectImage out(spec.width / factor, spec.height / factor);
  // Only the colour channels are read: a file may declare any number of others.
  const int nch = std::min(spec.nchannels, 3);
  // A block of rows per read (LoadOptions::read_block_bytes), whole output rows of it.
  const std::size_t row_bytes = static_cast<std::size_t>(spec.width) * nch * sizeof(float);
  const int out_rows_per_block = static_cast<int>(std::clamp<std::size_t>(
      options.read_block_bytes / (row_bytes * factor), 1, static_cast<std::size_t>(out.height)));
  std::vector<float> rows(static_cast<std::size_t>(spec.width) * factor * out_rows_per_block * nch);
  const std::array<float, 256>& lut = Srgb8ToLinearTable();
  const float scale = 1.0f / static_cast<float>(factor * factor);
  for (int block_row = 0; block_row < out.height; block_row += out_rows_per_block) {
    const int block_rows = std::min(out_rows_per_block, out.height - block_row);
    const int y0 = block_row * factor, y1 = (block_row + block_rows) * factor;
    if (!in->read_scanlines(0, 0, y0 + spec.y, y1 + spec.y, 0, 0, nch, OIIO::TypeDesc::FLOAT, rows.data())) {
      std::string why = in->geterror();
      std::replace(why.begin(), why.end(), '\n', ' ');
      throw Error(name, "corrupt or truncated in rows " + std::to_string(y0) + "-" + std::to_string(y1 - 1) +
                            (why.empty() ? "" : ": " + why));
    }
    for (int y = y0; y < y1; ++y) {
      float* dst = out.at(0, y / factor);
      const float* src = &rows[static_cast<std::size_t>(y - y0) * spec.width * nch];
      for (int x = 0; x < spec.width; ++x, src += nch) {
        float c[3];
        for (int k = 0; k < 3; ++k) c[k] = src[nch >= 3 ? k : 0];  // grey expands to RGB
        if (r.linearized_from_srgb) {
          for (float& v : c) {
            if (spec.format.basetype == OIIO::TypeDesc::UINT8) {
              v = lut[static_cast<std::size_t>(std::clamp(std::lround(v * 255.0f), 0L, 255L))];
            } else {
              v = SrgbToLinear(v);
            }
          }
        }
        float* d = dst + 3 * (x / factor);
        d[0] += c[0] * scale;
        d[1] += c[1] * scale;
        d[2] += c[2] * scale;
      }
    }
  }
  CheckReaderMessages(in.get(), name);
  in->close();
  const auto [bad, negative] = SanitizePixels(&out);
  r.nan_or_inf_pixels = bad;
  r.negative_pixels = negative;
  if (bad || negative) spdlog::warn("{}: clamped {} NaN/Inf and {} negative pixels to 0", name, bad, negative);
  if (report) *report = r;
  return out;
}

std::vector<float> LoadAlpha(const std::filesystem::path& path, int* width, int* height) {
  const std::string name = path.string();
  if (!std::filesystem::exists(path)) throw Error(name, "no such file");
  if (const std::string problem = ExrHeaderProblem(path); !problem.empty()) throw Error(name, problem);
  auto in = OIIO::ImageInput::open(name);
  if (!in) throw Error(name, "cannot read: not an image OpenImageIO can read");
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 ||
      static_cast<long long>(spec.width) * spec.height > LoadOptions{}.max_pixels)
    throw Error(name,
                "empty or too large an image (" + std::to_string(spec.width) + "x" + std::to_string(spec.height) + ")");
  *width = spec.width;
  *height = spec.height;
  std::vector<float> alpha(static_cast<std::size_t>(spec.width) * spec.height, 1.f);
  const int channel = spec.alpha_channel >= 0 ? spec.alpha_channel : (spec.nchannels >= 4 ? 3 : -1);
  if (channel < 0) return alpha;
  if (!in->read_image(0, 0, channel, channel + 1, OIIO::TypeDesc::FLOAT, alpha.data()))
    throw Error(name, "corrupt or truncated alpha channel");
  CheckReaderMessages(in.get(), name);
  for (float& a : alpha) a = std::isfinite(a) ? std::clamp(a, 0.f, 1.f) : 0.f;
  return alpha;
}

namespace {

// Writes `bytes` to `path`, every call checked: a short write (a full disk, a file size limit with
// SIGXFSZ ignored) or a failed close is an error naming `name`, the output the user asked for.
void WriteBytes(const std::filesystem::path& path, const std::vector<unsigned char>& bytes, const std::string& name) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd < 0) throw Error(name, std::string("cannot write: ") + std::strerror(errno));
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string why = n < 0 ? std::strerror(errno) : "no byte written";
      ::close(fd);
      throw Error(name, "cannot write (disk full?): " + why);
    }
    done += static_cast<std::size_t>(n);
  }
  if (::close(fd) != 0) throw Error(name, std::string("cannot write (disk full?): ") + std::strerror(errno));
}

// Reads the whole file back: for a writer that cannot encode into memory, the only way to learn
// that its file came out short, since OpenImageIO's writers report success after a short write.
void CheckReadable(const std::filesystem::path& tmp, const std::string& name) {
  auto in = OIIO::ImageInput::open(tmp.string());
  bool ok = in != nullptr;
  if (ok) {
    const OIIO::ImageSpec& spec = in->spec();
    std::vector<float> pixels(static_cast<std::size_t>(spec.width) * spec.height * spec.nchannels);
    ok = in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, pixels.data()) && in->geterror().empty();
  }
  if (!ok) throw Error(name, "cannot write: the file written does not read back whole (disk full?)");
}

}  // namespace

void SaveImage(const std::filesystem::path& path, const sphere::EquirectImage& image) {
  const std::string name = path.string();
  if (image.empty()) throw Error(name, "refusing to write an empty image");
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  const bool hdr = ext == ".exr" || ext == ".hdr";
  std::vector<unsigned char> bytes;
  if (!hdr) {
    bytes.resize(image.rgb.size());
    for (std::size_t i = 0; i < bytes.size(); ++i)
      bytes[i] = static_cast<unsigned char>(std::lround(LinearToSrgb(image.rgb[i]) * 255.0f));
  }
  const OIIO::TypeDesc type = hdr ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
  const void* pixels = hdr ? static_cast<const void*>(image.rgb.data()) : static_cast<const void*>(bytes.data());
  WriteFileAtomically(path, [&](const std::filesystem::path& tmp) {
    auto out = OIIO::ImageOutput::create(tmp.string());
    if (!out) throw Error(name, "no writer for '" + ext + "'");
    // OpenImageIO's writers (PNG among them) ignore a short write and report success, so the file
    // is encoded into memory where the format allows and written here, every write checked.
    std::vector<unsigned char> encoded;
    OIIO::Filesystem::IOVecOutput memory(encoded);
    const bool in_memory = out->supports("ioproxy") && out->set_ioproxy(&memory);
    const OIIO::ImageSpec spec(image.width, image.height, 3, type);
    if (!out->open(tmp.string(), spec) || !out->write_image(type, pixels))
      throw Error(name, "cannot write: " + out->geterror());
    // The encoder flushes its last blocks on close.
    if (!out->close()) throw Error(name, "cannot write: " + out->geterror());
    if (in_memory)
      WriteBytes(tmp, encoded, name);
    else
      CheckReadable(tmp, name);
  });
}

}  // namespace odvr::image
