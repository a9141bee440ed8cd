// scenestreamer inspect FILE... [--json]
#include <cstdio>

#include "engine/io/json_text.h"
#include "engine/scenario/read.h"
#include "tools/cli_args.h"
#include "tools/commands.h"
#include "tools/scenario_report.h"

namespace ss::cli {

int inspect_main(int argc, char** argv) {
  auto args = parse_args(argc, argv, 1, {}, {"json", "help"});
  if (!args.ok() || args->has("help") || args->positional.empty()) {
    if (!args.ok()) std::fprintf(stderr, "inspect: %s\n", std::string(args.status().message()).c_str());
    std::fputs("usage: scenestreamer inspect FILE... [--json]\n"
               "  FILE: GPUDrive/Nocturne .json, WOMD TFRecord, or a directory of them.\n"
               "  With one scenario, --json prints its report; with several, {\"scenarios\": [...], \"summary\": {...}}.\n",
               args.ok() && args->has("help") ? stdout : stderr);
    return args.ok() && args->has("help") ? 0 : 2;
  }
  auto scenarios = read_scenarios(args->positional);
  if (!scenarios.ok()) {
    std::fprintf(stderr, "inspect: %s\n", std::string(scenarios.status().message()).c_str());
    return 1;
  }
  nlohmann::ordered_json reports = nlohmann::ordered_json::array();
  TokenizationFidelity total;
  for (const Scenario& s : *scenarios) {
    ScenarioReport r = report_scenario(s);
    total.merge(r.fidelity);
    if (!args->has("json")) print_report(r.json);
    reports.push_back(std::move(r.json));
  }
  nlohmann::ordered_json summary = fidelity_json(total);
  summary["scenarios"] = scenarios->size();
  if (args->has("json")) {
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
