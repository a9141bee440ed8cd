// What `scenestreamer inspect` reports about a scenario, as JSON (the text table is printed from the same object).
#pragma once

#include "engine/scenario/scenario.h"
#include "engine/tokens/fidelity.h"
#include "nlohmann/json.hpp"

namespace ss::cli {

struct ScenarioReport {
  nlohmann::ordered_json json;       // scenario_id, tracks, map_features, segments, lights, and the fidelity keys
  TokenizationFidelity fidelity;     // kept to summarise several scenarios
};

ScenarioReport report_scenario(const Scenario& s);
// The fidelity keys (motion_ace_*, state_roundtrip_*) of a fidelity measurement.
nlohmann::ordered_json fidelity_json(const TokenizationFidelity& f);
// A readable table of one report's JSON.
void print_report(const nlohmann::ordered_json& j);

}  // namespace ss::cli
