// Sampling a token from logits: temperature, then nucleus (top-p) truncation, then one categorical draw.
#pragma once

#include <span>

#include "engine/base/rng.h"

namespace ss {

// Logits of -inf are never drawn. temperature > 0; top_p in (0, 1] (1: plain softmax sampling).
// The nucleus is the smallest set of most probable tokens whose mass reaches top_p (ties broken by index).
int sample_token(std::span<const float> logits, double temperature, double top_p, Rng& rng);

}  // namespace ss
