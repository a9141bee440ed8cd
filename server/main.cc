// scenestreamer-server: the SceneStreamer simulator over gRPC. With no flags it loads the bundled default model and the
// bundled sample scenarios (share/scenestreamer beside an installed server's bin/, or the source tree for a server in
// its build tree: ss::cli::bundled_dir) and serves on 127.0.0.1:50051.
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "grpcpp/ext/proto_server_reflection_plugin.h"
#include "grpcpp/generic/async_generic_service.h"
#include "grpcpp/grpcpp.h"
#include "grpcpp/health_check_service_interface.h"
#include "grpcpp/impl/server_builder_option.h"
#include "server/allocator.h"
#include "server/auth.h"
#include "server/metrics.h"
#include "server/session_manager.h"
#include "server/session_store.h"
#include "server/simulator_service.h"
#include "server/snapshot.h"
#include "server/tls.h"
#include "spdlog/spdlog.h"
#include "common/command_line.h"

ABSL_FLAG(std::string, host, "127.0.0.1",
          "Address to listen on. Loopback by default: pass --host=0.0.0.0 to serve other machines (the image and the "
          "manifests in deploy/ do, on purpose), ideally with --tls_cert/--tls_key and --tokens_file");
ABSL_FLAG(int, port, 50051, "gRPC port (0: pick a free one; the chosen port is logged)");
ABSL_FLAG(std::string, model, "",
          "Model weights (safetensors); empty: the bundled default model (models/default.safetensors in "
          "share/scenestreamer beside an installed server's bin/, or in the source tree for a server in its build "
          "tree), else random weights");
ABSL_FLAG(std::string, random_config, "large", "Config of the random weights used when no model exists");
ABSL_FLAG(std::string, scenario_dir, "",
          "Directory of WOMD TFRecord / GPUDrive JSON scenarios; empty: the bundled sample scenarios (data/ in "
          "share/scenestreamer beside an installed server's bin/, or in the source tree for a server in its build "
          "tree)");
ABSL_FLAG(std::string, snapshot_dir, "",
          "Where sessions are saved on eviction and SIGTERM, and restored from on start (made 0700; the server refuses "
          "to start when it cannot write there). Empty: no snapshots, and no eviction");
ABSL_FLAG(double, snapshot_interval_s, 30,
          "With --snapshot_dir or --session_store: a session that changed is saved at least this often, busy or "
          "idle, so a crash loses at most this much of it (0: saved only on eviction and SIGTERM)");
ABSL_FLAG(std::string, session_store, "",
          "A shared session store, redis://HOST:PORT[/DB] (Debian's redis-server): snapshots go there instead of "
          "--snapshot_dir, under a lease per session naming its replica, and any replica pointed at it continues any "
          "session (docs/deployment.md). Empty: none");
ABSL_FLAG(std::string, session_store_password_file, "",
          "With --session_store: a file holding the store's password (Redis AUTH; its first line)");
ABSL_FLAG(std::string, replica_id, "",
          "With --session_store: this replica's name in its leases, unique among the replicas (the StatefulSet passes "
          "the pod's name); empty: the host name");
ABSL_FLAG(int, lease_ms, 5000,
          "With --session_store: a session's lease lasts this long unless renewed (every quarter of it); a replica "
          "that dies holds its sessions this long at most");
ABSL_FLAG(int, max_sessions, 256, "Cap on sessions in memory");
ABSL_FLAG(int, max_cache_mb, 8192, "Cap on the bytes all sessions hold (KV caches, state, client-sent scenarios), MiB");
ABSL_FLAG(int, tenant_max_sessions, 0,
          "Cap on one tenant's sessions in memory; 0: --max_sessions divided evenly among the tenants of "
          "--tokens_file (all of it without tokens)");
ABSL_FLAG(int, tenant_max_cache_mb, 0,
          "Cap on the bytes one tenant's sessions hold, MiB; 0: --max_cache_mb divided evenly among the tenants of "
          "--tokens_file (all of it without tokens)");
