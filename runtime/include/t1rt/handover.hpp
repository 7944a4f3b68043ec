// Lock-free hand-over of the loop's newest value to another thread (a seqlock): the loop writes without ever
// waiting; a reader retries while a write is under way. One writer, any number of readers; T trivially
// copyable. For what leaves the 500 Hz loop for slow sinks (the live status line on stderr), so a blocked
// terminal or pipe never reaches the loop.
#pragma once
#include <atomic>
#include <cstdint>
#include <cstring>
#include <type_traits>

namespace t1rt {

template <class T>
class Latest {
  static_assert(std::is_trivially_copyable_v<T>, "a seqlock copies bytes");

 public:
  void write(const T& value) {  // the loop: never blocks
    const uint32_t s = seq_.load(std::memory_order_relaxed);
    seq_.store(s + 1, std::memory_order_relaxed);  // odd: a write is under way
    std::atomic_thread_fence(std::memory_order_release);
    std::memcpy(data_, &value, sizeof(T));
    seq_.store(s + 2, std::memory_order_release);
  }
  // The newest complete value into *out; false before the first write.
  bool read(T* out) const {
    for (;;) {
      const uint32_t before = seq_.load(std::memory_order_acquire);
      if (before == 0) return false;
      if (before & 1u) continue;
      std::memcpy(out, data_, sizeof(T));
      std::atomic_thread_fence(std::memory_order_acquire);
      if (seq_.load(std::memory_order_relaxed) == before) return true;
    }
  }

 private:
  std::atomic<uint32_t> seq_{0};
  alignas(T) unsigned char data_[sizeof(T)];
};

}  // namespace t1rt
