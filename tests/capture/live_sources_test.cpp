// CI has no camera: the live sources are tested on their error paths. The frame-set logic they
// share is tested with recorded timestamps in frame_set_assembler_test.cpp.
#include <gtest/gtest.h>

#include "capture/source.h"
#include "core/error.h"

namespace odvr::capture {
namespace {

std::string ErrorOf(const std::string& spec) {
  try {
    OpenSource(spec);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(LiveSources, MissingV4l2DeviceNamesTheDevice) {
  const std::string e = ErrorOf("v4l2:/dev/video_odvr_missing");
  EXPECT_NE(e.find("/dev/video_odvr_missing"), std::string::npos) << e;
  EXPECT_NE(e.find("cannot open"), std::string::npos) << e;
}

TEST(LiveSources, ANonVideoDeviceIsRejected) {
  const std::string e = ErrorOf("v4l2:/dev/null");
  EXPECT_NE(e.find("/dev/null"), std::string::npos) << e;
  EXPECT_NE(e.find("not a V4L2 device"), std::string::npos) << e;
}

TEST(LiveSources, EmptyDeviceListIsAnError) { EXPECT_NE(ErrorOf("v4l2:"), ""); }

TEST(LiveSources, LibcameraWithoutCamerasSaysSo) {
  const std::string all = ErrorOf("libcamera:");
  const std::string one = ErrorOf("libcamera:/base/soc/no_such_camera");
  // On a machine with cameras the first may succeed; the named one never exists.
  if (!all.empty()) {
    EXPECT_NE(all.find("no cameras"), std::string::npos) << all;
  }
  EXPECT_NE(one.find("no_such_camera"), std::string::npos) << one;
}

}  // namespace
}  // namespace odvr::capture
