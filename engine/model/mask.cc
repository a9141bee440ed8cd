#include "engine/model/mask.h"

#include <algorithm>

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
  std::vector<int> kept, outside;
  nearest_within(distances, order, limit, kept, outside);
  return kept;
}

void nearest_within(std::span<const double> distances, std::span<const int64_t> order, const NeighbourLimit& limit,
                    std::vector<int>& kept, std::vector<int>& outside) {
  // Sorted by distance, the keys within the radius come first; so the kept set is the nearest min(k, inside) of the
  // keys inside, topped up to `always` from the nearest outside. Only a cut needs a selection, never a full sort.
  auto closer = [&](int a, int b) {
    return distances[a] < distances[b] || (distances[a] == distances[b] && order[a] < order[b]);
  };
  std::vector<int>& inside = kept;
  inside.clear();
  outside.clear();
  for (int i = 0; i < static_cast<int>(distances.size()); ++i)
    (distances[i] <= limit.radius ? inside : outside).push_back(i);
  const int k = limit.k;
  if (static_cast<int>(inside.size()) > k) {
    std::nth_element(inside.begin(), inside.begin() + (k - 1), inside.end(), closer);
    inside.resize(k);
  } else {
    const int wanted = std::min(limit.always, k) - static_cast<int>(inside.size());
    const int extra = std::min(wanted, static_cast<int>(outside.size()));
    if (extra <= 0) return;  // built in ascending order, nothing selected: already sorted
    std::nth_element(outside.begin(), outside.begin() + (extra - 1), outside.end(), closer);
    inside.insert(inside.end(), outside.begin(), outside.begin() + extra);
  }
  std::sort(inside.begin(), inside.end());
}

}  // namespace ss
