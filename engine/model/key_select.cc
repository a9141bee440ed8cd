#include "engine/model/key_select.h"

#include <algorithm>
#include <bit>
#include <cstdint>

namespace ss {

SelfKeySelector::SelfKeySelector(std::span<const DecoderToken> cached, std::span<const DecoderToken> fresh,
                                 int window_steps, const NeighbourLimit& limit)
    : cached_(cached), fresh_(fresh), cached_size_(static_cast<int>(cached.size())), window_(window_steps),
      limit_(limit) {
  // Built for every decode call, so it lists only what the fresh tokens can read (a session places a new agent one
  // token at a time, and indexing the whole cache for each of those was 3.4 % of a busy server's time).
  const int total = cached_size_ + static_cast<int>(fresh.size());
  posed_bits_.assign((total + 63) / 64, 0);
  unposed_bits_.assign((total + 63) / 64, 0);
  if (fresh.empty()) return;
  int lo = fresh.front().step, hi = lo;
  for (const DecoderToken& t : fresh) {
    lo = std::min(lo, t.step);
    hi = std::max(hi, t.step);
    if (t.object != kNoObject) objects_.push_back(t.object);
  }
  std::sort(objects_.begin(), objects_.end());
  objects_.erase(std::unique(objects_.begin(), objects_.end()), objects_.end());
  object_tokens_.resize(objects_.size());
  first_step_ = lo - window_ + 1;
  steps_.resize(hi - first_step_ + 1);
  int64_t last_object = kNoObject;
  std::vector<int>* last_list = nullptr;  // the last object looked up, and its list (null: not a fresh object)
  for (int j = 0; j < total; ++j) {
    const DecoderToken& t = token(j);
    if (t.object != kNoObject && !objects_.empty()) {
      if (t.object != last_object) {  // an agent's group tokens come together: one lookup for the four
        last_object = t.object;
        auto it = std::lower_bound(objects_.begin(), objects_.end(), t.object);
        last_list = it != objects_.end() && *it == t.object ? &object_tokens_[it - objects_.begin()] : nullptr;
      }
      if (last_list) last_list->push_back(j);
    }
    if (t.step < first_step_ || t.step > hi) continue;
    Step& s = steps_[t.step - first_step_];
    if (t.kind == TokenKind::light) {
      if (t.step >= lo) s.lights.push_back(j);
    } else if (t.kind == TokenKind::motion) {
      if (t.step >= lo - 1) s.motion.push_back(j);
    } else if (t.step >= lo) {
      s.group.push_back(j);
    }
    if (t.kind == TokenKind::sos || t.kind == TokenKind::eos) s.bounds.push_back(j);
  }
}

namespace {

// Appends the set bits' indices in ascending order and clears them: the kept keys in sequence order without a sort
// (the candidates come from several lists; perf put 4 % of a busy server's time in sorting them).
void take_bits(std::vector<uint64_t>& bits, std::vector<int>& out) {
  for (size_t w = 0; w < bits.size(); ++w) {
    for (uint64_t b = bits[w]; b != 0; b &= b - 1) out.push_back(static_cast<int>(w * 64) + std::countr_zero(b));
    bits[w] = 0;
  }
}

void set_bit(std::vector<uint64_t>& bits, int j) { bits[j >> 6] |= uint64_t{1} << (j & 63); }

}  // namespace

const SelfKeySelector::Step* SelfKeySelector::at(int step) const {
  const int k = step - first_step_;
  return k >= 0 && k < static_cast<int>(steps_.size()) ? &steps_[k] : nullptr;
}

void SelfKeySelector::select(int i, SelfKeys& out) {
  const DecoderToken& q = fresh_[i];
  const int qj = cached_size_ + i;  // the query's own index: the sequence order is the index order
  out.posed.clear();
  out.unposed.clear();
  spatial_.clear();
  dist_.clear();
  order_.clear();
  // The lists below hold only keys the mask allows (may_attend's rules, case by case), except the query's own
  // object's tokens, which are checked. A key in two lists sets its bit twice; a spatial key (another object's
  // token with a position) is in one list only, as the lists are disjoint by step and kind but for the own object's.
  auto keep = [&](int j) {
    const DecoderToken& k = token(j);
    if (is_spatial_pair(q, k)) {
      spatial_.push_back(j);
      dist_.push_back(distance({q.pose.x, q.pose.y}, {k.pose.x, k.pose.y}));
      order_.push_back(k.seq);
    } else {
      set_bit(q.has_pose && k.has_pose ? posed_bits_ : unposed_bits_, j);
    }
  };
  auto keep_all = [&](const std::vector<int>& v) {
    for (int j : v) keep(j);
  };
  const bool group = is_agent_state_group(q.kind);
  if (const Step* now = at(q.step)) {
    keep_all(now->lights);                                 // every query reads the lights of its step
    if (q.kind == TokenKind::motion) keep_all(now->motion);  // and a motion token every motion token of it
    if (group)  // an agent-state token its group up to itself
      for (auto it = now->group.begin(); it != now->group.end() && *it <= qj; ++it) keep(*it);
  }
  if (q.kind != TokenKind::motion)  // lights and agent-state tokens read the step before's motion
    if (const Step* prev = at(q.step - 1)) keep_all(prev->motion);
  if (group)  // and agent-state tokens every earlier SOS and EOS in the window
    for (int s = q.step - window_ + 1; s < q.step; ++s)
      if (const Step* earlier = at(s)) keep_all(earlier->bounds);
  if (q.object != kNoObject)
    if (auto it = std::lower_bound(objects_.begin(), objects_.end(), q.object); it != objects_.end() && *it == q.object)
      for (int j : object_tokens_[it - objects_.begin()])
        if (may_attend(q, token(j), window_)) keep(j);
  nearest_within(dist_, order_, limit_, kept_, outside_);
  for (int pos : kept_) set_bit(posed_bits_, spatial_[pos]);
  take_bits(posed_bits_, out.posed);
  take_bits(unposed_bits_, out.unposed);
}

std::vector<int> map_keys_near(std::span<const MapSegment> segments, const SegmentIndex& index, Vec2 p,
                               const NeighbourLimit& limit) {
  const std::vector<int> near = index.k_nearest_unordered(p, limit.k);  // the keys are sorted by index below
  std::vector<double> dist;
  std::vector<int64_t> order(near.begin(), near.end());
  for (int j : near) dist.push_back(distance(p, {segments[j].pose.x, segments[j].pose.y}));
  std::vector<int> keys;
  for (int pos : nearest_within(dist, order, limit)) keys.push_back(near[pos]);
  std::sort(keys.begin(), keys.end());
  return keys;
}

}  // namespace ss
