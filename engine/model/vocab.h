// Vocabulary sizes and feature widths fixed by the paper and the tokenizers (not configurable).
#pragma once

#include "engine/map/segments.h"
#include "engine/tokens/agent_state.h"
#include "engine/tokens/light.h"
#include "engine/tokens/motion.h"

namespace ss {

inline constexpr int kPointFeatures = kPointFeatureDim;     // 27
inline constexpr int kAgentTypes = 3;                       // vehicle, pedestrian, cyclist
inline constexpr int kLightStates = kNumLightStates;        // unknown, green, yellow, red
inline constexpr int kMotionInputVocab = kMotionTokens;     // 1089 controls + START
inline constexpr int kRsFields = kStateFields;              // 8
inline constexpr int kRsBins = kStateBins;                  // 81
inline constexpr int kRelationFeatures = 7;                 // dx, dy, distance, sin, cos of dpsi, dt, has-pose
inline constexpr int kMotionStateFeatures = 5;              // local vx, vy; length, width, height
// Rows of embed.special.
inline constexpr int kSpecialSos = 0;  // start of a step's agent-state group
inline constexpr int kSpecialEos = 1;  // its end
inline constexpr int kSpecialSoa = 2;  // start of one agent
inline constexpr int kSpecialTokens = 3;

}  // namespace ss
