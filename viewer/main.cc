// scenestreamer-viewer: the live viewer's gateway (viewer/gateway.h, docs/viewer.md). Talks gRPC to one server (or
// router) and serves the page, its API and WebSocket to browsers, on 127.0.0.1 unless --host says otherwise.
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/strings/str_cat.h"
#include "engine/scenario/read.h"
#include "spdlog/spdlog.h"
#include "common/command_line.h"
#include "viewer/convert.h"
#include "viewer/gateway.h"

ABSL_FLAG(std::string, host, "127.0.0.1", "address the viewer listens on (0.0.0.0: every interface, on purpose)");
ABSL_FLAG(int, port, 8090, "HTTP port of the viewer; 0: any free port (the log line names it)");
ABSL_FLAG(std::string, target, "127.0.0.1:50051", "the server's (or router's) gRPC address");
ABSL_FLAG(std::string, tls_root, "",
          "PEM CA bundle: talk TLS to the server and check its certificate against it (the server's --tls_cert)");
ABSL_FLAG(std::string, tls_server_name, "", "the name the server's certificate must carry; empty: --target's host");
ABSL_FLAG(std::string, tls_client_cert, "", "PEM client certificate for a server with --tls_client_ca (mutual TLS)");
ABSL_FLAG(std::string, tls_client_key, "", "PEM key of --tls_client_cert");
ABSL_FLAG(std::string, tls_cert, "", "PEM certificate chain: serve the page over HTTPS and WSS (with --tls_key)");
ABSL_FLAG(std::string, tls_key, "", "PEM private key of --tls_cert");
ABSL_FLAG(std::string, scenario_dir, "",
          "the server's scenarios (its --scenario_dir), for the maps and the rollouts' logged futures; empty: the "
          "bundled sample scenarios");
ABSL_FLAG(std::string, web_dir, "", "the page's files; empty: the bundled viewer/web/dist");
ABSL_FLAG(int, threads, 64, "HTTP worker threads; each open WebSocket (a watching browser) holds one");
ABSL_FLAG(int, max_upload_mb, 256, "the largest rollout file the viewer decodes, MB");

