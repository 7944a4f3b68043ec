// The loop's lock-free hand-over (t1rt/handover.hpp): a reader never sees a torn value while the loop writes,
// and nothing before the first write.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <thread>

#include "t1rt/handover.hpp"

namespace {
struct Snapshot {
  std::array<int64_t, 32> words;  // every word equal when whole
};
}  // namespace

TEST(Latest, NothingBeforeTheFirstWrite) {
  t1rt::Latest<Snapshot> latest;
  Snapshot s{};
  EXPECT_FALSE(latest.read(&s));
}

TEST(Latest, AReaderNeverSeesATornValueWhileTheWriterRuns) {
  constexpr int64_t kReads = 20000, kMaxWrites = 100000000;  // the writer runs until the reader has its reads
  t1rt::Latest<Snapshot> latest;
  std::atomic<bool> read_enough{false};
  std::atomic<int64_t> written{0};
  std::thread writer([&] {
    Snapshot s{};
    int64_t k = 0;
    while (!read_enough.load(std::memory_order_relaxed) && k < kMaxWrites) {
      s.words.fill(++k);
      latest.write(s);
    }
    written.store(k);
  });
  int64_t reads = 0, newest = 0;
  Snapshot s{};
  while (reads < kReads && written.load() == 0) {
    if (!latest.read(&s)) continue;
    for (int64_t w : s.words) ASSERT_EQ(w, s.words[0]) << "torn read";
    ASSERT_GE(s.words[0], newest) << "went back in time";
    newest = s.words[0];
    ++reads;
  }
  read_enough.store(true);
  writer.join();
  ASSERT_TRUE(latest.read(&s));
  EXPECT_EQ(s.words[0], written.load());
  EXPECT_EQ(reads, kReads);
}
