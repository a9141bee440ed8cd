// The door for offline hosts that drive a session themselves (the tools' simulate and eval, the bench world): the
// model loaded as engine_create loads it, from the same EngineOptions (weights or random ones, step threads, the
// precisions), and the engine headers such a host needs to roll a scenario out. The server never includes this
// (tests/deploy/door_test.py); it has engine/scenestreamer.h.
#pragma once

#include <memory>

#include "absl/status/statusor.h"
#include "engine/model/model.h"
#include "engine/scenario/read.h"
#include "engine/scenestreamer.h"
#include "engine/sim/map_cache.h"
#include "engine/sim/session.h"

namespace ss {

// The model of `options`: the weights at model_path, or random ones of random_config and random_seed when it is
// empty; step_threads, kv_precision and matmul_precision as engine_create takes them, with the same errors.
absl::StatusOr<std::shared_ptr<const Model>> model_load(const EngineOptions& options);

}  // namespace ss
