// Checks a scenario for what the model cannot use: non-finite numbers, inconsistent lengths, indices out of range.
#pragma once

#include <string>

#include "absl/status/status.h"
#include "engine/scenario/scenario.h"

namespace ss {

// OK, or INVALID_ARGUMENT with a message that starts with `where` (file and record) and names the field, e.g.
// "a.tfrecord record 3: tracks[12] (id 512) states[40].center_x is NaN".
absl::Status validate_scenario(const Scenario& s, const std::string& where);

}  // namespace ss
