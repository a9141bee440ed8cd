// What the trainer's tests share: a tiny configuration of the model and a small teacher-forced real example.
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "engine/model/config.h"
#include "engine/scenario/read.h"
#include "training/teacher_forcing.h"

namespace ss::train::testing {

inline const std::string kRealTfRecord = std::string(SS_DATA_DIR) + "/womd/tfrecord/motion_data_one_scenario.tfrecord";

// The small configuration narrowed to d_model 32 and one encoder layer.
inline ModelConfig tiny_config(int decoder_layers) {
  ModelConfig c = *model_config_by_name("small");
  c.d_model = 32;
  c.decoder_layers = decoder_layers;
  c.encoder_layers = 1;
  return c;
}

// The first scenario of `path`, teacher-forced with at most 8 agents and 300 map segments.
inline void small_example(const std::string& path, const ModelConfig& c, TeacherForcedExample* out) {
  auto s = read_scenarios(path);
  ASSERT_TRUE(s.ok()) << s.status();
  TeacherForcingOptions o;
  o.max_agents = 8;
  o.max_map_segments = 300;
  auto ex = teacher_forced_example((*s)[0], c, o);
  ASSERT_TRUE(ex.ok()) << ex.status();
  *out = std::move(*ex);
}

}  // namespace ss::train::testing
