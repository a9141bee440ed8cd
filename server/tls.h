// TLS for the gRPC port (--tls_cert, --tls_key, optionally --tls_client_ca for mutual TLS). The PEM files are read
// and checked here with OpenSSL before gRPC sees them, so a wrong file is refused at startup with its name and what is
// wrong (gRPC itself would only fail the handshakes later).
#pragma once

#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "grpcpp/security/server_credentials.h"

namespace ss::server {

struct TlsFiles {
  std::string cert;       // PEM certificate chain, the server's first
  std::string key;        // PEM private key of the first certificate
  std::string client_ca;  // PEM CA bundle; set: clients must present a certificate it signed (mutual TLS)
};

// Insecure credentials when no file is given; else TLS ones. INVALID_ARGUMENT naming the flag and file when a file
// is missing, unreadable, not PEM, or the key does not belong to the certificate.
absl::StatusOr<std::shared_ptr<::grpc::ServerCredentials>> server_credentials(const TlsFiles& files);

}  // namespace ss::server
