#include "server/snapshot.h"

#include <algorithm>
#include <filesystem>

#include "absl/strings/str_cat.h"
#include "engine/io/file_io.h"
#include "server/session_id.h"
#include "state/snapshot.pb.h"

namespace ss::server {
namespace {

// The message's magic and version (its last two characters), refused with both versions named when they differ.
// SSSNAP01 had no checksum; SSSNAP02 kept the tick clock here (now the engine's state holds it); SSSNAP04 added the
// tenant and the controllers' credentials; SSSNAP05 is one protobuf message (proto/state/snapshot.proto) and holds
// an engine state of version 3. The file is the project's one framed record (engine/io/record.h); files in the
// layout before it (the magic, the message, an FNV-1a hash of both) are still read.
constexpr RecordFormat kFormat{"SSSNAP05", 2, "snapshot", "server", RecordFormat::Earlier::message_then_hash};
constexpr char kSuffix[] = ".snapshot";

}  // namespace

absl::StatusOr<std::string> snapshot_path(const std::string& dir, const std::string& session_id) {
  if (auto st = check_session_id(session_id); !st.ok()) return st;
  return (std::filesystem::path(dir) / (session_id + kSuffix)).string();
}

// --- encode_snapshot / decode_snapshot: the bytes alone, for the file and the session store ---
std::string encode_snapshot(const Snapshot& s) {
  state::Snapshot m;
  m.set_session_id(s.session_id);
  m.set_tenant(s.tenant);
  for (const auto& [agent, credential] : s.controllers) {
    state::Controller* c = m.add_controllers();
    c->set_agent_id(agent);
    c->set_credential(credential);
  }
  m.set_scenario_name(s.source.scenario_name);
  m.set_womd_bytes(s.source.womd_bytes);
  m.set_tick_deadline_ms(s.tick_deadline_ms);
  m.set_session_state(s.session_bytes);
  return record_write(kFormat, m.SerializeAsString());
}

absl::StatusOr<Snapshot> decode_snapshot(const std::string& bytes, const std::string& session_id,
                                         const std::string& where) {
  auto bad = [&](const std::string& what) { return absl::DataLossError(absl::StrCat(where, ": ", what)); };
  RecordFormat format = kFormat;
  format.what = where;
  auto message = record_read(format, bytes);
  if (!message.ok()) {
    if (message.status().code() == absl::StatusCode::kInvalidArgument)  // not a snapshot at all: its content is lost
      return absl::DataLossError(message.status().message());
    if (message.status().code() == absl::StatusCode::kFailedPrecondition)
      return absl::FailedPreconditionError(
          absl::StrCat(message.status().message(), "; the session cannot be restored by this version"));
    return message.status();
  }
  state::Snapshot m;
  if (!m.ParseFromArray(message->data(), static_cast<int>(message->size()))) return bad("the message does not parse");
  if (m.session_id() != session_id)
    return bad(absl::StrCat("holds session ", echo_id(m.session_id()), ", not the ", echo_id(session_id),
                            " its name says"));
  if (m.tick_deadline_ms() < 0 || m.tick_deadline_ms() > 3'600'000)
    return bad(absl::StrCat("tick_deadline_ms ", m.tick_deadline_ms()));
  Snapshot s;
  s.session_id = m.session_id();
  s.tenant = m.tenant();
  for (const state::Controller& c : m.controllers()) s.controllers.emplace_back(c.agent_id(), c.credential());
  s.source.scenario_name = m.scenario_name();
  s.source.womd_bytes = m.womd_bytes();
  s.tick_deadline_ms = m.tick_deadline_ms();
  s.session_bytes = m.session_state();
  return s;
}
// --- end of encode_snapshot / decode_snapshot ---

absl::Status write_snapshot(const std::string& dir, const Snapshot& s) {
  auto path = snapshot_path(dir, s.session_id);
  if (!path.ok()) return path.status();
  const std::string out = encode_snapshot(s);
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return absl::InternalError(absl::StrCat("snapshot directory ", dir, " cannot be created: ", ec.message()));
  return file_write_atomically(*path, out);
}

absl::StatusOr<Snapshot> read_snapshot(const std::string& dir, const std::string& session_id) {
  auto path = snapshot_path(dir, session_id);
  if (!path.ok()) return path.status();
  auto bytes = file_read_all(*path);
  if (!bytes.ok()) return absl::Status(bytes.status().code(), absl::StrCat("snapshot ", bytes.status().message()));
  return decode_snapshot(*bytes, session_id, absl::StrCat("snapshot ", *path));
}

std::vector<std::string> list_snapshots(const std::string& dir) {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec))
    if (e.path().extension() == kSuffix) out.push_back(e.path().stem().string());
  std::sort(out.begin(), out.end());
  return out;
}

void remove_snapshot(const std::string& dir, const std::string& session_id) {
  auto path = snapshot_path(dir, session_id);
  if (!path.ok()) return;
  std::error_code ec;
  std::filesystem::remove(*path, ec);
}

}  // namespace ss::server
