// scenestreamer dataset stats FILE_OR_DIR... [--json] [--markdown]
// Each argument is one column: a scenario file, or a directory read recursively (its *.json and *.tfrecord* files).
// TFRecords are read one record at a time, so a dataset of thousands of scenarios never has to fit in memory.
#include <cstdio>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "engine/io/json_text.h"
#include "engine/scenario/read.h"
#include "spdlog/spdlog.h"
#include "common/command_line.h"
#include "tools/dataset/dataset_commands.h"
#include "tools/dataset/scenario_stats.h"
#include "tools/shared_flags.h"

ABSL_FLAG(bool, markdown, false, "the table as Markdown");

namespace ss::dataset {
namespace {

absl::Status add_file(const std::string& path, ScenarioStats* stats) {
  auto count = for_each_scenario(path, [&](Scenario&& s) {
    stats->add(s);
    return absl::OkStatus();
  });
  return count.status();
}

}  // namespace

int stats_main(int argc, char** argv) {
  const cli::Command command{
      "scenestreamer dataset stats",
      "usage: scenestreamer dataset stats FILE_OR_DIR... [--json | --markdown]\n"
      "  Statistics of scenario files, one column per argument (a directory is read recursively):\n"
      "  agents per scenario by type, signal-controlled lanes per scenario, speeds by type, frames,\n"
      "  map features per scenario.\n",
      __FILE__,
      {cli::flag(FLAGS_json)},
      true};
  cli::CommandLine line;
  if (auto exit_code = cli::parse_command(command, argc, argv, &line)) return *exit_code;
  if (line.positional().empty()) return cli::usage_error(command, "no FILE_OR_DIR given");
  std::vector<std::pair<std::string, nlohmann::ordered_json>> columns;
  for (const std::string& p : line.positional()) {
    auto files = list_scenario_files(p, /*recursive=*/true);
    if (!files.ok()) {
      spdlog::error("dataset stats: {}", std::string(files.status().message()));
      return 1;
    }
    ScenarioStats stats;
    for (const std::string& f : *files) {
      if (auto st = add_file(f, &stats); !st.ok()) {
        spdlog::error("dataset stats: {}", std::string(st.message()));
        return 1;
      }
    }
    columns.emplace_back(p, stats.json());
  }
  if (absl::GetFlag(FLAGS_json)) {
    nlohmann::ordered_json out = nlohmann::ordered_json::object();
    for (const auto& [name, j] : columns) out[name] = j;
    std::puts(json_text(out).c_str());
  } else {
    std::fputs(stats_table(columns, absl::GetFlag(FLAGS_markdown)).c_str(), stdout);
  }
  return 0;
}

}  // namespace ss::dataset
