// The SceneStreamer model on the CPU: map encoder, decoder with a KV cache, and the heads.
// A Model is immutable after creation and shared by every session (thread-safe for concurrent use).
#pragma once

#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/map/segments.h"
#include "engine/map/spatial_index.h"
#include "engine/model/attention.h"
#include "engine/model/config.h"
#include "engine/model/kv_cache.h"
#include "engine/model/linalg.h"
#include "engine/model/mask.h"
#include "engine/model/matmul_bf16.h"
#include "engine/model/token.h"
#include "engine/model/weights.h"

namespace ss {

// A map as the decoder sees it: segments, their index, the encoded map tokens and what every layer derives from
// them. Built once per map and shared read-only by every session on it.
struct MapContext {
  std::vector<MapSegment> segments;  // nearest the focus first; the map token i is segment i
  SegmentIndex index;
  Mat tokens;                        // M x d: encoder output + map-id embedding
  std::vector<Mat> cross_keys, cross_values;  // per decoder layer, M x d; empty past the first layer when the
                                              // halves and the bf16 tiles below are both kept (never read then)
  // With bf16 products, per decoder layer and head ([layer * heads + h]): the keys (M x dh) and the values
  // transposed (dh x M) in bf16 tiles, for the queries that read the whole map together. Empty in fp32.
  std::vector<Bf16Weight> cross_keys_bf16, cross_values_bf16;
  // With fp16 keys and values, per decoder layer: the keys and values in half floats (M x d). Queries with keys of
  // their own read these, half the bytes of cross_keys (measured: bench 0.93x); queries that read the whole map
  // together read the bf16 tiles, or cross_keys without them. Empty with fp32 keys and values.
  std::vector<std::vector<uint16_t>> cross_keys_h, cross_values_h;
  Mat pointer_keys;                  // M x d: head.map_segment.key applied to the tokens
  std::vector<Anchor> anchors;       // each segment's pose as a relation anchor (step 0)

  explicit MapContext(std::vector<MapSegment> s) : segments(std::move(s)), index(segments) {}
  int size() const { return static_cast<int>(segments.size()); }
  size_t bytes() const;
};

struct EncoderLayerParams {
  NormParams attn_norm, ffn_norm;
  AttentionParams attn;
  LinearParams ffn1, ffn2;
};

struct DecoderLayerParams {
  NormParams cross_norm, self_norm, ffn_norm;
  AttentionParams cross, self;
  LinearParams ffn1, ffn2;
};

struct MlpHeadParams {
  NormParams norm1, norm2;
  LinearParams fc1, fc2;
};

struct RsBlockParams {
  LinearParams adaln1, adaln2;  // z -> (scale, shift), 2d outputs
  LinearParams query, key, value, output;
  LinearParams ffn1, ffn2;
};

// The dense products (every Linear layer over the model width, heads included): fp32 (Eigen), or bf16 on AMX tiles
// or with AVX512-BF16, weights and inputs rounded to bf16 and every sum in fp32 (engine/model/matmul_bf16.h; CPUs
// with AVX512-BF16 only).
// Keeping the heads in fp32 was tried: the logits' difference from fp32 stayed the same (0.091 against 0.096: it comes
// from the hidden states).
enum class MatmulPrecision : uint8_t { fp32, bf16 };

// How the model runs: the KV caches' storage, the dense products' precision, threads.
struct ModelOptions {
  // fp16 (the default) halves a session's keys and values and the bytes its attention gathers; the math stays fp32
  // (realism unchanged within its interval at K = 32: docs/performance.md). Unset: fp16. The programs that load a
  // model set it from their flags (the server's --kv_precision, bench's --kv-precision).
  std::optional<KvPrecision> kv_precision;
  // Unset: bf16 where the CPU has AVX512-BF16 (realism unchanged within its interval: docs/performance.md), else
  // fp32. bf16 asked for on a CPU without AVX512-BF16 is an error. From the flags as kv_precision is.
  std::optional<MatmulPrecision> matmul_precision;
  // Threads one decode call may use: its attention's groups of queries are shared out (the same bits at any count).
  // 1: the calling thread alone. For a lone session's latency; a server busy with many sessions gains nothing.
  int step_threads = 1;
};
// "fp32" / "fp16"; INVALID_ARGUMENT otherwise.
absl::StatusOr<KvPrecision> kv_precision_by_name(const std::string& name);
const char* kv_precision_name(KvPrecision p);
// "fp32" / "bf16"; INVALID_ARGUMENT otherwise.
absl::StatusOr<MatmulPrecision> matmul_precision_by_name(const std::string& name);
const char* matmul_precision_name(MatmulPrecision p);

// The relative-state head's state while one agent's fields are sampled (Model::rs_begin, rs_next).
struct RsHead {
  std::vector<Mat> modulation;   // per AdaLN (two per block, then the final one): 1 x 2d from z
  std::vector<Mat> keys, values; // per block: kRsFields x d, rows 0..fields-1 written
  int fields = 0;                // rows run so far
};

class Model {
 public:
  static absl::StatusOr<std::shared_ptr<const Model>> create(Weights weights, ModelOptions options = {});

  const ModelConfig& config() const { return weights_.config; }
  KvPrecision kv_precision() const { return *options_.kv_precision; }
  MatmulPrecision matmul_precision() const { return *options_.matmul_precision; }
  int step_threads() const { return pool_ ? pool_->threads() + 1 : 1; }
  const Weights& weights() const { return weights_; }

