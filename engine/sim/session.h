// A simulation session: one scenario's map, its agents and lights, the decoder's KV cache, the RNG and the tick
// clock, stepped at 2 Hz and ticked at 2 or 10 Hz. Hosts reach it through engine/scenestreamer.h. Every mode is a Session option (docs/design.md, section 6). Sessions are not thread-safe: callers
// serialise calls on one session; different sessions run in parallel (the Model and MapContext are shared read-only).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/base/rng.h"
#include "engine/model/model.h"
#include "engine/scenario/scenario.h"
#include "engine/sim/rule_agents.h"
#include "engine/sim/session_types.h"
#include "engine/sim/token_builders.h"
#include "engine/tokens/light.h"
#include "engine/tokens/motion.h"
#include "engine/tokens/resample.h"

namespace ss {

struct EventMap;

class Session {
 public:
  struct Probe;
  // Starts a session at the scenario's current step (frame current_time_index, i.e. step 2 on WOMD), with the log's
  // history before it teacher-forced. `map` must be the model's encoding of this scenario's map.
  // `probe` (tests only) records every decoder batch and its outputs from the first one on.
  static absl::StatusOr<std::unique_ptr<Session>> create(std::shared_ptr<const Model> model,
                                                         std::shared_ptr<const Scenario> scenario,
                                                         std::shared_ptr<const MapContext> map, SessionOptions options,
                                                         Probe* probe = nullptr);

  // Advances one 2 Hz step. `controls` gives every controlled agent's pose at the next step; a controlled agent
  // without one keeps its last control. On error the session is unchanged.
  absl::StatusOr<StepResult> step(const std::vector<ControlInput>& controls);
  // Advances one tick of the session's clock (options.tick_hz). At 2 Hz a tick is a step. At 10 Hz the poses pushed
  // at each tick are kept (they are part of the session's state, saved with it), the ticks between model steps show
  // background agents along the control they sampled (tick.h), and the fifth tick is the model step, each controlled
  // agent taking its latest pose since the last step. Every pose is checked when it arrives. On error the session is
  // unchanged.
  // The result carries each controlled agent's events since the previous tick (engine/sim/events.h).
  absl::StatusOr<StepResult> tick(const std::vector<ControlInput>& controls);
  // The map the events are measured on. Hosts share one per bundled scenario between its sessions; a session given
  // none builds its own at its first tick with a controlled agent. Forks share their source's.
  void set_event_map(std::shared_ptr<const EventMap> m) { event_map_ = std::move(m); }
  const EventMap* event_map() const { return event_map_.get(); }
  // What the current tick shows (current() at a step, else the sub-tick view with the pushed poses).
  StepResult tick_view() const;
  int64_t tick_index() const { return tick_; }  // ticks since the session started
  // Adds agents at the current step (the step's agent-state group and motion tokens are decoded again with them).
  // Returns the new agents' ids. On error the session is unchanged.
  absl::StatusOr<std::vector<int64_t>> inject(const InjectRequest& request);
  // States imposed at the next step. On error nothing is imposed.
  absl::Status state_force(const StateForceRequest& request);

  std::unique_ptr<Session> fork() const;
  // A compact byte form: scenario id, options, agents, lights, RNG, and the token batches of the last steps needed to
  // rebuild the cache exactly. restore() with the same model, scenario and map continues identically.
  std::string save() const;
  static absl::StatusOr<std::unique_ptr<Session>> restore(std::shared_ptr<const Model> model,
                                                          std::shared_ptr<const Scenario> scenario,
                                                          std::shared_ptr<const MapContext> map,
                                                          const std::string& bytes);

  StepResult current() const;
  // The agents `sub_tick` of `ticks_per_step` ticks into the coming 0.5 s step (0 <= sub_tick <= ticks_per_step), for
  // hosts that tick faster than the model: every agent step() will move by its sampled control is moved by that
  // control over the elapsed part of the step, so at sub_tick == ticks_per_step it is exactly where step() will put
  // it. The other agents follow tick.h's rules (controlled agents stay at their step pose here).
  StepResult sub_tick_view(int sub_tick, int ticks_per_step) const;
  const SessionOptions& options() const { return options_; }
  const Scenario& scenario() const { return *scenario_; }
  const MapContext& map() const { return *map_; }
  int step_index() const { return step_; }
  size_t memory_bytes() const;
  size_t cache_tokens() const { return cache_.tokens.size(); }
  const DecodeWork& decode_work() const { return cache_.work; }  // what the decoder did for this session
  const KvCache& cache() const { return cache_; }

  // For tests: every decoder batch (unbounded memory). Batches undone by a rejected sample are removed.
  struct Probe {
    std::vector<std::vector<DecoderToken>> batches;
    std::vector<Mat> outputs;  // decoder outputs per batch
  };

 private:
  struct Agent {
    int64_t id = 0;
    int type = 0;
    int slot = 0;
    StepState state;
    KinematicState kin;
    int last_motion = kMotionStart;   // the token that brought it to the current step
    int next_motion = -1;             // the control sampled for the next step (-1: none yet)
    bool controlled = false;
    int entered_step = 0;
    std::optional<StepState> forced;  // StateForce for the next step
    // Rule modes (log, idm) only: the arc length along its logged path (idm), and where the rule puts it at the next
    // step (none: its log has no state there, so it leaves). Planned from every agent's state at the current step,
    // as the model samples its controls, so a restored session plans the same again.
    double path_s = 0;
    std::optional<StepState> planned;
    double planned_s = 0;
  };
  struct Light {
    int64_t lane = 0;
    int map_id = 0;
    Pose pose;
    LightState state = LightState::unknown;
    LightState next_state = LightState::unknown;
    std::optional<LightState> forced;
  };
  struct Batch {
    int step = 0;
    std::vector<DecoderToken> tokens;
  };

