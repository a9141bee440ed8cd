#include "server/snapshot.h"

#include <sys/stat.h>

#include <algorithm>
#include <filesystem>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "engine/io/file_io.h"
#include "server/auth.h"
#include "server/session_id.h"
#include "spdlog/spdlog.h"
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
constexpr char kQuarantine[] = "quarantine";
namespace fs = std::filesystem;

// The directory, made 0700 (only the server's user may list it) when it is missing.
absl::Status make_dir(const std::string& dir) {
  std::error_code ec;
  if (fs::is_directory(dir, ec)) return absl::OkStatus();
  if (fs::exists(dir, ec)) return absl::FailedPreconditionError(absl::StrCat(dir, " exists and is not a directory"));
  fs::create_directories(dir, ec);
  if (ec) return absl::InternalError(absl::StrCat(dir, " cannot be created: ", ec.message()));
  fs::permissions(dir, fs::perms::owner_all, fs::perm_options::replace, ec);
  if (ec) return absl::InternalError(absl::StrCat(dir, ": cannot set its mode to 0700: ", ec.message()));
  return absl::OkStatus();
}

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
    c->set_credential_sha256(credential);
  }
  m.set_scenario_name(s.source.scenario_name);
  m.set_womd_bytes(s.source.womd_bytes);
  m.set_tick_deadline_ms(s.tick_deadline_ms);
  m.set_session_state(s.session_bytes);
  return record_write(kFormat, m.SerializeAsString());
}

absl::Status prepare_snapshot_dir(const std::string& dir) {
  const std::string flag = absl::StrCat("--snapshot_dir ", dir);
  if (auto st = make_dir(dir); !st.ok()) return absl::Status(st.code(), absl::StrCat(flag, ": ", st.message()));
  const std::string probe = (fs::path(dir) / ".write-probe").string();
  if (auto st = file_write_atomically(probe, "probe", 0600); !st.ok())
    return absl::Status(st.code(), absl::StrCat(flag, " cannot be written: ", st.message()));
  std::error_code ec;
  fs::remove(probe, ec);
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (absl::StrContains(name, absl::StrCat(kSuffix, ".tmp."))) {  // file_write_atomically's temporary files
      std::error_code rm;
      fs::remove(e.path(), rm);
      spdlog::info("snapshot directory: removed {}, left mid-write by a crash{}", name,
                   rm ? absl::StrCat(" (failed: ", rm.message(), ")") : "");
    }
  }
  struct stat sb;
  if (::stat(dir.c_str(), &sb) == 0 && (sb.st_mode & 077) != 0)
    spdlog::warn("{} may be listed by other users (mode {:o}): chmod 700 it (the files in it are 0600)", flag,
                 sb.st_mode & 0777);
  return absl::OkStatus();
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
  // Servers before credential_sha256 wrote the credential itself: it is kept as its digest from here on.
  for (const state::Controller& c : m.controllers())
    s.controllers.emplace_back(c.agent_id(),
                               c.credential_sha256().empty() ? secret_digest(c.credential()) : c.credential_sha256());
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
  if (auto st = make_dir(dir); !st.ok()) return absl::Status(st.code(), absl::StrCat("snapshot directory ", st.message()));
  return file_write_atomically(*path, out, 0600);
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

absl::StatusOr<std::string> quarantine_snapshot(const std::string& dir, const std::string& session_id) {
  auto path = snapshot_path(dir, session_id);
  if (!path.ok()) return path.status();
  const std::string qdir = (fs::path(dir) / kQuarantine).string();
  if (auto st = make_dir(qdir); !st.ok()) return st;
  const std::string to = (fs::path(qdir) / fs::path(*path).filename()).string();
  std::error_code ec;
  fs::rename(*path, to, ec);
  if (ec) return absl::InternalError(absl::StrCat(*path, " cannot be moved to ", to, ": ", ec.message()));
  return to;
}

}  // namespace ss::server
