"""Certificates made at test time with the openssl CLI (Debian's openssl), for the TLS tests."""
import os
import shutil
import subprocess
import tempfile


class Pki:
    """A CA (ca.pem), a server certificate it signed for 127.0.0.1, localhost and `scenestreamer` (the name the TLS
    routers check on replicas), a client certificate it signed, and an unrelated self-signed pair (other.pem), made
    with the openssl CLI in a temporary directory. server.bundle.pem: the server's certificate and key in one file
    (as HAProxy wants)."""

    def __init__(self):
        self.dir = tempfile.mkdtemp(prefix="ss-it-pki-")

        def ssl(*args):
            subprocess.run(["openssl", *args], check=True, capture_output=True, cwd=self.dir)

        ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
        ssl("req", "-x509", *ec, "-keyout", "ca.key", "-out", "ca.pem", "-days", "2", "-subj", "/CN=ss-test-ca")
        for name, ext in (("server", "subjectAltName=IP:127.0.0.1,DNS:localhost,DNS:scenestreamer"),
                          ("client", "extendedKeyUsage=clientAuth")):
            ssl("req", *ec, "-keyout", f"{name}.key", "-out", f"{name}.csr", "-subj", f"/CN=ss-test-{name}")
            with open(os.path.join(self.dir, f"{name}.ext"), "w") as f:
                f.write(ext + "\n")
            ssl("x509", "-req", "-in", f"{name}.csr", "-CA", "ca.pem", "-CAkey", "ca.key", "-CAcreateserial",
                "-out", f"{name}.pem", "-days", "2", "-extfile", f"{name}.ext")
        with open(self.path("server.bundle.pem"), "wb") as f:
            f.write(self.read("server.pem") + self.read("server.key"))
        # A self-signed pair no one trusts.
        ssl("req", "-x509", *ec, "-keyout", "other.key", "-out", "other.pem", "-days", "2", "-subj", "/CN=other",
            "-addext", "subjectAltName=IP:127.0.0.1")

    def path(self, name):
        return os.path.join(self.dir, name)

    def read(self, name):
        with open(self.path(name), "rb") as f:
            return f.read()

    def close(self):
        shutil.rmtree(self.dir, ignore_errors=True)