ABSL_FLAG(double, idle_timeout_s, 3600, "A session unused this long is closed");
ABSL_FLAG(double, evict_idle_s, 30, "A session unused this long may be evicted (least recently used first) for room");
ABSL_FLAG(int, threads, 0, "Compute threads (engine calls running at once); 0: the number of cores");
ABSL_FLAG(int, step_threads, 1,
          "Threads one session's step may use (its attention shared out; same results at any count). For few "
          "sessions on many cores: a step that finds them busy runs on its own thread");
ABSL_FLAG(std::string, kv_precision, "fp16",
          "fp16 or fp32: how sessions store their keys and values (fp16 halves a session's memory; the math is fp32)");
ABSL_FLAG(std::string, matmul_precision, "",
          "bf16 or fp32: the dense products' precision (bf16 needs a CPU with AVX512-BF16); empty: bf16 where the CPU "
          "has it, else fp32");
ABSL_FLAG(int, max_watchers, 1024, "Cap on WatchSession streams open at once (they cost no thread each)");
ABSL_FLAG(int, tick_deadline_ms, 2000, "Default wait of a multi-client tick for its late controllers");
ABSL_FLAG(double, call_deadline_s, 120, "Deadline of a call whose client set none");
ABSL_FLAG(int, max_message_mb, 64, "Largest request or response, MiB (also the largest client-sent scenario)");
ABSL_FLAG(int, max_scenario_tracks, 1024, "Largest number of tracks in a scenario");
ABSL_FLAG(int, max_map_features, 20000, "Largest number of map features in a scenario");
ABSL_FLAG(int, max_scenario_frames, 1000, "Largest number of frames (timestamps, states of a track) in a scenario");
ABSL_FLAG(int, max_map_points, 1000000,
          "Largest number of map points (polylines, polygons, lane boundaries and neighbours) in a scenario");
ABSL_FLAG(int, metrics_port, 9464, "Prometheus text metrics on METRICS_HOST:PORT (-1: off, 0: a free port)");
ABSL_FLAG(std::string, metrics_host, "127.0.0.1",
          "Address of the metrics port (containers set 0.0.0.0 so the cluster's Prometheus can scrape it)");
ABSL_FLAG(double, drain_grace_s, 1.0,
          "On SIGTERM, keep answering at least this long (health NOT_SERVING, new calls UNAVAILABLE) so clients and "
          "load balancers see the drain rather than a closed connection");
ABSL_FLAG(std::string, log_level, "info", "trace, debug, info, warn, error");
ABSL_FLAG(std::string, tls_cert, "", "PEM certificate chain: serve gRPC over TLS (with --tls_key)");
ABSL_FLAG(std::string, tls_key, "", "PEM private key of --tls_cert");
ABSL_FLAG(std::string, tls_client_ca, "",
          "PEM CA bundle: with it, clients must present a certificate this CA signed (mutual TLS)");
ABSL_FLAG(std::string, tokens_file, "",
          "Bearer-token authentication: a file of `TOKEN TENANT` lines (README, Server); every call then needs "
          "`authorization: Bearer TOKEN`, and a tenant sees only its own sessions. Empty: no authentication");
ABSL_FLAG(int, health_port, -1,
          "Also serve grpc.health.v1.Health alone (no reflection, no Simulator), plaintext and without tokens, on "
          "--health_host:PORT (for probes that cannot do TLS, like Kubernetes' gRPC probes; -1: off, 0: a free port)");
// The RSS that rose round by round under identical load (README, Faults; server/allocator.h).
ABSL_FLAG(double, malloc_trim_s, 10,
          "After sessions close, give the pages jemalloc holds unused back to the kernel (an arena purge) at most "
          "this often, seconds; 0: only as jemalloc's decay does (10 s after they fall unused, on later allocations)");
ABSL_FLAG(std::string, health_host, "127.0.0.1", "Address of --health_port");

