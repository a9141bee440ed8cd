// The world the step benchmarks run on: a real WOMD scenario, the model (random weights unless a file is given), and
// sessions holding exactly N agents and 16 lights. Shared by `scenestreamer bench` and bench/step_bench.
#pragma once

#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "engine/offline.h"

namespace ss {

struct BenchWorld {
  std::shared_ptr<const Model> model;
  std::shared_ptr<const Scenario> scenario;
  std::shared_ptr<const MapContext> map;
};

inline constexpr const char* kBenchScenario = "../shared/data/womd/tfrecord/motion_data_one_scenario.tfrecord";

// `model`: a weight file, or "small"/"large" for random weights (seed 1). The scenario's lights are topped up to
// `lights` by giving signals (a fixed green-yellow-red cycle, stop point at the lane's end) to the unsignalled lanes
// nearest the SDC: the goal is stated for 16 lights, and the real scenario has 12. `options`: the precisions and step
// threads (its model fields are set from `model`).
absl::StatusOr<BenchWorld> make_bench_world(const std::string& scenario_path, const std::string& model, int lights = 16,
                                            EngineOptions options = {});

// A densify session with exactly `agents` agents at creation; its region covers the whole map, so nobody leaves and
// the count stays at `agents` (new agents fill any gap up to the cap).
absl::StatusOr<std::unique_ptr<Session>> bench_session(const BenchWorld& w, int agents, uint64_t seed,
                                                       Session::Probe* probe = nullptr, bool motion_reject = true);

// The decoder batches of a 64-agent (or `agents`) rollout up to `step`, split into those before the step and those of
// the step: the incremental path decodes only the latter over a cache of the former; a full recompute decodes all.
struct HistoryBatches {
  std::vector<std::vector<DecoderToken>> before, at;
};
absl::StatusOr<HistoryBatches> history_batches(const BenchWorld& w, int agents, int step);

}  // namespace ss
