#include "server/simulator_service.h"

#include <atomic>
#include <deque>
#include <memory>
#include <mutex>

#include "absl/strings/str_cat.h"
#include "server/session_id.h"
#include "spdlog/spdlog.h"

namespace ss::server {
namespace {

void info_to_proto(const SessionInfo& i, pb::SessionInfo* o) {
  o->set_session_id(i.id);
  o->set_scenario_name(i.scenario_name);
  o->set_mode(mode_to_proto(i.options.mode));
  o->set_seed(i.options.seed);
  o->mutable_sampling()->set_top_p(i.options.top_p);
  o->mutable_sampling()->set_temperature(i.options.temperature);
  o->mutable_sampling()->set_no_motion_reject(!i.options.motion_reject);
  for (int64_t id : i.controlled) o->add_controlled_agent_ids(id);
  o->set_tick_hz(i.tick_hz);
  o->set_tick(i.tick);
  o->set_step(i.step);
  o->set_num_agents(i.num_agents);
  o->set_memory_bytes(i.memory_bytes);
  o->set_idle_seconds(i.idle_seconds);
  o->set_roi_radius(i.options.roi_radius);
  o->set_max_agents(i.options.max_agents);
}

// A router hashes the x-session-id metadata before the session exists, so the id it routed by is the session's: it
// stands in for an empty session_id, and one that differs from session_id would strand the session.
absl::StatusOr<std::string> proposed_session_id(const ::grpc::ServerContext& ctx, const std::string& field) {
  const auto m = ctx.client_metadata().find("x-session-id");
  if (m == ctx.client_metadata().end()) return field;
  const std::string routed(m->second.data(), m->second.size());
  if (field.empty() || routed == field) return routed;
  return absl::InvalidArgumentError(absl::StrCat("session_id ", echo_id(field), " differs from the x-session-id metadata ",
                                                 echo_id(routed), " the call was routed by"));
}

}  // namespace

TimePoint SimulatorService::deadline(const Ctx* ctx) const {
  // gRPC's deadline is on the system clock; the session manager's waits are on its own (steady) clock.
  const auto d = ctx->deadline();
  const auto now_sys = std::chrono::system_clock::now();
  const TimePoint now = sessions_.clock().now();
  const auto fallback = now + std::chrono::duration_cast<Duration>(std::chrono::duration<double>(default_deadline_s_));
  if (d == std::chrono::system_clock::time_point::max() || d - now_sys > std::chrono::hours(24)) return fallback;
  return now + std::chrono::duration_cast<Duration>(d - now_sys);
}

::grpc::Status SimulatorService::finish(const char* method, const std::string& session, const absl::Status& st) {
  metrics_.count_call(method);
  if (!st.ok()) {
    metrics_.count_rejected(absl::StatusCodeToString(st.code()));
    spdlog::debug("session {}: {} refused: {}: {}", session, method, absl::StatusCodeToString(st.code()),
                  std::string(st.message()));
  }
  return to_grpc(st);
}

::grpc::Status SimulatorService::CreateSession(Ctx* ctx, const pb::CreateSessionRequest* r,
                                               pb::CreateSessionResponse* out) {
  InFlight guard(in_flight_);
  auto tenant = caller_tenant(auth_, *ctx);
  if (!tenant.ok()) return finish("CreateSession", r->session_id(), tenant.status());
  auto options = options_from_proto(*r);
  if (!options.ok()) return finish("CreateSession", r->session_id(), options.status());
  SessionSource source;
  if (r->scenario_case() == pb::CreateSessionRequest::kScenarioName) source.scenario_name = r->scenario_name();
  else if (r->scenario_case() == pb::CreateSessionRequest::kWomdScenario) source.womd_bytes = r->womd_scenario();
  else
    return finish("CreateSession", r->session_id(),
                  absl::InvalidArgumentError("scenario: set scenario_name or womd_scenario"));
  if (source.scenario_name.empty() && source.womd_bytes.empty())
    return finish("CreateSession", r->session_id(),
                  absl::InvalidArgumentError("scenario: scenario_name or womd_scenario is empty"));
  auto proposed = proposed_session_id(*ctx, r->session_id());
  if (!proposed.ok()) return finish("CreateSession", r->session_id(), proposed.status());
  std::string id;
  std::vector<MapFeature> map;
  auto t = sessions_.create(*tenant, source, *options, r->tick_deadline_ms(), *proposed, deadline(ctx), &id,
                            r->include_map() ? &map : nullptr);
  if (!t.ok()) return finish("CreateSession", *proposed, t.status());
  out->set_session_id(id);
  tick_to_proto(t->view, t->tick, out->mutable_initial());
  map_to_proto(map, out);
  return finish("CreateSession", id, absl::OkStatus());
}

::grpc::Status SimulatorService::StepScene(Ctx* ctx, const pb::StepSceneRequest* r, pb::StepSceneResponse* out) {
  InFlight guard(in_flight_);
  auto tenant = caller_tenant(auth_, *ctx);
  if (!tenant.ok()) return finish("StepScene", r->session_id(), tenant.status());
  auto ticks = sessions_.step(r->session_id(), *tenant, r->controller_credential(), controls_from_proto(*r), r->num_ticks(),
                              deadline(ctx), [ctx] { return ctx->IsCancelled(); });
  if (!ticks.ok()) return finish("StepScene", r->session_id(), ticks.status());
  for (const TickView& t : *ticks) tick_to_proto(t.view, t.tick, out->add_ticks());
  return finish("StepScene", r->session_id(), absl::OkStatus());
}

::grpc::Status SimulatorService::InjectAgent(Ctx* ctx, const pb::InjectAgentRequest* r,
                                             pb::InjectAgentResponse* out) {
  InFlight guard(in_flight_);
  auto tenant = caller_tenant(auth_, *ctx);
  if (!tenant.ok()) return finish("InjectAgent", r->session_id(), tenant.status());
  auto ids = sessions_.inject(r->session_id(), *tenant, inject_from_proto(*r), deadline(ctx));
  if (!ids.ok()) return finish("InjectAgent", r->session_id(), ids.status());
  for (int64_t id : *ids) out->add_agent_ids(id);
  return finish("InjectAgent", r->session_id(), absl::OkStatus());
}

::grpc::Status SimulatorService::StateForce(Ctx* ctx, const pb::StateForceRequest* r, pb::StateForceResponse*) {
  InFlight guard(in_flight_);
  auto tenant = caller_tenant(auth_, *ctx);
  if (!tenant.ok()) return finish("StateForce", r->session_id(), tenant.status());
  auto q = force_from_proto(*r);
  if (!q.ok()) return finish("StateForce", r->session_id(), q.status());
  return finish("StateForce", r->session_id(),
                sessions_.state_force(r->session_id(), *tenant, r->controller_credential(), *q));
}

::grpc::Status SimulatorService::CloseSession(Ctx* ctx, const pb::CloseSessionRequest* r, pb::CloseSessionResponse*) {
  auto tenant = caller_tenant(auth_, *ctx);
  if (!tenant.ok()) return finish("CloseSession", r->session_id(), tenant.status());
  return finish("CloseSession", r->session_id(), sessions_.close(r->session_id(), *tenant));
}

::grpc::Status SimulatorService::GetSession(Ctx* ctx, const pb::GetSessionRequest* r, pb::GetSessionResponse* out) {
  auto tenant = caller_tenant(auth_, *ctx);
  if (!tenant.ok()) return finish("GetSession", r->session_id(), tenant.status());
  auto g = sessions_.get(r->session_id(), *tenant);
  if (!g.ok()) return finish("GetSession", r->session_id(), g.status());
  info_to_proto(g->first, out->mutable_info());
  tick_to_proto(g->second.view, g->second.tick, out->mutable_current());
  return finish("GetSession", r->session_id(), absl::OkStatus());
}

::grpc::Status SimulatorService::ForkSession(Ctx* ctx, const pb::ForkSessionRequest* r, pb::ForkSessionResponse* out) {
  InFlight guard(in_flight_);
  auto tenant = caller_tenant(auth_, *ctx);
  if (!tenant.ok()) return finish("ForkSession", r->session_id(), tenant.status());
  auto id = sessions_.fork(r->session_id(), *tenant, r->new_session_id(), deadline(ctx));
  if (!id.ok()) return finish("ForkSession", r->session_id(), id.status());
  out->set_session_id(*id);
  return finish("ForkSession", r->session_id(), absl::OkStatus());
}

::grpc::Status SimulatorService::ListScenarios(Ctx* ctx, const pb::ListScenariosRequest*,
                                               pb::ListScenariosResponse* out) {
  auto tenant = caller_tenant(auth_, *ctx);
  if (!tenant.ok()) return finish("ListScenarios", "-", tenant.status());
  for (const EngineScenario& s : engine_scenarios(engine_)) {
    pb::ScenarioInfo* o = out->add_scenarios();
    o->set_name(s.name);
    o->set_num_tracks(s.num_tracks);
    o->set_num_map_features(s.num_map_features);
    o->set_num_frames(s.num_frames);
    o->set_has_sdc(s.has_sdc);
  }
  return finish("ListScenarios", "-", absl::OkStatus());
}

::grpc::Status SimulatorService::ListSessions(Ctx* ctx, const pb::ListSessionsRequest*,
                                              pb::ListSessionsResponse* out) {
  auto tenant = caller_tenant(auth_, *ctx);
  if (!tenant.ok()) return finish("ListSessions", "-", tenant.status());
  for (const SessionInfo& i : sessions_.list(*tenant)) info_to_proto(i, out->add_sessions());
  return finish("ListSessions", "-", absl::OkStatus());
}

::grpc::Status SimulatorService::JoinSession(Ctx* ctx, const pb::JoinSessionRequest* r, pb::JoinSessionResponse* out) {
  auto tenant = caller_tenant(auth_, *ctx);
  if (!tenant.ok()) return finish("JoinSession", r->session_id(), tenant.status());
  auto j = sessions_.join(r->session_id(), *tenant, {r->agent_ids().begin(), r->agent_ids().end()},
                          r->controller_credential());
  if (!j.ok()) return finish("JoinSession", r->session_id(), j.status());
  out->set_controller_credential(j->credential);
  for (int64_t a : j->agents) out->add_agent_ids(a);
  return finish("JoinSession", r->session_id(), absl::OkStatus());
}

namespace {

// One WatchSession stream: ticks queue here as the session computes them and are written one at a time. A watcher
// that reads slower than the session steps loses the oldest queued ticks beyond kMaxQueued, as a watcher of the
// old thread-per-stream loop did beyond the session's recent ticks. The lock is recursive because gRPC may run
// OnWriteDone inline from StartWrite; the manager holds a reference while it calls in, and `self_` keeps the
// reactor alive until OnDone.
class WatchReactor final : public ::grpc::ServerWriteReactor<pb::Tick>, public TickWatcher {
 public:
  static std::shared_ptr<WatchReactor> make(SessionManager& sessions) {
    auto r = std::shared_ptr<WatchReactor>(new WatchReactor(sessions));
    r->self_ = r;
    return r;
  }

