#include "core/size_text.h"

#include <gtest/gtest.h>

#include <string>

#include "tests/error_message.h"

namespace odvr {
namespace {

TEST(SizeText, SizesParseStrictlyAndNameTheirOption) {
  EXPECT_EQ(ParseSize("1280x720"), std::make_pair(1280, 720));
  EXPECT_EQ(ParseSize("1X1"), std::make_pair(1, 1));
  for (const char* bad : {"", "640", "640x", "x360", "64ax36", "640x36 ", "0x5", "-4x4", "640x360x2", "9999999x1"}) {
    const std::string message = testing::ErrorMessageOf([&] { ParseSize(bad, "--resize"); });
    EXPECT_NE(message.find("--resize"), std::string::npos) << "'" << bad << "': " << message;
    EXPECT_NE(message.find("WIDTHxHEIGHT"), std::string::npos) << "'" << bad << "': " << message;
  }
}

}  // namespace
}  // namespace odvr
