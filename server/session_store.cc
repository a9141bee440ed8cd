#include "server/session_store.h"

#include <hiredis/hiredis.h>

#include <charconv>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "server/session_id.h"

namespace ss::server {
namespace {

// The connect and reply timeout: a store that does not answer within it is unreachable for this call.
constexpr int kTimeoutMs = 2000;

// Every script takes KEYS lease, epoch, want, snap, tenant and ARGV[1] = replica id, ARGV[2] = lease ms,
// ARGV[3] = retain ms.
// "Mine" is the one ownership rule: the lease names me with my epoch, or it lapsed and the epoch is still mine.
constexpr char kMine[] = R"(
local function mine(lease, epoch, me, e)
  local owner = redis.call('GET', lease)
  return (owner == me or not owner) and redis.call('GET', epoch) == e, owner
end
)";

constexpr char kCreate[] = R"(
if redis.call('EXISTS', KEYS[4]) == 1 or redis.call('EXISTS', KEYS[1]) == 1 then return {'exists'} end
local e = redis.call('INCR', KEYS[2])
redis.call('PEXPIRE', KEYS[2], ARGV[3])
redis.call('SET', KEYS[1], ARGV[1], 'PX', ARGV[2])
redis.call('SET', KEYS[4], ARGV[5], 'PX', ARGV[3])
redis.call('SET', KEYS[5], ARGV[4], 'PX', ARGV[3])
return {'ok', e}
)";

// ARGV[4] the caller's tenant: another tenant's session is as unknown as a missing one, and is not asked for. A
// lease held by another replica is asked for (want) and named; a free one, or one naming this replica (its process
// restarted), is taken with a new epoch.
constexpr char kAcquire[] = R"(
if redis.call('GET', KEYS[5]) ~= ARGV[4] then return {'unknown'} end
local owner = redis.call('GET', KEYS[1])
if owner and owner ~= ARGV[1] then
  redis.call('SET', KEYS[3], ARGV[1], 'PX', ARGV[2])
  return {'held', owner, redis.call('PTTL', KEYS[1])}
end
local snap = redis.call('GET', KEYS[4])
if not snap then return {'unknown'} end
local e = redis.call('INCR', KEYS[2])
redis.call('PEXPIRE', KEYS[2], ARGV[3])
redis.call('PEXPIRE', KEYS[4], ARGV[3])
redis.call('PEXPIRE', KEYS[5], ARGV[3])
redis.call('SET', KEYS[1], ARGV[1], 'PX', ARGV[2])
if redis.call('GET', KEYS[3]) == ARGV[1] then redis.call('DEL', KEYS[3]) end
return {'taken', e, snap}
)";

// ARGV[4] epoch, ARGV[5] snapshot, ARGV[6] '1' to release.
constexpr char kPut[] = R"(
local ok, owner = mine(KEYS[1], KEYS[2], ARGV[1], ARGV[4])
if not ok then return {'lost', owner or ''} end
redis.call('SET', KEYS[4], ARGV[5], 'PX', ARGV[3])
redis.call('PEXPIRE', KEYS[2], ARGV[3])
redis.call('PEXPIRE', KEYS[5], ARGV[3])
if ARGV[6] == '1' then redis.call('DEL', KEYS[1]) else redis.call('SET', KEYS[1], ARGV[1], 'PX', ARGV[2]) end
return {'ok'}
)";

constexpr char kRelease[] = R"(
local ok, owner = mine(KEYS[1], KEYS[2], ARGV[1], ARGV[4])
if not ok then return {'lost', owner or ''} end
redis.call('DEL', KEYS[1])
return {'ok'}
)";

constexpr char kRemove[] = R"(
local ok, owner = mine(KEYS[1], KEYS[2], ARGV[1], ARGV[4])
if not ok then return {'lost', owner or ''} end
redis.call('DEL', KEYS[1], KEYS[2], KEYS[3], KEYS[4], KEYS[5])
return {'ok'}
)";

