#include "server/session_leases.h"

#include <vector>

#include "absl/strings/str_cat.h"
#include "server/session_id.h"
#include "spdlog/spdlog.h"

namespace ss::server {
namespace {

using SteadyClock = std::chrono::steady_clock;

absl::Status not_held(const std::string& id) {
  return absl::NotFoundError(absl::StrCat("session ", echo_id(id), ": this replica holds no lease for it"));
}

}  // namespace

LeaseKeeper::LeaseKeeper(SessionStore& store, Hooks hooks) : store_(store), hooks_(std::move(hooks)) {
  thread_ = std::thread([this] { run(); });
}

LeaseKeeper::~LeaseKeeper() {
  {
    std::lock_guard<std::mutex> l(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

int LeaseKeeper::held() {
  std::lock_guard<std::mutex> l(mu_);
  return static_cast<int>(held_.size());
}

void LeaseKeeper::keep(const std::string& id, int64_t epoch, SteadyClock::time_point sent) {
  std::lock_guard<std::mutex> l(mu_);
  held_[id] = {epoch, sent + lease() * 3 / 4};
}

absl::Status LeaseKeeper::create(const std::string& id, const std::string& tenant, const std::string& snapshot) {
  const auto sent = SteadyClock::now();
  auto epoch = store_.create(id, tenant, snapshot);
  if (!epoch.ok()) return epoch.status();
  keep(id, *epoch, sent);
  return absl::OkStatus();
}

absl::Status LeaseKeeper::hold(const std::string& id) {
  int64_t epoch;
  {
    std::lock_guard<std::mutex> l(mu_);
    auto it = held_.find(id);
    if (it == held_.end()) return not_held(id);
    if (SteadyClock::now() < it->second.valid_until) return absl::OkStatus();
    epoch = it->second.epoch;
  }
  // The last renewal is too old to trust (the store was slow or unreachable): renew this one now.
  const auto sent = SteadyClock::now();
  auto r = store_.renew({{id, epoch}});
  if (!r.ok())
    return absl::UnavailableError(absl::StrCat("session ", echo_id(id), ": its lease cannot be renewed: ",
                                               r.status().message()));
  const std::string& v = r->at(id);
  if (v.empty() || v == "want") {
    keep(id, epoch, sent);
    return absl::OkStatus();
  }
  forget(id);
  const std::string owner = v.substr(5);  // "lost:OWNER"
  return absl::FailedPreconditionError(
      owner.empty() ? absl::StrCat("session ", echo_id(id), ": lease lost (it expired and was closed elsewhere)")
                    : absl::StrCat("session ", echo_id(id), ": lease lost: replica '", owner,
                                   "' holds it now, this replica's copy is stale and was dropped"));
}

absl::StatusOr<std::string> LeaseKeeper::acquire(const std::string& id, const std::string& tenant,
                                                 std::chrono::milliseconds wait) {
  const auto until = SteadyClock::now() + wait;
  auto pause = std::chrono::milliseconds(20);
  while (true) {
    const auto sent = SteadyClock::now();
    auto t = store_.acquire(id, tenant);
    if (!t.ok()) return t.status();
    if (t->taken) {
      keep(id, t->epoch, sent);
      return std::move(t->snapshot);
    }
    // Held by another replica, now asked to hand it over: it does at its next renewal (a quarter of the lease), or
    // its lease runs out if it is gone.
    if (SteadyClock::now() + pause > until)
      return absl::UnavailableError(absl::StrCat(
          "session ", echo_id(id), " is held by replica '", t->owner, "', which did not hand it over within ",
          std::to_string(wait.count()), " ms (its lease runs ", std::to_string(t->owner_ttl_ms),
          " ms more); retry the call"));
    std::unique_lock<std::mutex> l(mu_);
    if (cv_.wait_for(l, pause, [&] { return stop_; }))
      return absl::UnavailableError("the server is stopping");
    pause = std::min(pause * 2, std::chrono::milliseconds(200));
  }
}

absl::Status LeaseKeeper::put(const std::string& id, const std::string& snapshot, bool release) {
  int64_t epoch;
  {
    std::lock_guard<std::mutex> l(mu_);
    auto it = held_.find(id);
    if (it == held_.end()) return not_held(id);
    epoch = it->second.epoch;
  }
  const auto sent = SteadyClock::now();
  absl::Status st = store_.put(id, epoch, snapshot, release);
  if (st.code() == absl::StatusCode::kUnavailable) return st;
  std::lock_guard<std::mutex> l(mu_);
  auto it = held_.find(id);
  if (it == held_.end() || it->second.epoch != epoch) return st;
  if (st.ok() && !release)
    it->second.valid_until = sent + lease() * 3 / 4;
  else
    held_.erase(it);  // released, or lost
  return st;
}

void LeaseKeeper::release(const std::string& id) {
  int64_t epoch;
  {
    std::lock_guard<std::mutex> l(mu_);
    auto it = held_.find(id);
    if (it == held_.end()) return;
    epoch = it->second.epoch;
    held_.erase(it);
  }
  if (auto st = store_.release(id, epoch); !st.ok())
    spdlog::warn("session {}: its lease was not released: {}", id, std::string(st.message()));
}

absl::Status LeaseKeeper::remove(const std::string& id) {
  int64_t epoch;
  {
    std::lock_guard<std::mutex> l(mu_);
    auto it = held_.find(id);
    if (it == held_.end()) return not_held(id);
    epoch = it->second.epoch;
  }
  absl::Status st = store_.remove(id, epoch);
  if (st.code() != absl::StatusCode::kUnavailable) forget(id);
  return st;
}

void LeaseKeeper::forget(const std::string& id) {
  std::lock_guard<std::mutex> l(mu_);
  held_.erase(id);
}

void LeaseKeeper::renew_all() {
  std::map<std::string, int64_t> held;
  {
    std::lock_guard<std::mutex> l(mu_);
    for (const auto& [id, lease] : held_) held[id] = lease.epoch;
  }
  if (held.empty()) return;
  const auto sent = SteadyClock::now();
  auto r = store_.renew(held);
  if (!r.ok()) {
    // Calls then renew each lease themselves, and are refused with UNAVAILABLE once it is too old to trust.
    if (sent - last_warning_ > std::chrono::seconds(10)) {
      spdlog::warn("{} session leases not renewed: {}", held.size(), std::string(r.status().message()));
      last_warning_ = sent;
    }
    return;
  }
  std::vector<std::string> wanted;
  std::vector<std::pair<std::string, std::string>> lost;
  {
    std::lock_guard<std::mutex> l(mu_);
    for (const auto& [id, v] : *r) {
      auto it = held_.find(id);
      if (it == held_.end() || it->second.epoch != held[id]) continue;  // released or taken again meanwhile
      if (v.empty() || v == "want") {
        it->second.valid_until = sent + lease() * 3 / 4;
        if (v == "want") wanted.push_back(id);
      } else {
        held_.erase(it);
        lost.emplace_back(id, v.substr(5));
      }
    }
  }
  for (const auto& [id, owner] : lost) {
    spdlog::warn("session {}: lease lost{}: its copy here is dropped", id,
                 owner.empty() ? std::string(" (closed or expired)") : absl::StrCat(" to replica '", owner, "'"));
    hooks_.lost(id, owner);
  }
  // Hand-overs wait for a busy session's call to end: they stop a quarter of a lease after the renewal, so the next
  // renewal is never late; the rest are still wanted at the next pass.
  for (const std::string& id : wanted) {
    {
      std::lock_guard<std::mutex> l(mu_);
      if (stop_) return;
    }
    if (SteadyClock::now() - sent > lease() / 4) break;
    if (hooks_.hand_over(id)) spdlog::info("session {}: handed over (another replica asked for it)", id);
  }
}

void LeaseKeeper::run() {
  std::unique_lock<std::mutex> l(mu_);
  while (!stop_) {
    if (cv_.wait_for(l, lease() / 4, [&] { return stop_; })) return;
    l.unlock();
    renew_all();
    l.lock();
  }
}

}  // namespace ss::server
