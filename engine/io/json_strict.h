// The one way the project reads JSON it did not write itself (weight headers, GPUDrive scenarios, submissions,
// eval results): strict RFC 8259 into an nlohmann::json DOM, built from nlohmann's SAX events so that
// - a key given twice in one object is an error (a DOM parser keeps one of them silently: a duplicated tensor or
//   field would hide),
// - nesting and array lengths stay within the caller's limits (hostile input cannot build deep trees), and
// - every error names the JSON path where it was found, e.g. objects[3].position[12].x: invalid JSON: ...
// NaN and infinities are not JSON: nlohmann refuses the NaN / Infinity tokens and numbers that overflow a double as
// syntax errors, which then name the field. The writer side is json_text.h.
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "nlohmann/json.hpp"

namespace ss {

struct JsonLimits {
  size_t max_depth = 32;  // levels of objects and arrays
  size_t max_array_length = std::numeric_limits<size_t>::max();
};

// The document in `text`. INVALID_ARGUMENT with the path and the reason for anything that is not strict JSON or
// breaks the limits; RESOURCE_EXHAUSTED when the machine has no memory for it. Messages do not name the source:
// callers prefix their file name.
absl::StatusOr<nlohmann::json> json_parse_strict(std::string_view text, const JsonLimits& limits = {});

// A string from the input made safe to quote in a message: control bytes (and, when asked, every non-ASCII byte)
// become \xNN; more than 64 bytes are cut at a character boundary, with "...".
std::string json_printable(std::string_view s, bool escape_non_ascii = false);

// Appends `key` to a JSON path the way the messages write it: .key for an identifier, ["key"] otherwise.
void json_append_key(std::string& path, std::string_view key);

}  // namespace ss
