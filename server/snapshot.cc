#include "server/snapshot.h"

#include <cstring>
#include <filesystem>

#include "absl/strings/str_cat.h"

namespace ss::server {
namespace {

constexpr char kMagic[] = "SSSNAP01";
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

struct Reader {
  const std::string& in;
  size_t pos = 0;
  bool u64(uint64_t* v) {
    if (in.size() - pos < 8) return false;
    *v = 0;
    for (int i = 0; i < 8; ++i) *v |= uint64_t(static_cast<unsigned char>(in[pos + i])) << (8 * i);
    pos += 8;
    return true;
  }
  bool str(std::string* s) {
    uint64_t n;
    if (!u64(&n) || in.size() - pos < n) return false;
    s->assign(in, pos, n);
    pos += n;
    return true;
  }
};

}  // namespace

std::string snapshot_path(const std::string& dir, const std::string& session_id) {
  return (std::filesystem::path(dir) / (session_id + kSuffix)).string();
}

absl::Status write_snapshot(const std::string& dir, const Snapshot& s) {
  std::string out(kMagic, 8);
  put_str(out, s.session_id);
  put_str(out, s.source.scenario_name);
  put_str(out, s.source.womd_bytes);
  put_u64(out, static_cast<uint64_t>(s.tick_hz));
  put_u64(out, static_cast<uint64_t>(s.tick_deadline_ms));
  put_u64(out, static_cast<uint64_t>(s.tick));
  put_str(out, s.session_bytes);
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return absl::InternalError(absl::StrCat("snapshot directory ", dir, " cannot be created: ", ec.message()));
  return file_write_atomically(snapshot_path(dir, s.session_id), out);
}

absl::StatusOr<Snapshot> read_snapshot(const std::string& path) {
  auto bytes = file_read_all(path);
  if (!bytes.ok()) return absl::Status(bytes.status().code(), absl::StrCat("snapshot ", bytes.status().message()));
  const std::string& in = *bytes;
  if (in.size() < 8 || std::memcmp(in.data(), kMagic, 8) != 0)
    return absl::InvalidArgumentError(absl::StrCat("snapshot ", path, ": not a snapshot file (bad magic)"));
  Reader r{in, 8};
  Snapshot s;
  uint64_t hz, deadline, tick;
  if (!r.str(&s.session_id) || !r.str(&s.source.scenario_name) || !r.str(&s.source.womd_bytes) || !r.u64(&hz) ||
      !r.u64(&deadline) || !r.u64(&tick) || !r.str(&s.session_bytes) || r.pos != in.size())
    return absl::InvalidArgumentError(absl::StrCat("snapshot ", path, ": truncated or trailing bytes"));
  s.tick_hz = static_cast<int>(hz);
  s.tick_deadline_ms = static_cast<int>(deadline);
  s.tick = static_cast<int64_t>(tick);
  return s;
}

std::vector<std::string> list_snapshots(const std::string& dir) {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec))
    if (e.path().extension() == kSuffix) out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace ss::server
