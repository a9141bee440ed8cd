// A simulation session: one scenario's map, its agents and lights, the decoder's KV cache and the RNG, stepped at
// 2 Hz. Every mode of the paper is a Session option (DESIGN.md section 1). Sessions are not thread-safe: callers
// serialise calls on one session; different sessions run in parallel (the Model and MapContext are shared read-only).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/model/model.h"
#include "engine/scenario/scenario.h"
#include "engine/sim/rng.h"
#include "engine/sim/token_builders.h"
#include "engine/tokens/light.h"
#include "engine/tokens/motion.h"
#include "engine/tokens/resample.h"

namespace ss {

enum class SessionMode : int { motion = 0, full = 1, densify = 2 };
const char* session_mode_name(SessionMode m);

struct SessionOptions {
  SessionMode mode = SessionMode::motion;
  uint64_t seed = 0;
  // The defaults suit the trained default model (models/MODEL_CARD.md: a sweep on val scenarios cut collision and
  // offroad rates against 0.95 and 1.0, realism within noise of the best).
  double top_p = 0.8;          // motion tokens (nucleus sampling)
  double temperature = 0.7;    // every sampled token
  int max_agents = 128;        // the cap on agents alive at once (at most the model's agent slots)
  double roi_radius = 100.0;   // metres around the first controlled agent (else the SDC, else the scenario's focus):
                               // agents beyond it retire, new ones spawn within
  int window_steps = 0;        // history window W in steps; 0: the model's window (at most the model's)
  std::vector<int32_t> controlled_ids;  // track ids driven by the caller; empty: the SDC (if the scenario names one)
  bool control_sdc = true;     // with controlled_ids empty: false lets the model drive every agent, the SDC too
  int densify_target = 0;      // densify: agents to reach at the first step
  bool operator==(const SessionOptions&) const = default;
};

// An agent as the caller sees it.
struct AgentView {
  int64_t id = 0;         // public id: the track id for log agents; new ones count up from above the largest track id
  int type = 0;           // 0 vehicle, 1 pedestrian, 2 cyclist
  StepState state;
  bool controlled = false;
  bool entered = false;   // entered at this step
};

struct LightView {
  int64_t lane = 0;       // the lane feature it controls
  LightState state = LightState::unknown;
  Pose stop_point;        // stop point, heading of its lane
};

struct StepResult {
  int step = 0;                 // model step (2 Hz) since the scenario's first frame
  double time = 0;              // seconds: step * 0.5
  std::vector<AgentView> agents;
  std::vector<LightView> lights;
  std::vector<int64_t> left;    // agents retired at this step
};

// A controlled agent's pose at the next step.
struct ControlInput {
  int64_t agent_id = 0;
  double x = 0, y = 0, heading = 0;
  std::optional<double> speed;  // along the heading; derived from the displacement when absent
};

struct InjectRequest {
  int count = 0;                  // sample this many new agents (0 when `state` is given)
  std::optional<int> type;        // 0 vehicle, 1 pedestrian, 2 cyclist; sampled when absent
  std::optional<Vec2> near;       // spawn within `near_radius` of this point
  double near_radius = 20.0;
  std::optional<int> segment;     // spawn on this map segment (index among the session's map tokens)
  std::optional<StepState> state; // insert exactly this agent (with `type`, default vehicle)
};

struct StateForceRequest {
  std::vector<std::pair<int64_t, StepState>> agents;     // agent id -> state at the next step (a teleport)
  std::vector<std::pair<int64_t, LightState>> lights;    // lane id -> state at the next step
};

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
  // Samples one new agent after the group's last output `h_last`; returns false when the model (or the cap) ends.
  bool sample_agent(const Mat& h_last, bool force_continue, const InjectRequest* req, int order, int64_t* new_id);
  void sample_motions(const Mat& h);  // h: the agents' motion-token outputs, in agent order
  int allocate_slot();
  absl::Status check_state(const StepState& s, const std::string& what) const;

  std::shared_ptr<const Model> model_;
  std::shared_ptr<const Scenario> scenario_;
  std::shared_ptr<const MapContext> map_;
  SessionOptions options_;
  Rng rng_;
  int step_ = 0;
  std::vector<Agent> agents_;        // alive, in order of entry
  std::vector<Light> lights_;
  std::vector<int64_t> left_;        // retired at the current step
  std::vector<int64_t> entered_;     // entered at the current step
  int64_t next_agent_id_ = 0;
  std::vector<std::pair<int, int>> released_slots_;  // (slot, step it was released)
  std::vector<bool> slot_used_;
  KvCache cache_;
  std::vector<Batch> replay_;        // decode batches of the steps a restore must re-run
  Mat last_group_output_;            // decoder output of the group's last token (SOS or the last RS)
  int eos_cache_size_ = 0;           // cache size before the current step's EOS and motion batch
  Probe* probe_ = nullptr;
};

}  // namespace ss
