// scenestreamer-load --clients N --steps M --target ADDR [--json] [--scenario NAME]
// N concurrent clients, each with its own session, each stepping M times as fast as the server answers (the ego
// keeps its heading and speed). Reports steps per second over the whole run, per-step latency percentiles and
// errors.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "grpcpp/grpcpp.h"
#include "scenestreamer/v1/simulator.grpc.pb.h"

namespace pb = scenestreamer::v1;
using Clock = std::chrono::steady_clock;

int main(int argc, char** argv) {
  int clients = 4, steps = 20;
  std::string target = "127.0.0.1:50051", scenario;
  bool json = false;
  for (int i = 1; i < argc; ++i) {
    const bool has = i + 1 < argc;
    if (!std::strcmp(argv[i], "--json")) json = true;
    else if (!std::strcmp(argv[i], "--clients") && has) clients = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--steps") && has) steps = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--target") && has) target = argv[++i];
    else if (!std::strcmp(argv[i], "--scenario") && has) scenario = argv[++i];
    else {
      std::fprintf(stderr, "usage: scenestreamer-load --clients N --steps M --target ADDR [--json] [--scenario NAME]\n");
      return 2;
    }
  }
  if (clients < 1 || steps < 1) return std::fprintf(stderr, "--clients and --steps must be positive\n"), 2;
  auto channel = grpc::CreateChannel(target, grpc::InsecureChannelCredentials());
  auto stub = pb::Simulator::NewStub(channel);
  if (scenario.empty()) {
    grpc::ClientContext ctx;
    pb::ListScenariosResponse list;
    auto st = stub->ListScenarios(&ctx, {}, &list);
    if (!st.ok() || list.scenarios_size() == 0)
      return std::fprintf(stderr, "ListScenarios on %s: %s\n", target.c_str(), st.error_message().c_str()), 1;
    scenario = list.scenarios(0).name();
  }
  std::atomic<int> errors{0};
  std::mutex mu;
  std::vector<double> latencies_ms;
  std::string first_error;
  auto error = [&](const std::string& what, const grpc::Status& st) {
    errors++;
    std::lock_guard<std::mutex> l(mu);
    if (first_error.empty()) first_error = what + ": " + st.error_message();
  };
  const auto t0 = Clock::now();
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c)
    threads.emplace_back([&, c] {
      pb::CreateSessionRequest create;
      create.set_scenario_name(scenario);
      create.set_seed(static_cast<uint64_t>(c));
      pb::CreateSessionResponse session;
      {
        grpc::ClientContext ctx;
        if (auto st = stub->CreateSession(&ctx, create, &session); !st.ok()) return error("CreateSession", st);
      }
      pb::Tick tick = session.initial();
      std::vector<double> mine;
      for (int i = 0; i < steps; ++i) {
        pb::StepSceneRequest req;
        req.set_session_id(session.session_id());
        for (const pb::Agent& a : tick.agents())
          if (a.controlled()) {
            pb::ControlledPose* p = req.add_poses();
            p->set_agent_id(a.id());
            p->set_x(a.state().x() + 0.5 * a.state().vx());
            p->set_y(a.state().y() + 0.5 * a.state().vy());
            p->set_heading(a.state().heading());
            p->set_speed(std::hypot(a.state().vx(), a.state().vy()));
          }
        pb::StepSceneResponse resp;
        grpc::ClientContext ctx;
        ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(300));
        const auto s0 = Clock::now();
        auto st = stub->StepScene(&ctx, req, &resp);
        mine.push_back(std::chrono::duration<double, std::milli>(Clock::now() - s0).count());
        if (!st.ok() || resp.ticks_size() == 0) {
          error("StepScene", st);
          continue;
        }
        tick = resp.ticks(resp.ticks_size() - 1);
      }
      grpc::ClientContext ctx;
      pb::CloseSessionRequest close;
      close.set_session_id(session.session_id());
      pb::CloseSessionResponse closed;
      if (auto st = stub->CloseSession(&ctx, close, &closed); !st.ok()) error("CloseSession", st);
      std::lock_guard<std::mutex> l(mu);
      latencies_ms.insert(latencies_ms.end(), mine.begin(), mine.end());
    });
  for (auto& t : threads) t.join();
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  std::sort(latencies_ms.begin(), latencies_ms.end());
  auto pct = [&](double p) {
    if (latencies_ms.empty()) return 0.0;
    return latencies_ms[std::min(latencies_ms.size() - 1, static_cast<size_t>(p * latencies_ms.size()))];
  };
  const double sps = static_cast<double>(latencies_ms.size()) / seconds;
  if (json)
    std::printf("{\"clients\": %d, \"steps\": %d, \"errors\": %d, \"steps_per_second\": %.2f, "
                "\"latency_ms_p50\": %.2f, \"latency_ms_p99\": %.2f}\n",
                clients, steps, errors.load(), sps, pct(0.5), pct(0.99));
  else
    std::printf("%d clients x %d steps on %s: %.2f steps/s, latency p50 %.1f ms, p99 %.1f ms, %d errors%s%s\n",
                clients, steps, scenario.c_str(), sps, pct(0.5), pct(0.99), errors.load(),
                first_error.empty() ? "" : "; first: ", first_error.c_str());
  return errors ? 1 : 0;
}
