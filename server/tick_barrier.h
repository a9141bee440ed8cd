// The tick barrier of a multi-client session: each controller's client sends its agents' poses for the next tick,
// and the tick is computed once, by one of the callers, when every controller's pose is in or the session's tick
// deadline (counted from the first pose) has passed; every caller then answers with that same tick. With one
// controller (or none) the caller's call is the tick.
#pragma once

#include <functional>
#include <mutex>
#include <vector>

#include "absl/status/statusor.h"
#include "server/managed_session.h"

namespace ss::server {

// Computes the tick (and, for a session with at most one controller, the further ticks the call asked for) from the
// poses `taken`, appending each tick's view to `out`. Called without s.mu held.
using RunTicks = std::function<absl::Status(const std::vector<ControlInput>& taken, std::vector<TickView>* out)>;

// Adds the caller's `controls` for the next tick of `s` and waits for it (or runs it, through `run`). `l` holds s.mu
// on entry and on return. ABORTED while a tick is being computed or for an agent whose pose is in already;
// DEADLINE_EXCEEDED once `deadline` passed waiting for the other controllers (the caller's poses are taken back);
// FAILED_PRECONDITION if the session closes meanwhile; the tick's own error for every caller of a failed tick.
absl::StatusOr<std::vector<TickView>> barrier_step(ManagedSession& s, std::unique_lock<std::mutex>& l,
                                                   const std::vector<ControlInput>& controls, TimePoint deadline,
                                                   const RunTicks& run);

}  // namespace ss::server
