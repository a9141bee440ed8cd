// scenestreamer-health [--target HOST:PORT] [--service NAME] [--timeout_s S]
// The project's gRPC health probe (grpc.health.v1.Health/Check): exit 0 when the server answers SERVING, 1 when it
// answers anything else or cannot be reached (the reason on stderr), 2 on bad flags. The image's HEALTHCHECK and the
// tests use it; Kubernetes probes the same service with its built-in gRPC probe.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "client_common.h"
#include "grpc/health/v1/health.grpc.pb.h"

namespace health = grpc::health::v1;

int main(int argc, char** argv) {
  client::Flags flags;
  if (!client::parse_flags(argc, argv, {"target", "service", "timeout_s"}, {}, &flags)) {
    std::fprintf(stderr, "usage: scenestreamer-health [--target HOST:PORT] [--service NAME] [--timeout_s S]\n");
    return 2;
  }
  const std::string target = client::flag_string(flags, "target", client::kDefaultTarget);
  const double timeout_s = std::atof(client::flag_string(flags, "timeout_s", "3").c_str());
  if (!(timeout_s > 0)) return std::fprintf(stderr, "--timeout_s must be a positive number of seconds\n"), 2;
  auto stub = health::Health::NewStub(grpc::CreateChannel(target, grpc::InsecureChannelCredentials()));
  health::HealthCheckRequest req;
  req.set_service(client::flag_string(flags, "service", ""));
  health::HealthCheckResponse resp;
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() +
                   std::chrono::duration_cast<std::chrono::system_clock::duration>(
                       std::chrono::duration<double>(timeout_s)));
  const grpc::Status st = stub->Check(&ctx, req, &resp);
  if (!st.ok()) {
    std::fprintf(stderr, "health check of %s failed: code %d: %s\n", target.c_str(),
                 static_cast<int>(st.error_code()), st.error_message().c_str());
    return 1;
  }
  const std::string status = health::HealthCheckResponse::ServingStatus_Name(resp.status());
  std::printf("%s: %s\n", target.c_str(), status.c_str());
  return resp.status() == health::HealthCheckResponse::SERVING ? 0 : 1;
}
