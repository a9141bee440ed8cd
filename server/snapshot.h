// A session's snapshot file: what the server adds around Session::save() bytes (the scenario source, the
// multi-client tick deadline, the tenant and the controllers), so a restarted or evicted session continues exactly
// where it was. The file is named after the session id (checked against the id rule, never taken from inside a
// file), is the project's one framed record (engine/io/record.h: a cut or a flipped bit is refused, not restored),
// and is written through a temporary file renamed into place, so a crash never leaves half a snapshot. Files are 0600
// in a directory the server makes 0700, and hold the controllers' credentials as SHA-256 digests only.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/scenestreamer.h"

namespace ss::server {

struct Snapshot {
  std::string session_id;
  std::string tenant;                                  // the owner ("" without --tokens_file)
  std::vector<std::pair<int64_t, std::string>> controllers;  // agent -> its controller credential's SHA-256
  SessionSource source;
  int tick_deadline_ms = 0;
  std::string session_bytes;  // Session::save(): the engine's state, its tick clock included
};

// The snapshot's bytes, as the file holds them and the shared session store (server/session_store.h) too.
std::string encode_snapshot(const Snapshot& s);
// The snapshot of `session_id` from its bytes; `where` names their place in errors (DATA_LOSS for corrupt bytes,
// FAILED_PRECONDITION for another format version).
absl::StatusOr<Snapshot> decode_snapshot(const std::string& bytes, const std::string& session_id,
                                         const std::string& where);

// INVALID_ARGUMENT for an id that breaks the session id rule (so no id names a file outside `dir`).
absl::StatusOr<std::string> snapshot_path(const std::string& dir, const std::string& session_id);
// Makes `dir` ready at startup, or says why it cannot be used (the server then refuses to start): created 0700 if
// missing, a directory, writable (a probe file is written and removed); temporary files a crash left mid-write are
// removed (the snapshot they were replacing is intact beside them). A directory others may read is warned about.
absl::Status prepare_snapshot_dir(const std::string& dir);
// The one way a snapshot reaches its destination (the directory; every save goes through here).
absl::Status write_snapshot(const std::string& dir, const Snapshot& s);
// The snapshot of `session_id` in `dir`; DATA_LOSS naming what is wrong for a corrupt file, FAILED_PRECONDITION for
// one of another format version.
absl::StatusOr<Snapshot> read_snapshot(const std::string& dir, const std::string& session_id);
// The session ids of every snapshot file in `dir`, sorted.
std::vector<std::string> list_snapshots(const std::string& dir);
void remove_snapshot(const std::string& dir, const std::string& session_id);
// Moves the snapshot of `session_id` into `dir`/quarantine (a corrupt file: kept for a look, never read again);
// the path it went to.
absl::StatusOr<std::string> quarantine_snapshot(const std::string& dir, const std::string& session_id);

}  // namespace ss::server
