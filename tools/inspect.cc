// scenestreamer inspect FILE... [--json]
#include <cstdio>

#include "engine/io/json_text.h"
#include "engine/scenario/read.h"
#include "spdlog/spdlog.h"
#include "common/command_line.h"
#include "tools/commands.h"
#include "tools/scenario_report.h"
#include "tools/shared_flags.h"

namespace ss::cli {

int inspect_main(int argc, char** argv) {
  const Command command{"scenestreamer inspect",
                        "usage: scenestreamer inspect FILE... [--json]\n"
                        "  FILE: GPUDrive/Nocturne .json, WOMD TFRecord, or a directory of them.\n"
                        "  With one scenario, --json prints its report; with several, {\"scenarios\": [...], "
                        "\"summary\": {...}}.\n",
                        __FILE__,
                        {flag(FLAGS_json)},
                        true};
  CommandLine line;
  if (auto exit_code = parse_command(command, argc, argv, &line)) return *exit_code;
  if (line.positional().empty()) return usage_error(command, "no FILE given");
  const bool json = absl::GetFlag(FLAGS_json);
  auto scenarios = read_scenarios(line.positional());
  if (!scenarios.ok()) {
    spdlog::error("inspect: {}", std::string(scenarios.status().message()));
    return 1;
  }
  nlohmann::ordered_json reports = nlohmann::ordered_json::array();
  TokenizationFidelity total;
  for (const Scenario& s : *scenarios) {
    ScenarioReport r = report_scenario(s);
    total.merge(r.fidelity);
    if (!json) print_report(r.json);
    reports.push_back(std::move(r.json));
  }
  nlohmann::ordered_json summary = fidelity_json(total);
  summary["scenarios"] = scenarios->size();
  if (json) {
    std::puts(json_text(reports.size() == 1 ? reports[0]
                                            : nlohmann::ordered_json{{"scenarios", reports}, {"summary", summary}})
                  .c_str());
  } else if (reports.size() > 1) {
    std::printf("\nsummary over %zu scenarios:\n", scenarios->size());
    print_report(summary);
  }
  return 0;
}

}  // namespace ss::cli
