// SeqTracker: the frame-sequence bookkeeping behind rule R3 (counted gaps, late and duplicate frames of one
// state stream). The rule itself, what a gap or a stale stream does to the mode, is safety_supervisor.cpp's.
#include "t1rt/safety.hpp"

namespace t1rt {

SeqTracker::Step SeqTracker::step(int64_t seq) const {
  if (newest_ < 0 || seq > newest_) return Step::kNew;
  return seq < newest_ - kWindowFrames ? Step::kRestart : Step::kLate;
}

bool SeqTracker::accept(int64_t seq) {  // rule R3
  constexpr int kMaskBits = 64;
  static_assert(kWindowFrames <= kMaskBits, "the received-frame mask holds 64 frames");
  if (newest_ < 0 || seq < newest_ - kWindowFrames) {  // first frame, or the publisher restarted
    newest_ = first_ = seq;
    seen_ = 1;
    return true;
  }
  if (seq > newest_) {
    const int64_t ahead = seq - newest_;
    gaps_ += ahead - 1;
    seen_ = ahead >= kMaskBits ? 0 : seen_ << ahead;
    seen_ |= 1;
    newest_ = seq;
    return true;
  }
  const int64_t behind = newest_ - seq;  // 0 = duplicate of the newest; at most kWindowFrames here
  const uint64_t bit = behind < kMaskBits ? uint64_t{1} << behind : 0;
  if (bit && !(seen_ & bit) && seq > first_) {
    seen_ |= bit;
    --gaps_;  // counted missing when the newer frame came; it was only late
  }
  ++reordered_;
  return false;
}

}  // namespace t1rt
