"""Starts the real scenestreamer-server binary on a free 127.0.0.1 port, as a subprocess, for integration tests."""
import atexit
import collections
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import unittest

import grpc

from scenestreamer.v1 import simulator_pb2 as pb
from scenestreamer.v1 import simulator_pb2_grpc as rpc

SERVER = os.environ["SS_SERVER"]
TOOL = os.environ["SS_TOOL"]
DATA = os.environ["SS_WOMD_DIR"]
_MODEL = None


def small_model():
    """A small random model (init-weights --config small): the tests check plumbing, not traffic quality."""
    global _MODEL
    if _MODEL is None:
        directory = tempfile.mkdtemp(prefix="ss-it-model-")
        atexit.register(shutil.rmtree, directory, True)
        path = os.path.join(directory, "small.safetensors")
        subprocess.run([TOOL, "init-weights", "--config", "small", "--out", path], check=True, capture_output=True)
        _MODEL = path
    return _MODEL


class _Details(collections.namedtuple("_Details", "method timeout metadata credentials wait_for_ready compression"),
               grpc.ClientCallDetails):
    pass


class _Metadata(grpc.UnaryUnaryClientInterceptor, grpc.UnaryStreamClientInterceptor):
    """Adds fixed metadata (a bearer token) to every call, also on plaintext channels."""

    def __init__(self, metadata):
        self.metadata = list(metadata)

    def _details(self, d):
        return _Details(d.method, d.timeout, list(d.metadata or []) + self.metadata, d.credentials,
                        d.wait_for_ready, d.compression)

    def intercept_unary_unary(self, continuation, details, request):
        return continuation(self._details(details), request)

    def intercept_unary_stream(self, continuation, details, request):
        return continuation(self._details(details), request)


def channel_to(target, tls_root=None, token=None, client_cert=None):
    """A channel to `target`: TLS when `tls_root` (PEM bytes) is given, with a client certificate (cert, key PEM
    bytes) for mutual TLS, and `authorization: Bearer <token>` on every call when `token` is given."""
    if tls_root is not None:
        creds = grpc.ssl_channel_credentials(root_certificates=tls_root,
                                             private_key=client_cert[1] if client_cert else None,
                                             certificate_chain=client_cert[0] if client_cert else None)
        channel = grpc.secure_channel(target, creds)
    else:
        channel = grpc.insecure_channel(target)
    if token is not None:
        channel = grpc.intercept_channel(channel, _Metadata([("authorization", f"Bearer {token}")]))
    return channel


class Server:
    def __init__(self, *flags, snapshot_dir=None, tls_root=None, token=None, client_cert=None):
        """`flags` go to the server; `tls_root`, `token` and `client_cert` are how self.stub connects."""
        self.flags = list(flags)
        self.snapshot_dir = snapshot_dir
        self.tls_root, self.token, self.client_cert = tls_root, token, client_cert
        fd, self.log_path = tempfile.mkstemp(prefix="ss-it-server-", suffix=".log")
        os.close(fd)
        # Removed when the test process exits; a server that fails to start has its log in the exception.
        atexit.register(lambda p=self.log_path: os.path.exists(p) and os.remove(p))
        self.proc = None

    def start(self):
        args = [SERVER, "--host=127.0.0.1", "--port=0", "--metrics_port=0", f"--model={small_model()}",
                f"--scenario_dir={DATA}", "--threads=2"] + self.flags
        if self.snapshot_dir:
            args.append(f"--snapshot_dir={self.snapshot_dir}")
        self.log = open(self.log_path, "w")
        self.proc = subprocess.Popen(args, stdout=self.log, stderr=subprocess.STDOUT)
        deadline = time.time() + 60
        while time.time() < deadline:
            text = self.output()
            m = re.search(r"serving scenestreamer.v1.Simulator on 127.0.0.1:(\d+)", text)
            if m:
                self.port = int(m.group(1))
                mm = re.search(r"metrics on http://127.0.0.1:(\d+)/metrics", text)
                self.metrics_port = int(mm.group(1)) if mm else None
                self.channel = channel_to(f"127.0.0.1:{self.port}", self.tls_root, self.token, self.client_cert)
                self.stub = rpc.SimulatorStub(self.channel)
                return self
            if self.proc.poll() is not None:
                raise RuntimeError(f"server exited {self.proc.returncode}:\n{text}")
            time.sleep(0.1)
        raise RuntimeError("server did not start in 60 s:\n" + self.output())

    @property
    def target(self):
        return f"127.0.0.1:{self.port}"

    def terminate(self, timeout=60):
        """SIGTERM, then wait: returns the exit code."""
        self.proc.send_signal(signal.SIGTERM)
        code = self.proc.wait(timeout=timeout)
        self.channel.close()
        self.log.close()
        return code

    def kill(self):
        """SIGKILL (a crash: nothing is saved), then wait."""
        self.proc.kill()
        self.proc.wait(timeout=30)
        self.channel.close()
        self.log.close()

    def stop(self):
        if self.proc and self.proc.poll() is None:
            self.terminate()

    def output(self):
        with open(self.log_path) as f:
            return f.read()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


def womd_records(path):
    """The Scenario protos of a TFRecord file (length, crc, data, crc)."""
    out = []
    with open(path, "rb") as f:
        data = f.read()
    pos = 0
    while pos < len(data):
        n = int.from_bytes(data[pos:pos + 8], "little")
        out.append(data[pos + 12:pos + 12 + n])
        pos += 12 + n + 4
    return out


def error_of(fn, *args, **kw):
    """The (code, details) of the gRPC error that fn(*args, **kw) raises; (None, None) when it succeeds."""
    try:
        fn(*args, **kw)
    except grpc.RpcError as e:
        return e.code(), e.details()
    return None, None


def eventually(fn, what, timeout=60):
    """fn()'s first true value, polled until `timeout` s pass (then an AssertionError naming `what`): for a state of
    the server process that a test cannot be told of, instead of sleeping a fixed time and hoping."""
    deadline = time.time() + timeout
    while True:
        value = fn()
        if value:
            return value
        if time.time() > deadline:
            raise AssertionError(f"not within {timeout} s: {what}")
        time.sleep(0.02)


def ego_pose(tick):
    """A simple deterministic controller: the controlled agent keeps its heading and speed for 0.5 s."""
    import math
    for a in tick.agents:
        if a.controlled:
            s = a.state
            speed = math.hypot(s.vx, s.vy)
            return pb.ControlledPose(agent_id=a.id, x=s.x + 0.5 * s.vx, y=s.y + 0.5 * s.vy, heading=s.heading,
                                     speed=speed)
    return None


class ServerTestCase(unittest.TestCase):
    """Tests that share one server process, started once for the class (self.server), with the class's
    `server_flags`."""
    server_flags = ()

    @classmethod
    def setUpClass(cls):
        cls.server = Server(*cls.server_flags).start()

    @classmethod
    def tearDownClass(cls):
        cls.server.stop()
