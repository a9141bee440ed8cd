// A session's snapshot file: what the server adds around Session::save() bytes (the scenario source, the tick
// clock), so a restarted or evicted session continues exactly where it was. Written through a temporary file renamed
// into place, so a crash never leaves half a snapshot.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/scenestreamer.h"

namespace ss::server {

struct Snapshot {
  std::string session_id;
  SessionSource source;
  int tick_hz = 2;
  int tick_deadline_ms = 0;
  int64_t tick = 0;
  std::string session_bytes;  // Session::save()
};

std::string snapshot_path(const std::string& dir, const std::string& session_id);
absl::Status write_snapshot(const std::string& dir, const Snapshot& s);
absl::StatusOr<Snapshot> read_snapshot(const std::string& path);
// Every snapshot file in `dir` (paths).
std::vector<std::string> list_snapshots(const std::string& dir);

}  // namespace ss::server
