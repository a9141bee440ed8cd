"""The TLS routers on loopback: deploy/router/nginx-tls.conf (Debian's nginx) and deploy/router/haproxy-tls.cfg
(Debian's haproxy) run as shipped, with only the replica addresses, the listen port and the certificate directory
substituted, in front of two real replicas serving TLS with bearer tokens. Certificates are made at test time."""
import os
import re
import shutil
import socket
import subprocess
import tempfile
import time
import unittest

import grpc

from pki import Pki
from scenestreamer.v1 import simulator_pb2 as pb
from scenestreamer.v1 import simulator_pb2_grpc as rpc
from server_process import Server, channel_to, error_of

SOURCE_DIR = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ROUTER_DIR = os.path.join(SOURCE_DIR, "deploy", "router")
TOKEN = "router-test-token-0123456789"
C = grpc.StatusCode


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def render(name, upstreams, listen_port, tls_dir):
    """deploy/router/NAME with the replica addresses, the listen port and /etc/scenestreamer/tls/ replaced; fails if
    the file's shape changed, so the test runs the configuration users get."""
    with open(os.path.join(ROUTER_DIR, name)) as f:
        text = f.read()
    shipped = len(re.findall(r"server scenestreamer-\d+[ .]", text))
    # The file lists three replicas; the test runs two and drops the third's line.
    text = "\n".join(line for line in text.splitlines() if "scenestreamer-2" not in line) + "\n"
    if name.startswith("nginx"):
        found = [int(i) for i in re.findall(r"server scenestreamer-(\d+)\.scenestreamer:50051\b", text)]
        text = re.sub(r"server scenestreamer-(\d+)\.scenestreamer:50051\b",
                      lambda m: f"server {upstreams[int(m.group(1))]}", text)
        text, n = re.subn(r"listen 8443 ssl http2;", f"listen 127.0.0.1:{listen_port} ssl http2;", text)
    else:
        found = [int(i) for i in re.findall(r"server scenestreamer-(\d+) scenestreamer-\d+\.scenestreamer:50051\b",
                                            text)]
        text = re.sub(r"(server scenestreamer-(\d+)) scenestreamer-\d+\.scenestreamer:50051\b",
                      lambda m: f"{m.group(1)} {upstreams[int(m.group(2))]}", text)
        text, n = re.subn(r"bind :8443 ", f"bind 127.0.0.1:{listen_port} ", text)
    if shipped != 3 or found != [0, 1] or n != 1:
        raise RuntimeError(f"{name}: expected replicas scenestreamer-0..2 and one TLS listener, found {shipped}, "
                           f"{found}, {n}")
    if "/etc/scenestreamer/tls/" not in text:
        raise RuntimeError(f"{name}: no /etc/scenestreamer/tls/ paths")
    return text.replace("/etc/scenestreamer/tls/", tls_dir.rstrip("/") + "/")


class RouterTlsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.pki = Pki()
        # The file names the router configurations use.
        for src, dst in (("server.pem", "tls.crt"), ("server.key", "tls.key"), ("ca.pem", "ca.crt"),
                         ("server.bundle.pem", "router.pem")):
            shutil.copy(cls.pki.path(src), cls.pki.path(dst))
        cls.dir = tempfile.mkdtemp(prefix="ss-it-router-tls-")
        tokens = os.path.join(cls.dir, "tokens.txt")
        with open(tokens, "w") as f:
            f.write(f"{TOKEN} team\n")
        cls.replicas = [Server(f"--tls_cert={cls.pki.path('server.pem')}", f"--tls_key={cls.pki.path('server.key')}",
                               f"--tokens_file={tokens}", tls_root=cls.pki.read("ca.pem"), token=TOKEN).start()
                        for _ in range(2)]

    @classmethod
    def tearDownClass(cls):
        for r in cls.replicas:
            r.stop()
        cls.pki.close()
        shutil.rmtree(cls.dir, ignore_errors=True)

    def start_router(self, name, command):
        port = free_port()
        prefix = tempfile.mkdtemp(prefix="router-", dir=self.dir) + "/"
        conf = os.path.join(prefix, name)
        with open(conf, "w") as f:
            f.write(render(name, [r.target for r in self.replicas], port, self.pki.dir))
        log = open(os.path.join(prefix, "router.log"), "w")
        proc = subprocess.Popen(command(prefix, conf), stdout=log, stderr=subprocess.STDOUT, cwd=prefix)

        def stop():
            proc.terminate()
            proc.wait(timeout=30)
            log.close()
        self.addCleanup(stop)
        target = f"127.0.0.1:{port}"
        channel = channel_to(target, tls_root=self.pki.read("ca.pem"), token=TOKEN)
        self.addCleanup(channel.close)
        stub = rpc.SimulatorStub(channel)
        deadline = time.time() + 30
        while True:  # up when a call through it is answered
            try:
                stub.ListScenarios(pb.ListScenariosRequest(), timeout=5)
                return target, stub
            except grpc.RpcError:
                if proc.poll() is not None or time.time() > deadline:
                    with open(os.path.join(prefix, "router.log")) as f:
                        raise RuntimeError(f"{name} did not start:\n{f.read()}")
                time.sleep(0.2)

    def check_routes_over_tls(self, target, stub):
        name = stub.ListScenarios(pb.ListScenariosRequest()).scenarios[0].name
        # Sessions proposed by the client and routed by x-session-id: each lives on one replica, and every call of it
        # reaches that one.
        for i in range(2):
            sid = f"tls-routed-{i}"
            md = (("x-session-id", sid),)
            stub.CreateSession(pb.CreateSessionRequest(scenario_name=name, session_id=sid), metadata=md)
            for k in range(2):
                r = stub.StepScene(pb.StepSceneRequest(session_id=sid), metadata=md, timeout=60)
                self.assertEqual(r.ticks[0].tick, k + 1)
            holders = [rep for rep in self.replicas
                       if sid in [s.session_id for s in rep.stub.ListSessions(pb.ListSessionsRequest()).sessions]]
            self.assertEqual(len(holders), 1, sid)
            stub.CloseSession(pb.CloseSessionRequest(session_id=sid), metadata=md)
        # The token passes through the router and the replica checks it.
        for token in (None, "wrong-token-0123456789"):
            channel = channel_to(target, tls_root=self.pki.read("ca.pem"), token=token)
            code, _ = error_of(rpc.SimulatorStub(channel).ListSessions, pb.ListSessionsRequest())
            self.assertEqual(code, C.UNAUTHENTICATED)
            channel.close()
        # Plaintext, or a client that does not trust the router's CA: no handshake.
        for channel in (grpc.insecure_channel(target), channel_to(target, tls_root=self.pki.read("other.pem"))):
            code, _ = error_of(rpc.SimulatorStub(channel).ListScenarios, pb.ListScenariosRequest(), timeout=10)
            self.assertEqual(code, C.UNAVAILABLE)
            channel.close()

    @unittest.skipUnless(shutil.which("nginx"), "nginx is not installed (deploy/install-deps.sh installs it)")
    def test_nginx_tls(self):
        target, stub = self.start_router("nginx-tls.conf", lambda prefix, conf: ["nginx", "-p", prefix, "-c", conf,
                                                                                "-e", "stderr"])
        self.check_routes_over_tls(target, stub)

    @unittest.skipUnless(shutil.which("haproxy"), "haproxy is not installed (deploy/install-deps.sh installs it)")
    def test_haproxy_tls(self):
        target, stub = self.start_router("haproxy-tls.cfg", lambda prefix, conf: ["haproxy", "-f", conf])
        self.check_routes_over_tls(target, stub)


if __name__ == "__main__":
    unittest.main(verbosity=2)
