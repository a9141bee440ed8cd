// Validates protobuf wire bytes against a message descriptor before libprotobuf parses them.
// Why: libprotobuf silently moves a field whose wire type does not match the schema (and, in proto2, an enum value
// it does not know) into the unknown fields, and proto2 does not check that strings are UTF-8; a reader that relied
// on it alone would lose data without a word. This walk finds those cases and names the field.
#pragma once

#include <string>
#include <string_view>

#include "absl/status/status.h"

namespace google::protobuf {
class Descriptor;
}  // namespace google::protobuf

namespace ss {

// Nested messages (and groups) deeper than this are rejected, so hostile input cannot exhaust the stack.
inline constexpr int kMaxWireDepth = 64;

// OK, or INVALID_ARGUMENT "<where>: <path>: <problem> (byte offset N)" where path names the field with indices, e.g.
// "x.tfrecord record 2: Scenario.tracks[3].states[7].center_x: wire type 0 (varint), expected 1 (64-bit) for double
// (byte offset 1234)"; the offset counts from the start of `bytes`.
// Checked: tags, varint and length bounds, each known field's wire type against its declared type (repeated scalars
// packed or not), int32/uint32/bool ranges, proto2 enum values against the enum, UTF-8 in string fields, two members
// of one oneof in the same message, and the nesting depth. Unknown field numbers are skipped (the spec says so, and
// real WOMD files hold an undocumented field 3).
absl::Status check_wire(std::string_view bytes, const google::protobuf::Descriptor& d, const std::string& where);

// Whether `s` is well-formed UTF-8 (no overlong forms, no surrogates, nothing above U+10FFFF).
bool is_valid_utf8(std::string_view s);

}  // namespace ss
