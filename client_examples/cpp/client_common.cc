#include "client_common.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <random>

namespace client {

bool parse_flags(int argc, char** argv, const std::vector<std::string>& valued, const std::vector<std::string>& switches,
                 Flags* flags) {
  auto has = [](const std::vector<std::string>& names, const std::string& name) {
    return std::find(names.begin(), names.end(), name) != names.end();
  };
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (!arg.starts_with("--")) return false;
    const std::string name = arg.substr(2);
    if (has(switches, name)) flags->switches.insert(name);
    else if (has(valued, name) && i + 1 < argc) flags->values[name] = argv[++i];
    else return false;
  }
  return true;
}

std::string flag_string(const Flags& flags, const std::string& name, const std::string& fallback) {
  const auto it = flags.values.find(name);
  return it == flags.values.end() ? fallback : it->second;
}

int flag_int(const Flags& flags, const std::string& name, int fallback) {
  const auto it = flags.values.find(name);
  return it == flags.values.end() ? fallback : std::atoi(it->second.c_str());
}

std::string new_session_id() {
  static std::mutex mu;
  static std::mt19937_64 rng{std::random_device{}()};
  std::lock_guard<std::mutex> l(mu);
  char hex[33];
  std::snprintf(hex, sizeof hex, "%016llx%016llx", static_cast<unsigned long long>(rng()),
                static_cast<unsigned long long>(rng()));
  return hex;
}

void route_by(grpc::ClientContext* ctx, const std::string& session_id) {
  if (!session_id.empty()) ctx->AddMetadata(kSessionIdHeader, session_id);
}

std::unique_ptr<pb::Simulator::Stub> connect(const std::string& target) {
  return pb::Simulator::NewStub(grpc::CreateChannel(target, grpc::InsecureChannelCredentials()));
}

grpc::Status scenario_names(pb::Simulator::Stub& stub, std::vector<std::string>* names) {
  grpc::ClientContext ctx;
  pb::ListScenariosResponse list;
  grpc::Status st = stub.ListScenarios(&ctx, {}, &list);
  names->clear();
  if (st.ok())
    for (const pb::ScenarioInfo& s : list.scenarios()) names->push_back(s.name());
  return st;
}

pb::StepSceneRequest keep_heading_and_speed(const std::string& session_id, const pb::Tick& tick) {
  pb::StepSceneRequest req;
  req.set_session_id(session_id);
  for (const pb::Agent& a : tick.agents()) {
    if (!a.controlled()) continue;
    pb::ControlledPose* p = req.add_poses();
    p->set_agent_id(a.id());
    p->set_x(a.state().x() + 0.5 * a.state().vx());
    p->set_y(a.state().y() + 0.5 * a.state().vy());
    p->set_heading(a.state().heading());
    p->set_speed(std::hypot(a.state().vx(), a.state().vy()));
  }
  return req;
}

grpc::Status close_session(pb::Simulator::Stub& stub, const std::string& session_id, const std::string& route) {
  grpc::ClientContext ctx;
  route_by(&ctx, route);
  pb::CloseSessionRequest close;
  close.set_session_id(session_id);
  pb::CloseSessionResponse closed;
  return stub.CloseSession(&ctx, close, &closed);
}

}  // namespace client
