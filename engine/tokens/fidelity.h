// How faithfully the tokenizers encode a scenario: the motion tokens' reconstruction error (ACE) and the agent-state
// tokens' round-trip error. Used by `scenestreamer inspect` and to validate generated datasets.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "engine/map/segments.h"
#include "engine/map/spatial_index.h"
#include "engine/scenario/scenario.h"
#include "engine/tokens/agent_state.h"

namespace ss {

// A running mean and maximum.
struct ErrorStats {
  double sum = 0;
  double max = 0;
  int64_t count = 0;

  void add(double e);
  void merge(const ErrorStats& o);
  double mean() const { return count ? sum / count : 0.0; }
};

inline constexpr int kNumModelTypes = 3;  // vehicle, pedestrian, cyclist: the agent types the model knows
// 0 vehicle, 1 pedestrian, 2 cyclist; -1 for unset and other (not modelled).
int model_type(ObjectType t);
// The inverse: the scenario type of model type 0, 1 or 2 (anything else reads as a vehicle).
ObjectType object_type_of(int model_type);
const char* model_type_name(int model_type);

struct TokenizationFidelity {
  // Motion: ACE at every valid 2 Hz step reached by a motion token (START steps reproduce the truth and are left out).
  ErrorStats ace;
  std::array<ErrorStats, kNumModelTypes> ace_by_type;
  std::vector<ErrorStats> ace_by_step;  // indexed by 2 Hz step
  ErrorStats ace_last_step;             // each tokenized agent's last reached step: shows drift
  // Agent state: per field, |value - value of its bin| over every valid agent step with an anchor.
  std::array<ErrorStats, kStateFields> state_error;           // everything, out-of-range values included
  std::array<ErrorStats, kStateFields> state_error_in_range;  // values inside the field's range: quantisation only
  std::array<int64_t, kStateFields> state_out_of_range{};     // values clipped to the range
  ErrorStats state_position_error;      // global distance between the agent and its decoded state, metres
  int64_t state_samples = 0;
  int64_t state_without_anchor = 0;     // agent steps with no segment within 90 degrees of heading

  void merge(const TokenizationFidelity& o);
};

// Tokenizes every vehicle, pedestrian and cyclist track of `s` at 2 Hz and measures both tokenizers.
// `index` is built over `segments`.
TokenizationFidelity measure_tokenization(const Scenario& s, std::span<const MapSegment> segments,
                                          const SegmentIndex& index);

}  // namespace ss
