// Fuzzes the GPUDrive / Nocturne JSON reader: no input may crash it, hang it or make it return an unvalidated
// scenario; every error must be INVALID_ARGUMENT (or RESOURCE_EXHAUSTED) and name the source.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "engine/scenario/gpudrive_json.h"
#include "engine/scenario/validate.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string where = "fuzz.json";
  std::string_view text(reinterpret_cast<const char*>(data), size);
  auto s = ss::scenario_from_gpudrive_json(text, where);
  if (s.ok()) {
    // The reader promises a validated scenario with the fixed WOMD frame layout.
    if (!ss::validate_scenario(*s, where).ok()) __builtin_trap();
    if (s->current_time_index != 10 || s->num_frames() < 11) __builtin_trap();
    if (!s->signals.empty() && static_cast<int>(s->signals.size()) != s->num_frames()) __builtin_trap();
  } else {
    const auto code = s.status().code();
    if (code != absl::StatusCode::kInvalidArgument && code != absl::StatusCode::kResourceExhausted) __builtin_trap();
    if (s.status().message().substr(0, where.size() + 2) != where + ": ") __builtin_trap();
  }
  return 0;
}
