// A session's decoder state: the tokens of the last `window_steps` steps and their per-layer keys and values.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <tuple>
#include <vector>

#include "engine/model/attention.h"
#include "engine/model/linalg.h"
#include "engine/model/token.h"

namespace ss {

// What the decoder did for one cache, counted as it ran (the benchmark turns it into floating-point operations).
struct DecodeWork {
  int64_t calls = 0;
  int64_t tokens = 0;               // new tokens decoded
  int64_t query_layers = 0;         // (token, layer) pairs that ran a self-attention query and feed-forward
  int64_t key_reads = 0;            // (query, key, layer) triples, self- and cross-attention
  int64_t posed_key_reads = 0;      // those whose relation came from the query's own relation rows
  int64_t relation_rows = 0;        // relation MLP evaluations (once per decode call, shared by the layers)
};

// The map keys a query at one pose reads in cross-attention, with their relation rows: a function of the pose and
// the map alone, so a session keeps those of its recent poses. Lights and agents' anchor segments keep their pose
// from step to step, and an agent's motion token has its relative-state token's pose.
struct CrossKeyEntry {
  std::shared_ptr<const QueryKeys> keys;
  int last_step = 0;  // the last step whose tokens read it
};
using CrossKeyCache = std::map<std::tuple<double, double, double>, CrossKeyEntry>;

struct KvCache {
  std::vector<DecoderToken> tokens;     // sequence order, oldest first
  std::vector<Anchor> anchors;          // each token's place as a relation anchor (its heading's cos and sin computed once)
  std::vector<std::vector<float>> k, v; // per decoder layer: a ring of `capacity` rows of d_model; token j's keys and
                                        // values are at row(j), so evicting old tokens moves no data
  int head = 0;                         // the ring row of token 0
  int capacity = 0;                     // rows allocated per layer
  int d_model = 0;
  int64_t next_seq = 0;                 // seq of the next token appended
  DecodeWork work;                      // everything decoded into this cache so far
  CrossKeyCache cross_keys;             // by pose (x, y, heading); entries unused at the newest step are dropped.
                                        // They name one map's tokens: a cache serves one map (its session's)

  void init(int layers, int d);
  int size() const { return static_cast<int>(tokens.size()); }
  int row(int j) const { return head + j < capacity ? head + j : head + j - capacity; }
  // Makes room for `n` tokens (when it grows, the ring is laid out again from row 0).
  void reserve(int n);
  // Token j's keys or values at `layer` (d_model floats).
  const float* key_row(int layer, int j) const { return k[layer].data() + static_cast<size_t>(row(j)) * d_model; }
  const float* value_row(int layer, int j) const { return v[layer].data() + static_cast<size_t>(row(j)) * d_model; }
  // Drops tokens of steps before `first_step`: nothing later may attend to them (mask.h).
  void evict_before(int first_step);
  // Drops the newest tokens beyond the first `n` (undoes a decode, e.g. a rejected agent sample).
  void truncate(int n);
  // Bytes held (tokens and keys/values).
  size_t bytes() const;
};

}  // namespace ss
