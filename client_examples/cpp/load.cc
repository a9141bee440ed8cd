// scenestreamer-load --clients N --steps M --target ADDR [--json] [--scenario NAME | --scenarios K] [--route]
//                    [--densify A] [--no-motion-reject]
// N concurrent clients, each with its own session, each stepping M times as fast as the server answers (the ego
// keeps its heading and speed). Every session runs on one scenario (--scenario NAME, else the server's first), or with
// --scenarios K on the server's first K in turn (client c on the (c mod K)-th): K maps held at once, as a server
// serving many scenarios holds them. Reports steps per second over the whole run, per-step latency percentiles and
// errors. --route: each client proposes its session id and sends it as x-session-id metadata on every call, for a
// session-affine router (deploy/router/); the JSON then lists the ids. --densify A: densify mode, the log's agents
// topped up with sampled ones to A per session (the speed goals' 64-agent sessions). --no-motion-reject: sessions
// without reject sampling of motion (what it costs a server).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "client_common.h"
#include "engine/io/json_text.h"

namespace pb = scenestreamer::v1;
using Clock = std::chrono::steady_clock;

int main(int argc, char** argv) {
  client::Flags flags;
  if (!client::parse_flags(argc, argv, {"clients", "steps", "target", "scenario", "scenarios", "densify"},
                           {"json", "route", "no-motion-reject"}, &flags)) {
    std::fprintf(stderr,
                 "usage: scenestreamer-load --clients N --steps M --target ADDR [--json] [--scenario NAME | "
                 "--scenarios K] [--route] [--densify A] [--no-motion-reject]\n");
    return 2;
  }
  const int clients = client::flag_int(flags, "clients", 4);
  const int steps = client::flag_int(flags, "steps", 20);
  const int densify = client::flag_int(flags, "densify", 0);
  const std::string target = client::flag_string(flags, "target", client::kDefaultTarget);
  const std::string scenario = client::flag_string(flags, "scenario", "");
  const int spread = client::flag_int(flags, "scenarios", 1);
  const bool json = flags.switches.count("json") > 0;
  const bool route = flags.switches.count("route") > 0;
  const bool motion_reject = flags.switches.count("no-motion-reject") == 0;
  if (clients < 1 || steps < 1) return std::fprintf(stderr, "--clients and --steps must be positive\n"), 2;
  if (flags.values.count("densify") && densify < 1) return std::fprintf(stderr, "--densify must be positive\n"), 2;
  if (spread < 1) return std::fprintf(stderr, "--scenarios must be positive\n"), 2;
  if (!scenario.empty() && flags.values.count("scenarios"))
    return std::fprintf(stderr, "--scenario and --scenarios exclude each other\n"), 2;
  auto stub = client::connect(target);
  std::vector<std::string> scenarios{scenario};  // client c runs on scenarios[c % size]
  if (scenario.empty()) {
    auto st = client::scenario_names(*stub, &scenarios);
    if (!st.ok())
      return std::fprintf(stderr, "ListScenarios on %s: %s\n", target.c_str(), st.error_message().c_str()), 1;
    if (static_cast<int>(scenarios.size()) < spread)
      return std::fprintf(stderr, "the server at %s has %zu scenarios; the load asks for %d (--scenarios)\n",
                          target.c_str(), scenarios.size(), spread),
             1;
    scenarios.resize(spread);
  }
  std::atomic<int> errors{0};
  std::mutex mu;
  std::vector<double> latencies_ms;
  std::string first_error;
  std::vector<std::string> session_ids;
  std::vector<int> last_tick_agents;  // agents in each session's last tick
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
      create.set_scenario_name(scenarios[c % scenarios.size()]);
      create.set_seed(static_cast<uint64_t>(c));
      if (densify > 0) {
        create.set_mode(pb::MODE_DENSIFY);
        create.set_densify_target(densify);
      }
      if (!motion_reject) create.mutable_sampling()->set_no_motion_reject(true);
      const std::string key = route ? client::new_session_id() : "";  // the routing key: the proposed id
      create.set_session_id(key);
      pb::CreateSessionResponse session;
      {
        grpc::ClientContext ctx;
        client::route_by(&ctx, key);
        if (auto st = stub->CreateSession(&ctx, create, &session); !st.ok()) return error("CreateSession", st);
      }
      pb::Tick tick = session.initial();
      std::vector<double> mine;
      for (int i = 0; i < steps; ++i) {
        const pb::StepSceneRequest req = client::keep_heading_and_speed(session.session_id(), tick);
        pb::StepSceneResponse resp;
        grpc::ClientContext ctx;
        client::route_by(&ctx, key);
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
      if (auto st = client::close_session(*stub, session.session_id(), key); !st.ok()) error("CloseSession", st);
      std::lock_guard<std::mutex> l(mu);
      if (route) session_ids.push_back(session.session_id());
      last_tick_agents.push_back(tick.agents_size());
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
  double agents_mean = 0;
  for (int a : last_tick_agents) agents_mean += a;
  if (!last_tick_agents.empty()) agents_mean /= static_cast<double>(last_tick_agents.size());
  if (json) {
    nlohmann::ordered_json out = {{"clients", clients}, {"steps", steps}, {"scenarios", scenarios.size()},
                                  {"densify", densify}, {"motion_reject", motion_reject}, {"errors", errors.load()},
                                  {"steps_per_second", sps}, {"latency_ms_p50", pct(0.5)},
                                  {"latency_ms_p99", pct(0.99)}, {"agents_last_tick_mean", agents_mean}};
    if (route) out["session_ids"] = session_ids;
    std::puts(ss::json_text(out, -1).c_str());
  } else {
    const std::string on = scenarios.size() == 1 ? scenarios[0] : std::to_string(scenarios.size()) + " scenarios";
    std::printf("%d clients x %d steps on %s: %.2f steps/s, latency p50 %.1f ms, p99 %.1f ms, %d errors%s%s\n",
                clients, steps, on.c_str(), sps, pct(0.5), pct(0.99), errors.load(),
                first_error.empty() ? "" : "; first: ", first_error.c_str());
  }
  return errors ? 1 : 0;
}
