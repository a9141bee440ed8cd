#include "engine/sim/tick.h"

#include <cmath>

namespace ss {

StepResult tick_between_steps(const StepResult& at_step, int sub_tick, int ticks_per_step,
                              const std::vector<ControlInput>& pushed) {
  StepResult r = at_step;
  const double step_seconds = 0.5;
  const double dt = step_seconds * sub_tick / ticks_per_step;
  r.time = at_step.time + dt;
  r.left.clear();
  for (AgentView& a : r.agents) {
    a.entered = false;
    const ControlInput* c = nullptr;
    for (const ControlInput& p : pushed)
      if (p.agent_id == a.id) c = &p;
    if (a.controlled && c) {
      a.state.x = c->x;
      a.state.y = c->y;
      a.state.heading = c->heading;
      if (c->speed) {
        a.state.vx = *c->speed * std::cos(c->heading);
        a.state.vy = *c->speed * std::sin(c->heading);
      }
    } else if (!a.controlled) {
      a.state.x += a.state.vx * dt;
      a.state.y += a.state.vy * dt;
    }
  }
  return r;
}

}  // namespace ss
