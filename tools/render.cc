// scenestreamer render FILE [--scenario ID | --index I] [--step T | --animate] [--radius M] [--out OUT.svg]
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "engine/render/render.h"
#include "engine/scenario/read.h"
#include "tools/cli_args.h"
#include "tools/commands.h"

namespace ss::cli {
namespace {

constexpr const char* kUsage =
    "usage: scenestreamer render FILE [--scenario ID | --index I] [--step T | --animate] [--radius M] [--out OUT.svg]\n"
    "  FILE: a GPUDrive/Nocturne .json or a WOMD TFRecord (a recorded scenario or a rollout)\n"
    "  --scenario ID   the scenario with this id (default: the file's first)\n"
    "  --index I       the file's I-th scenario, from 0\n"
    "  --step T        draw frame T (default: the scenario's current frame)\n"
    "  --animate       an animated SVG of every frame instead of a still\n"
    "  --radius M      half the side of the square view around the SDC, metres (default 80)\n"
    "  --out OUT.svg   where to write (default: SCENARIO_ID.svg, or SCENARIO_ID-anim.svg; '-' for stdout)\n";

absl::StatusOr<int> parse_int(const std::string& flag, const std::string& text) {
  int v = 0;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty())
    return absl::InvalidArgumentError(absl::StrCat("bad --", flag, " '", text, "': expected a whole number"));
  return v;
}

absl::StatusOr<double> parse_positive(const std::string& flag, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(v) || v <= 0)
    return absl::InvalidArgumentError(absl::StrCat("bad --", flag, " '", text, "': expected a positive number"));
  return v;
}

absl::StatusOr<const Scenario*> pick_scenario(const std::vector<Scenario>& all, const Args& args,
                                              const std::string& file) {
  if (all.empty()) return absl::NotFoundError(absl::StrCat(file, ": holds no scenarios"));
  if (args.has("scenario")) {
    const std::string id = args.get("scenario");
    for (const Scenario& s : all)
      if (s.id == id) return &s;
    std::string ids;
    for (size_t i = 0; i < all.size() && i < 10; ++i) absl::StrAppend(&ids, i ? ", " : "", all[i].id);
    if (all.size() > 10) absl::StrAppend(&ids, ", ... (", all.size(), " in all)");
    return absl::NotFoundError(absl::StrCat("unknown scenario id '", id, "' in ", file, "; it holds: ", ids));
  }
  if (args.has("index")) {
    auto index = parse_int("index", args.get("index"));
    if (!index.ok()) return index.status();
    if (*index < 0 || *index >= static_cast<int>(all.size()))
      return absl::OutOfRangeError(absl::StrCat("--index ", *index, " is outside ", file, ", which holds ", all.size(),
                                                " scenario", all.size() == 1 ? "" : "s"));
    return &all[*index];
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

absl::Status run(const Args& args) {
  const std::string file = args.positional[0];
  if (args.has("scenario") && args.has("index"))
    return absl::InvalidArgumentError("give --scenario or --index, not both");
  if (args.has("step") && args.has("animate")) return absl::InvalidArgumentError("give --step or --animate, not both");
  RenderOptions options;
  options.animate = args.has("animate");
  if (args.has("step")) {
    auto step = parse_int("step", args.get("step"));
    if (!step.ok()) return step.status();
    if (*step < 0) return absl::InvalidArgumentError(absl::StrCat("bad --step ", *step, ": frames count from 0"));
    options.step = *step;
  }
  if (args.has("radius")) {
    auto radius = parse_positive("radius", args.get("radius"));
    if (!radius.ok()) return radius.status();
    options.radius_m = *radius;
  }
  auto scenarios = read_scenarios(file);
  if (!scenarios.ok()) return scenarios.status();
  auto scenario = pick_scenario(*scenarios, args, file);
  if (!scenario.ok()) return scenario.status();
  auto svg = render_scene_svg(**scenario, options);
  if (!svg.ok()) return svg.status();
  const std::string out = args.get("out", (*scenario)->id + (options.animate ? "-anim.svg" : ".svg"));
  if (auto st = write_file(out, *svg); !st.ok()) return st;
  if (out != "-") std::fprintf(stderr, "wrote %s (%zu bytes)\n", out.c_str(), svg->size());
  return absl::OkStatus();
}

}  // namespace

int render_main(int argc, char** argv) {
  auto args = parse_args(argc, argv, 1, {"scenario", "index", "step", "radius", "out"}, {"animate", "help"});
  const bool help = args.ok() && args->has("help");
  if (!args.ok() || help || args->positional.size() != 1) {
    if (!args.ok()) std::fprintf(stderr, "render: %s\n", std::string(args.status().message()).c_str());
    else if (!help && args->positional.size() > 1) std::fputs("render: one FILE at a time\n", stderr);
    std::fputs(kUsage, help ? stdout : stderr);
    return help ? 0 : 2;
  }
  if (auto st = run(*args); !st.ok()) {
    std::fprintf(stderr, "render: %s\n", std::string(st.message()).c_str());
    return 1;
  }
  return 0;
}

}  // namespace ss::cli
