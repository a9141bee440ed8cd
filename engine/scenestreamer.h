// The engine's small public surface for programs that host it (the gRPC server): one Engine holding the model, the
// shared map encodings and the named scenarios, and functions with shared prefixes (engine_*, session_*) to start
// sessions from a bundled scenario or from WOMD Scenario bytes a client sent. It re-exports the Session types, the
// per-tick events (engine/sim/events.h) and the whole-file reader and atomic writer (for a host's own files, e.g.
// snapshots), so a host includes only this header from the engine (the llama.cpp pattern: a C-like facade over the
// internals).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "engine/io/file_io.h"
#include "engine/sim/events.h"
#include "engine/sim/session.h"
#include "engine/sim/tick.h"

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
// Frees an Engine (it is opaque to hosts).
struct EngineDeleter {
  void operator()(Engine* e) const;
};
using EnginePtr = std::unique_ptr<Engine, EngineDeleter>;

// Loads the model (or makes random weights when no path is given) and reads every scenario. engine_random_weights()
// says which happened so the host can warn loudly.
absl::StatusOr<EnginePtr> engine_create(const EngineOptions& options);
const std::vector<EngineScenario>& engine_scenarios(const Engine& engine);
const ModelConfig& engine_model_config(const Engine& engine);
bool engine_random_weights(const Engine& engine);
// Number of map encodings computed so far (the rest were shared between sessions).
int engine_map_encodes(const Engine& engine);

// A new session on `source`: NOT_FOUND for an unknown scenario name, INVALID_ARGUMENT for bytes that are not a valid
// WOMD Scenario, RESOURCE_EXHAUSTED for a scenario above the limits, and Session::create's own errors.
absl::StatusOr<std::unique_ptr<Session>> session_create(Engine& engine, const SessionSource& source,
                                                        const SessionOptions& options);
// The scenario a session on `source` runs (bundled scenarios are shared; client bytes are parsed and checked against
// the limits, with session_create's errors): for hosts that send its map to clients or measure events on it.
absl::StatusOr<std::shared_ptr<const Scenario>> engine_scenario(Engine& engine, const SessionSource& source);
// A session from Session::save() bytes, on the same source it was created on.
absl::StatusOr<std::unique_ptr<Session>> session_restore(Engine& engine, const SessionSource& source,
                                                         const std::string& saved);

// Sets flush-to-zero for the calling compute thread (denormals slow the math 2-7x).
void engine_thread_init();

}  // namespace ss