  void on_tick(const TickView& t) override {
    std::lock_guard<std::recursive_mutex> l(mu_);
    if (finished_ || t.tick <= last_tick_) return;
    last_tick_ = t.tick;
    if (queue_.size() >= kMaxQueued) queue_.erase(queue_.begin() + 1);  // the front may be being written
    tick_to_proto(t.view, t.tick, &queue_.emplace_back());
    if (!writing_) {
      writing_ = true;
      StartWrite(&queue_.front());
    }
  }
  void on_end() override {
    std::lock_guard<std::recursive_mutex> l(mu_);
    ended_ = true;
    if (!writing_) finish_locked(::grpc::Status::OK);
  }
  bool done() const override { return done_; }

  void OnWriteDone(bool ok) override {
    std::lock_guard<std::recursive_mutex> l(mu_);
    writing_ = false;
    queue_.pop_front();
    if (!ok) return finish_locked(::grpc::Status(::grpc::StatusCode::CANCELLED, "the stream broke"));
    if (!queue_.empty() && !finished_) {
      writing_ = true;
      StartWrite(&queue_.front());
    } else if (ended_) {
      finish_locked(::grpc::Status::OK);
    }
  }
  void OnCancel() override {
    std::lock_guard<std::recursive_mutex> l(mu_);
    finish_locked(::grpc::Status::CANCELLED);
  }
  void OnDone() override {
    if (registered_) sessions_.watch_done();
    done_ = true;
    auto last_reference = std::move(self_);  // may free this reactor when the function returns
  }
  void registered() { registered_ = true; }
  void fail(const ::grpc::Status& st) {
    std::lock_guard<std::recursive_mutex> l(mu_);
    finish_locked(st);
  }

