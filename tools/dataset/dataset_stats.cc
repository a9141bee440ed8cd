// scenestreamer dataset stats FILE_OR_DIR... [--json] [--markdown]
// Each argument is one column: a scenario file, or a directory read recursively (its *.json and *.tfrecord* files).
// TFRecords are read one record at a time, so a dataset of thousands of scenarios never has to fit in memory.
#include <cstdio>
#include <string>
#include <vector>

#include "engine/io/json_text.h"
#include "engine/scenario/read.h"
#include "tools/cli_args.h"
#include "tools/dataset/dataset_commands.h"
#include "tools/dataset/scenario_stats.h"

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
  auto args = cli::parse_args(argc, argv, 1, {}, {"json", "markdown", "help"});
  if (!args.ok() || args->has("help") || args->positional.empty()) {
    if (!args.ok()) std::fprintf(stderr, "dataset stats: %s\n", std::string(args.status().message()).c_str());
    std::fputs("usage: scenestreamer dataset stats FILE_OR_DIR... [--json | --markdown]\n"
               "  Statistics of scenario files, one column per argument (a directory is read recursively):\n"
               "  agents per scenario by type, signal-controlled lanes per scenario, speeds by type, frames,\n"
               "  map features per scenario.\n",
               args.ok() && args->has("help") ? stdout : stderr);
    return args.ok() && args->has("help") ? 0 : 2;
  }
  std::vector<std::pair<std::string, nlohmann::ordered_json>> columns;
  for (const std::string& p : args->positional) {
    auto files = list_scenario_files(p, /*recursive=*/true);
    if (!files.ok()) {
      std::fprintf(stderr, "dataset stats: %s\n", std::string(files.status().message()).c_str());
      return 1;
    }
    ScenarioStats stats;
    for (const std::string& f : *files) {
      if (auto st = add_file(f, &stats); !st.ok()) {
        std::fprintf(stderr, "dataset stats: %s\n", std::string(st.message()).c_str());
        return 1;
      }
    }
    columns.emplace_back(p, stats.json());
  }
  if (args->has("json")) {
    nlohmann::ordered_json out = nlohmann::ordered_json::object();
    for (const auto& [name, j] : columns) out[name] = j;
    std::puts(json_text(out).c_str());
  } else {
    std::fputs(stats_table(columns, args->has("markdown")).c_str(), stdout);
  }
  return 0;
}

}  // namespace ss::dataset
