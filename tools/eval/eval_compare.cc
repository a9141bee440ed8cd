#include "tools/eval/eval_compare.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "offline/eval/estimators.h"
#include "offline/eval/evaluate.h"
#include "offline/eval/meta_metric.h"
#include "engine/io/file_io.h"
#include "engine/io/json_strict.h"

namespace ss::cli {
namespace {

using nlohmann::json;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct EvalFile {
  std::string path;
  json root;
  std::map<std::string, const json*> scenarios;  // per_scenario entries by id
};

absl::StatusOr<EvalFile> read_eval_file(const std::string& path) {
  auto text = file_read_all(path);
  if (!text.ok()) return text.status();
  EvalFile f;
  f.path = path;
  auto root = json_parse_strict(*text);
  if (!root.ok()) return absl::Status(root.status().code(), absl::StrCat(path, ": ", root.status().message()));
  f.root = *std::move(root);
  if (!f.root.is_object() || !f.root.contains("per_scenario") || !f.root["per_scenario"].is_array())
    return absl::InvalidArgumentError(absl::StrCat(path, ": not an eval result (no per_scenario array)"));
  if (!f.root.contains("sdc") || !f.root["sdc"].is_string())
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": says no --sdc rule (written before eval had --sdc?); evaluate again"));
  for (const json& s : f.root["per_scenario"]) {
    if (!s.is_object() || !s.contains("id") || !s["id"].is_string())
      return absl::InvalidArgumentError(absl::StrCat(path, ": a per_scenario entry has no string id"));
    if (!f.scenarios.emplace(s["id"].get<std::string>(), &s).second)
      return absl::InvalidArgumentError(absl::StrCat(path, ": scenario ", s["id"].get<std::string>(), " is listed twice"));
  }
  if (f.scenarios.empty()) return absl::InvalidArgumentError(absl::StrCat(path, ": per_scenario is empty"));
  return f;
}

// A number of an entry by key path ("windows/1/realism_meta"); NaN when absent or null.
double value_at(const json& entry, const std::vector<std::string>& path) {
  const json* j = &entry;
  for (const std::string& k : path) {
    if (j->is_array()) {
      const size_t i = std::stoul(k);
      if (i >= j->size()) return kNaN;
      j = &(*j)[i];
    } else if (j->is_object() && j->contains(k)) {
      j = &(*j)[k];
    } else {
      return kNaN;
    }
  }
  return j->is_number() ? j->get<double>() : kNaN;
}

std::string label(const json& root) {
  std::string policy = root.value("policy", "?");
  if (root.contains("mode") && root["mode"].is_string()) policy += absl::StrCat(", ", root["mode"].get<std::string>(), " mode");
  return absl::StrCat(policy, ", --sdc ", root["sdc"].get<std::string>(), ", K = ", root.value("rollouts", 0));
}

std::string fmt(double v) { return std::isfinite(v) ? absl::StrFormat("%.4f", v) : "n/a"; }

}  // namespace