 private:
  explicit WatchReactor(SessionManager& sessions) : sessions_(sessions) {}
  static constexpr size_t kMaxQueued = 64;
  void finish_locked(const ::grpc::Status& st) {
    if (finished_) return;
    finished_ = true;
    Finish(st);
  }

  SessionManager& sessions_;
  std::shared_ptr<WatchReactor> self_;
  std::recursive_mutex mu_;
  std::deque<pb::Tick> queue_;  // front: being written when writing_
  int64_t last_tick_ = -1;
  bool writing_ = false;
  bool ended_ = false;
  bool finished_ = false;
  bool registered_ = false;
  std::atomic<bool> done_{false};
};

}  // namespace

::grpc::ServerWriteReactor<pb::Tick>* SimulatorService::WatchSession(::grpc::CallbackServerContext* ctx,
                                                                   const pb::WatchSessionRequest* r) {
  auto reactor = WatchReactor::make(sessions_);
  auto tenant = caller_tenant(auth_, *ctx);
  const absl::Status st =
      tenant.ok() ? sessions_.watch_add(r->session_id(), *tenant, reactor) : tenant.status();
  if (st.ok()) {
    reactor->registered();
    metrics_.count_call("WatchSession");
  } else {
    reactor->fail(finish("WatchSession", r->session_id(), st));
  }
  return reactor.get();
}

}  // namespace ss::server
