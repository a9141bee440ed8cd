// Statistics of a set of scenarios, to put a generated dataset beside real WOMD data: agents per scenario by type,
// signal-controlled lanes per scenario, speeds by type, frames, and map features per scenario by kind.
#pragma once

#include <array>
#include <map>
#include <string>
#include <vector>

#include "engine/scenario/scenario.h"
#include "nlohmann/json.hpp"

namespace ss::dataset {

class ScenarioStats {
 public:
  void add(const Scenario& s);
  int scenarios() const { return scenarios_; }
  // {"scenarios", "frames": {min, max}, "agents_per_scenario": {type: {mean, p50, p90}}, "lights_per_scenario":
  //  {mean, p50, p90, with_lights}, "speed_mps": {type: {mean, p50, p90, samples}}, "map_features_per_scenario":
  //  {kind: mean}}
  nlohmann::ordered_json json() const;

 private:
  static constexpr int kTypes = 3;  // vehicle, pedestrian, cyclist
  int scenarios_ = 0;
  int min_frames_ = 0, max_frames_ = 0;
  std::array<std::vector<double>, kTypes> agents_;  // per scenario
  std::vector<double> lights_;                      // per scenario: distinct lanes with a signal state
  std::array<std::vector<float>, kTypes> speeds_;   // every valid state
  std::map<std::string, double> features_;          // total per kind
};

// Summary of `values`: mean, median and 90th percentile (nearest rank); zeros when empty.
nlohmann::ordered_json summary(std::vector<double> values);

// ScenarioStats::json() results side by side, one column per (name, stats) pair: aligned text, or a Markdown table.
std::string stats_table(const std::vector<std::pair<std::string, nlohmann::ordered_json>>& columns, bool markdown);

}  // namespace ss::dataset
