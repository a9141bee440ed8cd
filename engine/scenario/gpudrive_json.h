// Reader for the GPUDrive / Nocturne JSON scenario format (see ../shared/data/womd/README.md for its variants).
#pragma once

#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "engine/scenario/scenario.h"

namespace ss {

// Parses one scenario from JSON text. `where` names the source (the file name) in error messages.
// The result is validated (validate.h).
absl::StatusOr<Scenario> scenario_from_gpudrive_json(std::string_view text, const std::string& where);

}  // namespace ss
