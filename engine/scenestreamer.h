// The engine's public door for programs that host it (the gRPC server): one Engine holding the model, the shared map
// encodings and the named scenarios, and sessions behind an opaque handle, driven by functions with shared prefixes
// (engine_*, session_*) over plain value types (engine/sim/session_types.h: no Eigen, no engine internals). A host
// includes only this header from the engine (the llama.cpp pattern: opaque handles, plain structs, noun_verb names,
// and the state functions with their versioned format).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "engine/base/thread_pool.h"
#include "engine/io/record.h"
#include "engine/sim/session_types.h"

namespace ss {

struct EngineOptions {
  std::string model_path;               // safetensors weights; empty: random weights of `random_config`
  std::string random_config = "large";  // "small" or "large"
  uint64_t random_seed = 0;
  std::vector<std::string> scenario_paths;  // files or directories of WOMD TFRecords / GPUDrive JSON
  // Limits on a client-sent scenario: its size, its agents and its map (bundled scenarios are the operator's own).
  size_t max_scenario_bytes = size_t{64} << 20;
  int max_scenario_tracks = 1024;
  int max_map_features = 20000;
  int max_scenario_frames = 1000;   // timestamps, and states of a track (WOMD: 91; 20 s scenarios: 201)
  int max_map_points = 1'000'000;   // points, lane boundaries and neighbours over all map features (WOMD: <20,000)
  int step_threads = 1;  // threads one session's step may use (ModelOptions::step_threads): a lone session's latency
  // How keys and values are stored: "fp16" or "fp32"; "": fp16 (ModelOptions::kv_precision).
  std::string kv_precision;
  // The dense products: "bf16" (CPUs with AVX512-BF16 only) or "fp32"; "": bf16 where the CPU has it, else fp32.
  std::string matmul_precision;
};

struct EngineScenario {
  std::string name;        // the scenario id; how CreateSession names it
  int num_tracks = 0;
  int num_map_features = 0;
  int num_frames = 0;
  bool has_sdc = false;
};

// Where a session's scenario comes from: a bundled scenario's name, or serialized WOMD Scenario bytes.
struct SessionSource {
  std::string scenario_name;
  std::string womd_bytes;
};

class Engine;
class Session;
// Free an Engine or a Session (both are opaque to hosts). Closing a session is dropping its handle.
struct EngineDeleter {
  void operator()(Engine* e) const;
};
struct SessionDeleter {
  void operator()(Session* s) const;
};
using EnginePtr = std::unique_ptr<Engine, EngineDeleter>;
using SessionPtr = std::unique_ptr<Session, SessionDeleter>;

// Loads the model (or makes random weights when no path is given) and reads every scenario. engine_random_weights()
// says which happened so the host can warn loudly.
absl::StatusOr<EnginePtr> engine_create(const EngineOptions& options);
const std::vector<EngineScenario>& engine_scenarios(const Engine& engine);
const std::string& engine_model_name(const Engine& engine);  // the model config's name
const char* engine_kv_precision(const Engine& engine);       // "fp16" (default) or "fp32"
const char* engine_matmul_precision(const Engine& engine);   // "bf16" (default with AVX512-BF16) or "fp32"
bool engine_random_weights(const Engine& engine);
// Number of map encodings computed so far (the rest were shared between sessions).
int engine_map_encodes(const Engine& engine);
// Sets flush-to-zero for the calling compute thread (denormals slow the math 2-7x). A host runs its engine calls on a
// ThreadPool (engine/base/thread_pool.h, the project's one pool) whose threads start with this.
void engine_thread_init();

// A new session on `source`: NOT_FOUND for an unknown scenario name, INVALID_ARGUMENT for bytes that are not a valid
// WOMD Scenario or for bad options, RESOURCE_EXHAUSTED for a scenario above the limits.
absl::StatusOr<SessionPtr> session_create(Engine& engine, const SessionSource& source, const SessionOptions& options);
// A full copy (cache, RNG, tick clock and pushed poses included): both continue identically with the same inputs.
SessionPtr session_fork(const Session& session);
// One tick of the session's clock (options.tick_hz): `controls` are the controlled agents' poses at the new tick,
// checked when they arrive (INVALID_ARGUMENT naming the agent). On error the session is unchanged. The result's
// `events` are each controlled agent's events since the previous tick (overlaps, off road, red light, lane).
absl::StatusOr<StepResult> session_tick(Session& session, const std::vector<ControlInput>& controls);
// What the current tick shows, and its index (ticks since the session started).
StepResult session_view(const Session& session);
int64_t session_tick_index(const Session& session);
absl::StatusOr<std::vector<int64_t>> session_inject(Session& session, const InjectRequest& request);
absl::Status session_force(Session& session, const StateForceRequest& request);
const SessionOptions& session_options(const Session& session);
// The session's map as its scenario gives it (ids, kinds, polylines, lane links), for hosts that send it to clients.
const std::vector<MapFeature>& session_map_features(const Session& session);
// Bytes the session holds: its state and cache, plus a client-sent scenario's parsed form and map encoding, which
// no other session shares.
uint64_t session_memory_bytes(const Engine& engine, const Session& session);

// The session's state: everything needed to continue it (options, tick position, pushed poses, RNG, agents, the
// token batches that rebuild its cache), as one framed record (engine/io/record.h, which hosts use for their own
// saved files too) of kSessionStateMagic (session_types.h), whose last character is the format version; a state of
// another version is refused naming both (FAILED_PRECONDITION), a cut or corrupt one is DATA_LOSS.
std::string session_save(const Session& session);
// A session from session_save() bytes, on the same source it was created on.
absl::StatusOr<SessionPtr> session_restore(Engine& engine, const SessionSource& source, const std::string& state);

}  // namespace ss
