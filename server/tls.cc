#include "server/tls.h"

#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/pem.h>
#include <openssl/x509.h>

#include "absl/strings/str_cat.h"
#include "engine/io/file_io.h"

namespace ss::server {
namespace {

std::string openssl_error() {
  const unsigned long e = ERR_get_error();
  ERR_clear_error();
  if (e == 0) return "no PEM block of that kind";
  char buf[256];
  ERR_error_string_n(e, buf, sizeof buf);
  return buf;
}

absl::StatusOr<std::string> read_pem(const char* flag, const std::string& path) {
  auto text = file_read_all(path);
  if (!text.ok()) return absl::InvalidArgumentError(absl::StrCat(flag, " ", path, ": ", text.status().message()));
  if (text->find("-----BEGIN ") == std::string::npos)
    return absl::InvalidArgumentError(absl::StrCat(flag, " ", path, ": not a PEM file (no -----BEGIN line)"));
  return *text;
}

using BioPtr = std::unique_ptr<BIO, decltype(&BIO_free)>;
using X509Ptr = std::unique_ptr<X509, decltype(&X509_free)>;
using KeyPtr = std::unique_ptr<EVP_PKEY, decltype(&EVP_PKEY_free)>;

BioPtr bio_of(const std::string& s) { return BioPtr(BIO_new_mem_buf(s.data(), static_cast<int>(s.size())), BIO_free); }

}  // namespace

absl::StatusOr<std::shared_ptr<::grpc::ServerCredentials>> server_credentials(const TlsFiles& f) {
  if (f.cert.empty() && f.key.empty()) {
    if (!f.client_ca.empty())
      return absl::InvalidArgumentError("--tls_client_ca needs --tls_cert and --tls_key (mutual TLS is TLS)");
    return ::grpc::InsecureServerCredentials();
  }
  if (f.cert.empty() || f.key.empty())
    return absl::InvalidArgumentError("--tls_cert and --tls_key go together: give both or neither");
  auto cert = read_pem("--tls_cert", f.cert);
  if (!cert.ok()) return cert.status();
  auto key = read_pem("--tls_key", f.key);
  if (!key.ok()) return key.status();
  ERR_clear_error();
  auto cb = bio_of(*cert);
  X509Ptr x509(PEM_read_bio_X509(cb.get(), nullptr, nullptr, nullptr), X509_free);
  if (!x509)
    return absl::InvalidArgumentError(absl::StrCat("--tls_cert ", f.cert, ": no certificate: ", openssl_error()));
  auto kb = bio_of(*key);
  KeyPtr pkey(PEM_read_bio_PrivateKey(kb.get(), nullptr, nullptr, nullptr), EVP_PKEY_free);
  if (!pkey)
    return absl::InvalidArgumentError(absl::StrCat("--tls_key ", f.key, ": no private key (or it is encrypted): ",
                                                   openssl_error()));
  if (X509_check_private_key(x509.get(), pkey.get()) != 1) {
    ERR_clear_error();
    return absl::InvalidArgumentError(
        absl::StrCat("--tls_key ", f.key, " is not the private key of the certificate in --tls_cert ", f.cert));
  }
  ::grpc::SslServerCredentialsOptions o(GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE);
  o.pem_key_cert_pairs.push_back({*key, *cert});
  if (!f.client_ca.empty()) {
    auto ca = read_pem("--tls_client_ca", f.client_ca);
    if (!ca.ok()) return ca.status();
    auto ab = bio_of(*ca);
    X509Ptr first(PEM_read_bio_X509(ab.get(), nullptr, nullptr, nullptr), X509_free);
    if (!first)
      return absl::InvalidArgumentError(
          absl::StrCat("--tls_client_ca ", f.client_ca, ": no certificate: ", openssl_error()));
    o.pem_root_certs = *ca;
    o.client_certificate_request = GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY;
  }
  return ::grpc::SslServerCredentials(o);
}

}  // namespace ss::server
