#include "server/snapshot.h"

#include <algorithm>
#include <cstring>
#include <filesystem>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "server/session_id.h"
#include "state/snapshot.pb.h"

namespace ss::server {
namespace {

// The format's magic and version, refused with both versions named when they differ. SSSNAP01 had no checksum;
// SSSNAP02 kept the tick clock here (now the engine's state holds it); SSSNAP04 added the tenant and the
// controllers' credentials; SSSNAP05 is one protobuf message (proto/state/snapshot.proto) and holds an engine state
// of version 3 (older files could not be restored by this engine anyway).
constexpr char kMagicPrefix[] = "SSSNAP";
constexpr char kMagic[] = "SSSNAP05";
constexpr char kSuffix[] = ".snapshot";

void put_u64(std::string& out, uint64_t v) {
  for (int i = 0; i < 8; ++i) out += static_cast<char>((v >> (8 * i)) & 0xff);
}
uint64_t get_u64(const char* p) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= uint64_t(static_cast<unsigned char>(p[i])) << (8 * i);
  return v;
}

}  // namespace

absl::StatusOr<std::string> snapshot_path(const std::string& dir, const std::string& session_id) {
  if (auto st = check_session_id(session_id); !st.ok()) return st;
  return (std::filesystem::path(dir) / (session_id + kSuffix)).string();
}

absl::Status write_snapshot(const std::string& dir, const Snapshot& s) {
  auto path = snapshot_path(dir, s.session_id);
  if (!path.ok()) return path.status();
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
  std::string out(kMagic, 8);
  m.AppendToString(&out);
  put_u64(out, fnv1a64(out));
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
  const std::string& in = *bytes;
  auto bad = [&](const std::string& what) { return absl::DataLossError(absl::StrCat("snapshot ", *path, ": ", what)); };
  if (in.size() < 8 || std::memcmp(in.data(), kMagicPrefix, 6) != 0)
    return bad("not a snapshot file (no SSSNAP magic)");
  if (std::memcmp(in.data(), kMagic, 8) != 0)
    return absl::FailedPreconditionError(absl::StrCat("snapshot ", *path, ": format ", in.substr(0, 8),
                                                      " is not this server's ", kMagic,
                                                      "; the session cannot be restored by this version"));
  if (in.size() < 16) return bad("truncated (no checksum)");
  const uint64_t stored = get_u64(in.data() + in.size() - 8);
  const uint64_t actual = fnv1a64(std::string_view(in.data(), in.size() - 8));
  if (stored != actual)
    return bad(absl::StrFormat("checksum mismatch (the file says %016x, its %d bytes hash to %016x): the file is "
                               "corrupt", stored, in.size() - 8, actual));
  state::Snapshot m;
  if (!m.ParseFromArray(in.data() + 8, static_cast<int>(in.size() - 16))) return bad("the message does not parse");
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
