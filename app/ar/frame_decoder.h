#pragma once
// Decodes a recorded source on its own thread, ahead of the player, through a bounded queue.
// The player asks for the frame its clock shows; a request outside what is queued makes the
// thread seek. A file that ends before its announced length is reported, not fatal.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "capture/source.h"

namespace odvr::app {

// A 360° video or image sequence opened for playback as 2:1 equirect frames at its eye's width:
// one eye of a stereo video, the layout `stereo` names ("mono", "top-bottom", "side-by-side"), or
// for "auto" the one the file's metadata declares, else the one the frame's shape implies. Logs
// the layout it found when it is not mono. Throws odvr::Error naming `video` for a rig recording
// (several cameras), a file whose metadata names another projection, or an eye that is not 2:1.
std::unique_ptr<capture::Source> OpenPlayableVideo(const std::string& video, const std::string& stereo);

struct DecodedFrame {
  long index = 0;
  capture::FrameSet set;
  double decode_ms = 0;
};

class FrameDecoder {
 public:
  explicit FrameDecoder(std::unique_ptr<capture::Source> source, std::size_t queue_capacity = 6);
  ~FrameDecoder();
  FrameDecoder(const FrameDecoder&) = delete;
  FrameDecoder& operator=(const FrameDecoder&) = delete;

  // The frame `index` if it arrives within `wait`; frames before it are discarded. At once
  // nothing when the stream has ended without a decodable frame (available_frames() == 0).
  std::optional<DecodedFrame> Get(long index, std::chrono::milliseconds wait);

  long frame_count() const { return frame_count_; }
  double fps() const { return fps_; }
  int camera_count() const { return camera_count_; }
  // Frames actually decodable: less than frame_count() for a truncated file, once its end is hit.
  long available_frames() const;
  std::vector<capture::SourceEvent> TakeEvents();

 private:
  void Run();
  std::unique_ptr<capture::Source> source_;
  const std::size_t capacity_;
  long frame_count_ = 0;
  double fps_ = 25;
  int camera_count_ = 1;

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<DecodedFrame> queue_;
  std::vector<capture::SourceEvent> events_;
  long seek_to_ = -1;    // pending seek
  long next_index_ = 0;  // index of the next frame the thread will decode
  long end_index_ = -1;  // first index past the real end, once known
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace odvr::app
