// Token group attention (docs/design.md section 5) and the nearest-neighbour limit on spatial keys.
#pragma once

#include <span>
#include <vector>

#include "engine/model/token.h"

namespace ss {

// May query `q` read key `k`? Both tokens belong to one session's sequence.
//  - a light token at t: every light at t, the same light earlier, every motion token at t-1;
//  - an agent-state token at t: the group's tokens up to itself, lights at t, every motion token at t-1, its own
//    agent's earlier tokens, earlier SOS and EOS;
//  - a motion token at t: every motion token at t, lights at t, its own agent's agent-state tokens up to t, its own
//    earlier motion tokens.
// Nothing reaches back `window_steps` steps or more: that is what lets the cache drop old tokens.
bool may_attend(const DecoderToken& q, const DecoderToken& k, int window_steps);

struct NeighbourLimit {
  int k = 128;          // at most this many spatial keys
  double radius = 50;   // metres from the query
  int always = 8;       // the nearest keys kept whatever their distance
};

// Does the limit apply to key `k` of query `q`? Only when both have a position and `k` is not the query's own
// object's token (an object's own history is always visible).
bool is_spatial_pair(const DecoderToken& q, const DecoderToken& k);

// Given spatial candidates of one query (their distances to it and a tie-breaking order key), returns the positions
// (into `distances`) of those kept: sorted by distance, the first `always`, then any within the radius, at most k.
// The result is in ascending order of position, so the kept keys stay in sequence order.
std::vector<int> nearest_within(std::span<const double> distances, std::span<const int64_t> order,
                                const NeighbourLimit& limit);
// The same into `kept`, with `outside` as scratch: for a caller that selects for many queries.
void nearest_within(std::span<const double> distances, std::span<const int64_t> order, const NeighbourLimit& limit,
                    std::vector<int>& kept, std::vector<int>& outside);

}  // namespace ss
