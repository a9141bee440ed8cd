#include "offline/eval/aggregate.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <vector>

namespace ss {

namespace {

// NaN with fewer than 3 pairs or without spread on either side.
double pearson(const std::vector<double>& x, const std::vector<double>& y) {
  const size_t n = x.size();
  if (n < 3) return std::numeric_limits<double>::quiet_NaN();
  double mx = 0, my = 0;
  for (size_t i = 0; i < n; ++i) mx += x[i], my += y[i];
  mx /= n, my /= n;
  double sxy = 0, sxx = 0, syy = 0;
  for (size_t i = 0; i < n; ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
  }
  return sxx > 0 && syy > 0 ? sxy / std::sqrt(sxx * syy) : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

DatasetEvaluation aggregate(std::span<const ScenarioEvaluation> scenarios) {
  DatasetEvaluation d;
  d.scenarios = static_cast<int>(scenarios.size());
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  constexpr double kAbsent = -std::numeric_limits<double>::infinity();  // the scenario has no such value (not undefined)
  auto mean = [&](const std::string& key, const std::function<double(const ScenarioEvaluation&)>& get) {
    double sum = 0;
    int n = 0;
    for (const ScenarioEvaluation& s : scenarios) {
      const double v = get(s);
      if (std::isfinite(v)) sum += v, ++n;
      else if (v != kAbsent) ++d.undefined[key];
    }
    return n ? sum / n : kNaN;
  };
  // Realism means over the scenarios `get` gives a value for (null: the scenario lacks it, e.g. a short one's window).
  auto realism = [&](const std::string& prefix, const std::function<const RealismScores*(const ScenarioEvaluation&)>& get) {
    auto of = [&](const std::string& key, const std::function<double(const RealismScores&)>& value) {
      return mean(prefix + key, [&](const ScenarioEvaluation& s) {
        const RealismScores* r = get(s);
        return r ? value(*r) : kAbsent;
      });
    };
    RealismScores r;
    for (int f = 0; f < kNumRealismFeatures; ++f)
      r.likelihood[f] = of(std::string(wosac_2025_config()[f].name) + "_likelihood",
                           [f](const RealismScores& x) { return x.likelihood[f]; });
    r.meta = of("realism_meta", [](const RealismScores& x) { return x.meta; });
    r.kinematic = bucket_score(RealismBucket::kinematic, r.likelihood);
    r.interactive = bucket_score(RealismBucket::interactive, r.likelihood);
    r.map = bucket_score(RealismBucket::map, r.likelihood);
    r.collision_rate = of("collision_rate", [](const RealismScores& x) { return x.collision_rate; });
    r.offroad_rate = of("offroad_rate", [](const RealismScores& x) { return x.offroad_rate; });
    r.ade = of("ade", [](const RealismScores& x) { return x.ade; });
    r.min_ade = of("min_ade", [](const RealismScores& x) { return x.min_ade; });
    r.objects = 0;
    for (const ScenarioEvaluation& s : scenarios)
      if (const RealismScores* x = get(s)) r.objects += x->objects;
    return r;
  };
  d.realism = realism("", [](const ScenarioEvaluation& s) { return &s.realism; });
  size_t windows = 0;
  for (const ScenarioEvaluation& s : scenarios) windows = std::max(windows, s.windows.size());
  for (size_t w = 0; w < windows; ++w) {
    DatasetEvaluation::Window out;
    for (const ScenarioEvaluation& s : scenarios) out.scenarios += s.windows.size() > w;
    out.realism = realism(std::string("windows.") + realism_window_name(static_cast<int>(w)) + ".",
                          [w](const ScenarioEvaluation& s) { return s.windows.size() > w ? &s.windows[w] : nullptr; });
    d.windows.push_back(out);
  }

  auto motion = [&](const std::string& prefix, MotionMetrics ScenarioEvaluation::*group) {
    MotionMetrics m;
    m.ade_avg = mean(prefix + "ade_avg", [&](const auto& s) { return (s.*group).ade_avg; });
    m.ade_min = mean(prefix + "ade_min", [&](const auto& s) { return (s.*group).ade_min; });
    m.fde_avg = mean(prefix + "fde_avg", [&](const auto& s) { return (s.*group).fde_avg; });
    m.fde_min = mean(prefix + "fde_min", [&](const auto& s) { return (s.*group).fde_min; });
    m.add = mean(prefix + "add", [&](const auto& s) { return (s.*group).add; });
    m.fdd = mean(prefix + "fdd", [&](const auto& s) { return (s.*group).fdd; });
    for (const ScenarioEvaluation& s : scenarios) m.agents += (s.*group).agents;
    return m;
  };
  d.motion_all = motion("", &ScenarioEvaluation::motion_all);
  d.motion_predict = motion("tracks_to_predict.", &ScenarioEvaluation::motion_predict);

  std::vector<double> log_counts, generated_counts;  // full mode, per scenario with a log agent
  for (const ScenarioEvaluation& s : scenarios) {
    d.named_scenarios += s.named_by_scenario;
    d.evaluated_objects += s.evaluated;
    d.has_mmd = d.has_mmd || s.has_mmd;
    if (s.has_ego) {
      d.has_ego = true;
      EgoSummary& g = d.ego;
      g.episodes += s.ego.episodes, g.collided += s.ego.collided, g.rear_end += s.ego.rear_end;
      g.ego_at_fault += s.ego.ego_at_fault, g.side += s.ego.side, g.off_road += s.ego.off_road;
      g.background_collision_rate += s.ego.background_collision_rate;
    }
    d.to_match += s.to_match, d.matched += s.matched;
    d.match_distance += s.match_distance * s.matched;
    if (s.has_mmd) {
      for (auto [sum, add] :
           {std::pair{&d.placed_log, &s.placed_log}, std::pair{&d.placed_generated, &s.placed_generated}})
        *sum += *add;
      if (s.placed_log.agents > 0 && s.rollouts > 0) {
        ++d.placed_scenarios;
        const double generated = static_cast<double>(s.placed_generated.agents) / s.rollouts;
        d.placed_within_30 += std::abs(generated / s.placed_log.agents - 1) <= 0.3;
        log_counts.push_back(s.placed_log.agents);
        generated_counts.push_back(generated);
      }
    }
    for (int f = 0; f < kNumRealismFeatures; ++f) {
      auto& h = d.histograms[f];
      const auto& src = s.histograms[f];
      if (src.log.empty()) continue;
      h.log.resize(src.log.size(), 0.0), h.sim.resize(src.sim.size(), 0.0);
      for (size_t b = 0; b < src.log.size(); ++b) h.log[b] += src.log[b], h.sim[b] += src.sim[b];
    }
  }
  if (d.has_ego && !scenarios.empty()) d.ego.background_collision_rate /= static_cast<double>(scenarios.size());
  d.placed_count_correlation = pearson(log_counts, generated_counts);
  d.match_distance = d.matched ? d.match_distance / d.matched : 0.0;
  d.filled_share = mean("filled_share", [](const auto& s) { return s.filled_share; });
  if (d.has_mmd) {
    auto mmd = [&](const std::string& prefix, InitialStateMmd ScenarioEvaluation::*set) {
      return InitialStateMmd{mean(prefix + "position", [&](const auto& s) { return (s.*set).position; }),
                             mean(prefix + "heading", [&](const auto& s) { return (s.*set).heading; }),
                             mean(prefix + "size", [&](const auto& s) { return (s.*set).size; }),
                             mean(prefix + "velocity", [&](const auto& s) { return (s.*set).velocity; })};
    };
    d.mmd_strict = mmd("mmd.strict.", &ScenarioEvaluation::mmd_strict);
    d.mmd_relaxed = mmd("mmd.relaxed.", &ScenarioEvaluation::mmd_relaxed);
  }
  return d;
}

}  // namespace ss
