/* Debian bookworm's civetweb (1.15) loads OpenSSL at run time, by the name "libssl.so", and looks up
 * SSL_get_peer_certificate, which OpenSSL 3 only has as a macro for SSL_get1_peer_certificate: the pointer stays
 * NULL and the first HTTPS request crashes on it. This library is that name, "libssl.so" (its SONAME), on top of the
 * real libssl.so.3 (its dependency, where every other lookup lands), with the old name added. The viewer loads it
 * before civetweb starts (gateway.cc), so civetweb's dlopen("libssl.so") finds it already loaded. It is the only
 * name civetweb looks up that OpenSSL 3 lacks (checked against the library's symbol table). */
typedef struct ssl_st SSL;
typedef struct x509_st X509;

X509* SSL_get1_peer_certificate(const SSL* s);

/* As in OpenSSL 1.1: the caller owns a reference (civetweb frees it). */
X509* SSL_get_peer_certificate(const SSL* s) { return SSL_get1_peer_certificate(s); }
