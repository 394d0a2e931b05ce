#pragma once
// Groups frames from free-running cameras into frame sets by timestamp. Live cameras are
// synchronized only roughly: frames whose timestamps lie within `tolerance_s` of each other
// belong to one instant. A frame with no partner in time is dropped and counted; a camera that
// falls silent (no frame while the others have moved on by `stall_s`) is reported lost and the
// assembler goes on without it, leaving its slot empty.
#include <deque>
#include <limits>
#include <optional>
#include <vector>

#include "capture/frame.h"

namespace odvr::capture {

struct FrameSetAssemblerOptions {
  double tolerance_s = 0.010;  // half a frame at 50 fps; the seed's rig is hardware-synced at 25
  double stall_s = 0.5;        // silence after which a camera is declared lost
  std::size_t max_pending_per_camera = 8;
  void Check() const;  // throws odvr::Error for non-positive values
};

class FrameSetAssembler {
 public:
  FrameSetAssembler(int camera_count, FrameSetAssemblerOptions options = {});

  void Push(Frame frame);
  // The camera will deliver nothing more (device gone): stop waiting for it.
  void MarkLost(int camera, const std::string& why);
  // The next complete set, if one is ready.
  std::optional<FrameSet> TryPop();
  // At end of stream: whatever can still be grouped, lost cameras left empty.
  std::optional<FrameSet> Flush();

  std::vector<SourceEvent> TakeEvents();
  const SourceStats& stats() const { return stats_; }
  bool lost(int camera) const { return lost_[static_cast<std::size_t>(camera)]; }

 private:
  std::optional<FrameSet> Assemble(bool flushing);
  int camera_count_;
  FrameSetAssemblerOptions options_;
  std::vector<std::deque<Frame>> pending_;
  std::vector<bool> lost_;
  std::vector<double> last_seen_s_;
  double first_seen_s_ = std::numeric_limits<double>::infinity();
  std::vector<SourceEvent> events_;
  SourceStats stats_;
  long next_set_index_ = 0;
};

}  // namespace odvr::capture
