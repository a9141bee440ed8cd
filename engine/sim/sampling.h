// Sampling a token from logits: temperature, then nucleus (top-p) truncation, then one categorical draw.
#pragma once

#include <functional>
#include <span>

#include "engine/base/rng.h"

namespace ss {

// Logits of -inf are never drawn. temperature > 0; top_p in (0, 1] (1: plain softmax sampling).
// The nucleus is the smallest set of most probable tokens whose mass reaches top_p (ties broken by index).
int sample_token(std::span<const float> logits, double temperature, double top_p, Rng& rng);

// A draw from the nucleus' tokens that `accept` takes: the model's distribution given acceptance (within the
// nucleus). -1 when `accept` takes none. Draws without replacement until a token is taken, so `accept` is asked once
// at most per token, and only of those drawn; its first draw is sample_token's.
int sample_token_if(std::span<const float> logits, double temperature, double top_p, Rng& rng,
                    const std::function<bool(int)>& accept);

}  // namespace ss
