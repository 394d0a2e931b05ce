#pragma once
// Which video frame is on screen: play, pause, seek, single steps and playback speed, driven by
// wall-clock time. Kept apart from decoding so its rules can be tested without a video.
namespace odvr::app {

class PlaybackClock {
 public:
  PlaybackClock(int frame_count, double fps);  // throws odvr::Error for no frames or bad fps

  void Advance(double wall_dt_s);  // while playing, moves by dt · speed · fps frames
  void TogglePause() { playing_ = !playing_; }
  void SetPlaying(bool playing) { playing_ = playing; }
  void Seek(int frame);          // clamped to the video
  void SeekSeconds(double t_s);  // clamped
  void Step(int frames);         // pauses, then moves by whole frames
  void SetSpeed(double speed);   // clamped to [1/8, 8]; negative plays backward
  void SetLoop(bool loop) { loop_ = loop; }
  // The video turned out shorter than announced (truncated file): stop at the last good frame.
  void TruncateTo(int frame_count);

  int frame() const;
  double position_s() const { return position_ / fps_; }
  bool playing() const { return playing_; }
  double speed() const { return speed_; }
  int frame_count() const { return frame_count_; }
  bool at_end() const { return !loop_ && frame() == frame_count_ - 1 && speed_ > 0; }

 private:
  int frame_count_;
  double fps_;
  double position_ = 0;  // in frames, fractional
  double speed_ = 1;
  bool playing_ = true;
  bool loop_ = true;
};

}  // namespace odvr::app
