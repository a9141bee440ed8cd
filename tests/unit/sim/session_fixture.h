// Shared set-up for session tests: the real WOMD scenario with lights (read in place from ../shared) and a model
// with random weights.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "engine/map/focus.h"
#include "engine/model/model.h"
#include "engine/scenario/read.h"
#include "engine/sim/session.h"

namespace ss::testing {

struct World {
  std::shared_ptr<const Model> model;
  std::shared_ptr<const Scenario> scenario;
  std::shared_ptr<const MapContext> map;
};

// Model options with the KV caches' precision pinned, and fp32 products (tests that bind the fp32 numerics, or test
// both key precisions), whatever the environment says.
inline ModelOptions kv(KvPrecision p) {
  ModelOptions o;
  o.kv_precision = p;
  o.matmul_precision = MatmulPrecision::fp32;
  return o;
}

inline World load_world(const std::string& config = "small", uint64_t weight_seed = 1, ModelOptions options = {}) {
  World w;
  auto scenarios = read_scenarios(SS_DATA_DIR "/womd/tfrecord/motion_data_one_scenario.tfrecord");
  EXPECT_TRUE(scenarios.ok()) << scenarios.status();
  w.scenario = std::make_shared<const Scenario>((*scenarios)[0]);
  auto model = Model::create(init_weights(*model_config_by_name(config), weight_seed), options);
  EXPECT_TRUE(model.ok()) << model.status();
  w.model = *model;
  auto map = w.model->encode_map(nearest_segments(segment_map(*w.scenario), scenario_focus(*w.scenario)));
  EXPECT_TRUE(map.ok()) << map.status();
  w.map = *map;
  return w;
}

// A test suite whose tests share one world with the small model, loaded once for the suite.
class SmallWorldTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { world_ = new World(load_world("small")); }
  static void TearDownTestSuite() {
    delete world_;
    world_ = nullptr;
  }
  static const World& w() { return *world_; }
  static inline World* world_ = nullptr;
};

inline std::unique_ptr<Session> start(const World& w, SessionOptions o) {
  auto s = Session::create(w.model, w.scenario, w.map, o);
  EXPECT_TRUE(s.ok()) << s.status();
  return s.ok() ? std::move(*s) : nullptr;
}

// The SDC's log pose at a 2 Hz step, as a control.
inline ControlInput sdc_control(const World& w, int step) {
  const Track& sdc = w.scenario->tracks[w.scenario->sdc_track_index];
  const ObjectState& st = sdc.states[std::min(step * 5, static_cast<int>(sdc.states.size()) - 1)];
  return {sdc.id, st.x, st.y, st.heading, std::nullopt};
}

inline bool same_result(const StepResult& a, const StepResult& b) {
  if (a.step != b.step || a.agents.size() != b.agents.size() || a.lights.size() != b.lights.size() || a.left != b.left)
    return false;
  for (size_t i = 0; i < a.agents.size(); ++i)
    if (a.agents[i].id != b.agents[i].id || a.agents[i].type != b.agents[i].type || !(a.agents[i].state == b.agents[i].state))
      return false;
  for (size_t i = 0; i < a.lights.size(); ++i)
    if (a.lights[i].state != b.lights[i].state) return false;
  return true;
}

// `steps` steps with the SDC driven by its log; stops at the first error (reported).
inline std::vector<StepResult> roll(Session& s, const World& w, int steps) {
  std::vector<StepResult> out;
  for (int i = 0; i < steps; ++i) {
    auto r = s.step({sdc_control(w, s.step_index() + 1)});
    EXPECT_TRUE(r.ok()) << r.status();
    if (!r.ok()) break;
    out.push_back(*r);
  }
  return out;
}

inline bool same_rollout(const std::vector<StepResult>& a, const std::vector<StepResult>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (!same_result(a[i], b[i])) return false;
  return true;
}

}  // namespace ss::testing
