#include "server/auth.h"

#include <openssl/sha.h>
#include <sys/stat.h>

#include <set>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "engine/io/file_io.h"
#include "spdlog/spdlog.h"

namespace ss::server {

std::string secret_digest(const std::string& s) {
  unsigned char d[SHA256_DIGEST_LENGTH];
  SHA256(reinterpret_cast<const unsigned char*>(s.data()), s.size(), d);
  return std::string(reinterpret_cast<const char*>(d), sizeof d);
}

namespace {

bool token_char(char c) {
  return absl::ascii_isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.' || c == '_' || c == '~' ||
         c == '+' || c == '/' || c == '=';
}
bool tenant_char(char c) {
  return absl::ascii_isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.' || c == '_';
}

}  // namespace

absl::StatusOr<std::unique_ptr<TokenAuth>> TokenAuth::load(const std::string& path) {
  auto text = file_read_all(path);
  if (!text.ok())
    return absl::InvalidArgumentError(absl::StrCat("tokens file ", path, ": ", text.status().message()));
  struct stat sb;
  if (::stat(path.c_str(), &sb) == 0 && (sb.st_mode & 077) != 0)
    spdlog::warn("tokens file {} is readable by other users (mode {:o}): chmod 600 it (or mount its Secret with "
                 "defaultMode 0400)",
                 path, sb.st_mode & 0777);
  return parse(path, *text);
}

absl::StatusOr<std::unique_ptr<TokenAuth>> TokenAuth::parse(const std::string& path, const std::string& text) {
  auto auth = std::unique_ptr<TokenAuth>(new TokenAuth());
  std::map<std::string, int> line_of;  // digest -> line, for duplicates
  int line_no = 0;
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    ++line_no;
    auto bad = [&](const std::string& what) {
      return absl::InvalidArgumentError(absl::StrCat("tokens file ", path, " line ", line_no, ": ", what));
    };
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const absl::string_view trimmed = absl::StripAsciiWhitespace(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    std::vector<absl::string_view> fields = absl::StrSplit(trimmed, absl::ByAnyChar(" \t"), absl::SkipEmpty());
    if (fields.size() != 2)
      return bad(absl::StrCat("expected `TOKEN TENANT` (2 fields separated by spaces), found ", fields.size(),
                              " fields"));
    const std::string token(fields[0]), tenant(fields[1]);
    if (token.size() < 16 || token.size() > 256)
      return bad(absl::StrCat("the token is ", token.size(), " characters; tokens are 16-256 characters"));
    for (char c : token)
      if (!token_char(c))
        return bad("the token has a character outside letters, digits and -._~+/= (RFC 6750)");
    if (tenant.size() > 64) return bad(absl::StrCat("the tenant is ", tenant.size(), " characters; at most 64"));
    for (char c : tenant)
      if (!tenant_char(c))
        return bad(absl::StrCat("tenant '", tenant, "' has a character outside letters, digits and -_."));
    const std::string digest = secret_digest(token);
    if (auto it = line_of.find(digest); it != line_of.end())
      return bad(absl::StrCat("the token of line ", it->second, " appears again (a token names one tenant)"));
    line_of[digest] = line_no;
    auth->tenants_[digest] = tenant;
  }
  std::set<std::string> tenants;
  for (const auto& [digest, tenant] : auth->tenants_) tenants.insert(tenant);
  auth->tenant_count_ = static_cast<int>(tenants.size());
  if (auth->tenants_.empty())
    return absl::InvalidArgumentError(absl::StrCat("tokens file ", path, ": no tokens (", line_no,
                                                   " lines, all blank or comments)"));
  return auth;
}

absl::StatusOr<std::string> TokenAuth::tenant_of_header(const std::string& authorization) const {
  // RFC 6750 2.1: credentials = "Bearer" 1*SP b64token, the scheme case-insensitive (RFC 7235 2.1).
  constexpr absl::string_view kBearer = "bearer ";
  const absl::string_view h(authorization);
  if (h.size() < kBearer.size() || !absl::EqualsIgnoreCase(h.substr(0, kBearer.size()), kBearer))
    return absl::UnauthenticatedError("the authorization metadata is not `Bearer <token>`");
  const size_t start = h.find_first_not_of(' ', kBearer.size());
  const std::string token(start == absl::string_view::npos ? absl::string_view() : h.substr(start));
  for (char c : token)
    if (!token_char(c))
      return absl::UnauthenticatedError(
          "the authorization metadata is not `Bearer <token>` (spaces, then the token and nothing else)");
  auto it = tenants_.find(secret_digest(token));
  if (it == tenants_.end()) return absl::UnauthenticatedError("the bearer token is not one of this server's tokens");
  return it->second;
}

absl::StatusOr<std::string> TokenAuth::tenant(const ::grpc::ServerContextBase& ctx) const {
  const auto& md = ctx.client_metadata();
  auto it = md.find("authorization");
  if (it == md.end())
    return absl::UnauthenticatedError(
        "this server requires a bearer token: send the metadata `authorization: Bearer <token>`");
  if (md.count("authorization") > 1) return absl::UnauthenticatedError("more than one authorization metadata");
  return tenant_of_header(std::string(it->second.data(), it->second.size()));
}

absl::StatusOr<std::string> caller_tenant(const TokenAuth* auth, const ::grpc::ServerContextBase& ctx) {
  if (auth == nullptr) return std::string();
  return auth->tenant(ctx);
}

}  // namespace ss::server
