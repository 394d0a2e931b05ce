#include "app/player/view_controller.h"

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

namespace odvr::app {
namespace {

TEST(ViewController, YawIsUnlimitedPitchAndFovAreClamped) {
  ViewController v;
  for (int i = 0; i < 100; ++i) v.Turn(1, 0, 0.1);  // 900° of turning
  EXPECT_NEAR(v.state().yaw_deg, 180, 1e-9);
  v.Turn(0, 1, 10);
  EXPECT_EQ(v.state().pitch_deg, 90);
  v.Turn(0, -1, 100);
  EXPECT_EQ(v.state().pitch_deg, -90);
  v.Scroll(100);
  EXPECT_EQ(v.state().fov_deg, 30);
  v.Scroll(-100);
  EXPECT_EQ(v.state().fov_deg, 150);
}

TEST(ViewController, DraggingByTheViewportHeightTurnsByTheFieldOfView) {
  ViewController v;
  v.Set({0, 0, 60});
  v.Drag(-720, 0, 720);  // drag left by a full height: turn right by 60°
  EXPECT_NEAR(v.state().yaw_deg, 60, 1e-9);
  v.Drag(0, 360, 720);  // drag down half a height: look up by 30°
  EXPECT_NEAR(v.state().pitch_deg, 30, 1e-9);
}

TEST(ViewController, ForwardFollowsOdvrsFrame) {
  ViewController v;
  EXPECT_NEAR(v.Forward().x, 1, 1e-12);  // yaw 0 looks forward (+X)
  v.Set({90, 0, 90});
  EXPECT_NEAR(v.Forward().z, 1, 1e-12);  // positive yaw turns right (+Z)
  v.Set({0, 90, 90});
  EXPECT_NEAR(v.Forward().y, 1, 1e-12);
  EXPECT_NEAR(glm::dot(v.Forward(), v.Up()), 0, 1e-12);  // up stays defined at the pole
  EXPECT_NEAR(glm::length(v.Up()), 1, 1e-12);
}

TEST(ViewController, NonFiniteInputIsIgnored) {
  ViewController v;
  v.Set({std::nan(""), std::nan(""), std::nan("")});
  EXPECT_EQ(v.state().fov_deg, 90);
  v.Drag(10, 10, 0);  // a 1×1 or minimized window
  EXPECT_EQ(v.state().yaw_deg, 0);
}

}  // namespace
}  // namespace odvr::app
