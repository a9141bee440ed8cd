// OrderedPool (engine/base/ordered_pool.h): results come back in job order whatever finishes first, with no more jobs
// running at once than workers, and an error is the result of its own job.
#include "engine/base/ordered_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

namespace ss {
namespace {

TEST(OrderedPool, ResultsInJobOrderWithAnyNumberOfWorkers) {
  for (int workers : {1, 2, 4}) {
    std::atomic<int> running{0}, most{0};
    std::atomic<bool> last_of_first_round_done{false};
    OrderedPool<int> pool(workers, 2 * workers, [&](int i) -> absl::StatusOr<int> {
      const int now = ++running;
      for (int m = most; now > m && !most.compare_exchange_weak(m, now);) {
      }
      // Job 0 finishes after job workers - 1 (which runs beside it), so a later job finishes first.
      if (i == 0 && workers > 1)
        while (!last_of_first_round_done) std::this_thread::yield();
      if (i == workers - 1) last_of_first_round_done = true;
      --running;
      if (i == 9) return absl::InternalError("job 9 failed");
      return i * i;
    });
    for (int i = 0; i < 9; ++i) {
      auto r = pool.next();
      ASSERT_TRUE(r.ok());
      EXPECT_EQ(*r, i * i) << workers << " workers";
    }
    auto failed = pool.next();
    EXPECT_FALSE(failed.ok());
    pool.stop();
    EXPECT_LE(most.load(), workers);
  }
}

TEST(OrderedPool, NoMoreThanTheLookaheadRunsPastTheConsumer) {
  std::atomic<int> highest{-1};
  OrderedPool<int> pool(2, 3, [&](int i) -> absl::StatusOr<int> {
    for (int h = highest; i > h && !highest.compare_exchange_weak(h, i);) {
    }
    return i;
  });
  ASSERT_EQ(*pool.next(), 0);
  ASSERT_EQ(*pool.next(), 1);
  pool.stop();
  EXPECT_LE(highest.load(), 1 + 3) << "jobs started beyond consumed + lookahead";
}

}  // namespace
}  // namespace ss
