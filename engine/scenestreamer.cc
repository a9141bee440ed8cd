#include "engine/scenestreamer.h"

#include <bit>
#include <map>
#include <mutex>

#include "absl/strings/str_cat.h"
#include "engine/geometry/limits.h"
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
  // The limits are checked on the wire, before anything is built (a refused scenario costs no memory).
  WomdLimits limits;
  limits.max_tracks = e.options.max_scenario_tracks;
  limits.max_map_features = e.options.max_map_features;
  limits.max_frames = e.options.max_scenario_frames;
  limits.max_map_points = e.options.max_map_points;
  auto s = scenario_from_womd_bytes(source.womd_bytes, "womd_bytes", limits);
  if (!s.ok())
    return s.status().code() == absl::StatusCode::kResourceExhausted ? s.status()
                                                                      : absl::InvalidArgumentError(s.status().message());
  return std::make_shared<const Scenario>(std::move(*s));
}

// What an allocation of n bytes takes: jemalloc's size classes, four per doubling (a 1 MiB + 1 string takes 1.25 MiB).
uint64_t allocated(uint64_t n) {
  if (n <= 16) return n == 0 ? 0 : 16;
  const int k = 63 - std::countl_zero(n - 1);  // 2^k < n <= 2^(k+1)
  const uint64_t step = uint64_t{1} << std::max(k - 2, 4);
  return (n + step - 1) / step * step;
}
template <class T>
uint64_t heap(const std::vector<T>& v) {
  return allocated(v.capacity() * sizeof(T));
}
uint64_t heap(const std::string& s) {
  return s.capacity() > 15 ? allocated(s.capacity() + 1) : 0;  // libstdc++ keeps up to 15 characters in the string
}

// The heap bytes a scenario holds (every vector's and string's capacity, nested ones included) plus the struct.
uint64_t scenario_bytes(const Scenario& s) {
  uint64_t b = sizeof(Scenario) + heap(s.id) + heap(s.timestamps) + heap(s.tracks) + heap(s.map_features) +
               heap(s.signals) + heap(s.objects_of_interest) + heap(s.tracks_to_predict) + heap(s.laser_data) +
               heap(s.camera_tokens);
  for (const Track& t : s.tracks) b += heap(t.states);
  for (const MapFeature& f : s.map_features) {
    b += heap(f.points) + heap(f.stop_sign_lanes) + heap(f.lane.entry_lanes) + heap(f.lane.exit_lanes) +
         heap(f.lane.left_neighbors) + heap(f.lane.right_neighbors) + heap(f.lane.left_boundaries) +
         heap(f.lane.right_boundaries);
    for (const LaneNeighbor& n : f.lane.left_neighbors) b += heap(n.boundaries);
    for (const LaneNeighbor& n : f.lane.right_neighbors) b += heap(n.boundaries);
  }
  for (const auto& frame : s.signals) b += heap(frame);
  for (const std::string& x : s.laser_data) b += heap(x);
  for (const std::string& x : s.camera_tokens) b += heap(x);
  return b;
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
  const Scenario& sc = **scenario;
  // The SDC is the controlled agent unless the host says otherwise: a scenario without one valid now would leave
  // the session with no controlled agent, which the caller did not ask for.
  if (options.controlled_ids.empty() && options.control_sdc &&
      (sc.sdc_track_index < 0 || !sc.tracks[sc.sdc_track_index].states[sc.current_time_index].valid))
    return absl::InvalidArgumentError(absl::StrCat(
        "the scenario has no SDC valid at its current frame (",
        sc.sdc_track_index < 0 ? std::string("it names none")
                               : absl::StrCat("track ", sc.tracks[sc.sdc_track_index].id, " is not valid at frame ",
                                              sc.current_time_index),
        "), so no agent would be controlled: set model_drives_sdc to let the model drive every agent, or name "
        "controlled_agent_ids"));
  auto map = engine.maps->get(sc);
  if (!map.ok()) return map.status();
  auto s = Session::create(engine.model, *scenario, *map, options);
  if (!s.ok()) return s.status();
  // Full mode places its own agents; every other mode starts from the log's, and a session of none is a mistake.
  if (options.mode != SessionMode::full && (*s)->tick_view().agents.empty())
    return absl::InvalidArgumentError(absl::StrCat(
        "the session would have no agent: no vehicle, pedestrian or cyclist of the scenario is valid at its current "
        "frame ", sc.current_time_index, " within roi_radius ", options.roi_radius, " m"));
  (*s)->set_event_map(event_map_for(engine, sc));
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
  if (!(request.near_radius > 0 && request.near_radius <= kMaxCoordinate))
    return absl::InvalidArgumentError(absl::StrCat("near_radius ", request.near_radius, " is not a distance in (0, ",
                                                   kMaxCoordinate, "] m"));
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
  // A client-sent scenario: its parsed form, its map encoding and its event map are this session's alone (an
  // encoding shared by sessions on the same map is counted by each: the count errs on the safe side).
  if (session.event_map()) b += session.event_map()->bytes();
  return b + scenario_bytes(s) + session.map().bytes();
}

void engine_thread_init() { enable_flush_to_zero(); }

}  // namespace ss
