#include "tools/shared_flags.h"

#include <filesystem>

#include "absl/flags/flag.h"
#include "absl/strings/str_cat.h"
#include "engine/sim/session_types.h"
#include "common/command_line.h"

ABSL_FLAG(std::string, model, "",
          "model weights (safetensors); default: the bundled default model, models/default.safetensors in "
          "share/scenestreamer beside an installed program's bin/ (the source tree's for a program in its build tree)");
ABSL_FLAG(uint64_t, seed, 0, "random seed: the same seed gives the same output");
ABSL_FLAG(bool, json, false, "print one JSON object instead of text");
ABSL_FLAG(std::string, out, "", "where to write");
ABSL_FLAG(int, index, 0, "the file's I-th scenario, from 0");
ABSL_FLAG(std::string, mode, "motion",
          "motion: the model moves the log's agents; full: the model creates the agents itself, and new ones may "
          "enter; densify: the log's agents and new ones up to --densify-target (simulate only); log: the baseline "
          "that replays the log (non-reactive); idm: the baseline whose vehicles follow their logged path with "
          "Intelligent Driver Model speed control (engine/sim/rule_agents.h)");
ABSL_FLAG(std::string, sdc, "model",
          "model: the model drives the SDC like every other agent (WOSAC's rule); log: the SDC follows its logged "
          "poses, as an RL client's ego would");
ABSL_FLAG(double, top_p, ss::SessionOptions{}.top_p, "the model's nucleus sampling of motion tokens, in (0, 1]");
ABSL_FLAG(double, temperature, ss::SessionOptions{}.temperature, "the model's sampling temperature of motion and light tokens (a new agent's tokens: 1.0)");
ABSL_FLAG(bool, motion_reject, ss::SessionOptions{}.motion_reject,
          "reject sampling of motion: a sampled control that would run an agent into another, or a vehicle off the "
          "road, is drawn again (--motion-reject=false: the model's draws as they come)");
ABSL_FLAG(bool, placement_room, ss::SessionOptions{}.placement_room,
          "simulate (full and densify modes), eval --protocol scenario-gen: a new agent leaves room to stop (braking "
          "at 6 m/s^2 it stops short of every agent moving on, and every agent braking so stops short of it); with "
          "agent counts, moved back along its velocity over the last second it also clears the SDC's logged boxes");
ABSL_FLAG(bool, pedestrian_contact, ss::SessionOptions{}.pedestrian_contact,
          "simulate, eval --protocol scenario-gen: the motion reject sampler lets pedestrians touch one another "
          "(logged pedestrians walking in groups do)");
ABSL_FLAG(std::string, wosac_submission, "",
          "write the rollouts as a Waymo Open Sim Agents Challenge submission in this directory "
          "(submission.binproto-00000-of-0000N)");
ABSL_FLAG(std::string, submission_metadata, "",
          "a JSON object of the challenge's metadata fields (account_name, unique_method_name, authors, ...), "
          "copied into every shard; with --wosac-submission");
ABSL_FLAG(std::string, kv_precision, "", "fp32 or fp16: how keys and values are stored; default: fp16");
ABSL_FLAG(std::string, matmul_precision, "",
          "fp32 or bf16 (AVX512-BF16 CPUs): the dense products' precision; default: bf16 where the CPU has "
          "AVX512-BF16, else fp32");

namespace ss::cli {

absl::StatusOr<std::string> model_path() {
  if (!absl::GetFlag(FLAGS_model).empty()) return absl::GetFlag(FLAGS_model);
  const absl::StatusOr<std::string> bundled = bundled_dir();
  if (!bundled.ok()) return absl::NotFoundError(absl::StrCat("no --model given, and ", bundled.status().message()));
  const std::string path = (std::filesystem::path(*bundled) / kDefaultModel).string();
  std::error_code ec;
  if (std::filesystem::exists(path, ec)) return path;
  return absl::NotFoundError(absl::StrCat("no --model given and no default model at ", path));
}

void set_precisions(EngineOptions& o) {
  o.kv_precision = absl::GetFlag(FLAGS_kv_precision);
  o.matmul_precision = absl::GetFlag(FLAGS_matmul_precision);
}

absl::StatusOr<EngineOptions> model_options() {
  auto path = model_path();
  if (!path.ok()) return path.status();
  EngineOptions o;
  o.model_path = *path;
  set_precisions(o);
  return o;
}

}  // namespace ss::cli
