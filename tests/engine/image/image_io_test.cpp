#include "engine/image/image_io.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "core/error.h"

namespace odvr::image {
namespace {

namespace fs = std::filesystem;

class ImageIo : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("odvr_image_" + std::to_string(::getpid()) +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string ErrorOf(const fs::path& p, LoadOptions o = {}) {
    try {
      LoadImage(p, o);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }
  fs::path dir_;
};

TEST_F(ImageIo, ExrRoundTripKeepsHdrValuesAndPngIsSrgb) {
  sphere::EquirectImage img(8, 4);
  img.at(1, 1)[0] = 1e5f;  // a sun
  img.at(2, 2)[1] = 0.5f;
  SaveImage(dir_ / "a.exr", img);
  LoadReport r;
  const auto back = LoadImage(dir_ / "a.exr", {}, &r);
  EXPECT_EQ(back.width, 8);
  EXPECT_FLOAT_EQ(back.at(1, 1)[0], 1e5f);
  EXPECT_FALSE(r.linearized_from_srgb);

  SaveImage(dir_ / "a.png", img);
  const auto png = LoadImage(dir_ / "a.png", {}, &r);
  EXPECT_TRUE(r.linearized_from_srgb);
  EXPECT_NEAR(png.at(2, 2)[1], 0.5f, 0.005f);  // through 8-bit sRGB and back
  EXPECT_FLOAT_EQ(png.at(1, 1)[0], 1.0f);      // clipped, as an LDR file must
}

TEST_F(ImageIo, NanInfAndNegativePixelsAreClampedAndCounted) {
  sphere::EquirectImage img(4, 2, 1.0f);
  img.at(0, 0)[0] = std::nanf("");
  img.at(1, 0)[2] = INFINITY;
  img.at(2, 1)[1] = -3894.0f;
  SaveImage(dir_ / "bad.exr", img);
  LoadReport r;
  const auto back = LoadImage(dir_ / "bad.exr", {}, &r);
  EXPECT_EQ(r.nan_or_inf_pixels, 2);
  EXPECT_EQ(r.negative_pixels, 1);
  for (float v : back.rgb) {
    EXPECT_TRUE(std::isfinite(v));
    EXPECT_GE(v, 0.0f);
  }
}

TEST_F(ImageIo, SharedEnvMapsWithNegativeLobesLoadClean) {
  const fs::path sky = fs::path(ODVR_SHARED_DIR) / "data/env/esplanade.exr";
  if (!fs::exists(sky)) GTEST_SKIP() << "needs ../shared/data/env (absent in a user's clone)";
  LoadReport r;
  const auto img = LoadImage(sky, {}, &r);
  EXPECT_EQ(img.width, 512);
  EXPECT_EQ(img.height, 256);
  EXPECT_GT(r.negative_pixels, 0);  // the DWAB compression artefacts the data README warns of
  EXPECT_GE(*std::min_element(img.rgb.begin(), img.rgb.end()), 0.0f);
}

TEST_F(ImageIo, WideInputsAreDownsampledWhileReading) {
  sphere::EquirectImage img(64, 32, 2.0f);
  img.at(0, 0)[0] = 2.0f + 15.0f;  // one bright pixel: its energy must survive the box filter
  SaveImage(dir_ / "wide.exr", img);
  LoadReport r;
  LoadOptions o;
  o.max_width = 16;
  const auto small = LoadImage(dir_ / "wide.exr", o, &r);
  EXPECT_EQ(r.downsample_factor, 4);
  EXPECT_EQ(small.width, 16);
  EXPECT_NEAR(small.at(0, 0)[0], 2.0f + 15.0f / 16, 1e-5);
}

TEST_F(ImageIo, BlocksOfRowsReadAsOneRead) {
  // 38 rows (19 at half width) in blocks of 3 and 5 input rows: each last block is a short one.
  sphere::EquirectImage img(76, 38, 0.0f);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      for (int k = 0; k < 3; ++k) img.at(x, y)[k] = 0.25f * static_cast<float>(k + 1) + 0.01f * x + 0.5f * y;
  SaveImage(dir_ / "rows.exr", img);
  for (const int factor : {1, 2}) {
    LoadOptions whole;
    whole.max_width = img.width / factor;
    const auto reference = LoadImage(dir_ / "rows.exr", whole);
    for (const int block_rows : {3, 5}) {
      LoadOptions blocks = whole;
      blocks.read_block_bytes = static_cast<std::size_t>(block_rows) * img.width * 3 * sizeof(float);
      const auto back = LoadImage(dir_ / "rows.exr", blocks);
      ASSERT_EQ(back.width, reference.width);
      ASSERT_EQ(back.height, reference.height);
      EXPECT_EQ(back.rgb, reference.rgb) << "factor " << factor << ", " << block_rows << " rows a block";
    }
  }
  LoadOptions whole;
  EXPECT_EQ(LoadImage(dir_ / "rows.exr", whole).rgb, img.rgb);
}

TEST_F(ImageIo, BadFilesAreOneLineErrorsNamingTheFile) {
  EXPECT_NE(ErrorOf(dir_ / "missing.exr").find("missing.exr: no such file"), std::string::npos);
  std::ofstream(dir_ / "garbage.exr") << "this is not an exr";
  EXPECT_NE(ErrorOf(dir_ / "garbage.exr").find("garbage.exr"), std::string::npos);
  SaveImage(dir_ / "tiny.exr", sphere::EquirectImage(1, 1, 1.0f));
  EXPECT_NE(ErrorOf(dir_ / "tiny.exr").find("too small"), std::string::npos);
  SaveImage(dir_ / "square.exr", sphere::EquirectImage(8, 8, 1.0f));
  LoadOptions equirect;
  equirect.require_equirect = true;
  EXPECT_NE(ErrorOf(dir_ / "square.exr", equirect).find("twice as wide"), std::string::npos);
  // A truncated PNG.
  SaveImage(dir_ / "t.png", sphere::EquirectImage(64, 32, 0.3f));
  fs::resize_file(dir_ / "t.png", fs::file_size(dir_ / "t.png") / 2);
  EXPECT_NE(ErrorOf(dir_ / "t.png").find("t.png"), std::string::npos);
}

TEST_F(ImageIo, ATooLargeHeaderIsRefusedBeforeAPixelIsRead) {
  SaveImage(dir_ / "64x32.png", sphere::EquirectImage(64, 32, 0.3f));
  LoadOptions few;
  few.max_pixels = 64 * 32 - 1;
  EXPECT_NE(ErrorOf(dir_ / "64x32.png", few).find("64x32.png: is 64x32: more than the 2047 pixels an image may have"),
            std::string::npos)
      << ErrorOf(dir_ / "64x32.png", few);
  few.max_pixels = 64 * 32;
  EXPECT_EQ(ErrorOf(dir_ / "64x32.png", few), "");
  // Wider than any block of rows may be, though few pixels: refused by default.
  SaveImage(dir_ / "wide.exr", sphere::EquirectImage(70000, 2, 0.5f));
  EXPECT_NE(ErrorOf(dir_ / "wide.exr").find("is 70000x2: wider than the 65536 pixels"), std::string::npos)
      << ErrorOf(dir_ / "wide.exr");
}

std::string LittleEndianBytes(std::int32_t value) {
  std::string bytes;
  for (int k = 0; k < 4; ++k) bytes.push_back(static_cast<char>((static_cast<std::uint32_t>(value) >> (8 * k)) & 0xff));
  return bytes;
}

// An attribute `name` of `type` that declares `size` bytes and holds `value`, made the header's first.
void InsertExrAttribute(const fs::path& path, const std::string& name, const std::string& type, std::int32_t size,
                        const std::string& value) {
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  bytes.insert(8, name + '\0' + type + '\0' + LittleEndianBytes(size) + value);
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

// The fuzzer's timeout: an OpenEXR header whose first attribute, a string, claims `size` bytes.
// OpenEXR allocated and cleared 2 GB for it before finding the file 3 kB long.
void InsertExrString(const fs::path& path, std::int32_t size, const std::string& value) {
  InsertExrAttribute(path, "owner", "string", size, value);
}

TEST_F(ImageIo, AnExrAttributeLongerThanItsFileIsRefusedBeforeOpenExrAllocatesIt) {
  SaveImage(dir_ / "ok.exr", sphere::EquirectImage(8, 4, 0.5f));
  InsertExrString(dir_ / "ok.exr", 3, "abc");  // a well-formed attribute passes the check
  EXPECT_EQ(ExrHeaderProblem(dir_ / "ok.exr"), "");

  SaveImage(dir_ / "bad.exr", sphere::EquirectImage(8, 4, 0.5f));
  InsertExrString(dir_ / "bad.exr", 0x7ffffff0, "abc");
  const std::string expected = "bad.exr: its OpenEXR header's attribute 'owner' claims 2147483632 bytes, but ";
  EXPECT_NE(ErrorOf(dir_ / "bad.exr").find(expected), std::string::npos) << ErrorOf(dir_ / "bad.exr");
  int width = 0, height = 0;
  EXPECT_THROW(LoadAlpha(dir_ / "bad.exr", &width, &height), Error);

  SaveImage(dir_ / "negative.exr", sphere::EquirectImage(8, 4, 0.5f));
  InsertExrString(dir_ / "negative.exr", -1, "");
  EXPECT_NE(ExrHeaderProblem(dir_ / "negative.exr").find("claims -1 bytes"), std::string::npos);
  // Cut inside the header's first attribute name.
  SaveImage(dir_ / "cut.exr", sphere::EquirectImage(8, 4, 0.5f));
  std::filesystem::resize_file(dir_ / "cut.exr", 12);
  EXPECT_NE(ExrHeaderProblem(dir_ / "cut.exr").find("ends early"), std::string::npos)
      << ExrHeaderProblem(dir_ / "cut.exr");
  std::ofstream(dir_ / "text.exr") << "not an exr";
  EXPECT_EQ(ExrHeaderProblem(dir_ / "text.exr"), "");  // not OpenEXR: the readers say what it is
}

// The fuzzer's second timeout: a box2i that declares 0 bytes. OpenEXR reads 16 whatever the size
// says, so it met the next attributes inside this one's value, one of them claiming gigabytes
// that a reader trusting the declared sizes never saw.
TEST_F(ImageIo, AnExrAttributeWhoseContentIsNotItsDeclaredSizeIsRefused) {
  const auto made = [&](const std::string& file, const std::string& type, std::int32_t size, const std::string& value) {
    SaveImage(dir_ / file, sphere::EquirectImage(8, 4, 0.5f));
    InsertExrAttribute(dir_ / file, "extra", type, size, value);
    return ExrHeaderProblem(dir_ / file);
  };
  const std::string box(16, '\0');
  EXPECT_EQ(made("box.exr", "box2i", 16, box), "");
  EXPECT_NE(made("box0.exr", "box2i", 0, box).find("'extra' of type box2i claims 0 bytes, where the type has 16"),
            std::string::npos);
  EXPECT_NE(ErrorOf(dir_ / "box0.exr").find("box0.exr: its OpenEXR header"), std::string::npos);

  const std::string channel = std::string("Y\0", 2) + std::string(16, '\0');
  EXPECT_EQ(made("chlist.exr", "chlist", 19, channel + '\0'), "");
  EXPECT_NE(
      made("chlist_long.exr", "chlist", 24, channel + '\0' + "abcd").find("holds its channels in 19 of its 24 bytes"),
      std::string::npos);
  EXPECT_NE(made("chlist_open.exr", "chlist", 18, channel).find("ends inside a channel"), std::string::npos);

  EXPECT_EQ(made("strings.exr", "stringvector", 11, LittleEndianBytes(3) + "abc" + LittleEndianBytes(0)), "");
  EXPECT_NE(made("string_huge.exr", "stringvector", 7, LittleEndianBytes(0x7ffffff0) + "abc")
                .find("has a string of 2147483632 bytes"),
            std::string::npos);
  EXPECT_EQ(made("preview.exr", "preview", 12, LittleEndianBytes(1) + LittleEndianBytes(1) + "rgba"), "");
  EXPECT_NE(made("preview_huge.exr", "preview", 12, LittleEndianBytes(65536) + LittleEndianBytes(65536) + "rgba")
                .find("claims a preview of 65536x65536"),
            std::string::npos);
  // 2^32 - 1 on each side: a product that overflows 64 bits must not wrap into a small size.
  EXPECT_NE(made("preview_wrap.exr", "preview", 12, LittleEndianBytes(-1) + LittleEndianBytes(-1) + "rgba")
                .find("claims a preview of 4294967295x4294967295"),
            std::string::npos);
  EXPECT_NE(made("floats.exr", "floatvector", 6, "abcdef").find("not a whole number of floats"), std::string::npos);
}

TEST_F(ImageIo, ATruncatedJpegIsRefusedNotFilledWithGrey) {
  // libjpeg decodes a JPEG that ends early "successfully", grey below the cut; only a message says so.
  sphere::EquirectImage noise(256, 128);
  unsigned state = 12345;
  for (float& v : noise.rgb) {
    state = state * 1103515245u + 12345u;
    v = static_cast<float>((state >> 16) & 0xff) / 255.0f;
  }
  SaveImage(dir_ / "whole.jpg", noise);
  EXPECT_EQ(ErrorOf(dir_ / "whole.jpg"), "");
  fs::copy_file(dir_ / "whole.jpg", dir_ / "cut.jpg");
  fs::resize_file(dir_ / "cut.jpg", fs::file_size(dir_ / "whole.jpg") / 2);
  const std::string error = ErrorOf(dir_ / "cut.jpg");
  EXPECT_NE(error.find("cut.jpg: truncated"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos) << error;
}

// A full disk, stood in for by a file size limit with SIGXFSZ ignored (odvr ignores it, so an
// over-limit write fails with EFBIG): OpenImageIO's PNG writer reported success after the short
// write, and the truncated file replaced the good one. Now the write fails naming the output, the
// good file is kept and no temporary is left. Written and checked in a child process of its own
// (the limit is the whole process's; OpenImageIO's threads rule out a plain fork), which exits 3
// when every check holds.
void WriteOverTheFileSizeLimitAndCheck(const fs::path& dir, const std::string& ext) {
  const auto bytes_of = [](const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const fs::path target = dir / ("out" + ext);
  SaveImage(target, sphere::EquirectImage(4, 2, 0.25f));
  const std::string good = bytes_of(target);
  sphere::EquirectImage noise(256, 128);  // tens of KiB in either format
  unsigned state = 4321;
  for (float& v : noise.rgb) {
    state = state * 1103515245u + 12345u;
    v = static_cast<float>((state >> 16) & 0xff) / 255.0f;
  }
  ::signal(SIGXFSZ, SIG_IGN);
  rlimit limit;
  limit.rlim_cur = limit.rlim_max = 16384;
  ::setrlimit(RLIMIT_FSIZE, &limit);
  std::string error = "no error";
  try {
    SaveImage(target, noise);
  } catch (const Error& e) {
    error = e.what();
  }
  int entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++entries;
  const bool kept = bytes_of(target) == good;
  std::fprintf(stderr, "%s; old file kept: %d; entries: %d\n", error.c_str(), kept, entries);
  fs::remove_all(dir);
  std::_Exit(kept && entries == 1 ? 3 : 4);
}

TEST_F(ImageIo, AShortWriteFailsNamingTheOutputAndKeepsTheOldFile) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  for (const std::string ext : {".png", ".exr"})
    EXPECT_EXIT(WriteOverTheFileSizeLimitAndCheck(dir_, ext), ::testing::ExitedWithCode(3),
                "odvr_image_[0-9]+AShortWriteFailsNamingTheOutputAndKeepsTheOldFile/out\\" + ext +
                    ": cannot write .*; old file kept: 1; entries: 1")
        << ext;
}

}  // namespace
}  // namespace odvr::image