// Five keys per session; ARGV[3 + i] the epoch of the i-th.
constexpr char kRenew[] = R"(
local out = {}
for i = 1, #KEYS / 5 do
  local k = 5 * i - 5
  local lease, epoch, want, snap, tenant = KEYS[k + 1], KEYS[k + 2], KEYS[k + 3], KEYS[k + 4], KEYS[k + 5]
  local ok, owner = mine(lease, epoch, ARGV[1], ARGV[3 + i])
  if ok then
    redis.call('SET', lease, ARGV[1], 'PX', ARGV[2])
    redis.call('PEXPIRE', epoch, ARGV[3])
    redis.call('PEXPIRE', snap, ARGV[3])
    redis.call('PEXPIRE', tenant, ARGV[3])
    local w = redis.call('GET', want)
    out[i] = (w and w ~= ARGV[1]) and 'want' or ''
  else
    out[i] = 'lost:' .. (owner or '')
  end
end
return out
)";

std::vector<std::string> keys_of(const std::string& id) {
  const std::string base = absl::StrCat("ss:{", id, "}:");
  return {base + "lease", base + "epoch", base + "want", base + "snap", base + "tenant"};
}

std::string reply_string(const redisReply* r) {
  switch (r->type) {
    case REDIS_REPLY_INTEGER:
      return std::to_string(r->integer);
    case REDIS_REPLY_STRING:
    case REDIS_REPLY_STATUS:
    case REDIS_REPLY_ERROR:
      return std::string(r->str, r->len);
    default:
      return "";
  }
}

}  // namespace

absl::StatusOr<StoreAddress> parse_store_url(const std::string& url) {
  auto bad = [&](const std::string& what) {
    return absl::InvalidArgumentError(absl::StrCat("--session_store '", url, "': ", what,
                                                   " (expected redis://HOST:PORT or redis://HOST:PORT/DB)"));
  };
  constexpr std::string_view kScheme = "redis://";
  if (url.rfind(kScheme, 0) != 0) return bad("not a redis:// URL");
  std::string rest = url.substr(kScheme.size());
  StoreAddress a;
  if (const size_t slash = rest.find('/'); slash != std::string::npos) {
    const std::string db = rest.substr(slash + 1);
    if (!absl::SimpleAtoi(db, &a.db) || a.db < 0 || a.db > 15)
      return bad(absl::StrCat("database '", db, "' is not 0..15"));
    rest = rest.substr(0, slash);
  }
  if (rest.find('@') != std::string::npos)
    return bad("a password in the URL would show in the process list: use --session_store_password_file");
  const size_t colon = rest.rfind(':');
  if (colon == std::string::npos) return bad("no port");
  a.host = rest.substr(0, colon);
  if (a.host.empty()) return bad("no host");
  const std::string port = rest.substr(colon + 1);
  if (!absl::SimpleAtoi(port, &a.port) || a.port < 1 || a.port > 65535)
    return bad(absl::StrCat("port '", port, "' is not 1..65535"));
  return a;
}

absl::Status check_replica_id(const std::string& id) {
  if (id.empty() || id.size() > 64)
    return absl::InvalidArgumentError(absl::StrCat("--replica_id '", id, "': must be 1 to 64 characters"));
  for (char c : id)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.'))
      return absl::InvalidArgumentError(
          absl::StrCat("--replica_id '", id, "': only letters, digits, '-', '_' and '.'"));
  return absl::OkStatus();
}

SessionStore::SessionStore(StoreOptions options, StoreAddress address)
    : options_(std::move(options)), address_(std::move(address)) {}

SessionStore::~SessionStore() {
  for (redisContext* c : idle_) redisFree(c);
}

std::string SessionStore::where() const {
  return absl::StrCat("redis://", address_.host, ":", address_.port, "/", address_.db);
}

