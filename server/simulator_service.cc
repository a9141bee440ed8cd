#include "server/simulator_service.h"

#include "absl/strings/str_cat.h"
#include "spdlog/spdlog.h"

namespace ss::server {
namespace {

::grpc::Status to_grpc(const absl::Status& st) {
  if (st.ok()) return ::grpc::Status::OK;
  return ::grpc::Status(static_cast<::grpc::StatusCode>(static_cast<int>(st.code())), std::string(st.message()));
}

void info_to_proto(const SessionInfo& i, pb::SessionInfo* o) {
  o->set_session_id(i.id);
  o->set_scenario_name(i.scenario_name);
  o->set_mode(mode_to_proto(i.options.mode));
  o->set_seed(i.options.seed);
  o->mutable_sampling()->set_top_p(i.options.top_p);
  o->mutable_sampling()->set_temperature(i.options.temperature);
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

}  // namespace

Clock::time_point SimulatorService::deadline(const Ctx* ctx) const {
  // gRPC's deadline is on the system clock; engine waits use the steady clock.
  const auto d = ctx->deadline();
  const auto now_sys = std::chrono::system_clock::now();
  const auto fallback = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                           std::chrono::duration<double>(default_deadline_s_));
  if (d == std::chrono::system_clock::time_point::max() || d - now_sys > std::chrono::hours(24)) return fallback;
  return Clock::now() + std::chrono::duration_cast<Clock::duration>(d - now_sys);
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
  // The scenario's map, for the events and the client (a client's bytes are parsed here and again by the session).
  auto scenario = engine_scenario(engine_, source);
  if (!scenario.ok()) return finish("CreateSession", r->session_id(), scenario.status());
  // A router hashes the x-session-id metadata before the session exists, so the id it routed by is the session's:
  // it stands in for an empty session_id, and one that differs from session_id would strand the session.
  std::string proposed = r->session_id();
  if (const auto m = ctx->client_metadata().find("x-session-id"); m != ctx->client_metadata().end()) {
    const std::string routed(m->second.data(), m->second.size());
    if (proposed.empty()) proposed = routed;
    else if (routed != proposed)
      return finish("CreateSession", proposed,
                    absl::InvalidArgumentError(absl::StrCat("session_id '", proposed.substr(0, 64),
                                                            "' differs from the x-session-id metadata '",
                                                            routed.substr(0, 64), "' the call was routed by")));
  }
  std::string id;
  auto t = sessions_.create(source, *options, r->tick_hz(), r->tick_deadline_ms(), proposed, deadline(ctx), &id);
  if (!t.ok()) return finish("CreateSession", proposed, t.status());
  out->set_session_id(id);
  tick_to_proto(t->view, t->tick, out->mutable_initial());
  event_maps_.add(id, source.scenario_name, *scenario);
  if (r->include_map()) map_to_proto(**scenario, out);
  return finish("CreateSession", id, absl::OkStatus());
}

::grpc::Status SimulatorService::StepScene(Ctx* ctx, const pb::StepSceneRequest* r, pb::StepSceneResponse* out) {
  InFlight guard(in_flight_);
  auto controls = controls_from_proto(*r);
  if (!controls.ok()) return finish("StepScene", r->session_id(), controls.status());
  // The tick before this call's ticks: the events (a stop line crossed, progress) are measured from it.
  auto before = sessions_.get(r->session_id());
  if (!before.ok()) return finish("StepScene", r->session_id(), before.status());
  auto ticks = sessions_.step(r->session_id(), *controls, r->num_ticks(), deadline(ctx));
  if (!ticks.ok()) return finish("StepScene", r->session_id(), ticks.status());
  const auto map = event_maps_.find(r->session_id(), before->first.scenario_name);
  const StepResult* previous = &before->second.view;
  for (const TickView& t : *ticks) {
    pb::Tick* tick = out->add_ticks();
    tick_to_proto(t.view, t.tick, tick);
    if (map) events_to_proto(tick_events(*map, *previous, t.view), tick);
    previous = &t.view;
  }
  return finish("StepScene", r->session_id(), absl::OkStatus());
}

::grpc::Status SimulatorService::InjectAgent(Ctx* ctx, const pb::InjectAgentRequest* r,
                                             pb::InjectAgentResponse* out) {
  InFlight guard(in_flight_);
  auto q = inject_from_proto(*r);
  if (!q.ok()) return finish("InjectAgent", r->session_id(), q.status());
  auto ids = sessions_.inject(r->session_id(), *q, deadline(ctx));
  if (!ids.ok()) return finish("InjectAgent", r->session_id(), ids.status());
  for (int64_t id : *ids) out->add_agent_ids(id);
  return finish("InjectAgent", r->session_id(), absl::OkStatus());
}

::grpc::Status SimulatorService::StateForce(Ctx*, const pb::StateForceRequest* r, pb::StateForceResponse*) {
  InFlight guard(in_flight_);
  auto q = force_from_proto(*r);
  if (!q.ok()) return finish("StateForce", r->session_id(), q.status());
  return finish("StateForce", r->session_id(), sessions_.state_force(r->session_id(), *q));
}

::grpc::Status SimulatorService::CloseSession(Ctx*, const pb::CloseSessionRequest* r, pb::CloseSessionResponse*) {
  const absl::Status st = sessions_.close(r->session_id());
  if (st.ok()) event_maps_.remove(r->session_id());
  return finish("CloseSession", r->session_id(), st);
}

::grpc::Status SimulatorService::GetSession(Ctx*, const pb::GetSessionRequest* r, pb::GetSessionResponse* out) {
  auto g = sessions_.get(r->session_id());
  if (!g.ok()) return finish("GetSession", r->session_id(), g.status());
  info_to_proto(g->first, out->mutable_info());
  tick_to_proto(g->second.view, g->second.tick, out->mutable_current());
  return finish("GetSession", r->session_id(), absl::OkStatus());
}

::grpc::Status SimulatorService::ForkSession(Ctx* ctx, const pb::ForkSessionRequest* r, pb::ForkSessionResponse* out) {
  InFlight guard(in_flight_);
  auto id = sessions_.fork(r->session_id(), r->new_session_id(), deadline(ctx));
  if (!id.ok()) return finish("ForkSession", r->session_id(), id.status());
  event_maps_.fork(r->session_id(), *id);
  out->set_session_id(*id);
  return finish("ForkSession", r->session_id(), absl::OkStatus());
}

::grpc::Status SimulatorService::ListScenarios(Ctx*, const pb::ListScenariosRequest*, pb::ListScenariosResponse* out) {
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

::grpc::Status SimulatorService::ListSessions(Ctx*, const pb::ListSessionsRequest*, pb::ListSessionsResponse* out) {
  for (const SessionInfo& i : sessions_.list()) info_to_proto(i, out->add_sessions());
  return finish("ListSessions", "-", absl::OkStatus());
}

::grpc::Status SimulatorService::WatchSession(Ctx* ctx, const pb::WatchSessionRequest* r,
                                              ::grpc::ServerWriter<pb::Tick>* writer) {
  auto st = sessions_.watch(
      r->session_id(),
      [&](const TickView& t) {
        pb::Tick tick;
        tick_to_proto(t.view, t.tick, &tick);
        return writer->Write(tick);
      },
      [&] { return ctx->IsCancelled(); });
  return finish("WatchSession", r->session_id(), st);
}

}  // namespace ss::server