namespace {

constexpr const char* kUsage =
    "usage: scenestreamer-server [--host H] [--port P] [--model W] [--scenario_dir D] [--snapshot_dir S] ...\n"
    "  Serves the SceneStreamer simulator (scenestreamer.v1.Simulator, gRPC health, reflection) on H:P, with the\n"
    "  bundled default model and sample scenarios unless --model and --scenario_dir say otherwise.";

// The bundled default model; "" (random weights, loudly) when there is none, with the reason.
std::string default_model(std::string* why) {
  const absl::StatusOr<std::string> bundled = ss::cli::bundled_dir();
  if (!bundled.ok()) {
    *why = std::string(bundled.status().message());
    return "";
  }
  const std::filesystem::path path = std::filesystem::path(*bundled) / "models" / "default.safetensors";
  std::error_code ec;
  if (std::filesystem::exists(path, ec)) return path.string();
  *why = "no default model at " + path.string();
  return "";
}

// The bundled sample scenarios' folder; NOT_FOUND saying where it looked when it holds none.
absl::StatusOr<std::string> default_scenario_dir() {
  const absl::StatusOr<std::string> bundled = ss::cli::bundled_dir();
  if (!bundled.ok())
    return absl::NotFoundError(absl::StrCat("no --scenario_dir given, and ", bundled.status().message()));
  const std::filesystem::path dir = std::filesystem::path(*bundled) / "data";
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    const std::string n = e.path().filename().string();
    if (n.find(".tfrecord") != std::string::npos || e.path().extension() == ".json") return dir.string();
  }
  return absl::NotFoundError(absl::StrCat("no --scenario_dir given, and the bundled scenarios' folder ", dir.string(),
                                          " holds no WOMD TFRecord or JSON scenario"));
}

// Takes the reflection plugin off a ServerBuilder: the health port serves health alone. Reflection (the API's schema)
// is the main port's, behind its TLS and tokens; its plugin registers itself for every builder when the library
// loads, so it is removed here rather than left out.
class WithoutReflection : public grpc::ServerBuilderOption {
 public:
  void UpdateArguments(grpc::ChannelArguments*) override {}
  void UpdatePlugins(std::vector<std::unique_ptr<grpc::ServerBuilderPlugin>>* plugins) override {
    std::erase_if(*plugins, [](const auto& p) { return p->name() == "proto_server_reflection"; });
  }
};

}  // namespace

