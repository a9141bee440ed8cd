// A dynamic token of the decoder: what it is, when, whose, where, and what it embeds.
#pragma once

#include <array>
#include <cstdint>

#include "engine/geometry/geometry.h"
#include "engine/model/vocab.h"

namespace ss {

enum class TokenKind : uint8_t {
  light,           // one per light per step
  sos,             // start of the step's agent-state group
  soa,             // start of one agent
  type,            // the agent's type
  map_segment,     // the agent's anchor segment (MS)
  relative_state,  // the agent's state relative to the anchor (RS)
  eos,             // end of the agent-state group
  motion,          // one per agent per step
};

inline bool is_agent_state_group(TokenKind k) { return k >= TokenKind::sos && k <= TokenKind::eos; }

// Lights and agents share one object namespace: agents use their public id (>= 0), lights -1 - light index.
inline int64_t light_object(int light) { return -1 - static_cast<int64_t>(light); }
inline constexpr int64_t kNoObject = INT64_MIN;

struct DecoderToken {
  TokenKind kind = TokenKind::sos;
  int64_t seq = 0;         // position in the session's token sequence (orders tokens within a step's group)
  int step = 0;            // model step (0.5 s each)
  int64_t object = kNoObject;
  bool has_pose = false;   // SOS, EOS, SOA and TYPE have none: they attend without spatial pruning
  Pose pose;               // light: stop point, lane heading; MS: segment pose; RS, motion: the agent's pose

  // Embedding inputs (those the kind uses).
  int agent_slot = 0;      // agent-id embedding slot
  int agent_type = 0;      // 0 vehicle, 1 pedestrian, 2 cyclist
  int intra_index = 0;     // 4 * (agent's order in the group) + (0 SOA, 1 TYPE, 2 MS, 3 RS)
  int light_slot = 0;
  int light_state = 0;     // LightState
  int map_id = 0;          // MS, RS, light: index of the segment among the map tokens
  int motion_action = kMotionStart;  // motion: the token that brought the agent here (START when it appears)
  std::array<float, kMotionStateFeatures> motion_state{};  // motion: local vx, vy, length, width, height
  std::array<float, kRsFields> relative_state{};           // RS: the 8 fields, each scaled to [-1, 1]
};

}  // namespace ss
