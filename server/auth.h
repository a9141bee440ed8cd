// Bearer-token authentication (--tokens_file): every Simulator call carries `authorization: Bearer <token>`, and the
// token names the caller's tenant. The check runs first in every handler (one call, server/simulator_service.cc)
// rather than in a grpc::AuthMetadataProcessor: gRPC 1.51 aborts when a processor is set on insecure credentials, and
// tokens must work on plaintext backends behind a TLS-terminating router too; its server interceptors cannot fail a
// call. The gRPC health service and reflection are not checked (probes carry no token).
//
// Tokens file: one `TOKEN TENANT` pair a line, separated by spaces or tabs (any number: the file is the operator's,
// and its columns may be aligned); blank lines and lines starting with `#` are ignored. A file other users may read
// is warned about at startup. A token is 16-256 characters of the RFC 6750 token alphabet (letters, digits, `-._~+/=`); a tenant is
// 1-64 letters, digits, `-_.`. Several tokens may name one tenant; a token may appear once. Anything else refuses
// the file at startup, naming the file and line.
//
// The header: `Bearer`, in any case (RFC 7235 2.1: the scheme is case-insensitive), one or more spaces, the token and
// nothing else (RFC 6750 2.1: "Bearer" 1*SP b64token). A tab or trailing whitespace is refused.
#pragma once

#include <map>
#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "grpcpp/server_context.h"

namespace ss::server {

class TokenAuth {
 public:
  // Reads and checks a tokens file; INVALID_ARGUMENT "tokens file F line N: ..." for a malformed one.
  static absl::StatusOr<std::unique_ptr<TokenAuth>> load(const std::string& path);
  // Parses the text of a tokens file (`path` only names it in errors).
  static absl::StatusOr<std::unique_ptr<TokenAuth>> parse(const std::string& path, const std::string& text);

  // The caller's tenant, or UNAUTHENTICATED saying what is missing or wrong.
  absl::StatusOr<std::string> tenant(const ::grpc::ServerContextBase& ctx) const;
  absl::StatusOr<std::string> tenant_of_header(const std::string& authorization) const;
  size_t size() const { return tenants_.size(); }
  // The distinct tenants the file names (the per-tenant shares' default divides the caps by it).
  int tenants() const { return tenant_count_; }

 private:
  // SHA-256 of each token -> tenant: lookups compare digests, so the time a lookup takes says nothing about how much
  // of a guessed token was right.
  std::map<std::string, std::string> tenants_;
  int tenant_count_ = 0;
};

// SHA-256 of a secret (a token, a controller credential), 32 raw bytes: what the server keeps of it in memory and in
// snapshot files.
std::string secret_digest(const std::string& secret);

// The tenant of a call: TokenAuth's when `auth` is set, else "" (one shared tenant: every client sees every session).
absl::StatusOr<std::string> caller_tenant(const TokenAuth* auth, const ::grpc::ServerContextBase& ctx);

}  // namespace ss::server
