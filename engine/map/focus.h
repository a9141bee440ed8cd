// Where a scenario is "centred": the point map segments are kept nearest to (the paper keeps the 3000 segments
// nearest the self-driving car).
#pragma once

#include "engine/geometry/geometry.h"
#include "engine/scenario/scenario.h"

namespace ss {

// The SDC's position at the current frame when the scenario names a valid SDC; otherwise the mean position of the
// agents valid at the current frame (older JSON files name no SDC); otherwise the mean of all map points; else 0.
Vec2 scenario_focus(const Scenario& s);

}  // namespace ss
