#include "engine/scenestreamer.h"

#include <map>
#include <mutex>

#include "absl/strings/str_cat.h"
#include "engine/model/linalg.h"
#include "engine/model/weights.h"
#include "engine/offline.h"
#include "engine/scenario/read.h"
#include "engine/scenario/womd_proto.h"
#include "engine/sim/events.h"
#include "engine/sim/map_cache.h"
#include "engine/sim/session.h"

namespace ss {

class Engine {
 public:
  EngineOptions options;
  std::shared_ptr<const Model> model;
  std::unique_ptr<MapCache> maps;
  bool random_weights = false;
  std::vector<EngineScenario> listing;
  std::map<std::string, std::shared_ptr<const Scenario>> scenarios;
  // The event maps of bundled scenarios, built at their first session and shared by all of them.
  std::mutex event_maps_mu;
  std::map<const Scenario*, std::shared_ptr<const EventMap>> event_maps;
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

bool bundled(const Engine& e, const Scenario& s) {
  auto it = e.scenarios.find(s.id);
  return it != e.scenarios.end() && it->second.get() == &s;
}

// The map a session's events are measured on: a bundled scenario's is shared, a client-sent one's is its own.
std::shared_ptr<const EventMap> event_map_for(Engine& e, const Scenario& s) {
  if (!bundled(e, s)) return std::make_shared<const EventMap>(event_map_from_scenario(s));
  std::lock_guard<std::mutex> l(e.event_maps_mu);
  auto& m = e.event_maps[&s];
  if (!m) m = std::make_shared<const EventMap>(event_map_from_scenario(s));
  return m;
}

}  // namespace

void EngineDeleter::operator()(Engine* e) const { delete e; }

absl::StatusOr<std::shared_ptr<const Model>> model_load(const EngineOptions& options) {
  absl::StatusOr<Weights> w;
  if (options.model_path.empty()) {
    auto config = model_config_by_name(options.random_config);
    if (!config.ok()) return config.status();
    w = init_weights(*config, options.random_seed);
  } else {
    w = load_weights(options.model_path);
    if (!w.ok()) return w.status();
  }
  ModelOptions mo;
  mo.step_threads = options.step_threads;
  if (!options.kv_precision.empty()) {
    auto p = kv_precision_by_name(options.kv_precision);
    if (!p.ok()) return absl::InvalidArgumentError(absl::StrCat("kv precision: ", p.status().message()));
    mo.kv_precision = *p;
  }
  if (!options.matmul_precision.empty()) {
    auto p = matmul_precision_by_name(options.matmul_precision);
    if (!p.ok()) return absl::InvalidArgumentError(absl::StrCat("matmul precision: ", p.status().message()));
    mo.matmul_precision = *p;
  }
  auto model = Model::create(std::move(*w), mo);
  if (!model.ok()) {
    if (options.model_path.empty()) return model.status();
    return absl::Status(model.status().code(), absl::StrCat(options.model_path, ": ", model.status().message()));
  }
  return std::shared_ptr<const Model>(*std::move(model));
}

absl::StatusOr<EnginePtr> engine_create(const EngineOptions& options) {
  EnginePtr e(new Engine());
  e->options = options;
  e->random_weights = options.model_path.empty();
  auto model = model_load(options);
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
const std::string& engine_model_name(const Engine& engine) { return engine.model->config().name; }
const char* engine_kv_precision(const Engine& engine) { return kv_precision_name(engine.model->kv_precision()); }
const char* engine_matmul_precision(const Engine& engine) {
  return matmul_precision_name(engine.model->matmul_precision());
}
bool engine_random_weights(const Engine& engine) { return engine.random_weights; }
int engine_map_encodes(const Engine& engine) { return engine.maps->encodes(); }

void SessionDeleter::operator()(Session* s) const { delete s; }

absl::StatusOr<SessionPtr> session_create(Engine& engine, const SessionSource& source, const SessionOptions& options) {
  auto scenario = resolve(engine, source);
  if (!scenario.ok()) return scenario.status();
  auto map = engine.maps->get(**scenario);
  if (!map.ok()) return map.status();
  auto s = Session::create(engine.model, *scenario, *map, options);
  if (!s.ok()) return s.status();
  (*s)->set_event_map(event_map_for(engine, **scenario));
  return SessionPtr(s->release());
}

absl::StatusOr<SessionPtr> session_restore(Engine& engine, const SessionSource& source, const std::string& state) {
  auto scenario = resolve(engine, source);
  if (!scenario.ok()) return scenario.status();
  auto map = engine.maps->get(**scenario);
  if (!map.ok()) return map.status();
  auto s = Session::restore(engine.model, *scenario, *map, state);
  if (!s.ok()) return s.status();
  (*s)->set_event_map(event_map_for(engine, **scenario));
  return SessionPtr(s->release());
}

SessionPtr session_fork(const Session& session) { return SessionPtr(session.fork().release()); }
absl::StatusOr<StepResult> session_tick(Session& session, const std::vector<ControlInput>& controls) {
  return session.tick(controls);
}
StepResult session_view(const Session& session) { return session.tick_view(); }
int64_t session_tick_index(const Session& session) { return session.tick_index(); }
absl::StatusOr<std::vector<int64_t>> session_inject(Session& session, const InjectRequest& request) {
  return session.inject(request);
}
absl::Status session_force(Session& session, const StateForceRequest& request) { return session.state_force(request); }
const SessionOptions& session_options(const Session& session) { return session.options(); }
const std::vector<MapFeature>& session_map_features(const Session& session) {
  return session.scenario().map_features;
}
std::string session_save(const Session& session) { return session.save(); }

uint64_t session_memory_bytes(const Engine& engine, const Session& session) {
  uint64_t b = session.memory_bytes();
  const Scenario& s = session.scenario();
  if (bundled(engine, s)) return b;
  // A client-sent scenario: its parsed form, its map encoding and its event map are this session's alone.
  if (session.event_map()) b += session.event_map()->bytes();
  b += sizeof(Scenario) + s.timestamps.capacity() * sizeof(double) + s.signals.capacity() * 64;
  for (const Track& t : s.tracks) b += sizeof(Track) + t.states.capacity() * sizeof(ObjectState);
  for (const MapFeature& m : s.map_features) b += sizeof(MapFeature) + m.points.capacity() * sizeof(MapPoint);
  return b + session.map().bytes();
}

void engine_thread_init() { enable_flush_to_zero(); }

}  // namespace ss
