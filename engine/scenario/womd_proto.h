// Conversion between WOMD Scenario protos (wire bytes) and ss::Scenario. Lossless both ways for everything
// scenario.h holds; what WOMD has and scenario.h does not (unknown fields, which optional fields were present) is
// not kept.
#pragma once

#include <climits>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "engine/scenario/scenario.h"

namespace ss {

// Limits on what a decoded scenario may hold, checked on the wire bytes before anything is built: decoding costs
// tens of bytes of memory per element, and an element costs as little as 2 bytes on the wire (an empty state or
// point), so a 36 MB request could take gigabytes to be refused after. A real WOMD scenario holds at most 257
// tracks, 301 map features, 19,628 map points and 91 frames (the 50 records of data/womd, counted on the wire).
struct WomdLimits {
  int max_tracks = INT_MAX;        // tracks (and tracks_to_predict)
  int max_map_features = INT_MAX;  // map features (and lane states in one frame: each names a lane)
  int max_frames = INT_MAX;        // timestamps, states of one track, dynamic map states
  int max_map_points = INT_MAX;    // points, polygons' corners, lane boundaries and neighbours of all map features
};

// Decodes one serialized waymo.open_dataset.Scenario: `limits` are checked on the wire first (RESOURCE_EXHAUSTED
// naming the count and the limit), then the wire bytes are checked (wire_check.h), so a field of the wrong wire type,
// an unknown enum value or bad UTF-8 is an error rather than silently dropped; then the scenario is converted and
// validated (validate.h). Errors start with `where` (e.g. "x.tfrecord record 2").
absl::StatusOr<Scenario> scenario_from_womd_bytes(std::string_view bytes, const std::string& where,
                                                  const WomdLimits& limits = {});

// Encodes a scenario as a serialized waymo.open_dataset.Scenario, laid out as real WOMD files are (a real record
// re-encodes to the same bytes). Deterministic: equal scenarios give equal bytes; for a scenario that
// check_womd_representable accepts, bytes also differ when any value differs bit for bit. Parts WOMD cannot hold are
// left out, and enum values outside their WOMD enum are written as they are, so reading them back is an error.
std::string scenario_to_womd_bytes(const Scenario& s);

// OK when scenario_to_womd_bytes keeps everything in `s`; otherwise INVALID_ARGUMENT naming the part it would drop:
// more than one stop-sign point, lane data on a feature that is not a lane, stop-sign lanes on a feature that is not
// a stop sign, a subtype on a kind without one, an unknown kind, a stop point with has_stop_point false.
absl::Status check_womd_representable(const Scenario& s, const std::string& where);

// check_womd_representable, then scenario_to_womd_bytes, refusing a record too large for a TFRecord or protobuf.
absl::StatusOr<std::string> encode_womd_scenario(const Scenario& s, const std::string& where);

}  // namespace ss
