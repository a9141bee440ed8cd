// The rule modes of a session (SessionMode::log and SessionMode::idm, engine/sim/rule_agents.h): who is present at a
// step, and where each rule-driven agent goes next.
#include <algorithm>
#include <cmath>

#include "engine/sim/session.h"
#include "engine/sim/token_builders.h"
#include "engine/tokens/fidelity.h"

namespace ss {

int Session::track_of(int64_t id) const {
  for (size_t i = 0; i < scenario_->tracks.size(); ++i)
    if (scenario_->tracks[i].id == id) return static_cast<int>(i);
  return -1;
}

void Session::join_logged_agents() {
  const int frame = step_ * kFramesPerStep;
  for (size_t i = 0; i < scenario_->tracks.size(); ++i) {
    const Track& t = scenario_->tracks[i];
    if (model_type(t.type) < 0 || frame >= static_cast<int>(t.states.size()) || !t.states[frame].valid) continue;
    if (std::any_of(agents_.begin(), agents_.end(), [&](const Agent& a) { return a.id == t.id; })) continue;
    Agent a;
    a.id = t.id;
    a.type = model_type(t.type);
    a.entered_step = step_;
    a.state = step_state_from_object(t.states[frame]);
    a.kin = kinematic_state(a.state);
    a.path_s = path_s_at_frame((*paths_)[i], frame);
    agents_.push_back(a);
    entered_.push_back(a.id);
  }
}

void Session::plan_rule_agents() {
  const int next_frame = (step_ + 1) * kFramesPerStep;
  static const IdmParams idm;
  // Every agent's box and velocity now: what IDM looks ahead at (the controlled ego at its current pose).
  std::vector<IdmOther> now(agents_.size());
  for (size_t i = 0; i < agents_.size(); ++i) {
    const StepState& s = agents_[i].state;
    now[i] = {{{s.x, s.y, s.heading}, s.length, s.width}, {s.vx, s.vy}};
  }
  std::vector<IdmOther> others;
  for (size_t i = 0; i < agents_.size(); ++i) {
    Agent& a = agents_[i];
    a.planned.reset();
    if (a.controlled) continue;
    const int k = track_of(a.id);
    const Track& t = scenario_->tracks[k];
    if (next_frame >= static_cast<int>(t.states.size()) || !t.states[next_frame].valid) continue;  // it leaves
    const StepState logged = step_state_from_object(t.states[next_frame]);
    if (options_.mode == SessionMode::log || a.type != 0) {
      a.planned = logged;
      a.planned_s = path_s_at_frame((*paths_)[k], next_frame);
      continue;
    }
    others.clear();
    for (size_t j = 0; j < agents_.size(); ++j)
      if (j != i) others.push_back(now[j]);
    const double v = std::max(0.0, a.state.vx * std::cos(a.state.heading) + a.state.vy * std::sin(a.state.heading));
    const double v0 = std::hypot(logged.vx, logged.vy);
    const IdmMove m = idm_step(idm, (*paths_)[k], a.path_s, v, v0, a.state.length, a.state.width, others, kStepSeconds);
    const Pose p = path_pose((*paths_)[k], m.s);
    StepState s = a.state;
    s.x = p.x, s.y = p.y, s.heading = wrap_angle(p.heading);
    s.vx = m.speed * std::cos(s.heading), s.vy = m.speed * std::sin(s.heading);
    a.planned = s;
    a.planned_s = m.s;
  }
  for (Light& l : lights_) l.next_state = log_light_state(*scenario_, l.lane, next_frame);
}

}  // namespace ss
