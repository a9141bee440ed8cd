#include "engine/scenestreamer.h"

#include <map>

#include "absl/strings/str_cat.h"
#include "engine/model/linalg.h"
#include "engine/model/weights.h"
#include "engine/scenario/read.h"
#include "engine/scenario/womd_proto.h"
#include "engine/sim/map_cache.h"

namespace ss {

class Engine {
 public:
  EngineOptions options;
  std::shared_ptr<const Model> model;
  std::unique_ptr<MapCache> maps;
  bool random_weights = false;
  std::vector<EngineScenario> listing;
  std::map<std::string, std::shared_ptr<const Scenario>> scenarios;
};

namespace {

absl::Status check_limits(const Engine& e, const Scenario& s, const std::string& where) {
  if (static_cast<int>(s.tracks.size()) > e.options.max_scenario_tracks)
    return absl::ResourceExhaustedError(absl::StrCat(where, ": ", std::to_string(s.tracks.size()),
                                                     " tracks, above the limit of ",
                                                     std::to_string(e.options.max_scenario_tracks)));
  if (static_cast<int>(s.map_features.size()) > e.options.max_map_features)
    return absl::ResourceExhaustedError(absl::StrCat(where, ": ", std::to_string(s.map_features.size()),
                                                     " map features, above the limit of ",
                                                     std::to_string(e.options.max_map_features)));
  return absl::OkStatus();
}

absl::StatusOr<std::shared_ptr<const Scenario>> resolve(Engine& e, const SessionSource& source) {
  if (!source.scenario_name.empty() && !source.womd_bytes.empty())
    return absl::InvalidArgumentError("scenario: give either scenario_name or womd_bytes, not both");
  if (!source.scenario_name.empty()) {
    auto it = e.scenarios.find(source.scenario_name);
    if (it == e.scenarios.end())
      return absl::NotFoundError(absl::StrCat("scenario_name '", source.scenario_name,
                                              "' is not a bundled scenario (ListScenarios names them)"));
    return it->second;
  }
  if (source.womd_bytes.empty()) return absl::InvalidArgumentError("scenario: neither scenario_name nor womd_bytes set");
  if (source.womd_bytes.size() > e.options.max_scenario_bytes)
    return absl::ResourceExhaustedError(absl::StrCat("womd_bytes: ", std::to_string(source.womd_bytes.size()),
                                                     " bytes, above the limit of ",
                                                     std::to_string(e.options.max_scenario_bytes)));
  auto s = scenario_from_womd_bytes(source.womd_bytes, "womd_bytes");
  if (!s.ok()) return absl::InvalidArgumentError(s.status().message());
  if (auto st = check_limits(e, *s, "womd_bytes"); !st.ok()) return st;
  return std::make_shared<const Scenario>(std::move(*s));
}

}  // namespace

void EngineDeleter::operator()(Engine* e) const { delete e; }

absl::StatusOr<EnginePtr> engine_create(const EngineOptions& options) {
  EnginePtr e(new Engine());
  e->options = options;
  absl::StatusOr<Weights> w;
  if (options.model_path.empty()) {
    auto config = model_config_by_name(options.random_config);
    if (!config.ok()) return config.status();
    w = init_weights(*config, options.random_seed);
    e->random_weights = true;
  } else {
    w = load_weights(options.model_path);
    if (!w.ok()) return w.status();
  }
  auto model = Model::create(std::move(*w));
  if (!model.ok()) return model.status();
  e->model = *model;
  e->maps = std::make_unique<MapCache>(e->model);
  if (!options.scenario_paths.empty()) {
    auto all = read_scenarios(options.scenario_paths);
    if (!all.ok()) return all.status();
    for (Scenario& s : *all) {
      if (e->scenarios.count(s.id))
        return absl::InvalidArgumentError(absl::StrCat("scenario id '", s.id, "' appears twice in the scenario paths"));
      e->listing.push_back({s.id, static_cast<int>(s.tracks.size()), static_cast<int>(s.map_features.size()),
                            s.num_frames(), s.sdc_track_index >= 0});
      const std::string id = s.id;
      e->scenarios[id] = std::make_shared<const Scenario>(std::move(s));
    }
  }
  return e;
}

const std::vector<EngineScenario>& engine_scenarios(const Engine& engine) { return engine.listing; }
const ModelConfig& engine_model_config(const Engine& engine) { return engine.model->config(); }
bool engine_random_weights(const Engine& engine) { return engine.random_weights; }
int engine_map_encodes(const Engine& engine) { return engine.maps->encodes(); }

absl::StatusOr<std::shared_ptr<const Scenario>> engine_scenario(Engine& engine, const SessionSource& source) {
  return resolve(engine, source);
}

absl::StatusOr<std::unique_ptr<Session>> session_create(Engine& engine, const SessionSource& source,
                                                        const SessionOptions& options) {
  auto scenario = resolve(engine, source);
  if (!scenario.ok()) return scenario.status();
  auto map = engine.maps->get(**scenario);
  if (!map.ok()) return map.status();
  return Session::create(engine.model, *scenario, *map, options);
}

absl::StatusOr<std::unique_ptr<Session>> session_restore(Engine& engine, const SessionSource& source,
                                                         const std::string& saved) {
  auto scenario = resolve(engine, source);
  if (!scenario.ok()) return scenario.status();
  auto map = engine.maps->get(**scenario);
  if (!map.ok()) return map.status();
  return Session::restore(engine.model, *scenario, *map, saved);
}

void engine_thread_init() { enable_flush_to_zero(); }

}  // namespace ss
