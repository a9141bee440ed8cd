// The shared session store: a Redis server (Debian's redis-server, reached through hiredis) that holds every
// session's snapshot (the very bytes a --snapshot_dir file holds, server/snapshot.h) and a lease per session naming
// the replica that owns it, so any replica can continue any session. Each operation is one Lua script, run atomically
// by Redis, so a check and the write it guards are one step: a replica writes a session's snapshot only while the
// lease is its own, and a replica that lost a lease can never overwrite the history of the replica that took it.
//
// Keys of session S (all in one Redis Cluster hash slot, `{S}`):
//   ss:{S}:snap   the snapshot
//   ss:{S}:lease  the owner's replica id; expires --lease_ms after its last renewal
//   ss:{S}:epoch  counts the owners S has had: an owner whose lease lapsed unrenewed may take it back only while the
//                 epoch is still its own (no other replica took it meanwhile)
//   ss:{S}:want   a replica asking the owner to hand S over (expires after --lease_ms)
//   ss:{S}:tenant the owning tenant: another tenant's call finds no session S, and does not move it
// The snapshot, the epoch and the tenant expire `retain_ms` after their last write or renewal, so the sessions of
// replicas that died are not kept forever by a store no replica cleans.
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/status/statusor.h"

struct redisContext;

namespace ss::server {

struct StoreAddress {
  std::string host;
  int port = 6379;
  int db = 0;
};

// redis://HOST:PORT[/DB] (PORT 1..65535, DB 0..15); INVALID_ARGUMENT saying what is wrong otherwise.
absl::StatusOr<StoreAddress> parse_store_url(const std::string& url);

struct StoreOptions {
  std::string url;
  std::string password;    // Redis AUTH; empty: none
  std::string replica_id;  // the name this replica's leases carry
  int lease_ms = 10000;
  int64_t retain_ms = int64_t{3600} * 1000;
};

// --replica_id's rule: 1..64 letters, digits, '-', '_', '.'.
absl::Status check_replica_id(const std::string& id);

class SessionStore {
 public:
  // Connects and checks the server answers (PING, and AUTH with a password): UNAVAILABLE naming the address and why
  // when it cannot be reached, INVALID_ARGUMENT for a bad URL, replica id or lease.
  static absl::StatusOr<std::unique_ptr<SessionStore>> connect(const StoreOptions& options);
  ~SessionStore();

  const StoreOptions& options() const { return options_; }
  std::string where() const;  // redis://HOST:PORT/DB, for messages

  // A new session: takes its lease and writes its first snapshot, unless the store has the id already
  // (ALREADY_EXISTS). Returns the lease's epoch.
  absl::StatusOr<int64_t> create(const std::string& id, const std::string& tenant, const std::string& snapshot);

  // One attempt at taking the lease of `id`.
  struct Taken {
    bool taken = false;
    int64_t epoch = 0;     // taken: the new lease's epoch
    std::string snapshot;  // taken: the session's snapshot
    std::string owner;     // not taken: the replica holding it, now asked to hand it over
    int64_t owner_ttl_ms = 0;
  };
  // NOT_FOUND when the store holds no session `id` of `tenant`.
  absl::StatusOr<Taken> acquire(const std::string& id, const std::string& tenant);

  // Writes the snapshot of a session whose lease (of `epoch`) this replica holds, renewing the lease, or giving it up
  // with `release`. FAILED_PRECONDITION "lease lost" naming the new owner when the lease is another's.
  absl::Status put(const std::string& id, int64_t epoch, const std::string& snapshot, bool release);
  // Gives the lease up (the snapshot stays).
  absl::Status release(const std::string& id, int64_t epoch);
  // Deletes the session (CloseSession); FAILED_PRECONDITION when the lease is another's.
  absl::Status remove(const std::string& id, int64_t epoch);

  // Renews the leases of `held` (id -> epoch) in one script. Per id: "" (renewed), "want" (renewed, and another
  // replica asked for it) or the owner that took it ("lost:OWNER"; "lost:" when it was closed or expired).
  absl::StatusOr<std::map<std::string, std::string>> renew(const std::map<std::string, int64_t>& held);

 private:
  explicit SessionStore(StoreOptions options, StoreAddress address);
  // Runs one script with `keys` and `args`; the reply's top-level elements as strings (integers written out).
  absl::StatusOr<std::vector<std::string>> eval(const char* script, const std::vector<std::string>& keys,
                                                const std::vector<std::string>& args);
  // A connection from the pool (connecting a new one when none is free), back with give_back.
  absl::StatusOr<redisContext*> take();
  void give_back(redisContext* c);

  StoreOptions options_;
  StoreAddress address_;
  std::mutex mu_;
  std::vector<redisContext*> idle_;  // under mu_
};

}  // namespace ss::server
