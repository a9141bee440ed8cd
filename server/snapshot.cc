#include "server/snapshot.h"

#include <algorithm>
#include <cstring>
#include <filesystem>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "server/session_id.h"

namespace ss::server {
namespace {

// The format's magic and version, refused with both versions named when they differ. SSSNAP01 had no checksum;
// SSSNAP02 kept the tick clock here (now the engine's state holds it).
constexpr char kMagicPrefix[] = "SSSNAP";
constexpr char kMagic[] = "SSSNAP03";
constexpr char kSuffix[] = ".snapshot";

void put_u64(std::string& out, uint64_t v) {
  char b[8];
  for (int i = 0; i < 8; ++i) b[i] = static_cast<char>((v >> (8 * i)) & 0xff);
  out.append(b, 8);
}
void put_str(std::string& out, const std::string& s) {
  put_u64(out, s.size());
  out += s;
}
uint64_t get_u64(const char* p) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= uint64_t(static_cast<unsigned char>(p[i])) << (8 * i);
  return v;
}

struct Reader {
  const std::string& in;
  size_t end;
  size_t pos = 0;
  bool u64(uint64_t* v) {
    if (end - pos < 8) return false;
    *v = get_u64(in.data() + pos);
    pos += 8;
    return true;
  }
  bool str(std::string* s) {
    uint64_t n;
    if (!u64(&n) || end - pos < n) return false;
    s->assign(in, pos, n);
    pos += n;
    return true;
  }
};

}  // namespace

absl::StatusOr<std::string> snapshot_path(const std::string& dir, const std::string& session_id) {
  if (auto st = check_session_id(session_id); !st.ok()) return st;
  return (std::filesystem::path(dir) / (session_id + kSuffix)).string();
}

absl::Status write_snapshot(const std::string& dir, const Snapshot& s) {
  auto path = snapshot_path(dir, s.session_id);
  if (!path.ok()) return path.status();
  std::string out(kMagic, 8);
  put_str(out, s.session_id);
  put_str(out, s.source.scenario_name);
  put_str(out, s.source.womd_bytes);
  put_u64(out, static_cast<uint64_t>(s.tick_deadline_ms));
  put_str(out, s.session_bytes);
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
  Reader r{in, in.size() - 8, 8};
  Snapshot s;
  uint64_t deadline;
  if (!r.str(&s.session_id) || !r.str(&s.source.scenario_name) || !r.str(&s.source.womd_bytes) ||
      !r.u64(&deadline) || !r.str(&s.session_bytes) || r.pos != r.end)
    return bad("fields truncated or trailing bytes");
  if (s.session_id != session_id)
    return bad(absl::StrCat("holds session ", echo_id(s.session_id), ", not the ", echo_id(session_id),
                            " its name says"));
  if (deadline > 3'600'000) return bad(absl::StrCat("tick_deadline_ms ", std::to_string(deadline)));
  s.tick_deadline_ms = static_cast<int>(deadline);
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
