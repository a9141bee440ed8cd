#include "engine/model/mask.h"

#include <algorithm>
#include <numeric>

namespace ss {

bool may_attend(const DecoderToken& q, const DecoderToken& k, int window_steps) {
  const int dt = q.step - k.step;
  if (dt < 0 || dt >= window_steps) return false;
  const bool same_object = q.object != kNoObject && q.object == k.object;
  const bool k_group = is_agent_state_group(k.kind);
  switch (q.kind) {
    case TokenKind::light:
      if (k.kind == TokenKind::light) return dt == 0 || same_object;
      return k.kind == TokenKind::motion && dt == 1;
    case TokenKind::motion:
      if (dt == 0 && (k.kind == TokenKind::light || k.kind == TokenKind::motion)) return true;
      return same_object && (k_group || k.kind == TokenKind::motion);
    default:  // the agent-state group
      if (dt == 0) {
        if (k.kind == TokenKind::light) return true;
        return k_group && k.seq <= q.seq;
      }
      if (k.kind == TokenKind::motion && dt == 1) return true;
      if (k.kind == TokenKind::sos || k.kind == TokenKind::eos) return true;
      return same_object && (k_group || k.kind == TokenKind::motion);
  }
}

bool is_spatial_pair(const DecoderToken& q, const DecoderToken& k) {
  return q.has_pose && k.has_pose && !(q.object != kNoObject && q.object == k.object);
}

std::vector<int> nearest_within(std::span<const double> distances, std::span<const int64_t> order,
                                const NeighbourLimit& limit) {
  const int n = static_cast<int>(distances.size());
  std::vector<int> idx(n);
  std::iota(idx.begin(), idx.end(), 0);
  auto closer = [&](int a, int b) {
    return distances[a] < distances[b] || (distances[a] == distances[b] && order[a] < order[b]);
  };
  const int cap = std::min(n, limit.k);
  std::partial_sort(idx.begin(), idx.begin() + cap, idx.end(), closer);
  int kept = 0;
  while (kept < cap && (kept < limit.always || distances[idx[kept]] <= limit.radius)) ++kept;
  idx.resize(kept);
  std::sort(idx.begin(), idx.end());
  return idx;
}

}  // namespace ss
