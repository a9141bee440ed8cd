#include "server/auth.h"

#include <openssl/sha.h>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "engine/io/file_io.h"

namespace ss::server {
namespace {

std::string sha256(const std::string& s) {
  unsigned char d[SHA256_DIGEST_LENGTH];
  SHA256(reinterpret_cast<const unsigned char*>(s.data()), s.size(), d);
  return std::string(reinterpret_cast<const char*>(d), sizeof d);
}

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
    const std::string digest = sha256(token);
    if (auto it = line_of.find(digest); it != line_of.end())
      return bad(absl::StrCat("the token of line ", it->second, " appears again (a token names one tenant)"));
    line_of[digest] = line_no;
    auth->tenants_[digest] = tenant;
  }
  if (auth->tenants_.empty())
    return absl::InvalidArgumentError(absl::StrCat("tokens file ", path, ": no tokens (", line_no,
                                                   " lines, all blank or comments)"));
  return auth;
}

absl::StatusOr<std::string> TokenAuth::tenant_of_header(const std::string& authorization) const {
  constexpr absl::string_view kBearer = "bearer ";
  if (authorization.size() < kBearer.size() ||
      !absl::EqualsIgnoreCase(absl::string_view(authorization).substr(0, kBearer.size()), kBearer))
    return absl::UnauthenticatedError("the authorization metadata is not `Bearer <token>`");
  const std::string token(absl::StripAsciiWhitespace(absl::string_view(authorization).substr(kBearer.size())));
  auto it = tenants_.find(sha256(token));
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
