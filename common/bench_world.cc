#include "common/bench_world.h"

#include <algorithm>
#include <set>

#include "absl/strings/str_cat.h"
#include "engine/map/focus.h"

namespace ss {

absl::StatusOr<BenchWorld> make_bench_world(const std::string& scenario_path, const std::string& model, int lights,
                                            EngineOptions options) {
  BenchWorld w;
  if (model == "small" || model == "large") {
    options.random_config = model;
    options.random_seed = 1;
  } else {
    options.model_path = model;
  }
  auto m = model_load(options);
  if (!m.ok()) return m.status();
  w.model = *m;

  auto scenarios = read_scenarios(scenario_path);
  if (!scenarios.ok()) return scenarios.status();
  Scenario s = (*scenarios)[0];
  std::set<int64_t> signalled;
  for (const auto& frame : s.signals)
    for (const SignalLaneState& l : frame) signalled.insert(l.lane);
  const Vec2 focus = scenario_focus(s);
  std::vector<std::pair<double, const MapFeature*>> lanes;
  for (const MapFeature& f : s.map_features)
    if (f.kind == MapFeatureKind::lane && !signalled.count(f.id) && f.points.size() >= 2)
      lanes.push_back({distance(focus, {f.points.back().x, f.points.back().y}), &f});
  std::sort(lanes.begin(), lanes.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  if (s.signals.empty()) s.signals.resize(s.num_frames());
  const int missing = std::max(0, lights - static_cast<int>(signalled.size()));
  for (int k = 0; k < missing && k < static_cast<int>(lanes.size()); ++k)
    for (int f = 0; f < s.num_frames(); ++f) {
      const SignalState state = f < 40 ? SignalState::go : f < 50 ? SignalState::caution : SignalState::stop;
      s.signals[f].push_back({lanes[k].second->id, state, lanes[k].second->points.back(), true});
    }
  w.scenario = std::make_shared<const Scenario>(std::move(s));
  MapCache maps(w.model);
  auto map = maps.get(*w.scenario);
  if (!map.ok()) return map.status();
  w.map = *map;
  return w;
}

absl::StatusOr<std::unique_ptr<Session>> bench_session(const BenchWorld& w, int agents, uint64_t seed,
                                                       Session::Probe* probe, bool motion_reject) {
  SessionOptions o;
  o.motion_reject = motion_reject;
  o.mode = SessionMode::densify;
  o.seed = seed;
  o.max_agents = agents;
  o.densify_target = agents;
  o.roi_radius = 1e5;
  auto s = Session::create(w.model, w.scenario, w.map, o, probe);
  if (!s.ok()) return s.status();
  const size_t have = (*s)->current().agents.size();
  if (have != static_cast<size_t>(agents))
    return absl::InternalError(absl::StrCat("bench session holds ", have, " agents, not ", agents));
  return s;
}

absl::StatusOr<HistoryBatches> history_batches(const BenchWorld& w, int agents, int step) {
  Session::Probe probe;
  auto s = bench_session(w, agents, 1, &probe);
  if (!s.ok()) return s.status();
  while ((*s)->step_index() < step)
    if (auto r = (*s)->step({}); !r.ok()) return r.status();
  HistoryBatches h;
  for (auto& b : probe.batches) (b.front().step < step ? h.before : h.at).push_back(std::move(b));
  return h;
}

}  // namespace ss
