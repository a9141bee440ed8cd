// A minimal closed-loop client: opens a session on the first bundled scenario, drives the ego at its current speed
// and heading for N steps, and prints what it sees each step.
//   scenestreamer-closed-loop [--target HOST:PORT] [--steps N]
#include <chrono>
#include <cstdio>
#include <string>

#include "client_common.h"

namespace pb = scenestreamer::v1;

int main(int argc, char** argv) {
  client::Flags flags;
  if (!client::parse_flags(argc, argv, {"target", "steps"}, {}, &flags)) {
    std::fprintf(stderr, "usage: scenestreamer-closed-loop [--target HOST:PORT] [--steps N]\n");
    return 2;
  }
  const std::string target = client::flag_string(flags, "target", client::kDefaultTarget);
  const int steps = client::flag_int(flags, "steps", 10);
  auto stub = client::connect(target);
  auto fail = [](const char* what, const grpc::Status& st) {
    std::fprintf(stderr, "%s: %d %s\n", what, static_cast<int>(st.error_code()), st.error_message().c_str());
    return 1;
  };
  pb::CreateSessionRequest create;
  {
    std::vector<std::string> names;
    if (auto st = client::scenario_names(*stub, &names); !st.ok()) return fail("ListScenarios", st);
    if (names.empty()) return std::fprintf(stderr, "the server has no scenarios\n"), 1;
    create.set_scenario_name(names[0]);
  }
  pb::CreateSessionResponse session;
  {
    grpc::ClientContext ctx;
    if (auto st = stub->CreateSession(&ctx, create, &session); !st.ok()) return fail("CreateSession", st);
  }
  std::printf("session %s on %s: %d agents\n", session.session_id().c_str(), create.scenario_name().c_str(),
              session.initial().agents_size());
  pb::Tick tick = session.initial();
  for (int i = 0; i < steps; ++i) {
    const pb::StepSceneRequest req = client::keep_heading_and_speed(session.session_id(), tick);
    pb::StepSceneResponse resp;
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    if (auto st = stub->StepScene(&ctx, req, &resp); !st.ok()) return fail("StepScene", st);
    tick = resp.ticks(resp.ticks_size() - 1);
    int entered = 0;
    for (const pb::Agent& a : tick.agents()) entered += a.entered();
    std::printf("tick %lld t=%.1f s: %d agents (%d entered, %d left), %d lights\n",
                static_cast<long long>(tick.tick()), tick.sim_time(), tick.agents_size(), entered, tick.left_size(),
                tick.lights_size());
  }
  if (auto st = client::close_session(*stub, session.session_id()); !st.ok()) return fail("CloseSession", st);
  return 0;
}
