// Fuzzes the weight-file loader: no input may crash it or hang it, every error must be INVALID_ARGUMENT (or
// RESOURCE_EXHAUSTED) naming the source, and whatever it accepts must meet the contract and survive a round trip.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "engine/model/weights.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string where = "fuzz.safetensors";
  std::string_view bytes(reinterpret_cast<const char*>(data), size);
  auto w = ss::parse_weights(bytes, where);
  if (w.ok()) {
    // The loader promises exactly the configuration's tensors, right shapes, finite values.
    if (!ss::validate_weights(*w, where).ok()) __builtin_trap();
    if (w->tensors.size() != ss::model_parameter_specs(w->config).size()) __builtin_trap();
    // Our own serialization of what was accepted is accepted again and means the same.
    auto again = ss::parse_weights(ss::serialize_weights(*w), where);
    if (!again.ok() || !(*again == *w)) __builtin_trap();
  } else {
    const auto code = w.status().code();
    if (code != absl::StatusCode::kInvalidArgument && code != absl::StatusCode::kResourceExhausted) __builtin_trap();
    if (w.status().message().substr(0, where.size() + 2) != where + ": ") __builtin_trap();
  }
  return 0;
}
