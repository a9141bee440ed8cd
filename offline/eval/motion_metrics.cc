#include "offline/eval/motion_metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ss {
namespace {

double dist2d(const BoxState& a, const BoxState& b) { return std::hypot(a.x - b.x, a.y - b.y); }

// The largest distance between any two rollouts' positions of one object at one frame.
double spread(std::span<const JointScene> rollouts, int object, int t) {
  double m = 0;
  for (size_t a = 0; a < rollouts.size(); ++a)
    for (size_t b = a + 1; b < rollouts.size(); ++b)
      m = std::max(m, dist2d(rollouts[a].objects[object].states[t], rollouts[b].objects[object].states[t]));
  return m;
}

}  // namespace

MotionMetrics motion_metrics(const JointScene& log, std::span<const JointScene> rollouts, std::span<const int> objects,
                             int current_frame) {
  MotionMetrics m;
  int diversity_agents = 0;
  for (int n : objects) {
    const auto& truth = log.objects[n].states;
    const int frames = static_cast<int>(truth.size());
    double ade_sum = 0, ade_best = INFINITY, fde_sum = 0, fde_best = INFINITY;
    bool scored = !rollouts.empty();
    for (const JointScene& r : rollouts) {
      const auto& pred = r.objects[n].states;
      double sum = 0, last = 0;
      int count = 0;
      for (int t = current_frame + 1; t < frames; ++t) {
        if (!truth[t].valid || !pred[t].valid) continue;
        last = dist2d(truth[t], pred[t]);
        sum += last;
        ++count;
      }
      if (!count) {
        scored = false;
        break;
      }
      ade_sum += sum / count, ade_best = std::min(ade_best, sum / count);
      fde_sum += last, fde_best = std::min(fde_best, last);
    }
    if (scored) {
      const double k = static_cast<double>(rollouts.size());
      m.ade_avg += ade_sum / k, m.ade_min += ade_best, m.fde_avg += fde_sum / k, m.fde_min += fde_best;
      ++m.agents;
    }
    // Diversity: over the frames where every rollout has the object.
    double spread_sum = 0, final_spread = 0;
    int count = 0;
    for (int t = current_frame + 1; t < frames && !rollouts.empty(); ++t) {
      if (!std::all_of(rollouts.begin(), rollouts.end(), [&](const JointScene& r) { return r.objects[n].states[t].valid; }))
        continue;
      final_spread = spread(rollouts, n, t);
      spread_sum += final_spread;
      ++count;
    }
    if (count) {
      m.add += spread_sum / count, m.fdd += final_spread;
      ++diversity_agents;
    }
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto mean = [&](double sum, int n) { return n ? sum / n : nan; };
  m.ade_avg = mean(m.ade_avg, m.agents), m.ade_min = mean(m.ade_min, m.agents);
  m.fde_avg = mean(m.fde_avg, m.agents), m.fde_min = mean(m.fde_min, m.agents);
  m.add = mean(m.add, diversity_agents), m.fdd = mean(m.fdd, diversity_agents);
  return m;
}

}  // namespace ss