absl::StatusOr<std::unique_ptr<SessionStore>> SessionStore::connect(const StoreOptions& options) {
  auto address = parse_store_url(options.url);
  if (!address.ok()) return address.status();
  if (auto st = check_replica_id(options.replica_id); !st.ok()) return st;
  if (options.lease_ms < 300 || options.lease_ms > 600000)
    return absl::InvalidArgumentError(
        absl::StrCat("--lease_ms ", options.lease_ms, ": must be 300..600000 (a lease renewed every quarter of it)"));
  std::unique_ptr<SessionStore> store(new SessionStore(options, *address));
  auto c = store->take();  // connects, authenticates and pings
  if (!c.ok()) return c.status();
  store->give_back(*c);
  return store;
}

absl::StatusOr<redisContext*> SessionStore::take() {
  {
    std::lock_guard<std::mutex> l(mu_);
    if (!idle_.empty()) {
      redisContext* c = idle_.back();
      idle_.pop_back();
      return c;
    }
  }
  const timeval tv{kTimeoutMs / 1000, (kTimeoutMs % 1000) * 1000};
  redisContext* c = redisConnectWithTimeout(address_.host.c_str(), address_.port, tv);
  auto fail = [&](const std::string& what) {
    const std::string why = c && c->err ? std::string(c->errstr) : what;
    if (c) redisFree(c);
    return absl::UnavailableError(absl::StrCat("session store ", where(), " cannot be reached: ", why));
  };
  if (c == nullptr || c->err) return fail("out of memory");
  redisSetTimeout(c, tv);
  auto command = [&](std::vector<std::string> argv) -> absl::Status {
    std::vector<const char*> a;
    std::vector<size_t> n;
    for (const auto& s : argv) {
      a.push_back(s.data());
      n.push_back(s.size());
    }
    auto* r = static_cast<redisReply*>(redisCommandArgv(c, static_cast<int>(a.size()), a.data(), n.data()));
    if (r == nullptr) return absl::UnavailableError(c->errstr);
    const bool error = r->type == REDIS_REPLY_ERROR;
    const std::string text = reply_string(r);
    freeReplyObject(r);
    if (error) return absl::FailedPreconditionError(text);
    return absl::OkStatus();
  };
  if (!options_.password.empty())
    if (auto st = command({"AUTH", options_.password}); !st.ok()) return fail(absl::StrCat("AUTH: ", st.message()));
  if (address_.db != 0)
    if (auto st = command({"SELECT", std::to_string(address_.db)}); !st.ok())
      return fail(absl::StrCat("SELECT: ", st.message()));
  if (auto st = command({"PING"}); !st.ok()) return fail(absl::StrCat("PING: ", st.message()));
  return c;
}

void SessionStore::give_back(redisContext* c) {
  std::lock_guard<std::mutex> l(mu_);
  idle_.push_back(c);
}

absl::StatusOr<std::vector<std::string>> SessionStore::eval(const char* script, const std::vector<std::string>& keys,
                                                            const std::vector<std::string>& args) {
  auto c = take();
  if (!c.ok()) return c.status();
  std::vector<std::string> argv = {"EVAL", absl::StrCat(kMine, script), std::to_string(keys.size())};
  argv.insert(argv.end(), keys.begin(), keys.end());
  argv.push_back(options_.replica_id);
  argv.push_back(std::to_string(options_.lease_ms));
  argv.push_back(std::to_string(options_.retain_ms));
  argv.insert(argv.end(), args.begin(), args.end());
  std::vector<const char*> a;
  std::vector<size_t> n;
  for (const auto& s : argv) {
    a.push_back(s.data());
    n.push_back(s.size());
  }
  auto* r = static_cast<redisReply*>(redisCommandArgv(*c, static_cast<int>(a.size()), a.data(), n.data()));
  if (r == nullptr) {  // the connection broke: dropped, the next call connects again
    const std::string why = (*c)->errstr;
    redisFree(*c);
    return absl::UnavailableError(absl::StrCat("session store ", where(), ": ", why));
  }
  std::vector<std::string> out;
  absl::Status st;
  if (r->type == REDIS_REPLY_ERROR)
    st = absl::InternalError(absl::StrCat("session store ", where(), " refused a script: ", reply_string(r)));
  else if (r->type == REDIS_REPLY_ARRAY)
    for (size_t i = 0; i < r->elements; ++i) out.push_back(reply_string(r->element[i]));
  else
    st = absl::InternalError(absl::StrCat("session store ", where(), ": a script's reply is not a list"));
  freeReplyObject(r);
  give_back(*c);
  if (!st.ok()) return st;
  if (out.empty()) return absl::InternalError(absl::StrCat("session store ", where(), ": an empty reply"));
  return out;
}

