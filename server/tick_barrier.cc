#include "server/tick_barrier.h"

#include <algorithm>
#include <string>

#include "absl/strings/str_cat.h"
#include "server/session_id.h"
#include "spdlog/spdlog.h"

namespace ss::server {

absl::StatusOr<std::vector<TickView>> barrier_step(ManagedSession& s, std::unique_lock<std::mutex>& l,
                                                   const std::vector<ControlInput>& controls, TimePoint deadline,
                                                   const RunTicks& run) {
  BarrierState& b = s.barrier;
  const Clock& clock = s.clock;
  if (b.stepping)
    return absl::AbortedError(absl::StrCat("session '", s.id, "' is computing tick ", std::to_string(s.tick + 1),
                                           ": calls on one session are serialised; retry after it returns"));
  for (const ControlInput& c : controls)
    if (b.pending.count(c.agent_id))
      return absl::AbortedError(absl::StrCat("agent ", std::to_string(c.agent_id), " already sent its pose for tick ",
                                             std::to_string(s.tick + 1), " of session '", s.id, "'"));
  if (!b.pending_since) {
    // A new attempt at the next tick: an earlier failed attempt's error is not this one's.
    b.failed_tick = -1;
    b.pending_since = clock.now();
  }
  for (const ControlInput& c : controls) b.pending[c.agent_id] = c;
  const int64_t target = s.tick + 1;
  std::vector<TickView> out;  // the ticks this call computed (all of them, however many it asked for)
  while (s.tick < target) {
    if (s.closed) return absl::FailedPreconditionError(absl::StrCat("session ", echo_id(s.id), " was closed"));
    if (b.failed_tick == target) return b.failed_status;
    // With one controller (or none) the caller is the only client: its call is the tick. With several, the tick
    // waits for every controller's pose or the session's tick deadline.
    bool all = true;
    if (s.controllers.size() > 1)
      for (int64_t c : s.controllers) all = all && b.pending.count(c);
    const TimePoint tick_deadline = *b.pending_since + std::chrono::milliseconds(s.tick_deadline_ms);
    if (!b.stepping && (all || clock.now() >= tick_deadline)) {
      b.stepping = true;
      std::vector<ControlInput> taken;
      for (const auto& [aid, c] : b.pending) taken.push_back(c);
      b.pending.clear();
      b.pending_since.reset();
      l.unlock();
      const absl::Status st = run(taken, &out);
      l.lock();
      b.stepping = false;
      if (!st.ok()) {
        b.failed_tick = target;
        b.failed_status = st;
        s.cv.notify_all();
        spdlog::warn("session {}: tick {} failed: {}", s.id, target, std::string(st.message()));
        return st;
      }
      s.cv.notify_all();
      break;
    }
    if (clock.now() >= deadline) {
      for (const ControlInput& c : controls) b.pending.erase(c.agent_id);
      return absl::DeadlineExceededError(absl::StrCat("the call's deadline passed waiting for the other controllers "
                                                      "of session '", s.id, "'"));
    }
    clock.wait_until(l, s.cv, b.stepping ? deadline : std::min(tick_deadline, deadline));
  }
  if (out.empty())  // another controller's call computed the tick (multi-client calls ask for one tick)
    for (const TickView& t : s.recent)
      if (t.tick == target) out.push_back(t);
  return out;
}

}  // namespace ss::server
