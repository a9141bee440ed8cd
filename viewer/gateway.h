// The viewer's gateway: HTTP and WebSocket for browsers (civetweb) in front of the server's gRPC API. The server's
// stepping threads never serve a browser; a watched session costs the server one WatchSession stream, whatever the
// browsers do (docs/viewer.md).
//
//   GET  /                   the page (viewer/web/dist)
//   GET  /api/sessions       ListSessions as the caller's tenant (the page's token, `Authorization: Bearer`)
//   GET  /api/map?session=S  the map of S's scenario, read from the gateway's --scenario_dir (GetSession names it)
//   POST /api/rollout        a scenario file (WOMD TFRecord or JSON; header X-File-Name) decoded for the page
//   WS   /ws/watch           first message {"session", "token"}; then a "session" message, the current tick and
//                            every tick from WatchSession; {"type": "error", "message"} on a refusal
#pragma once

#include <cstddef>
#include <map>
#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "engine/scenario/scenario.h"
#include "engine/sim/events.h"
#include "grpcpp/grpcpp.h"
#include "scenestreamer/v1/simulator.grpc.pb.h"

struct mg_context;

namespace viewer {

struct GatewayOptions {
  std::string host = "127.0.0.1";
  int port = 8090;                  // 0: any free port (Gateway::port says which)
  std::string web_dir;              // the page's files
  std::string tls_cert, tls_key;    // PEM: serve HTTPS and WSS
  int threads = 64;                 // civetweb's workers: each open WebSocket holds one
  size_t max_upload_bytes = 256u << 20;
};

// A scenario the gateway read from --scenario_dir: its map for the page and for the events.
struct KnownScenario {
  ss::Scenario scenario;
  ss::EventMap event_map;
  std::string map_json;  // {"features": [...]} text, made once
};

class Gateway {
 public:
  Gateway(std::shared_ptr<grpc::Channel> channel, std::string target,
          std::map<std::string, std::shared_ptr<const KnownScenario>> scenarios, GatewayOptions options);
  ~Gateway();

  // Starts listening; an error names the address or the TLS file.
  absl::Status start();
  void stop();
  int port() const { return port_; }
  bool tls() const { return !options_.tls_cert.empty(); }

  // For the handlers (civetweb calls C functions).
  scenestreamer::v1::Simulator::Stub& stub() { return *stub_; }
  const std::string& target() const { return target_; }
  const KnownScenario* scenario(const std::string& name) const;
  const GatewayOptions& options() const { return options_; }

 private:
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<scenestreamer::v1::Simulator::Stub> stub_;
  std::string target_;
  std::map<std::string, std::shared_ptr<const KnownScenario>> scenarios_;
  GatewayOptions options_;
  std::string pem_path_;  // certificate and key in one file, as civetweb reads them
  mg_context* ctx_ = nullptr;
  int port_ = 0;
};

// A well-formed bearer token (RFC 6750's characters, 1-512 of them) or the empty string (no token).
bool token_ok(const std::string& token);

}  // namespace viewer
