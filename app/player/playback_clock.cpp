#include "app/player/playback_clock.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace odvr::app {

PlaybackClock::PlaybackClock(int frame_count, double fps) : frame_count_(frame_count), fps_(fps) {
  if (frame_count <= 0) throw Error("video", "has no frames");
  if (!(fps > 0 && fps < 1000)) throw Error("video", "frame rate must be in (0, 1000)");
}

void PlaybackClock::Advance(double wall_dt_s) {
  if (!playing_ || !(wall_dt_s > 0)) return;
  position_ += std::min(wall_dt_s, 1.0) * speed_ * fps_;  // a stall does not skip seconds
  if (loop_) {
    position_ = std::fmod(position_, static_cast<double>(frame_count_));
    if (position_ < 0) position_ += frame_count_;
  } else {
    position_ = std::clamp(position_, 0.0, static_cast<double>(frame_count_ - 1));
  }
}

void PlaybackClock::Seek(int frame) { position_ = std::clamp(frame, 0, frame_count_ - 1); }

void PlaybackClock::SeekSeconds(double t_s) {
  if (!std::isfinite(t_s)) return;
  position_ = std::clamp(t_s * fps_, 0.0, static_cast<double>(frame_count_ - 1));
}

void PlaybackClock::Step(int frames) {
  playing_ = false;
  int f = frame() + frames;
  if (loop_) f = ((f % frame_count_) + frame_count_) % frame_count_;
  Seek(f);
}

void PlaybackClock::SetSpeed(double speed) {
  if (!std::isfinite(speed) || speed == 0) return;
  speed_ = std::copysign(std::clamp(std::abs(speed), 0.125, 8.0), speed);
}

void PlaybackClock::TruncateTo(int frame_count) {
  frame_count_ = std::clamp(frame_count, 1, frame_count_);
  position_ = std::min(position_, static_cast<double>(frame_count_ - 1));
}

int PlaybackClock::frame() const {
  return std::clamp(static_cast<int>(std::floor(position_ + 1e-9)), 0, frame_count_ - 1);
}

}  // namespace odvr::app
