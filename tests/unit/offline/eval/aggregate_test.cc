// Full mode's placement figures over scenarios: the count within 30 % of the log's, and the correlation of the
// generated counts with the log's.
#include "offline/eval/aggregate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace ss {
namespace {

// A full-mode scenario whose log holds `log` agents in the region and whose `rollouts` rollouts placed `generated`
// agents in all.
ScenarioEvaluation placed(int log, int generated, int rollouts = 4) {
  ScenarioEvaluation s;
  s.has_mmd = true;
  s.rollouts = rollouts;
  s.placed_log.agents = log;
  s.placed_generated.agents = generated;
  return s;
}

TEST(Aggregate, PlacedCountsWithinThirtyPercentAndTheirCorrelation) {
  // Means per rollout 10, 25, 50, 20 against the log's 10, 20, 40, 40: within 30 % for the first three
  // (1.0, 1.25, 1.25) and not the last (0.5).
  const std::vector<ScenarioEvaluation> s = {placed(10, 40), placed(20, 100), placed(40, 200), placed(40, 80),
                                             placed(0, 12)};  // no log agent: not counted
  const DatasetEvaluation d = aggregate(s);
  EXPECT_EQ(d.placed_scenarios, 4);
  EXPECT_EQ(d.placed_within_30, 3);
  // Pearson over (10, 10), (20, 25), (40, 50), (40, 20): 512.5 / sqrt(675 * 868.75), by hand.
  EXPECT_NEAR(d.placed_count_correlation, 512.5 / std::sqrt(675 * 868.75), 1e-12);
  EXPECT_NEAR(d.placed_count_correlation, 0.6693, 1e-4);
}

TEST(Aggregate, PlacedCountCorrelationNeedsThreeScenariosAndSpread) {
  EXPECT_TRUE(std::isnan(aggregate(std::vector{placed(10, 40), placed(20, 80)}).placed_count_correlation));
  // The model places the same count everywhere: no spread, no correlation.
  EXPECT_TRUE(
      std::isnan(aggregate(std::vector{placed(10, 40), placed(20, 40), placed(30, 40)}).placed_count_correlation));
  // Proportional to the log's: 1.
  EXPECT_NEAR(aggregate(std::vector{placed(10, 40), placed(20, 80), placed(30, 120)}).placed_count_correlation, 1.0,
              1e-12);
}

}  // namespace
}  // namespace ss
