#include "tools/scenario_report.h"

#include <cstdio>
#include <map>
#include <set>
#include <string>

#include "engine/map/focus.h"
#include "engine/map/segments.h"
#include "engine/map/spatial_index.h"
#include "engine/tokens/light.h"
#include "engine/tokens/resample.h"

namespace ss::cli {

using nlohmann::ordered_json;

namespace {

ordered_json stats_json(const ErrorStats& e) {
  return {{"mean", e.mean()}, {"max", e.max}, {"count", e.count}};
}

}  // namespace

ordered_json fidelity_json(const TokenizationFidelity& f) {
  ordered_json j;
  j["motion_ace_mean"] = f.ace.mean();
  j["motion_ace_max"] = f.ace.max;
  j["motion_ace_count"] = f.ace.count;
  ordered_json by_type = ordered_json::object();
  for (int t = 0; t < kNumModelTypes; ++t) by_type[model_type_name(t)] = stats_json(f.ace_by_type[t]);
  j["motion_ace_by_type"] = by_type;
  ordered_json by_step = ordered_json::array();
  for (const ErrorStats& e : f.ace_by_step) by_step.push_back(stats_json(e));
  j["motion_ace_by_step"] = by_step;
  j["motion_ace_last_step"] = stats_json(f.ace_last_step);
  ordered_json max_err = ordered_json::object(), in_range = ordered_json::object(), clipped = ordered_json::object();
  for (int k = 0; k < kStateFields; ++k) {
    max_err[state_field_name(k)] = f.state_error[k].max;
    in_range[state_field_name(k)] = f.state_error_in_range[k].max;
    clipped[state_field_name(k)] = f.state_out_of_range[k];
  }
  j["state_roundtrip_max_error"] = max_err;
  j["state_roundtrip_max_error_in_range"] = in_range;
  j["state_out_of_range"] = clipped;
  j["state_roundtrip_position_error"] = stats_json(f.state_position_error);
  j["state_samples"] = f.state_samples;
  j["state_without_anchor"] = f.state_without_anchor;
  return j;
}

ScenarioReport report_scenario(const Scenario& s) {
  ScenarioReport r;
  ordered_json& j = r.json;
  j["scenario_id"] = s.id;
  j["frames"] = s.num_frames();
  j["steps_2hz"] = num_model_steps(s.num_frames());
  j["current_time_index"] = s.current_time_index;
  j["sdc_track_index"] = s.sdc_track_index;

  std::map<std::string, int> tracks;
  for (ObjectType t : {ObjectType::vehicle, ObjectType::pedestrian, ObjectType::cyclist}) tracks[object_type_name(t)] = 0;
  for (const Track& t : s.tracks) ++tracks[object_type_name(t.type)];
  j["tracks"] = tracks;
  j["tracks"]["total"] = s.tracks.size();
  j["tracks_to_predict"] = s.tracks_to_predict.size();

  std::map<std::string, int> features;
  for (const MapFeature& f : s.map_features) ++features[map_feature_kind_name(f.kind)];
  j["map_features"] = features;
  j["map_features"]["total"] = s.map_features.size();

  std::vector<MapSegment> all = segment_map(s);
  const size_t total_segments = all.size();
  std::vector<MapSegment> segments = nearest_segments(std::move(all), scenario_focus(s));
  j["segments"] = {{"total", total_segments}, {"kept", segments.size()}};

  std::set<int64_t> lanes;
  std::map<std::string, int> states;
  for (size_t f = 0; f < s.signals.size(); ++f) {
    for (const SignalLaneState& ls : s.signals[f]) {
      lanes.insert(ls.lane);
      if (frame_to_step(static_cast<int>(f)) >= 0) ++states[light_state_name(light_state_from_womd(ls.state))];
    }
  }
  j["lights"] = {{"lanes", lanes.size()}, {"states_2hz", states}};

  SegmentIndex index(segments);
  r.fidelity = measure_tokenization(s, segments, index);
  j.update(fidelity_json(r.fidelity));
  return r;
}

void print_report(const ordered_json& j) {
  auto num = [](const ordered_json& v) { return v.is_number() ? v.get<double>() : 0.0; };
  if (j.contains("scenario_id")) {
    std::printf("scenario %s: %d frames (%d steps at 2 Hz), current frame %d, sdc track %d\n",
                j["scenario_id"].get<std::string>().c_str(), j["frames"].get<int>(), j["steps_2hz"].get<int>(),
                j["current_time_index"].get<int>(), j["sdc_track_index"].get<int>());
    std::printf("  tracks:       %s\n", j["tracks"].dump().c_str());
    std::printf("  map features: %s\n", j["map_features"].dump().c_str());
    std::printf("  segments:     %s\n", j["segments"].dump().c_str());
    std::printf("  lights:       %s\n", j["lights"].dump().c_str());
  }
  std::printf("  motion tokens: ACE mean %.4f m, max %.4f m over %lld steps; last step mean %.4f m\n",
              num(j["motion_ace_mean"]), num(j["motion_ace_max"]), j["motion_ace_count"].get<long long>(),
              num(j["motion_ace_last_step"]["mean"]));
  for (const auto& [type, e] : j["motion_ace_by_type"].items())
    std::printf("    %-10s mean %.4f m  max %.4f m  (%lld steps)\n", type.c_str(), num(e["mean"]), num(e["max"]),
                e["count"].get<long long>());
  std::printf("    by step (mean m):");
  for (const auto& e : j["motion_ace_by_step"]) std::printf(" %.3f", num(e["mean"]));
  std::printf("\n  agent-state tokens (%lld agent steps, %lld without anchor): position error mean %.3f m max %.3f m\n",
              j["state_samples"].get<long long>(), j["state_without_anchor"].get<long long>(),
              num(j["state_roundtrip_position_error"]["mean"]), num(j["state_roundtrip_position_error"]["max"]));
  std::printf("    %-8s %12s %14s %12s\n", "field", "max error", "max in range", "clipped");
  for (const auto& [field, e] : j["state_roundtrip_max_error"].items())
    std::printf("    %-8s %12.4f %14.4f %12lld\n", field.c_str(), num(e),
                num(j["state_roundtrip_max_error_in_range"][field]), j["state_out_of_range"][field].get<long long>());
}

}  // namespace ss::cli
