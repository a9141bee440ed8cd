// ADE/FDE (average and minimum over rollouts) and ADD/FDD diversity on a hand-computed case.
#include "offline/eval/motion_metrics.h"

#include <gtest/gtest.h>

#include <cmath>

namespace ss {
namespace {

// One object moving 1 m per frame along x; `dy[t]` offsets it sideways.
JointScene scene(std::vector<double> dy, std::vector<bool> valid = {}) {
  SceneObject o{1, ObjectType::vehicle, {}};
  for (size_t t = 0; t < dy.size(); ++t) {
    BoxState b;
    b.x = static_cast<double>(t);
    b.y = dy[t];
    b.valid = valid.empty() || valid[t];
    o.states.push_back(b);
  }
  return {{o}};
}

TEST(MotionMetrics, HandComputed) {
  const JointScene log = scene({0, 0, 0, 0});
  // Frames 1..3 scored (current frame 0). Rollout A: 1 m off throughout; B: on track, then 3 m off at the end.
  const std::vector<JointScene> rollouts = {scene({0, 1, 1, 1}), scene({0, 0, 0, 3})};
  const std::vector<int> objects = {0};
  const MotionMetrics m = motion_metrics(log, rollouts, objects, 0);
  EXPECT_EQ(m.agents, 1);
  EXPECT_DOUBLE_EQ(m.ade_avg, 1.0);  // A: 1, B: 1
  EXPECT_DOUBLE_EQ(m.ade_min, 1.0);
  EXPECT_DOUBLE_EQ(m.fde_avg, 2.0);  // A: 1, B: 3
  EXPECT_DOUBLE_EQ(m.fde_min, 1.0);
  EXPECT_DOUBLE_EQ(m.add, 4.0 / 3);  // spreads 1, 1, 2
  EXPECT_DOUBLE_EQ(m.fdd, 2.0);
}

TEST(MotionMetrics, LogValidityAndDiversityOfThree) {
  // The log loses the object at the last frame: FDE is taken at frame 2.
  const JointScene log = scene({0, 0, 0, 0}, {true, true, true, false});
  const std::vector<JointScene> rollouts = {scene({0, 0, 2, 5}), scene({0, 0, -1, 5}), scene({0, 0, 0, 0})};
  const std::vector<int> objects = {0};
  const MotionMetrics m = motion_metrics(log, rollouts, objects, 0);
  EXPECT_DOUBLE_EQ(m.fde_avg, 1.0);   // 2, 1, 0
  EXPECT_DOUBLE_EQ(m.fde_min, 0.0);
  EXPECT_DOUBLE_EQ(m.ade_avg, 0.5);   // (2/2 + 1/2 + 0) / 3
  // Diversity counts every frame all rollouts have: spreads 0, 3, 5.
  EXPECT_DOUBLE_EQ(m.add, 8.0 / 3);
  EXPECT_DOUBLE_EQ(m.fdd, 5.0);
}

TEST(MotionMetrics, NoAgentsIsUndefined) {
  const JointScene log = scene({0, 0});
  const std::vector<JointScene> rollouts = {scene({0, 0})};
  const MotionMetrics m = motion_metrics(log, rollouts, {}, 0);
  EXPECT_EQ(m.agents, 0);
  EXPECT_TRUE(std::isnan(m.ade_avg));
  EXPECT_TRUE(std::isnan(m.add));
}

}  // namespace
}  // namespace ss
