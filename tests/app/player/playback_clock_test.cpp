#include "app/player/playback_clock.h"

#include <gtest/gtest.h>

#include "core/error.h"

namespace odvr::app {
namespace {

TEST(PlaybackClock, PlaysAtTheVideoRateAndLoops) {
  PlaybackClock c(50, 25);
  c.Advance(0.5);
  EXPECT_EQ(c.frame(), 12);
  for (int i = 0; i < 4; ++i) c.Advance(0.5);  // 2.5 s in total = 62.5 frames
  EXPECT_EQ(c.frame(), 12);
}

TEST(PlaybackClock, PauseStepSeekAndSpeed) {
  PlaybackClock c(100, 25);
  c.TogglePause();
  c.Advance(1);
  EXPECT_EQ(c.frame(), 0);
  c.Step(3);
  EXPECT_EQ(c.frame(), 3);
  c.Step(-5);  // wraps when looping
  EXPECT_EQ(c.frame(), 98);
  c.SeekSeconds(2.0);
  EXPECT_EQ(c.frame(), 50);
  c.SetPlaying(true);
  c.SetSpeed(2);
  c.Advance(0.2);
  EXPECT_EQ(c.frame(), 60);
  c.SetSpeed(100);
  EXPECT_EQ(c.speed(), 8);
  c.SetSpeed(-1);
  c.Advance(0.4);
  EXPECT_EQ(c.frame(), 50);
}

TEST(PlaybackClock, StopsAtTheEndWithoutLoopAndSurvivesTruncation) {
  PlaybackClock c(30, 30);
  c.SetLoop(false);
  c.Advance(0.9);
  c.Advance(0.9);
  EXPECT_EQ(c.frame(), 29);
  EXPECT_TRUE(c.at_end());
  c.TruncateTo(12);  // the file ended early
  EXPECT_EQ(c.frame(), 11);
  c.Seek(1000);
  EXPECT_EQ(c.frame(), 11);
}

TEST(PlaybackClock, AStalledWindowDoesNotSkipAhead) {
  PlaybackClock c(1000, 25);
  c.Advance(60);  // 60 s without a frame (window dragged)
  EXPECT_EQ(c.frame(), 25);
}

TEST(PlaybackClock, BadVideosAreClearErrors) {
  EXPECT_THROW(PlaybackClock(0, 25), Error);
  EXPECT_THROW(PlaybackClock(10, 0), Error);
}

}  // namespace
}  // namespace odvr::app