int main(int argc, char** argv) {
  // --help: the server's flags with their defaults, as the tools list theirs (Abseil's own --help looks for flags in
  // a file named after the program, and finds none). --helpfull is still Abseil's: every flag of every library.
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--") == 0) break;
    if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-help") == 0) {
      std::fputs(ss::cli::file_flags_help(kUsage, __FILE__).c_str(), stdout);
      return 0;
    }
  }
  absl::SetProgramUsageMessage(kUsage);
  absl::ParseCommandLine(argc, argv);
  spdlog::set_level(spdlog::level::from_str(absl::GetFlag(FLAGS_log_level)));
  const int compute_threads = absl::GetFlag(FLAGS_threads) > 0 ? absl::GetFlag(FLAGS_threads)
                                                               : static_cast<int>(std::thread::hardware_concurrency());
  const absl::StatusOr<std::string> allocator = ss::server::allocator_version();
  if (!allocator.ok()) {
    spdlog::critical("cannot start: {}", std::string(allocator.status().message()));
    return 1;
  }
  spdlog::info("malloc: {}, unused pages given back {}", *allocator,
               absl::GetFlag(FLAGS_malloc_trim_s) > 0
                   ? fmt::format("at most every {:g} s after sessions close", absl::GetFlag(FLAGS_malloc_trim_s))
                   : std::string("by jemalloc's decay only (--malloc_trim_s=0)"));

  // SIGTERM and SIGINT are taken by one thread (sigwait), so no handler runs inside gRPC's threads.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  ss::EngineOptions eo;
  std::string no_model_why;
  eo.model_path = absl::GetFlag(FLAGS_model).empty() ? default_model(&no_model_why) : absl::GetFlag(FLAGS_model);
  eo.random_config = absl::GetFlag(FLAGS_random_config);
  std::string scenario_dir = absl::GetFlag(FLAGS_scenario_dir);
  if (scenario_dir.empty()) {
    const absl::StatusOr<std::string> bundled = default_scenario_dir();
    if (!bundled.ok()) {
      spdlog::critical("cannot start: {} (pass --scenario_dir DIR)", std::string(bundled.status().message()));
      return 1;
    }
    scenario_dir = *bundled;
  }
  eo.scenario_paths = {scenario_dir};
  const int max_message = absl::GetFlag(FLAGS_max_message_mb) << 20;
  eo.max_scenario_bytes = static_cast<size_t>(max_message);
  eo.max_scenario_tracks = absl::GetFlag(FLAGS_max_scenario_tracks);
  eo.max_map_features = absl::GetFlag(FLAGS_max_map_features);
  eo.max_scenario_frames = absl::GetFlag(FLAGS_max_scenario_frames);
  eo.max_map_points = absl::GetFlag(FLAGS_max_map_points);
  eo.step_threads = absl::GetFlag(FLAGS_step_threads);
  eo.kv_precision = absl::GetFlag(FLAGS_kv_precision);
  eo.matmul_precision = absl::GetFlag(FLAGS_matmul_precision);
  auto engine = ss::engine_create(eo);
  if (!engine.ok()) {
    spdlog::critical("cannot start: {}", std::string(engine.status().message()));
    return 1;
  }
  if (ss::engine_random_weights(**engine))
    spdlog::warn("!!! NO TRAINED MODEL: serving RANDOM '{}' weights (traffic will be noise): {}. Pass --model FILE "
                 "!!!", eo.random_config, no_model_why);
  else
    spdlog::info("model {} (config {}, {} keys and values, {} products, {} threads per step)", eo.model_path,
                 ss::engine_model_name(**engine), ss::engine_kv_precision(**engine),
                 ss::engine_matmul_precision(**engine), eo.step_threads);
  spdlog::info("{} scenarios from {}", ss::engine_scenarios(**engine).size(), scenario_dir);

  // The shared session store, checked before anything is served: a replica that cannot reach it refuses to start.
  std::unique_ptr<ss::server::SessionStore> store;
  if (!absl::GetFlag(FLAGS_session_store).empty()) {
    if (!absl::GetFlag(FLAGS_snapshot_dir).empty()) {
      spdlog::critical("cannot start: --snapshot_dir and --session_store both given: with a session store the "
                       "snapshots go there only (drop --snapshot_dir)");
      return 1;
    }
    ss::server::StoreOptions so;
    so.url = absl::GetFlag(FLAGS_session_store);
    so.replica_id = absl::GetFlag(FLAGS_replica_id);
    if (so.replica_id.empty()) {
      char host[256] = {};
      gethostname(host, sizeof(host) - 1);
      so.replica_id = host;
    }
    so.lease_ms = absl::GetFlag(FLAGS_lease_ms);
    // Sessions no replica holds (theirs died and no call came since) leave the store after the idle timeout.
    so.retain_ms = static_cast<int64_t>(absl::GetFlag(FLAGS_idle_timeout_s) * 1000) + so.lease_ms;
    if (const std::string file = absl::GetFlag(FLAGS_session_store_password_file); !file.empty()) {
      std::ifstream in(file);
      if (!in) {
        spdlog::critical("cannot start: --session_store_password_file {}: cannot be read: {}", file,
                         std::strerror(errno));
        return 1;
      }
      std::getline(in, so.password);
      if (!so.password.empty() && so.password.back() == '\r') so.password.pop_back();
      if (so.password.empty()) {
        spdlog::critical("cannot start: --session_store_password_file {}: its first line is empty", file);
        return 1;
      }
    }
    auto connected = ss::server::SessionStore::connect(so);
    if (!connected.ok()) {
      spdlog::critical("cannot start: {}", std::string(connected.status().message()));
      return 1;
    }
    store = std::move(*connected);
    spdlog::info("session store {} (replica '{}', leases of {} ms)", store->where(), so.replica_id, so.lease_ms);
  } else if (!absl::GetFlag(FLAGS_session_store_password_file).empty()) {
    spdlog::critical("cannot start: --session_store_password_file without --session_store");
    return 1;
  }

  std::unique_ptr<ss::server::TokenAuth> auth;
  if (!absl::GetFlag(FLAGS_tokens_file).empty()) {
    auto loaded = ss::server::TokenAuth::load(absl::GetFlag(FLAGS_tokens_file));
    if (!loaded.ok()) {
      spdlog::critical("cannot start: {}", std::string(loaded.status().message()));
      return 1;
    }
    auth = std::move(*loaded);
    spdlog::info("bearer-token authentication: {} tokens from {}", auth->size(), absl::GetFlag(FLAGS_tokens_file));
  }

  ss::server::Metrics metrics;
  ss::server::ManagerOptions mo;
  mo.session_store = store.get();
  mo.snapshot_dir = absl::GetFlag(FLAGS_snapshot_dir);
  mo.snapshot_interval_s = absl::GetFlag(FLAGS_snapshot_interval_s);
  mo.max_sessions = absl::GetFlag(FLAGS_max_sessions);
  mo.max_cache_bytes = static_cast<uint64_t>(absl::GetFlag(FLAGS_max_cache_mb)) << 20;
  // An even share by default: the shares then add up to the caps, so no tenant ever finds the server full of others'
  // sessions, and none is evicted to make room for another tenant.
  const int tenants = auth ? std::max(1, auth->tenants()) : 1;
  mo.tenant_max_sessions = absl::GetFlag(FLAGS_tenant_max_sessions) > 0 ? absl::GetFlag(FLAGS_tenant_max_sessions)
                                                                         : std::max(1, mo.max_sessions / tenants);
  mo.tenant_max_cache_bytes = absl::GetFlag(FLAGS_tenant_max_cache_mb) > 0
                                  ? static_cast<uint64_t>(absl::GetFlag(FLAGS_tenant_max_cache_mb)) << 20
                                  : mo.max_cache_bytes / tenants;
  if (auth)
    spdlog::info("{} tenants, each with at most {} sessions and {} MiB", tenants, mo.tenant_max_sessions,
                 mo.tenant_max_cache_bytes >> 20);
  mo.idle_timeout_s = absl::GetFlag(FLAGS_idle_timeout_s);
  mo.evict_idle_s = absl::GetFlag(FLAGS_evict_idle_s);
  mo.compute_threads = compute_threads;
  mo.default_tick_deadline_ms = absl::GetFlag(FLAGS_tick_deadline_ms);
  mo.max_watchers = absl::GetFlag(FLAGS_max_watchers);
  mo.malloc_trim_interval_s = absl::GetFlag(FLAGS_malloc_trim_s);
  if (!mo.snapshot_dir.empty()) {
    if (auto st = ss::server::prepare_snapshot_dir(mo.snapshot_dir); !st.ok()) {
      spdlog::critical("cannot start: {}", std::string(st.message()));
      return 1;
    }
  }
  ss::server::SessionManager sessions(**engine, mo, metrics);
  metrics.sessions = [&] { return sessions.count(); };
  metrics.cache_bytes = [&] { return sessions.total_bytes(); };
  metrics.watchers = [&] { return sessions.watchers(); };
  metrics.compute_queued = [&] { return sessions.compute_queued(); };
  if (!mo.snapshot_dir.empty()) {
    const int n = sessions.restore_all();
    spdlog::info("restored {} sessions from {}", n, mo.snapshot_dir);
  }

  if (absl::GetFlag(FLAGS_metrics_port) >= 0) {
    const std::string host = absl::GetFlag(FLAGS_metrics_host);
    auto metrics_port = metrics.serve(host, absl::GetFlag(FLAGS_metrics_port));
    if (metrics_port.ok())
      spdlog::info("metrics on http://{}:{}/metrics", host, *metrics_port);
    else
      spdlog::warn("metrics off: {}", std::string(metrics_port.status().message()));
  }

  auto credentials = ss::server::server_credentials(
      {absl::GetFlag(FLAGS_tls_cert), absl::GetFlag(FLAGS_tls_key), absl::GetFlag(FLAGS_tls_client_ca)});
  if (!credentials.ok()) {
    spdlog::critical("cannot start: {}", std::string(credentials.status().message()));
    return 1;
  }

  ss::server::SimulatorService service(**engine, sessions, metrics, absl::GetFlag(FLAGS_call_deadline_s), auth.get());
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  int port = 0;
  const std::string address = absl::GetFlag(FLAGS_host) + ":" + std::to_string(absl::GetFlag(FLAGS_port));
  builder.AddListeningPort(address, *credentials, &port);
  builder.SetMaxReceiveMessageSize(max_message);
  builder.SetMaxSendMessageSize(max_message);
  builder.RegisterService(&service);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) {
    spdlog::critical("cannot listen on {}", address);
    return 1;
  }
  // The health-only server: its own port, no TLS, no tokens; the same status as the main port's health service.
  std::unique_ptr<grpc::Server> health_server;
  // Every other method on the health port: UNIMPLEMENTED (gRPC's default generic service). It also gives the port's
  // server the polled completion queue gRPC needs before the health service is added at start.
  grpc::CallbackGenericService health_port_rest;
  if (absl::GetFlag(FLAGS_health_port) >= 0) {
    grpc::ServerBuilder hb;
    hb.SetOption(std::make_unique<WithoutReflection>());
    hb.RegisterCallbackGenericService(&health_port_rest);
    int health_port = 0;
    const std::string health_address =
        absl::GetFlag(FLAGS_health_host) + ":" + std::to_string(absl::GetFlag(FLAGS_health_port));
    hb.AddListeningPort(health_address, grpc::InsecureServerCredentials(), &health_port);
    health_server = hb.BuildAndStart();
    if (!health_server || health_port == 0) {
      spdlog::critical("cannot listen on {} (--health_port)", health_address);
      return 1;
    }
    health_server->GetHealthCheckService()->SetServingStatus(true);
    spdlog::info("health (plaintext, no tokens) on {}:{}", absl::GetFlag(FLAGS_health_host), health_port);
  }
  server->GetHealthCheckService()->SetServingStatus(true);
  spdlog::info("serving scenestreamer.v1.Simulator on {}:{} ({}, {}, {} compute threads)", absl::GetFlag(FLAGS_host),
               port,
               absl::GetFlag(FLAGS_tls_cert).empty()           ? "plaintext"
               : absl::GetFlag(FLAGS_tls_client_ca).empty()    ? "TLS"
                                                               : "mutual TLS",
               auth ? "bearer tokens" : "no authentication", mo.compute_threads);

  int sig = 0;
  sigwait(&signals, &sig);
  spdlog::info("signal {}: draining (health NOT_SERVING, no new sessions, finishing calls in flight)", sig);
  server->GetHealthCheckService()->SetServingStatus(false);
  if (health_server) health_server->GetHealthCheckService()->SetServingStatus(false);
  sessions.start_draining();
  // Calls in flight finish while the server still answers (new ones get UNAVAILABLE from the handlers).
  const auto drain_start = std::chrono::steady_clock::now();
  const auto grace_end = drain_start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                           std::chrono::duration<double>(absl::GetFlag(FLAGS_drain_grace_s)));
  const auto drain_deadline = drain_start + std::chrono::seconds(30);
  while ((service.in_flight() > 0 || std::chrono::steady_clock::now() < grace_end) &&
         std::chrono::steady_clock::now() < drain_deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(30));
  server->Wait();
  if (health_server) {
    health_server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(1));
    health_server->Wait();
  }
  const int saved = sessions.save_all();
  if (!mo.snapshot_dir.empty()) spdlog::info("saved {} sessions to {}", saved, mo.snapshot_dir);
  if (store) spdlog::info("saved {} sessions to the session store {}, their leases released", saved, store->where());
  spdlog::info("stopped");
  return 0;
}
