// A minimal closed-loop client: opens a session on the first bundled scenario, drives the ego at its current speed
// and heading for N steps, and prints what it sees each step.
//   scenestreamer-closed-loop [--target HOST:PORT] [--steps N]
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "grpcpp/grpcpp.h"
#include "scenestreamer/v1/simulator.grpc.pb.h"

namespace pb = scenestreamer::v1;

int main(int argc, char** argv) {
  std::string target = "127.0.0.1:50051";
  int steps = 10;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--target")) target = argv[i + 1];
    else if (!std::strcmp(argv[i], "--steps")) steps = std::atoi(argv[i + 1]);
    else {
      std::fprintf(stderr, "usage: scenestreamer-closed-loop [--target HOST:PORT] [--steps N]\n");
      return 2;
    }
  }
  auto stub = pb::Simulator::NewStub(grpc::CreateChannel(target, grpc::InsecureChannelCredentials()));
  auto fail = [](const char* what, const grpc::Status& st) {
    std::fprintf(stderr, "%s: %d %s\n", what, static_cast<int>(st.error_code()), st.error_message().c_str());
    return 1;
  };
  pb::ListScenariosResponse scenarios;
  {
    grpc::ClientContext ctx;
    if (auto st = stub->ListScenarios(&ctx, {}, &scenarios); !st.ok()) return fail("ListScenarios", st);
  }
  if (scenarios.scenarios_size() == 0) return std::fprintf(stderr, "the server has no scenarios\n"), 1;
  pb::CreateSessionRequest create;
  create.set_scenario_name(scenarios.scenarios(0).name());
  pb::CreateSessionResponse session;
  {
    grpc::ClientContext ctx;
    if (auto st = stub->CreateSession(&ctx, create, &session); !st.ok()) return fail("CreateSession", st);
  }
  std::printf("session %s on %s: %d agents\n", session.session_id().c_str(), create.scenario_name().c_str(),
              session.initial().agents_size());
  pb::Tick tick = session.initial();
  for (int i = 0; i < steps; ++i) {
    pb::StepSceneRequest req;
    req.set_session_id(session.session_id());
    for (const pb::Agent& a : tick.agents()) {
      if (!a.controlled()) continue;
      // The ego's controller: keep heading and speed for the next 0.5 s.
      pb::ControlledPose* p = req.add_poses();
      p->set_agent_id(a.id());
      p->set_x(a.state().x() + 0.5 * a.state().vx());
      p->set_y(a.state().y() + 0.5 * a.state().vy());
      p->set_heading(a.state().heading());
      p->set_speed(std::hypot(a.state().vx(), a.state().vy()));
    }
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
  grpc::ClientContext ctx;
  pb::CloseSessionRequest close;
  close.set_session_id(session.session_id());
  pb::CloseSessionResponse closed;
  if (auto st = stub->CloseSession(&ctx, close, &closed); !st.ok()) return fail("CloseSession", st);
  return 0;
}
