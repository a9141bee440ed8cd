// The gRPC handlers: proto -> engine types (convert.h) -> one SessionManager call -> proto. No simulation logic.
#pragma once

#include "scenestreamer/v1/simulator.grpc.pb.h"
#include "server/auth.h"
#include "server/metrics.h"
#include "server/convert.h"
#include "server/session_manager.h"

namespace ss::server {

// WatchSession uses gRPC's callback API: a stream is a reactor fed by the session's ticks, not a thread blocked on
// it (once 3000 streams held 3015 threads).
class SimulatorService final
    : public ::scenestreamer::v1::Simulator::WithCallbackMethod_WatchSession<::scenestreamer::v1::Simulator::Service> {
 public:
  // `auth`: the tokens (--tokens_file), or null for no authentication (every caller is tenant "").
  SimulatorService(Engine& engine, SessionManager& sessions, Metrics& metrics, double default_deadline_s,
                   const TokenAuth* auth = nullptr)
      : engine_(engine), sessions_(sessions), metrics_(metrics), default_deadline_s_(default_deadline_s),
        auth_(auth) {}

  using Ctx = ::grpc::ServerContext;
  ::grpc::Status CreateSession(Ctx*, const pb::CreateSessionRequest*, pb::CreateSessionResponse*) override;
  ::grpc::Status StepScene(Ctx*, const pb::StepSceneRequest*, pb::StepSceneResponse*) override;
  ::grpc::Status InjectAgent(Ctx*, const pb::InjectAgentRequest*, pb::InjectAgentResponse*) override;
  ::grpc::Status StateForce(Ctx*, const pb::StateForceRequest*, pb::StateForceResponse*) override;
  ::grpc::Status CloseSession(Ctx*, const pb::CloseSessionRequest*, pb::CloseSessionResponse*) override;
  ::grpc::Status GetSession(Ctx*, const pb::GetSessionRequest*, pb::GetSessionResponse*) override;
  ::grpc::Status ForkSession(Ctx*, const pb::ForkSessionRequest*, pb::ForkSessionResponse*) override;
  ::grpc::Status ListScenarios(Ctx*, const pb::ListScenariosRequest*, pb::ListScenariosResponse*) override;
  ::grpc::Status ListSessions(Ctx*, const pb::ListSessionsRequest*, pb::ListSessionsResponse*) override;
  ::grpc::Status JoinSession(Ctx*, const pb::JoinSessionRequest*, pb::JoinSessionResponse*) override;
  ::grpc::ServerWriteReactor<pb::Tick>* WatchSession(::grpc::CallbackServerContext*,
                                                     const pb::WatchSessionRequest*) override;

  // Unary calls running now: a drain waits for them before the gRPC server shuts down, so calls that arrive in the
  // meantime get our UNAVAILABLE rather than a transport error.
  int in_flight() const { return in_flight_; }

 private:
  TimePoint deadline(const Ctx* ctx) const;
  ::grpc::Status finish(const char* method, const std::string& session, const absl::Status& st);

  Engine& engine_;
  SessionManager& sessions_;
  Metrics& metrics_;
  double default_deadline_s_;
  const TokenAuth* auth_;
  std::atomic<int> in_flight_{0};
  struct InFlight {
    std::atomic<int>& n;
    explicit InFlight(std::atomic<int>& c) : n(c) { n++; }
    ~InFlight() { n--; }
  };
};

}  // namespace ss::server
