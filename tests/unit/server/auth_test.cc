// The tokens file (server/auth.h) and the TLS flags' checks (server/tls.h): what is accepted, and that every malformed
// input is refused naming the file and line (or the flag and file).
#include "server/auth.h"

#include <gtest/gtest.h>

#include "server/tls.h"

namespace ss::server {
namespace {

const std::string kTok1 = "0123456789abcdef0123";
const std::string kTok2 = "tok-ABC.def_ghi~+/=xyz";

TEST(TokenAuth, AValidFileMapsTokensToTenants) {
  auto a = TokenAuth::parse("t.txt", "# comment\n\n" + kTok1 + " alice\r\n  " + kTok2 + "\tbob  \n");
  ASSERT_TRUE(a.ok()) << a.status();
  EXPECT_EQ((*a)->size(), 2u);
  EXPECT_EQ(*(*a)->tenant_of_header("Bearer " + kTok1), "alice");
  EXPECT_EQ(*(*a)->tenant_of_header("bearer " + kTok2), "bob");  // the scheme is case-insensitive (RFC 7235)
}

TEST(TokenAuth, WrongOrMissingCredentialsAreUnauthenticated) {
  auto a = TokenAuth::parse("t.txt", kTok1 + " alice\n");
  ASSERT_TRUE(a.ok());
  for (const std::string& h : std::vector<std::string>{"", "Basic " + kTok1, kTok1, "Bearer " + kTok1 + "x", "Bearer "})
    EXPECT_EQ((*a)->tenant_of_header(h).status().code(), absl::StatusCode::kUnauthenticated) << h;
}

// The header's grammar is RFC 6750's `"Bearer" 1*SP b64token` with the scheme case-insensitive (RFC 7235): one or
// more spaces, then exactly the token. Once a tab, or whitespace after the token, was taken too.
TEST(TokenAuth, TheHeaderIsBearerSpacesAndTheTokenExactly) {
  auto a = TokenAuth::parse("t.txt", kTok1 + " alice\n");
  ASSERT_TRUE(a.ok());
  for (const std::string& h : {"Bearer " + kTok1, "bearer " + kTok1, "BEARER " + kTok1, "Bearer   " + kTok1})
    EXPECT_EQ(*(*a)->tenant_of_header(h), "alice") << h;
  for (const std::string& h : {"Bearer\t" + kTok1, "Bearer \t" + kTok1, "Bearer " + kTok1 + " ",
                               "Bearer " + kTok1 + "\t", " Bearer " + kTok1, "Bearer" + kTok1})
    EXPECT_EQ((*a)->tenant_of_header(h).status().code(), absl::StatusCode::kUnauthenticated) << h;
}

TEST(TokenAuth, AMalformedFileIsRefusedNamingFileAndLine) {
  struct Case {
    std::string text;
    std::string says;
  };
  const std::vector<Case> cases = {
      {"# only a comment\n", "tokens file f.txt: no tokens"},
      {"", "tokens file f.txt: no tokens"},
      {kTok1 + "\n", "f.txt line 1: expected `TOKEN TENANT`"},
      {"\n" + kTok1 + " alice extra\n",
       "f.txt line 2: expected `TOKEN TENANT` (2 fields separated by spaces), found 3"},
      {"short alice\n", "f.txt line 1: the token is 5 characters"},
      {kTok1 + "\xc3\xa9 alice\n", "line 1: the token has a character outside"},
      {kTok1 + " al/ice\n", "line 1: tenant 'al/ice' has a character outside"},
      {kTok1 + " " + std::string(65, 't') + "\n", "line 1: the tenant is 65 characters"},
      {kTok1 + " alice\n" + kTok2 + " bob\n" + kTok1 + " carol\n", "f.txt line 3: the token of line 1 appears again"},
  };
  for (const Case& c : cases) {
    auto a = TokenAuth::parse("f.txt", c.text);
    ASSERT_FALSE(a.ok()) << c.text;
    EXPECT_EQ(a.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_NE(a.status().message().find(c.says), std::string::npos) << a.status() << "\nwanted: " << c.says;
  }
  auto missing = TokenAuth::load("/nonexistent/tokens.txt");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.status().message().find("tokens file /nonexistent/tokens.txt"), std::string::npos)
      << missing.status();
}

TEST(Tls, FlagsAreCheckedBeforeGrpcSeesThem) {
  auto files = [](std::string cert, std::string key, std::string ca) {
    TlsFiles f;
    f.cert = cert;
    f.key = key;
    f.client_ca = ca;
    return f;
  };
  EXPECT_TRUE(server_credentials({}).ok());  // no flags: plaintext
  auto half = server_credentials(files("/x/cert.pem", "", ""));
  EXPECT_NE(half.status().message().find("go together"), std::string::npos) << half.status();
  auto ca_only = server_credentials(files("", "", "/x/ca.pem"));
  EXPECT_NE(ca_only.status().message().find("--tls_client_ca needs --tls_cert"), std::string::npos);
  auto missing = server_credentials(files("/nonexistent/c.pem", "/nonexistent/k.pem", ""));
  EXPECT_NE(missing.status().message().find("--tls_cert /nonexistent/c.pem"), std::string::npos) << missing.status();
}

}  // namespace
}  // namespace ss::server
