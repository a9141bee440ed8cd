#include "engine/sim/tick.h"

#include <cmath>

namespace ss {

StepResult tick_between_steps(const Session& session, int sub_tick, int ticks_per_step,
                              const std::vector<ControlInput>& pushed) {
  StepResult r = session.sub_tick_view(sub_tick, ticks_per_step);
  for (AgentView& a : r.agents) {
    if (!a.controlled) continue;
    const ControlInput* c = nullptr;
    for (const ControlInput& p : pushed)
      if (p.agent_id == a.id) c = &p;
    if (!c) continue;
    a.state.x = c->x;
    a.state.y = c->y;
    a.state.heading = c->heading;
    if (c->speed) {
      a.state.vx = *c->speed * std::cos(c->heading);
      a.state.vy = *c->speed * std::sin(c->heading);
    }
  }
  return r;
}

}  // namespace ss
