// Proto <-> engine types. Pure translation and input checks (finite numbers, known enum values); every error names
// the field.
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "engine/scenestreamer.h"
#include "scenestreamer/v1/simulator.pb.h"

namespace ss::server {

namespace pb = ::scenestreamer::v1;

absl::StatusOr<SessionOptions> options_from_proto(const pb::CreateSessionRequest& r);
absl::StatusOr<std::vector<ControlInput>> controls_from_proto(const pb::StepSceneRequest& r);
absl::StatusOr<InjectRequest> inject_from_proto(const pb::InjectAgentRequest& r);
absl::StatusOr<StateForceRequest> force_from_proto(const pb::StateForceRequest& r);

void tick_to_proto(const StepResult& s, int64_t tick, pb::Tick* out);
void events_to_proto(const std::vector<AgentEvents>& events, pb::Tick* out);
void map_to_proto(const Scenario& s, pb::CreateSessionResponse* out);
pb::Mode mode_to_proto(SessionMode m);

}  // namespace ss::server