namespace {

absl::Status lost(const std::string& id, const std::string& owner) {
  return absl::FailedPreconditionError(
      owner.empty() ? absl::StrCat("session ", echo_id(id), ": lease lost (the session was closed or expired)")
                    : absl::StrCat("session ", echo_id(id), ": lease lost: replica '", owner, "' holds it now"));
}

int64_t to_int(const std::string& s) {
  int64_t v = 0;
  std::from_chars(s.data(), s.data() + s.size(), v);
  return v;
}

}  // namespace

absl::StatusOr<int64_t> SessionStore::create(const std::string& id, const std::string& tenant,
                                             const std::string& snapshot) {
  auto r = eval(kCreate, keys_of(id), {tenant, snapshot});
  if (!r.ok()) return r.status();
  if ((*r)[0] == "exists")
    return absl::AlreadyExistsError(absl::StrCat("session_id ", echo_id(id), " is already in use"));
  if (r->size() != 2) return absl::InternalError("session store: a malformed reply to create");
  return to_int((*r)[1]);
}

absl::StatusOr<SessionStore::Taken> SessionStore::acquire(const std::string& id, const std::string& tenant) {
  auto r = eval(kAcquire, keys_of(id), {tenant});
  if (!r.ok()) return r.status();
  Taken t;
  if ((*r)[0] == "unknown")
    return absl::NotFoundError(absl::StrCat("session_id ", echo_id(id), " is not an open session"));
  if ((*r)[0] == "held" && r->size() == 3) {
    t.owner = (*r)[1];
    t.owner_ttl_ms = to_int((*r)[2]);
    return t;
  }
  if ((*r)[0] != "taken" || r->size() != 3) return absl::InternalError("session store: a malformed reply to acquire");
  t.taken = true;
  t.epoch = to_int((*r)[1]);
  t.snapshot = std::move((*r)[2]);
  return t;
}

absl::Status SessionStore::put(const std::string& id, int64_t epoch, const std::string& snapshot, bool release) {
  auto r = eval(kPut, keys_of(id), {std::to_string(epoch), snapshot, release ? "1" : "0"});
  if (!r.ok()) return r.status();
  if ((*r)[0] == "lost") return lost(id, r->size() > 1 ? (*r)[1] : "");
  return absl::OkStatus();
}

absl::Status SessionStore::release(const std::string& id, int64_t epoch) {
  auto r = eval(kRelease, keys_of(id), {std::to_string(epoch)});
  if (!r.ok()) return r.status();
  if ((*r)[0] == "lost") return lost(id, r->size() > 1 ? (*r)[1] : "");
  return absl::OkStatus();
}

absl::Status SessionStore::remove(const std::string& id, int64_t epoch) {
  auto r = eval(kRemove, keys_of(id), {std::to_string(epoch)});
  if (!r.ok()) return r.status();
  if ((*r)[0] == "lost") return lost(id, r->size() > 1 ? (*r)[1] : "");
  return absl::OkStatus();
}

absl::StatusOr<std::map<std::string, std::string>> SessionStore::renew(const std::map<std::string, int64_t>& held) {
  std::map<std::string, std::string> out;
  if (held.empty()) return out;
  std::vector<std::string> keys, args;
  for (const auto& [id, epoch] : held) {
    for (auto& k : keys_of(id)) keys.push_back(std::move(k));
    args.push_back(std::to_string(epoch));
  }
  auto r = eval(kRenew, keys, args);
  if (!r.ok()) return r.status();
  if (r->size() != held.size()) return absl::InternalError("session store: a malformed reply to renew");
  size_t i = 0;
  for (const auto& [id, epoch] : held) out[id] = (*r)[i++];
  return out;
}

}  // namespace ss::server