namespace {

constexpr const char* kUsage =
    "usage: scenestreamer-viewer [--port P] [--target HOST:PORT] [--scenario_dir D] [--tls_root CA.pem] ...\n"
    "  The live viewer: open http://127.0.0.1:P/ in a browser. Lists the server's sessions (the page's token picks\n"
    "  the tenant), watches one as it ticks, and opens rollout files (docs/viewer.md).";

int fail(const std::string& msg) {
  spdlog::error("scenestreamer-viewer: {}", msg);
  return 1;
}

absl::StatusOr<std::string> read_file(const std::string& flag, const std::string& path) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(absl::StrCat("--", flag, " ", path, ": cannot read it"));
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

}  // namespace

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--") == 0) break;
    if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-help") == 0) {
      std::fputs(ss::cli::file_flags_help(kUsage, __FILE__).c_str(), stdout);
      return 0;
    }
  }
  const std::vector<char*> rest = absl::ParseCommandLine(argc, argv);
  if (rest.size() > 1) return fail(absl::StrCat("unexpected argument '", rest[1], "' (see --help)"));

  const int port = absl::GetFlag(FLAGS_port);
  if (port < 0 || port > 65535) return fail(absl::StrCat("--port ", port, " is not in 0..65535"));
  if (absl::GetFlag(FLAGS_threads) < 2 || absl::GetFlag(FLAGS_threads) > 1024)
    return fail("--threads must be in 2..1024");
  if (absl::GetFlag(FLAGS_max_upload_mb) < 1 || absl::GetFlag(FLAGS_max_upload_mb) > 4096)
    return fail("--max_upload_mb must be in 1..4096");

  std::string scenario_dir = absl::GetFlag(FLAGS_scenario_dir), web_dir = absl::GetFlag(FLAGS_web_dir);
  if (scenario_dir.empty() || web_dir.empty()) {
    const absl::StatusOr<std::string> bundled = ss::cli::bundled_dir();
    if (!bundled.ok())
      return fail(absl::StrCat("no --scenario_dir or --web_dir given, and ", bundled.status().message()));
    if (scenario_dir.empty()) scenario_dir = (std::filesystem::path(*bundled) / "data").string();
    if (web_dir.empty()) web_dir = (std::filesystem::path(*bundled) / "viewer" / "web" / "dist").string();
  }

  // The scenarios, by id (the name CreateSession and ListSessions use).
  std::map<std::string, std::shared_ptr<const viewer::KnownScenario>> scenarios;
  size_t num_scenarios = 0;
  const absl::StatusOr<std::vector<std::string>> files = ss::list_scenario_files(scenario_dir, false);
  if (!files.ok()) return fail(absl::StrCat("--scenario_dir: ", files.status().message()));
  for (const std::string& file : *files) {
    const absl::StatusOr<int> n = ss::for_each_scenario(file, [&](ss::Scenario&& s) {
      auto known = std::make_shared<viewer::KnownScenario>();
      known->event_map = ss::event_map_from_scenario(s);
      known->map_json = nlohmann::json{{"scenario", s.id}, {"features", viewer::map_json(s.map_features)}}.dump();
      known->scenario = std::move(s);
      scenarios[known->scenario.id] = std::move(known);
      ++num_scenarios;
      return absl::OkStatus();
    });
    if (!n.ok()) return fail(absl::StrCat("--scenario_dir: ", n.status().message()));
  }

  // The channel to the server, as the Python client makes it: TLS with a CA bundle, or plaintext.
  const std::string target = absl::GetFlag(FLAGS_target);
  std::shared_ptr<grpc::ChannelCredentials> creds = grpc::InsecureChannelCredentials();
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(64 << 20);
  if (!absl::GetFlag(FLAGS_tls_root).empty()) {
    grpc::SslCredentialsOptions ssl;
    absl::StatusOr<std::string> root = read_file("tls_root", absl::GetFlag(FLAGS_tls_root));
    if (!root.ok()) return fail(std::string(root.status().message()));
    ssl.pem_root_certs = *root;
    const std::string cert = absl::GetFlag(FLAGS_tls_client_cert), key = absl::GetFlag(FLAGS_tls_client_key);
    if (cert.empty() != key.empty()) return fail("--tls_client_cert and --tls_client_key go together");
    if (!cert.empty()) {
      absl::StatusOr<std::string> c = read_file("tls_client_cert", cert), k = read_file("tls_client_key", key);
      if (!c.ok()) return fail(std::string(c.status().message()));
      if (!k.ok()) return fail(std::string(k.status().message()));
      ssl.pem_cert_chain = *c;
      ssl.pem_private_key = *k;
    }
    creds = grpc::SslCredentials(ssl);
    if (!absl::GetFlag(FLAGS_tls_server_name).empty())
      args.SetSslTargetNameOverride(absl::GetFlag(FLAGS_tls_server_name));
  } else if (!absl::GetFlag(FLAGS_tls_client_cert).empty() || !absl::GetFlag(FLAGS_tls_server_name).empty()) {
    return fail("--tls_client_cert and --tls_server_name need --tls_root (TLS to the server)");
  }
  auto channel = grpc::CreateCustomChannel(target, creds, args);

  viewer::GatewayOptions options;
  options.host = absl::GetFlag(FLAGS_host);
  options.port = port;
  options.web_dir = web_dir;
  options.tls_cert = absl::GetFlag(FLAGS_tls_cert);
  options.tls_key = absl::GetFlag(FLAGS_tls_key);
  options.threads = absl::GetFlag(FLAGS_threads);
  options.max_upload_bytes = static_cast<size_t>(absl::GetFlag(FLAGS_max_upload_mb)) << 20;
  viewer::Gateway gateway(channel, target, std::move(scenarios), options);
  if (absl::Status st = gateway.start(); !st.ok()) return fail(std::string(st.message()));

  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  spdlog::info("serving the viewer on {}://{}:{}/ for the server {} ({}), {} scenarios from {}",
               gateway.tls() ? "https" : "http", options.host, gateway.port(), target,
               absl::GetFlag(FLAGS_tls_root).empty() ? "plaintext" : "TLS", num_scenarios, scenario_dir);
  while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  spdlog::info("viewer: stopping");
  gateway.stop();
  return 0;
}
