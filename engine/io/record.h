// The project's one framed record, for every state it writes to read back: a session's state (session_save) and a
// server's snapshot file. A record is one TFRecord record (engine/scenario/tfrecord.h: the length, a CRC-32C of the
// length, the data, a CRC-32C of the data) whose data is an 8-character magic followed by a protobuf message; the magic
// names the message's format and its last characters the version.
//
// Why TFRecord's framing rather than a magic and an FNV-1a hash (what the two states had, each its own way): the
// project reads it anyway (WOMD ships in it; the reader is fuzzed), its length finds a cut before the message is
// parsed (a protobuf message cut at a field boundary still parses), CRC-32C detects every burst error up to 32 bits,
// which FNV-1a does not promise, and any TFRecord reader (tf.data, the tests' Python helper) opens a saved state.
//
// The layouts before this one began with the magic (then the hash and the message, or the message and the hash).
// They are still read, checked against their hash, so snapshot files written by earlier versions restore.
#pragma once

#include <string>
#include <string_view>

#include "absl/status/statusor.h"

namespace ss {

struct RecordFormat {
  enum class Earlier { hash_then_message, message_then_hash };
  std::string_view magic;         // 8 characters: the format's name, then its version
  int version_chars = 1;          // how many of the magic's last characters are the version
  std::string_view what;          // what errors call a record: "session state", "snapshot"
  std::string_view reader;        // what errors call the reading side: "engine", "server"
  Earlier earlier = Earlier::hash_then_message;  // the layout before the framing
};

// The record of `message` in format `f`.
std::string record_write(const RecordFormat& f, std::string_view message);

// The message of a record in format `f`:
// - DATA_LOSS ("checksum mismatch ...") when the bytes are cut or a checksum fails;
// - FAILED_PRECONDITION for another version of the format, naming both ("format X is not this engine's Y");
// - INVALID_ARGUMENT for bytes that are not a record of the format at all.
absl::StatusOr<std::string> record_read(const RecordFormat& f, std::string_view bytes);

}  // namespace ss