absl::StatusOr<CompareReport> compare_eval_files(const CompareRequest& request) {
  auto a = read_eval_file(request.a_path);
  if (!a.ok()) return a.status();
  auto b = read_eval_file(request.b_path);
  if (!b.ok()) return b.status();
  if (a->root["sdc"] != b->root["sdc"])
    return absl::InvalidArgumentError(absl::StrCat(
        a->path, " was scored with --sdc ", a->root["sdc"].get<std::string>(), ", ", b->path, " with --sdc ",
        b->root["sdc"].get<std::string>(), ": their evaluated objects differ, so their scenarios do not pair"));
  std::vector<std::string> only_a, only_b;
  for (const auto& [id, e] : a->scenarios)
    if (!b->scenarios.count(id)) only_a.push_back(id);
  for (const auto& [id, e] : b->scenarios)
    if (!a->scenarios.count(id)) only_b.push_back(id);
  if (!only_a.empty() || !only_b.empty())
    return absl::InvalidArgumentError(absl::StrCat(
        a->path, " and ", b->path, " are not over the same scenarios: ", only_a.size(), " only in the first",
        only_a.empty() ? "" : absl::StrCat(" (", only_a[0], only_a.size() > 1 ? ", ..." : "", ")"), ", ",
        only_b.size(), " only in the second", only_b.empty() ? "" : absl::StrCat(" (", only_b[0], only_b.size() > 1 ? ", ..." : "", ")")));
  for (const auto& [id, e] : a->scenarios) {
    const json* other = b->scenarios.at(id);
    if (e->contains("evaluated_ids") && other->contains("evaluated_ids") && (*e)["evaluated_ids"] != (*other)["evaluated_ids"])
      return absl::InvalidArgumentError(
          absl::StrCat("scenario ", id, ": the two files evaluated different objects (evaluated_ids differ)"));
  }

  // Columns: every per-scenario value a metric reads; windows as "windows/<w>/<key>".
  PairedColumns columns;
  std::vector<std::vector<std::string>> paths;
  std::map<std::string, int> column_of;
  auto column = [&](std::vector<std::string> path) {
    const std::string name = absl::StrJoin(path, "/");
    auto [it, added] = column_of.emplace(name, static_cast<int>(paths.size()));
    if (added) paths.push_back(std::move(path)), columns.names.push_back(name);
    return it->second;
  };
  std::vector<CompareMetric> metrics;
  const auto& config = wosac_2025_config();
  size_t windows = 0;
  for (const EvalFile* f : {&*a, &*b})
    for (const auto& [id, e] : f->scenarios)
      if (e->contains("windows") && (*e)["windows"].is_array()) windows = std::max(windows, (*e)["windows"].size());
  auto realism_metrics = [&](const std::string& prefix, std::vector<std::string> base, bool likelihoods) {
    auto at = [&](const std::string& key) {
      std::vector<std::string> p = base;
      p.push_back(key);
      return column(p);
    };
    metrics.push_back({prefix + "realism_meta", {{at("realism_meta"), 1.0}}});
    for (RealismBucket bucket : {RealismBucket::kinematic, RealismBucket::interactive, RealismBucket::map}) {
      CompareMetric m;
      m.name = prefix + (bucket == RealismBucket::kinematic ? "kinematic" : bucket == RealismBucket::interactive ? "interactive" : "map");
      for (RealismFeature f : bucket_features(bucket))
        m.terms.push_back({at(std::string(config[f].name) + "_likelihood"), config[f].weight});
      metrics.push_back(m);
    }
    if (likelihoods)
      for (int f = 0; f < kNumRealismFeatures; ++f) {
        const std::string key = std::string(config[f].name) + "_likelihood";
        metrics.push_back({prefix + key, {{at(key), 1.0}}});
      }
    for (const char* key : {"collision_rate", "offroad_rate", "min_ade"}) metrics.push_back({prefix + key, {{at(key), 1.0}}});
  };
  realism_metrics("", {}, true);
  for (const char* key : {"ade_avg", "ade_min", "fde_avg", "fde_min", "add", "fdd"})
    metrics.push_back({key, {{column({key}), 1.0}}});
  // The ego benchmark's episode shares, when both files ran it (eval --ego).
  bool ego = true;
  for (const EvalFile* f : {&*a, &*b})
    for (const auto& [id, e] : f->scenarios) ego = ego && e->contains("ego_outcome");
  if (ego)
    for (const char* key : {"collision", "rear_end", "ego_at_fault", "side", "background_fault", "off_road",
                            "background_collision_rate"})
      metrics.push_back({absl::StrCat("ego: ", key), {{column({"ego_outcome", key}), 1.0}}});
  if (windows > 1)
    for (size_t w = 0; w < windows; ++w)
      realism_metrics(absl::StrCat("window ", realism_window_name(static_cast<int>(w)), ": "),
                      {"windows", std::to_string(w)}, false);

  for (const auto& [id, e] : a->scenarios) {
    const json* other = b->scenarios.at(id);
    std::vector<double> ra, rb;
    for (const auto& p : paths) ra.push_back(value_at(*e, p)), rb.push_back(value_at(*other, p));
    columns.a.push_back(std::move(ra));
    columns.b.push_back(std::move(rb));
  }
  auto diffs = compare_paired(columns, metrics, request.bootstrap);
  if (!diffs.ok()) return diffs.status();

  CompareReport r;
  const int n = static_cast<int>(a->scenarios.size());
  const int level = static_cast<int>(std::lround(100 * request.bootstrap.level));
  absl::StrAppendFormat(&r.table, "A: %s (%s)\nB: %s (%s)\n", a->path, label(a->root), b->path, label(b->root));
  absl::StrAppendFormat(&r.table,
                        "B - A over %d paired scenarios; %d %% percentile bootstrap interval (%d resamples of the "
                        "scenarios, seed %d); * the interval excludes 0\n\n",
                        n, level, request.bootstrap.resamples, request.bootstrap.seed);
  absl::StrAppendFormat(&r.table, "  %-44s %9s %9s %9s %22s %5s\n", "metric", "A", "B", "B - A",
                        absl::StrCat(level, " % interval"), "n");
  json metrics_json = json::array();
  for (const MetricDifference& d : *diffs) {
    const bool excludes = std::isfinite(d.low) && std::isfinite(d.high) && (d.low > 0 || d.high < 0);
    absl::StrAppendFormat(&r.table, "  %-44s %9s %9s %9s %22s %5d %s\n", d.name, fmt(d.a), fmt(d.b), fmt(d.difference),
                          absl::StrCat("[", fmt(d.low), ", ", fmt(d.high), "]"), d.scenarios, excludes ? "*" : "");
    metrics_json.push_back({{"name", d.name}, {"scenarios", d.scenarios}, {"a", d.a}, {"b", d.b},
                            {"difference", d.difference}, {"low", d.low}, {"high", d.high},
                            {"excludes_zero", excludes}});
  }
  r.json = {{"a", a->path}, {"b", b->path}, {"scenarios", n}, {"resamples", request.bootstrap.resamples},
            {"seed", request.bootstrap.seed}, {"level", request.bootstrap.level}, {"sdc", a->root["sdc"]},
            {"metrics", metrics_json}};
  return r;
}

}  // namespace ss::cli
