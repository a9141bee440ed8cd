// scenestreamer render FILE [--scenario ID | --index I] [--step T | --animate] [--radius M] [--out OUT.svg]
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

#include "absl/flags/flag.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "offline/render/render.h"
#include "engine/scenario/read.h"
#include "spdlog/spdlog.h"
#include "common/command_line.h"
#include "tools/commands.h"
#include "tools/shared_flags.h"

// render_: simulate's and bench's --scenario is a file, dataset sumo's --radius another radius.
ABSL_FLAG(std::string, render_scenario, "", "the scenario with this id; default: the file's first");
ABSL_FLAG(int, step, -1, "the frame to draw, from 0; -1: the scenario's current frame");
ABSL_FLAG(bool, animate, false, "an animated SVG of every frame instead of a still");
ABSL_FLAG(double, render_radius, ss::RenderOptions{}.radius_m, "half the side of the square view around the SDC, metres");

namespace ss::cli {
namespace {

constexpr const char* kUsage =
    "usage: scenestreamer render FILE [--scenario ID | --index I] [--step T | --animate] [--radius M] [--out OUT.svg]\n"
    "  FILE: a GPUDrive/Nocturne .json or a WOMD TFRecord (a recorded scenario or a rollout)\n"
    "  --out: default SCENARIO_ID.svg, or SCENARIO_ID-anim.svg; '-' for stdout\n";

absl::StatusOr<const Scenario*> pick_scenario(const std::vector<Scenario>& all, const CommandLine& line,
                                              const std::string& file) {
  if (all.empty()) return absl::NotFoundError(absl::StrCat(file, ": holds no scenarios"));
  if (line.has(FLAGS_render_scenario)) {
    const std::string id = absl::GetFlag(FLAGS_render_scenario);
    for (const Scenario& s : all)
      if (s.id == id) return &s;
    std::string ids;
    for (size_t i = 0; i < all.size() && i < 10; ++i) absl::StrAppend(&ids, i ? ", " : "", all[i].id);
    if (all.size() > 10) absl::StrAppend(&ids, ", ... (", all.size(), " in all)");
    return absl::NotFoundError(absl::StrCat("unknown scenario id '", id, "' in ", file, "; it holds: ", ids));
  }
  if (line.has(FLAGS_index)) {
    const int index = absl::GetFlag(FLAGS_index);
    if (index < 0 || index >= static_cast<int>(all.size()))
      return absl::OutOfRangeError(absl::StrCat("--index ", index, " is outside ", file, ", which holds ", all.size(),
                                                " scenario", all.size() == 1 ? "" : "s"));
    return &all[index];
  }
  return &all[0];
}

absl::Status write_file(const std::string& path, const std::string& text) {
  if (path == "-") {
    if (std::fwrite(text.data(), 1, text.size(), stdout) != text.size() || std::fflush(stdout) != 0)
      return absl::UnavailableError("cannot write the picture to stdout");
    return absl::OkStatus();
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return absl::PermissionDeniedError(absl::StrCat("cannot write ", path, ": ", std::strerror(errno)));
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  out.close();
  if (!out) {
    std::remove(path.c_str());  // a half-written picture is worse than none
    return absl::DataLossError(absl::StrCat("cannot write ", path, ": ", std::strerror(errno)));
  }
  return absl::OkStatus();
}

absl::Status run(const CommandLine& line) {
  const std::string file = line.positional()[0];
  if (line.has(FLAGS_render_scenario) && line.has(FLAGS_index))
    return absl::InvalidArgumentError("give --scenario or --index, not both");
  if (line.has(FLAGS_step) && line.has(FLAGS_animate))
    return absl::InvalidArgumentError("give --step or --animate, not both");
  RenderOptions options;
  options.animate = absl::GetFlag(FLAGS_animate);
  options.step = absl::GetFlag(FLAGS_step);
  if (options.step < -1) return absl::InvalidArgumentError(absl::StrCat("bad --step ", options.step, ": frames count from 0"));
  options.radius_m = absl::GetFlag(FLAGS_render_radius);
  if (!std::isfinite(options.radius_m) || options.radius_m <= 0)
    return absl::InvalidArgumentError(
        absl::StrCat("bad --radius '", options.radius_m, "': expected a positive number"));
  auto scenarios = read_scenarios(file);
  if (!scenarios.ok()) return scenarios.status();
  auto scenario = pick_scenario(*scenarios, line, file);
  if (!scenario.ok()) return scenario.status();
  auto svg = render_scene_svg(**scenario, options);
  if (!svg.ok()) return svg.status();
  const std::string out = line.has(FLAGS_out) ? absl::GetFlag(FLAGS_out)
                                              : (*scenario)->id + (options.animate ? "-anim.svg" : ".svg");
  if (auto st = write_file(out, *svg); !st.ok()) return st;
  if (out != "-") spdlog::info("wrote {} ({} bytes)", out, svg->size());
  return absl::OkStatus();
}

}  // namespace

int render_main(int argc, char** argv) {
  const Command command{"scenestreamer render", kUsage, __FILE__, {flag(FLAGS_index), flag(FLAGS_out)}, true};
  CommandLine line;
  if (auto exit_code = parse_command(command, argc, argv, &line)) return *exit_code;
  if (line.positional().size() != 1)
    return usage_error(command, line.positional().empty() ? "no FILE given" : "one FILE at a time");
  if (auto st = run(line); !st.ok()) {
    spdlog::error("render: {}", std::string(st.message()));
    return 1;
  }
  return 0;
}

}  // namespace ss::cli
