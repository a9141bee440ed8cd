#include "training/batch.h"

#include <algorithm>

#include "engine/map/segments.h"

namespace ss::train {
namespace {

torch::Tensor ints(const std::vector<int64_t>& v) {
  return torch::from_blob(const_cast<int64_t*>(v.data()), {static_cast<int64_t>(v.size())}, torch::kInt64).clone();
}

torch::Tensor floats(const std::vector<float>& v, int64_t cols) {
  return torch::from_blob(const_cast<float*>(v.data()), {static_cast<int64_t>(v.size()) / cols, cols}, torch::kFloat32)
      .clone();
}

// Appends `lists` with key indices offset by `key_base`, queries after those already there.
void append_keys(const KeyLists& lists, int64_t key_base, std::vector<int64_t>& offsets, std::vector<int64_t>& keys,
                 std::vector<float>& features) {
  const int64_t base = keys.size();
  for (size_t i = 1; i < lists.offsets.size(); ++i) offsets.push_back(base + lists.offsets[i]);
  for (int k : lists.keys) keys.push_back(key_base + k);
  features.insert(features.end(), lists.features.begin(), lists.features.end());
}

SparseKeys sparse(const std::vector<int64_t>& offsets, const std::vector<int64_t>& keys) {
  return {ints(offsets), ints(keys)};
}

}  // namespace

int64_t Batch::target_count() const {
  int64_t n = light_rows.numel() + motion_rows.numel() + type_rows.numel() + end_rows.numel() + state_target.numel();
  for (const auto& s : segment_rows) n += s.numel();
  return n;
}

Batch make_batch(const std::vector<const TeacherForcedExample*>& examples) {
  Batch b;
  b.examples = static_cast<int>(examples.size());
  int64_t segments = 0, tokens = 0;
  for (const auto* ex : examples) segments += ex->segments.size(), tokens += ex->tokens.size();

  std::vector<float> points(segments * kMaxVectorsPerSegment * kPointFeatureDim, 0.0f);
  std::vector<uint8_t> mask(segments * kMaxVectorsPerSegment, 0);
  std::vector<int64_t> map_row, map_off{0}, map_keys, self_off{0}, self_keys, cross_off{0}, cross_keys;
  std::vector<float> map_feat, self_feat, cross_feat;
  std::vector<int64_t> kind, light_state, light_slot, map_id, intra, agent_slot, agent_type, motion_action;
  std::vector<float> motion_state, relative_state;
  std::vector<int64_t> light_rows, light_t, motion_rows, motion_t, type_rows, type_t, end_rows, end_t, end_first,
      state_rows, state_t;
  int64_t seg_base = 0, tok_base = 0;
  for (const auto* ex : examples) {
    b.map_begin.push_back(seg_base);
    b.token_begin.push_back(tok_base);
    // Points, segment by segment (the example stacks each segment's valid vectors).
    std::vector<int> seen(ex->segments.size(), 0);
    for (size_t r = 0; r < ex->point_segment.size(); ++r) {
      const int s = ex->point_segment[r];
      const int64_t slot = (seg_base + s) * kMaxVectorsPerSegment + seen[s]++;
      std::copy_n(ex->point_features.data() + r * kPointFeatureDim, kPointFeatureDim, points.data() + slot * kPointFeatureDim);
      mask[slot] = 1;
    }
    for (size_t s = 0; s < ex->segments.size(); ++s) map_row.push_back(s);
    append_keys(ex->map_keys, seg_base, map_off, map_keys, map_feat);
    append_keys(ex->self_keys, tok_base, self_off, self_keys, self_feat);
    append_keys(ex->cross_keys, seg_base, cross_off, cross_keys, cross_feat);
    std::vector<int64_t> unposed, seg_rows, seg_t;
    for (size_t i = 0; i < ex->tokens.size(); ++i) {
      const DecoderToken& t = ex->tokens[i];
      const int64_t row = tok_base + i;
      kind.push_back(static_cast<int64_t>(t.kind));
      light_state.push_back(t.light_state);
      light_slot.push_back(t.light_slot);
      map_id.push_back(t.map_id);
      intra.push_back(t.intra_index);
      agent_slot.push_back(t.agent_slot);
      agent_type.push_back(t.agent_type);
      motion_action.push_back(t.motion_action);
      motion_state.insert(motion_state.end(), t.motion_state.begin(), t.motion_state.end());
      relative_state.insert(relative_state.end(), t.relative_state.begin(), t.relative_state.end());
      if (!t.has_pose) unposed.push_back(row);
      auto target = [&](int value, std::vector<int64_t>& rows, std::vector<int64_t>& out) {
        if (value != kNoTarget) rows.push_back(row), out.push_back(value);
      };
      target(ex->light_target[i], light_rows, light_t);
      target(ex->motion_target[i], motion_rows, motion_t);
      target(ex->type_target[i], type_rows, type_t);
      target(ex->end_target[i], end_rows, end_t);
      if (ex->end_target[i] != kNoTarget) end_first.push_back(t.step == 0);
      target(ex->segment_target[i], seg_rows, seg_t);
      if (ex->state_target[i][0] != kNoTarget) {
        state_rows.push_back(row);
        state_t.insert(state_t.end(), ex->state_target[i].begin(), ex->state_target[i].end());
      }
    }
    b.unposed.push_back(ints(unposed));
    b.segment_rows.push_back(ints(seg_rows));
    b.segment_target.push_back(ints(seg_t));
    seg_base += ex->segments.size();
    tok_base += ex->tokens.size();
  }
  b.map_begin.push_back(seg_base);
  b.token_begin.push_back(tok_base);

  b.points = floats(points, kPointFeatureDim).view({segments, kMaxVectorsPerSegment, kPointFeatureDim});
  b.point_mask = torch::from_blob(mask.data(), {segments, kMaxVectorsPerSegment}, torch::kUInt8).clone().to(torch::kBool);
  b.map_row = ints(map_row);
  b.map_keys = sparse(map_off, map_keys);
  b.map_features = floats(map_feat, kRelationFeatures);
  b.kind = ints(kind);
  b.light_state = ints(light_state);
  b.light_slot = ints(light_slot);
  b.map_id = ints(map_id);
  b.intra = ints(intra);
  b.agent_slot = ints(agent_slot);
  b.agent_type = ints(agent_type);
  b.motion_action = ints(motion_action);
  b.motion_state = floats(motion_state, kMotionStateFeatures);
  b.relative_state = floats(relative_state, kRsFields);
  b.self_keys = sparse(self_off, self_keys);
  b.self_features = floats(self_feat, kRelationFeatures);
  b.cross_keys = sparse(cross_off, cross_keys);
  b.cross_features = floats(cross_feat, kRelationFeatures);
  b.light_rows = ints(light_rows), b.light_target = ints(light_t);
  b.motion_rows = ints(motion_rows), b.motion_target = ints(motion_t);
  b.type_rows = ints(type_rows), b.type_target = ints(type_t);
  b.end_rows = ints(end_rows), b.end_target = ints(end_t);
  b.end_first = ints(end_first).to(torch::kBool);
  b.state_rows = ints(state_rows), b.state_target = ints(state_t).view({-1, kRsFields});
  return b;
}

}  // namespace ss::train
