// The flags several `scenestreamer` commands take, each defined once (tools/shared_flags.cc); a command lists the
// ones it takes in its Command (common/command_line.h).
#pragma once

#include <cstdint>
#include <string>

#include "absl/flags/declare.h"
#include "absl/status/statusor.h"
#include "engine/scenestreamer.h"

ABSL_DECLARE_FLAG(std::string, model);                // simulate, eval
ABSL_DECLARE_FLAG(uint64_t, seed);                    // init-weights, simulate, eval, dataset sumo
ABSL_DECLARE_FLAG(bool, json);                        // inspect, bench, dataset stats
ABSL_DECLARE_FLAG(std::string, out);                  // convert, init-weights, simulate, render, dataset sumo
ABSL_DECLARE_FLAG(int, index);                        // simulate, render
ABSL_DECLARE_FLAG(std::string, mode);                 // simulate, eval
ABSL_DECLARE_FLAG(std::string, sdc);                  // simulate, eval
ABSL_DECLARE_FLAG(double, top_p);                     // simulate, eval
ABSL_DECLARE_FLAG(double, temperature);               // simulate, eval
ABSL_DECLARE_FLAG(bool, motion_reject);               // simulate, eval
ABSL_DECLARE_FLAG(bool, placement_room);              // simulate, eval
ABSL_DECLARE_FLAG(bool, pedestrian_contact);          // simulate, eval
ABSL_DECLARE_FLAG(std::string, wosac_submission);     // convert, eval
ABSL_DECLARE_FLAG(std::string, submission_metadata);  // convert, eval
ABSL_DECLARE_FLAG(std::string, kv_precision);         // simulate, eval, bench
ABSL_DECLARE_FLAG(std::string, matmul_precision);     // simulate, eval, bench

namespace ss::cli {

// The trained default model, relative to the bundled files' folder (bundled_dir(), common/command_line.h): the
// installed share/scenestreamer, or the source tree of a program in its build tree.
inline constexpr const char* kDefaultModel = "models/default.safetensors";
// --model, or the default model when the flag is absent; NOT_FOUND naming where it looked when neither exists.
absl::StatusOr<std::string> model_path();
// The engine's options for the model of simulate and eval: model_path() and --kv-precision, --matmul-precision
// (checked when the model loads: model_load, engine/offline.h).
absl::StatusOr<EngineOptions> model_options();
// --kv-precision and --matmul-precision into `o`.
void set_precisions(EngineOptions& o);

}  // namespace ss::cli