  // Encodes a map (segments nearest the focus first, at most max_map_segments). FAILED_PRECONDITION when empty.
  absl::StatusOr<std::shared_ptr<const MapContext>> encode_map(std::vector<MapSegment> segments) const;

  // Incremental forward: runs `tokens` (new tokens of one session, in sequence order) through the decoder, reading
  // and extending `cache`. Returns their final hidden states (n x d). Assigns each token's seq.
  Mat decode(const MapContext& map, KvCache& cache, std::vector<DecoderToken>& tokens) const;
  // The same, returning only the hidden states of the tokens at `outputs` (indices into `tokens`, rows in that
  // order). Tokens whose output nobody reads (state-forced agents, a replay) skip their last layer's self-attention
  // and feed-forward; the cache is the same either way.
  Mat decode(const MapContext& map, KvCache& cache, std::vector<DecoderToken>& tokens,
             std::span<const int> outputs) const;
  // Full recompute: the whole history at once with a fresh cache (to test and measure the incremental path).
  Mat decode_full(const MapContext& map, std::vector<DecoderToken>& tokens) const;
  KvCache new_cache() const;
  // Floating-point operations (multiply and add counted apart) of the work counted in `w`: the dense projections,
  // the attention over every key read, and the relation MLP.
  double decode_flops(const DecodeWork& w) const;

  // Heads, on decoder outputs (one row per token).
  Mat light_logits(const Mat& h) const;         // n x 4: the light's state at the next step
  Mat motion_logits(const Mat& h) const;        // n x 1089: the agent's next control
  Mat agent_type_logits(const Mat& h) const;    // n x 3, read at SOA
  Mat end_of_agents_logits(const Mat& h) const; // n x 2 (another agent, end), read at SOS and RS
  Mat map_segment_logits(const Mat& h, const MapContext& map) const;  // n x M, read at TYPE
  // Logits of relative-state field `prefix.size()` (0..7) given the earlier fields' bins, conditioned on `z`, the
  // decoder output of the MS token (1 x d).
  Vec relative_state_logits(const Mat& z, std::span<const int> prefix) const;
  // The same head field by field, each field's work done once: rs_begin(z), then rs_next gives field 0's logits
  // (previous_bin unused), and each further call the next field's given the bin chosen for the one before.
  RsHead rs_begin(const Mat& z) const;
  Vec rs_next(RsHead& s, int previous_bin) const;

  Mat embed(std::span<const DecoderToken> tokens) const;

 private:
  Model(Weights w, ModelOptions options);
  // Construction only: lin packs the weight in bf16 when the products run in bf16 and the layer is applied by
  // linear() (`through_linear`; the relation key and value projections are read per head as fp32 matrices).
  LinearParams lin(const std::string& name, bool bias = true, bool through_linear = true);
  NormParams norm(const std::string& name) const;
  AttentionParams attn(const std::string& name);
  MlpHeadParams mlp_head(const std::string& name);
  Mat mlp_head_forward(const Mat& h, const MlpHeadParams& p) const;
  // Which keys each new token reads in self-attention (indices into cache tokens followed by new tokens), with
  // relation embeddings.
  // Queries may share one QueryKeys (e.g. every query without a position reads the whole map the same way), so the
  // result is the distinct key sets plus one pointer per query.
  struct KeySets {
    std::vector<std::shared_ptr<const QueryKeys>> sets;  // the sets computed by this call
    std::vector<const QueryKeys*> per_query;
  };
  KeySets self_keys(const KvCache& cache, std::span<const DecoderToken> tokens) const;
  // Reuses and refreshes the cache's cross-key sets (cache.cross_keys).
  KeySets cross_keys(const MapContext& map, KvCache& cache, std::span<const DecoderToken> tokens) const;
  void count_work(DecodeWork& w, const KeySets& self, const KeySets& cross, std::span<const int> outputs) const;

  Weights weights_;
  ModelOptions options_;
  std::vector<std::unique_ptr<const Bf16Weight>> bf16_weights_;  // what the LinearParams' bf16 point to
  std::unique_ptr<ThreadPool> pool_;  // step_threads - 1 threads beside the caller; step_threads > 1 only
  NeighbourLimit limit_;
  LinearParams poly_fc1_, poly_fc2_, poly_fc3_, poly_fc4_;
  NormParams poly_norm1_, poly_norm2_, encoder_final_norm_, decoder_final_norm_;
  RelationParams encoder_relation_, self_relation_, cross_relation_;
  Mat self_relation_by_step_;   // window x relation_dim: h of a self-attention pair without positions, by step difference
  Mat cross_relation_at_rest_;  // 1 x relation_dim: h of a map key seen from a query without a position
  std::vector<EncoderLayerParams> encoder_layers_;
  std::vector<DecoderLayerParams> decoder_layers_;
  const float* map_id_embedding_ = nullptr;
  const float *agent_type_emb_ = nullptr, *agent_slot_emb_ = nullptr, *light_slot_emb_ = nullptr,
              *light_state_emb_ = nullptr, *motion_action_emb_ = nullptr, *special_emb_ = nullptr,
              *intra_emb_ = nullptr;
  LinearParams motion_state_fc1_, motion_state_fc2_, rs_embed_fc1_, rs_embed_fc2_;
  MlpHeadParams light_head_, motion_head_;
  LinearParams agent_type_head_, end_of_agents_head_, pointer_query_, pointer_key_;
  const float *rs_input_emb_ = nullptr, *rs_position_emb_ = nullptr;
  std::vector<RsBlockParams> rs_blocks_;
  LinearParams rs_final_adaln_, rs_output_;
};

}  // namespace ss
