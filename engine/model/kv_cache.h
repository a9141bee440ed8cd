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
  int64_t posed_key_reads = 0;      // those whose relation came from the query's own relation columns
  int64_t relation_rows = 0;        // relation MLP evaluations (once per decode call, shared by the layers)
  int64_t kept_cross_queries = 0;   // first-layer cross-attention queries taken from kept rows (KvCache::poseless)
};

// The map keys a query at one pose reads in cross-attention, with their relation columns: a function of the pose and
// the map alone, so a session keeps those of its recent poses. Lights and agents' anchor segments keep their pose
// from step to step, and an agent's motion token has its relative-state token's pose.
struct CrossKeyEntry {
  std::shared_ptr<const QueryKeys> keys;
  int last_step = 0;  // the last step whose tokens read it
};
using CrossKeyCache = std::map<std::tuple<double, double, double>, CrossKeyEntry>;

// How a cache stores its keys and values: floats, or half floats (binary16: half the bytes; the attention converts
// them to float, so every sum is still a float sum, of rounded keys and values).
enum class KvPrecision : uint8_t { fp32, fp16 };

// A position-less token (SOS, EOS, SOA, TYPE) enters the decoder as a sum of embedding rows named by its kind and
// embedding inputs, and its first layer's cross-attention reads the whole map with no spatial relation: the result
// (that layer's residual after cross-attention) is a function of those inputs, the model and the map alone, so a
// session keeps it from step to step. It is computed one token at a time (never in a batch), so its bits do not depend
// on which tokens were decoded with it: a restored session recomputes the same values.
using PoselessKey = std::tuple<uint8_t, int, int, int>;  // kind, intra_index, agent_slot, agent_type
struct PoselessEntry {
  Vec x;              // 1 x d: embedding + first layer's cross-attention
  int last_step = 0;  // the last step whose tokens read it
};

struct KvCache {
  std::vector<DecoderToken> tokens;     // sequence order, oldest first
  std::vector<Anchor> anchors;          // each token's place as a relation anchor (its heading's cos and sin computed once)
  std::vector<std::vector<float>> k, v; // per decoder layer: a ring of `capacity` rows of d_model; token j's keys and
                                        // values are at row(j), so evicting old tokens moves no data (fp32 storage)
  std::vector<std::vector<uint16_t>> kh, vh;  // the same rings in half floats (fp16 storage; k and v stay empty)
  KvPrecision precision = KvPrecision::fp32;
  int head = 0;                         // the ring row of token 0
  int capacity = 0;                     // rows allocated per layer
  int d_model = 0;
  int64_t next_seq = 0;                 // seq of the next token appended
  DecodeWork work;                      // everything decoded into this cache so far
  CrossKeyCache cross_keys;             // by pose (x, y, heading); entries unused at the newest step are dropped.
                                        // They name one map's tokens: a cache serves one map (its session's)
  std::map<PoselessKey, PoselessEntry> poseless;  // kept first-layer rows of position-less tokens, dropped when
                                                  // neither of the last two steps read them

  void init(int layers, int d, KvPrecision p = KvPrecision::fp32);
  bool half() const { return precision == KvPrecision::fp16; }
  int size() const { return static_cast<int>(tokens.size()); }
  int row(int j) const { return head + j < capacity ? head + j : head + j - capacity; }
  // Makes room for `n` tokens (when it grows, the ring is laid out again from row 0).
  void reserve(int n);
  // Token j's keys or values at `layer` (d_model floats; fp32 storage only).
  const float* key_row(int layer, int j) const { return k[layer].data() + static_cast<size_t>(row(j)) * d_model; }
  const float* value_row(int layer, int j) const { return v[layer].data() + static_cast<size_t>(row(j)) * d_model; }
  // Token j's keys or values at `layer` as floats, whatever the storage (d_model floats written to `out`).
  void read_key(int layer, int j, float* out) const;
  void read_value(int layer, int j, float* out) const;
  // Stores `n` rows (d_model floats each, `src` row-major) as the keys or values of tokens first..first+n-1.
  void write_keys(int layer, int first, const float* src, int n);
  void write_values(int layer, int first, const float* src, int n);
  int layers() const { return static_cast<int>(half() ? kh.size() : k.size()); }
  // Drops tokens of steps before `first_step`: nothing later may attend to them (mask.h).
  void evict_before(int first_step);
  // Drops the newest tokens beyond the first `n` (undoes a decode, e.g. a rejected agent sample).
  void truncate(int n);
  // Bytes held (tokens and keys/values).
  size_t bytes() const;
};

}  // namespace ss
