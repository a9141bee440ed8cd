#include "tools/dataset/scenario_stats.h"

#include <algorithm>
#include <cmath>
#include <set>

#include "absl/strings/str_format.h"

namespace ss::dataset {
namespace {

constexpr const char* kTypeNames[] = {"vehicle", "pedestrian", "cyclist"};

int type_slot(ObjectType t) {
  switch (t) {
    case ObjectType::vehicle: return 0;
    case ObjectType::pedestrian: return 1;
    case ObjectType::cyclist: return 2;
    default: return -1;
  }
}

double rank_percentile(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return 0;
  const size_t k = static_cast<size_t>(std::ceil(q * sorted.size()));
  return sorted[std::clamp<size_t>(k, 1, sorted.size()) - 1];
}

}  // namespace

nlohmann::ordered_json summary(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  double sum = 0;
  for (double v : values) sum += v;
  return {{"mean", values.empty() ? 0.0 : sum / values.size()},
          {"p50", rank_percentile(values, 0.5)},
          {"p90", rank_percentile(values, 0.9)}};
}

void ScenarioStats::add(const Scenario& s) {
  const int frames = s.num_frames();
  min_frames_ = scenarios_ ? std::min(min_frames_, frames) : frames;
  max_frames_ = scenarios_ ? std::max(max_frames_, frames) : frames;
  ++scenarios_;
  std::array<int, kTypes> counts{};
  for (const Track& t : s.tracks) {
    const int k = type_slot(t.type);
    if (k < 0) continue;
    bool seen = false;
    for (const ObjectState& st : t.states) {
      if (!st.valid) continue;
      seen = true;
      speeds_[k].push_back(std::hypot(st.vx, st.vy));
    }
    counts[k] += seen ? 1 : 0;  // a track never valid is no agent of the scenario
  }
  for (int k = 0; k < kTypes; ++k) agents_[k].push_back(counts[k]);
  std::set<int64_t> lanes;
  for (const auto& frame : s.signals)
    for (const SignalLaneState& l : frame) lanes.insert(l.lane);
  lights_.push_back(static_cast<double>(lanes.size()));
  for (const MapFeature& f : s.map_features) features_[map_feature_kind_name(f.kind)] += 1;
}

nlohmann::ordered_json ScenarioStats::json() const {
  nlohmann::ordered_json j;
  j["scenarios"] = scenarios_;
  j["frames"] = {{"min", min_frames_}, {"max", max_frames_}};
  nlohmann::ordered_json agents = nlohmann::ordered_json::object(), speeds = nlohmann::ordered_json::object();
  std::vector<double> total(scenarios_, 0.0);
  for (int k = 0; k < kTypes; ++k) {
    agents[kTypeNames[k]] = summary(agents_[k]);
    for (int i = 0; i < scenarios_; ++i) total[i] += agents_[k][i];
    speeds[kTypeNames[k]] = summary(std::vector<double>(speeds_[k].begin(), speeds_[k].end()));
    speeds[kTypeNames[k]]["samples"] = speeds_[k].size();
  }
  agents["all"] = summary(total);
  j["agents_per_scenario"] = agents;
  nlohmann::ordered_json lights = summary(lights_);
  lights["with_lights"] = std::count_if(lights_.begin(), lights_.end(), [](double v) { return v > 0; });
  j["lights_per_scenario"] = lights;
  j["speed_mps"] = speeds;
  nlohmann::ordered_json features = nlohmann::ordered_json::object();
  for (const auto& [kind, n] : features_) features[kind] = scenarios_ ? n / scenarios_ : 0.0;
  j["map_features_per_scenario"] = features;
  return j;
}

std::string stats_table(const std::vector<std::pair<std::string, nlohmann::ordered_json>>& columns, bool markdown) {
  std::vector<std::pair<std::string, std::vector<std::string>>> rows;
  auto row = [&](const std::string& name, auto cell) {
    std::vector<std::string> cells;
    for (const auto& [col, j] : columns) cells.push_back(cell(j));
    rows.emplace_back(name, std::move(cells));
  };
  auto msummary = [](const nlohmann::ordered_json& s, const char* fmt_mean) {
    if (s.is_null()) return std::string("-");
    return absl::StrFormat("%s / %s / %s", absl::StrFormat(fmt_mean, s["mean"].get<double>()),
                           absl::StrFormat(fmt_mean, s["p50"].get<double>()),
                           absl::StrFormat(fmt_mean, s["p90"].get<double>()));
  };
  row("scenarios", [](const nlohmann::ordered_json& j) { return std::to_string(j["scenarios"].get<int>()); });
  row("frames", [](const nlohmann::ordered_json& j) {
    const int lo = j["frames"]["min"], hi = j["frames"]["max"];
    return lo == hi ? std::to_string(lo) : absl::StrFormat("%d-%d", lo, hi);
  });
  for (const char* t : {"vehicle", "pedestrian", "cyclist", "all"})
    row(absl::StrFormat("%s agents / scenario (mean / p50 / p90)", t),
        [&](const nlohmann::ordered_json& j) { return msummary(j["agents_per_scenario"][t], "%.1f"); });
  row("signal lanes / scenario (mean / p50 / p90)",
      [&](const nlohmann::ordered_json& j) { return msummary(j["lights_per_scenario"], "%.1f"); });
  row("scenarios with signals", [](const nlohmann::ordered_json& j) {
    return absl::StrFormat("%d", j["lights_per_scenario"]["with_lights"].get<int>());
  });
  for (const char* t : {"vehicle", "pedestrian", "cyclist"})
    row(absl::StrFormat("%s speed m/s (mean / p50 / p90)", t),
        [&](const nlohmann::ordered_json& j) { return msummary(j["speed_mps"][t], "%.2f"); });
  std::set<std::string> kinds;
  for (const auto& [col, j] : columns)
    for (const auto& [k, v] : j["map_features_per_scenario"].items()) kinds.insert(k);
  for (const std::string& k : kinds)
    row(absl::StrFormat("%s features / scenario (mean)", k), [&](const nlohmann::ordered_json& j) {
      const auto& f = j["map_features_per_scenario"];
      return f.contains(k) ? absl::StrFormat("%.1f", f[k].get<double>()) : std::string("0");
    });

  if (markdown) {
    std::string out = "| |";
    for (const auto& [col, j] : columns) out += " " + col + " |";
    out += "\n|---|";
    for (size_t c = 0; c < columns.size(); ++c) out += "---|";
    out += "\n";
    for (const auto& [name, cells] : rows) {
      out += "| " + name + " |";
      for (const std::string& c : cells) out += " " + c + " |";
      out += "\n";
    }
    return out;
  }
  std::vector<size_t> width(columns.size() + 1, 0);
  width[0] = 0;
  for (const auto& [name, cells] : rows) {
    width[0] = std::max(width[0], name.size());
    for (size_t c = 0; c < cells.size(); ++c) width[c + 1] = std::max(width[c + 1], cells[c].size());
  }
  for (size_t c = 0; c < columns.size(); ++c) width[c + 1] = std::max(width[c + 1], columns[c].first.size());
  std::string out = absl::StrFormat("%-*s", static_cast<int>(width[0]), "");
  for (size_t c = 0; c < columns.size(); ++c)
    out += absl::StrFormat("  %*s", static_cast<int>(width[c + 1]), columns[c].first);
  out += "\n";
  for (const auto& [name, cells] : rows) {
    out += absl::StrFormat("%-*s", static_cast<int>(width[0]), name);
    for (size_t c = 0; c < cells.size(); ++c) out += absl::StrFormat("  %*s", static_cast<int>(width[c + 1]), cells[c]);
    out += "\n";
  }
  return out;
}

}  // namespace ss::dataset
