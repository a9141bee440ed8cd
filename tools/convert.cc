// scenestreamer convert IN... --out FILE.tfrecord
// scenestreamer convert ROLLOUT... --wosac-submission DIR [--submission-metadata FILE.json]
#include <cstdio>
#include <map>

#include "absl/strings/str_cat.h"
#include "offline/eval/submission.h"
#include "engine/scenario/read.h"
#include "spdlog/spdlog.h"
#include "common/command_line.h"
#include "tools/commands.h"
#include "tools/shared_flags.h"

namespace ss::cli {
namespace {

constexpr const char* kUsage =
    "usage: scenestreamer convert IN... --out FILE.tfrecord\n"
    "       scenestreamer convert ROLLOUT... --wosac-submission DIR [--submission-metadata FILE.json]\n"
    "  IN: GPUDrive/Nocturne .json files, WOMD TFRecords, or directories of them; --out writes them as one WOMD\n"
    "  TFRecord.\n"
    "  --wosac-submission: rollouts as `simulate` writes them (complete WOMD scenarios, any number per scenario id)\n"
    "  become a Waymo Open Sim Agents Challenge submission in DIR (submission.binproto-00000-of-0000N), which\n"
    "  `eval --submission DIR` scores: each rollout is one joint scene of every agent valid at its current frame,\n"
    "  x, y, z, heading after it; an agent the rollout leaves without a state (it left the model's region) moves on\n"
    "  at constant velocity, as in eval.\n";

int fail(const std::string& msg) {
  spdlog::error("convert: {}", msg);
  return 1;
}

int to_submission(const std::vector<std::string>& inputs) {
  SubmissionMetadata metadata;
  if (const std::string path = absl::GetFlag(FLAGS_submission_metadata); !path.empty()) {
    auto m = read_submission_metadata(path);
    if (!m.ok()) return fail(std::string(m.status().message()));
    metadata = std::move(*m);
  }
  std::vector<ScenarioRollouts> rollouts;  // by scenario id, in order of first appearance
  std::map<std::string, size_t> index;
  std::vector<Scenario> shapes;  // per scenario: id, frames and current frame (for challenge_problems)
  for (const std::string& path : inputs) {
    auto files = list_scenario_files(path, false);
    if (!files.ok()) return fail(std::string(files.status().message()));
    for (const std::string& file : *files) {
      int record = 0;
      auto read = for_each_scenario(file, [&](Scenario&& s) -> absl::Status {
        const int now = s.current_time_index;
        if (now + 1 >= s.num_frames())
          return absl::InvalidArgumentError(absl::StrCat(file, " record ", record, ": scenario ", s.id,
                                                         " has no frame after its current frame ", now));
        auto [it, added] = index.emplace(s.id, rollouts.size());
        if (added) {
          rollouts.push_back({s.id, {}});
          Scenario shape;
          shape.id = s.id, shape.current_time_index = now, shape.timestamps = s.timestamps;
          shapes.push_back(std::move(shape));
        } else if (shapes[it->second].num_frames() != s.num_frames()) {
          return absl::InvalidArgumentError(absl::StrCat(file, " record ", record, ": scenario ", s.id, " has ",
                                                         s.num_frames(), " frames, its earlier rollouts ",
                                                         shapes[it->second].num_frames()));
        }
        rollouts[it->second].joint_scenes.push_back(trajectories_from_rollout(s));
        ++record;
        return absl::OkStatus();
      });
      if (!read.ok()) return fail(std::string(read.status().message()));
    }
  }
  const std::string dir = absl::GetFlag(FLAGS_wosac_submission);
  if (auto st = write_submission(dir, rollouts, metadata); !st.ok()) return fail(std::string(st.message()));
  size_t scenes = 0;
  for (const ScenarioRollouts& r : rollouts) scenes += r.joint_scenes.size();
  std::printf("wrote %zu rollouts of %zu scenarios as a submission in %d shard(s) in %s\n", scenes, rollouts.size(),
              submission_shard_count(static_cast<int>(rollouts.size())), dir.c_str());
  std::vector<const Scenario*> logs;
  for (const Scenario& s : shapes) logs.push_back(&s);
  for (const std::string& p : challenge_problems(rollouts, logs, metadata))
    std::printf("  not yet valid for the challenge: %s\n", p.c_str());
  return 0;
}

}  // namespace

int convert_main(int argc, char** argv) {
  const Command command{"scenestreamer convert", kUsage, __FILE__,
                        {flag(FLAGS_out), flag(FLAGS_wosac_submission), flag(FLAGS_submission_metadata)},
                        true};
  CommandLine line;
  if (auto exit_code = parse_command(command, argc, argv, &line)) return *exit_code;
  if (line.positional().empty()) return usage_error(command, "no input given");
  if (line.has(FLAGS_out) == line.has(FLAGS_wosac_submission))
    return usage_error(command, line.has(FLAGS_out) ? "give --out or --wosac-submission, not both"
                                                    : "give --out or --wosac-submission");
  if (line.has(FLAGS_wosac_submission)) return to_submission(line.positional());
  if (line.has(FLAGS_submission_metadata)) return fail("--submission-metadata goes with --wosac-submission");
  auto scenarios = read_scenarios(line.positional());
  if (!scenarios.ok()) return fail(std::string(scenarios.status().message()));
  const std::string out = absl::GetFlag(FLAGS_out);
  if (auto st = write_scenarios_tfrecord(out, *scenarios); !st.ok()) return fail(std::string(st.message()));
  std::printf("wrote %zu scenarios to %s\n", scenarios->size(), out.c_str());
  return 0;
}

}  // namespace ss::cli
