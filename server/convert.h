// Proto <-> engine types: decoding only. The engine checks the values once, at its entry, and its errors name the
// field; the only errors here are values the engine's types cannot hold (a 64-bit track id, a light state past a
// byte).
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "engine/scenestreamer.h"
#include "grpcpp/support/status.h"
#include "scenestreamer/v1/simulator.pb.h"

namespace ss::server {

namespace pb = ::scenestreamer::v1;

absl::StatusOr<SessionOptions> options_from_proto(const pb::CreateSessionRequest& r);
std::vector<ControlInput> controls_from_proto(const pb::StepSceneRequest& r);
InjectRequest inject_from_proto(const pb::InjectAgentRequest& r);
absl::StatusOr<StateForceRequest> force_from_proto(const pb::StateForceRequest& r);

// A tick's agents, lights and (for a tick a call made) its controlled agents' events.
void tick_to_proto(const StepResult& s, int64_t tick, pb::Tick* out);
void map_to_proto(const std::vector<MapFeature>& map, pb::CreateSessionResponse* out);
// The one conversion of an engine or manager status to the gRPC status a handler returns (the codes are the same
// numbers; the message is kept).
::grpc::Status to_grpc(const absl::Status& st);
pb::Mode mode_to_proto(SessionMode m);

}  // namespace ss::server
