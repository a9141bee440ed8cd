// The dataset generator's worker pool: results come back in job order whatever finishes first.
#include "tools/dataset/ordered_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>

namespace ss::dataset {
namespace {

TEST(OrderedPool, ResultsInJobOrderWithAnyNumberOfWorkers) {
  for (int workers : {1, 2, 4}) {
    std::atomic<int> running{0}, most{0};
    OrderedPool<int> pool(workers, 2 * workers, [&](int i) -> absl::StatusOr<int> {
      const int now = ++running;
      most = std::max(most.load(), now);
      // Early jobs take longest, so later ones finish first.
      std::this_thread::sleep_for(std::chrono::milliseconds(i < 4 ? 20 - 4 * i : 1));
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

}  // namespace
}  // namespace ss::dataset
