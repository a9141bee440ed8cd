#include "engine/tokens/fidelity.h"

#include <algorithm>
#include <cmath>

#include "engine/tokens/motion.h"
#include "engine/tokens/resample.h"

namespace ss {

void ErrorStats::add(double e) {
  sum += e;
  max = std::max(max, e);
  ++count;
}

void ErrorStats::merge(const ErrorStats& o) {
  sum += o.sum;
  max = std::max(max, o.max);
  count += o.count;
}

int model_type(ObjectType t) {
  switch (t) {
    case ObjectType::vehicle: return 0;
    case ObjectType::pedestrian: return 1;
    case ObjectType::cyclist: return 2;
    default: return -1;
  }
}

ObjectType object_type_of(int model_type) {
  switch (model_type) {
    case 1: return ObjectType::pedestrian;
    case 2: return ObjectType::cyclist;
    default: return ObjectType::vehicle;
  }
}

const char* model_type_name(int t) {
  static constexpr const char* kNames[kNumModelTypes] = {"vehicle", "pedestrian", "cyclist"};
  return t >= 0 && t < kNumModelTypes ? kNames[t] : "invalid";
}

void TokenizationFidelity::merge(const TokenizationFidelity& o) {
  ace.merge(o.ace);
  for (int t = 0; t < kNumModelTypes; ++t) ace_by_type[t].merge(o.ace_by_type[t]);
  if (ace_by_step.size() < o.ace_by_step.size()) ace_by_step.resize(o.ace_by_step.size());
  for (size_t t = 0; t < o.ace_by_step.size(); ++t) ace_by_step[t].merge(o.ace_by_step[t]);
  ace_last_step.merge(o.ace_last_step);
  for (int f = 0; f < kStateFields; ++f) {
    state_error[f].merge(o.state_error[f]);
    state_error_in_range[f].merge(o.state_error_in_range[f]);
    state_out_of_range[f] += o.state_out_of_range[f];
  }
  state_position_error.merge(o.state_position_error);
  state_samples += o.state_samples;
  state_without_anchor += o.state_without_anchor;
}

TokenizationFidelity measure_tokenization(const Scenario& s, std::span<const MapSegment> segments,
                                          const SegmentIndex& index) {
  TokenizationFidelity out;
  out.ace_by_step.resize(num_model_steps(s.num_frames()));
  for (const Track& track : s.tracks) {
    const int type = model_type(track.type);
    if (type < 0) continue;
    const std::vector<StepState> steps = downsample_track(track);

    const MotionTrack motion = tokenize_motion(steps);
    int last = -1;
    for (size_t t = 0; t < steps.size(); ++t) {
      if (motion.tokens[t] < 0 || motion.tokens[t] == kMotionStart) continue;
      out.ace.add(motion.ace[t]);
      out.ace_by_type[type].add(motion.ace[t]);
      out.ace_by_step[t].add(motion.ace[t]);
      last = static_cast<int>(t);
    }
    if (last >= 0) out.ace_last_step.add(motion.ace[last]);

    for (const StepState& st : steps) {
      if (!st.valid) continue;
      auto tokens = encode_agent_state(st, index, segments);
      if (!tokens.ok()) {
        ++out.state_without_anchor;
        continue;
      }
      ++out.state_samples;
      const RelativeState rel = relative_state(st, segments[tokens->segment].pose);
      for (int f = 0; f < kStateFields; ++f) {
        const double err = std::abs(rel[f] - state_bin_value(f, tokens->bins[f]));
        out.state_error[f].add(err);
        if (rel[f] < kStateRanges[f].min || rel[f] > kStateRanges[f].max)
          ++out.state_out_of_range[f];
        else
          out.state_error_in_range[f].add(err);
      }
      const StepState decoded = decode_agent_state(*tokens, segments);
      out.state_position_error.add(std::hypot(decoded.x - st.x, decoded.y - st.y));
    }
  }
  return out;
}

}  // namespace ss