  Session() = default;
  // The decoder call every token goes through; keeps the batch for save/restore. Returns the hidden states of the
  // tokens at `outputs` (rows in that order); by default every token's.
  Mat decode(std::vector<DecoderToken>& tokens);
  Mat decode(std::vector<DecoderToken>& tokens, std::span<const int> outputs);
  void evict();
  Vec2 roi_centre() const;
  int effective_window() const;
  int anchor_segment(const StepState& s) const;
  // With agent_counts the SDC's last second is the log's: a new agent moved back along its velocity over that second
  // stays clear of the SDC's logged boxes (options.placement_room).
  bool clear_of_sdc_past(const StepState& a) const;
  static TokenAgent token_agent(const Agent& a);
  DecoderToken light_token(const Light& l) const;
  void group_tokens(const Agent& a, int order, std::vector<DecoderToken>& out) const;
  DecoderToken motion_token(const Agent& a) const;
  // Decodes the current step's tokens: lights, the agent-state group (sampling new agents as the mode allows), motion.
  absl::Status decode_step(bool sample_lights, bool allow_new, int force_new, const std::vector<InjectRequest>& inject,
                           std::vector<int64_t>* injected);
  absl::Status add_agents(bool allow_new, int force_new, const std::vector<InjectRequest>& inject,
                          std::vector<int64_t>* injected);
  void finish_step();  // EOS and the motion tokens of every agent, then the next controls
  void sample_light_states(const Mat& h);
  void trim_replay();
  // Drops the newest decoded tokens back to a cache size (and their batches): undoes a rejected sample.
  void undo_to(int cache_size, size_t replay_size);
  // Samples one new agent after the group's last output `h_last`: placed, the group ended (the model's end of
  // agents, the cap, no free slot or no segment allowed), or dropped (no place free of overlap after the retries).
  enum class NewAgent { placed, ended, dropped };
  NewAgent sample_agent(const Mat& h_last, bool force_continue, const InjectRequest* req, int order, int64_t* new_id);
  void sample_motions(const Mat& h);  // h: the agents' motion-token outputs, in agent order
  void reject_motion_faults(const std::function<std::span<const float>(size_t)>& row);  // row(i): agent i's logits
  int allocate_slot();
  // tick() without the events; controls already checked.
  absl::StatusOr<StepResult> advance_tick(const std::vector<ControlInput>& controls);
  // step() with controls already checked: tick() checks once at its entry and comes here.
  absl::StatusOr<StepResult> step_checked(const std::vector<ControlInput>& controls);
  absl::Status check_state(const StepState& s, const std::string& what) const;
  // The one rule for a pose from a client: a controlled agent, given once, finite, on the map's scale, at most
  // kMaxStepDistance from the agent's pose at the last model step, speed in 0..100 m/s.
  absl::Status check_controls(const std::vector<ControlInput>& controls) const;
  int ticks_per_step() const { return options_.tick_hz / 2; }
  // Rule modes (rule_agents.h): no decoder; agents follow their log or IDM along their logged path.
  bool rule_mode() const { return options_.mode == SessionMode::log || options_.mode == SessionMode::idm; }
  int track_of(int64_t id) const;  // the track index of a log agent's id, -1 for none
  // Rule modes: the agents of the current step's log that are not in the session yet join it.
  void join_logged_agents();
  void plan_rule_agents();  // each rule-driven agent's state at the next step

  std::shared_ptr<const Model> model_;
  std::shared_ptr<const Scenario> scenario_;
  std::shared_ptr<const MapContext> map_;
  std::shared_ptr<const EventMap> event_map_;  // read-only, shared
  SessionOptions options_;
  Rng rng_;
  int step_ = 0;
  std::vector<Agent> agents_;        // alive, in order of entry
  std::vector<Light> lights_;
  std::vector<int64_t> left_;        // retired at the current step
  std::vector<int64_t> entered_;     // entered at the current step
  int64_t next_agent_id_ = 0;
  int64_t tick_ = 0;                                  // ticks since the session started
  std::map<int64_t, ControlInput> latest_pose_;       // 10 Hz: each controlled agent's latest pushed pose
  std::map<int64_t, ControlInput> step_controls_;     // 10 Hz: poses pushed since the last model step
  std::vector<std::pair<int, int>> released_slots_;  // (slot, step it was released)
  std::vector<bool> slot_used_;
  KvCache cache_;
  std::vector<Batch> replay_;        // decode batches of the steps a restore must re-run
  Mat last_group_output_;            // decoder output of the group's last token (SOS or the last RS)
  int eos_cache_size_ = 0;           // cache size before the current step's EOS and motion batch
  Probe* probe_ = nullptr;
  // While the first step places agents by count (options.agent_counts): how many of each type are still to place.
  std::vector<int> quota_;
  std::shared_ptr<const std::vector<LoggedPath>> paths_;  // rule modes: each track's logged path, by track index
};

}  // namespace ss
