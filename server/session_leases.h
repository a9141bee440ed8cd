// The leases this replica holds in the shared session store (server/session_store.h), and the thread that keeps them:
// every quarter of --lease_ms it renews them all in one script, hands over the sessions other replicas asked for
// (their `want`), and reports the ones another replica took. A call on a held session trusts its lease only until
// three quarters of --lease_ms after the renewal was sent: the store cannot give the lease to another replica before a
// whole --lease_ms passed after it received that renewal, so this replica never serves a session while another one
// might.
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>

#include "absl/status/statusor.h"
#include "server/session_store.h"

namespace ss::server {

class LeaseKeeper {
 public:
  struct Hooks {
    // Another replica asked for `id`: save it with its lease released and drop it; false to try again at the next
    // renewal (the session was busy).
    std::function<bool(const std::string& id)> hand_over;
    // Another replica took `id` (this one failed to renew in time): drop the local copy, it is stale.
    std::function<void(const std::string& id, const std::string& owner)> lost;
  };
  LeaseKeeper(SessionStore& store, Hooks hooks);
  // Stops the renewal thread.
  ~LeaseKeeper();

  SessionStore& store() { return store_; }
  // A new session: its lease and first snapshot (ALREADY_EXISTS when the store has the id).
  absl::Status create(const std::string& id, const std::string& tenant, const std::string& snapshot);
  // For a call on a session this replica has in memory: OK while its lease is this replica's (renewed now if the
  // last renewal is getting old); NOT_FOUND when this replica does not hold it (handed over: take it again through
  // acquire); FAILED_PRECONDITION "lease lost" naming the replica that took it; UNAVAILABLE when the store cannot be
  // reached to renew it.
  absl::Status hold(const std::string& id);
  // Takes the lease of a session held elsewhere or nowhere, asking its holder to hand it over and waiting up to
  // `wait` for it: the session's snapshot. NOT_FOUND for an id the store does not have, UNAVAILABLE naming the holder
  // when it did not hand the session over in time.
  absl::StatusOr<std::string> acquire(const std::string& id, const std::string& tenant,
                                      std::chrono::milliseconds wait);
  // Writes the snapshot of a held session (releasing the lease with `release`).
  absl::Status put(const std::string& id, const std::string& snapshot, bool release);
  // Gives up the lease, keeping the snapshot (a session this replica restored but cannot keep).
  void release(const std::string& id);
  // Deletes the session from the store (CloseSession).
  absl::Status remove(const std::string& id);
  // Forgets the lease without telling the store (its copy was dropped because the lease was lost).
  void forget(const std::string& id);
  int held();

 private:
  struct Lease {
    int64_t epoch = 0;
    std::chrono::steady_clock::time_point valid_until;
  };
  std::chrono::milliseconds lease() const { return std::chrono::milliseconds(store_.options().lease_ms); }
  void keep(const std::string& id, int64_t epoch, std::chrono::steady_clock::time_point sent);
  void renew_all();
  void run();

  SessionStore& store_;
  Hooks hooks_;
  std::mutex mu_;
  std::map<std::string, Lease> held_;  // under mu_
  std::condition_variable cv_;
  bool stop_ = false;  // under mu_
  std::chrono::steady_clock::time_point last_warning_;
  std::thread thread_;
};

}  // namespace ss::server
