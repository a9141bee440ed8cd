"""A session-affine cluster on loopback for integration tests: N real scenestreamer-server replicas on fixed
127.0.0.1 ports, each with its own snapshot directory, behind Debian's nginx running deploy/router/nginx.conf itself
(the upstream addresses and the listen port substituted, nothing else)."""
import os
import re
import signal
import shutil
import socket
import subprocess
import tempfile
import time
import urllib.request

import grpc

from scenestreamer.v1 import simulator_pb2 as pb
from scenestreamer.v1 import simulator_pb2_grpc as rpc
from server_process import Server

SOURCE_DIR = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
NGINX_CONF = os.path.join(SOURCE_DIR, "deploy", "router", "nginx.conf")
HAPROXY_CFG = os.path.join(SOURCE_DIR, "deploy", "router", "haproxy.cfg")
UPSTREAM = re.compile(r"server scenestreamer-(\d+)\.scenestreamer:50051\b")
LISTEN = re.compile(r"listen 8080 http2;")
ROUTE = "x-session-id"


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def render_nginx(upstreams, listen_port):
    """deploy/router/nginx.conf with its upstream servers and listen port replaced; fails if the file's shape changed,
    so the test always runs the configuration users get."""
    with open(NGINX_CONF) as f:
        text = f.read()
    found = [int(i) for i in UPSTREAM.findall(text)]
    if found != list(range(len(upstreams))):
        raise RuntimeError(f"{NGINX_CONF}: expected upstreams scenestreamer-0..{len(upstreams) - 1}, found {found}")
    text = UPSTREAM.sub(lambda m: f"server {upstreams[int(m.group(1))]}", text)
    text, n = LISTEN.subn(f"listen 127.0.0.1:{listen_port} http2;", text)
    if n != 1:
        raise RuntimeError(f"{NGINX_CONF}: expected one 'listen 8080 http2;', found {n}")
    return text


def render_haproxy(upstreams, listen_port):
    """deploy/router/haproxy.cfg with its server addresses and bind port replaced (and nothing else)."""
    with open(HAPROXY_CFG) as f:
        text = f.read()
    found = [int(i) for i in re.findall(r"server scenestreamer-(\d+) scenestreamer-\d+\.scenestreamer:50051\b", text)]
    if found != list(range(len(upstreams))):
        raise RuntimeError(f"{HAPROXY_CFG}: expected servers scenestreamer-0..{len(upstreams) - 1}, found {found}")
    text = re.sub(r"(server scenestreamer-(\d+)) scenestreamer-\d+\.scenestreamer:50051\b",
                  lambda m: f"{m.group(1)} {upstreams[int(m.group(2))]}", text)
    text, n = re.subn(r"bind :8080 ", f"bind 127.0.0.1:{listen_port} ", text)
    if n != 1:
        raise RuntimeError(f"{HAPROXY_CFG}: expected one 'bind :8080', found {n}")
    return text


def metrics(port):
    """The replica's Prometheus text as {'name{labels}': value}."""
    text = urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=10).read().decode()
    out = {}
    for line in text.splitlines():
        if line and not line.startswith("#"):
            key, value = line.rsplit(" ", 1)
            out[key] = float(value)
    return out


def rss_mb(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return 0.0


def routed(session_id):
    return ((ROUTE, session_id),)


def start_nginx(owner, prefix, conf):
    """nginx on `conf` under `prefix` for a cluster `owner` (its nginx, nginx_log, channel and stub), once a call
    through it is answered."""
    owner.nginx_log = open(os.path.join(prefix, "nginx.log"), "w")
    owner.nginx = subprocess.Popen(["nginx", "-p", prefix, "-c", conf, "-e", "stderr"], stdout=owner.nginx_log,
                                   stderr=subprocess.STDOUT)
    owner.channel = grpc.insecure_channel(owner.target)
    owner.stub = rpc.SimulatorStub(owner.channel)
    deadline = time.time() + 30
    while True:  # the router is up when a call through it is answered
        try:
            owner.stub.ListScenarios(pb.ListScenariosRequest(), timeout=5)
            return
        except grpc.RpcError:
            if owner.nginx.poll() is not None or time.time() > deadline:
                raise RuntimeError("nginx did not start:\n" + owner.router_output())
            time.sleep(0.2)


class Cluster:
    def __init__(self, replicas=3, flags=()):
        self.dir = tempfile.mkdtemp(prefix="ss-it-cluster-")
        self.ports = [free_port() for _ in range(replicas)]
        self.router_port = free_port()
        self.servers = []
        for i, port in enumerate(self.ports):
            snapshots = os.path.join(self.dir, f"snapshots-{i}")
            os.mkdir(snapshots)
            self.servers.append(Server(f"--port={port}", *flags, snapshot_dir=snapshots))
        self.nginx = None

    def start(self):
        for s in self.servers:
            s.start()
        prefix = os.path.join(self.dir, "router") + "/"
        os.mkdir(prefix)
        conf = os.path.join(prefix, "nginx.conf")
        with open(conf, "w") as f:
            f.write(render_nginx([f"127.0.0.1:{p}" for p in self.ports], self.router_port))
        start_nginx(self, prefix, conf)
        return self

    @property
    def target(self):
        return f"127.0.0.1:{self.router_port}"

    def router_output(self):
        with open(os.path.join(self.dir, "router", "nginx.log")) as f:
            return f.read()

    def start_haproxy(self):
        """HAProxy with deploy/router/haproxy.cfg in front of the same replicas; returns (process, target)."""
        port = free_port()
        cfg = os.path.join(self.dir, "haproxy.cfg")
        with open(cfg, "w") as f:
            f.write(render_haproxy([f"127.0.0.1:{p}" for p in self.ports], port))
        log = open(os.path.join(self.dir, "haproxy.log"), "w")
        proc = subprocess.Popen(["haproxy", "-db", "-f", cfg], stdout=log, stderr=subprocess.STDOUT)
        log.close()
        return proc, f"127.0.0.1:{port}"

    def holder(self, session_id):
        """Indexes of the replicas that hold the session (asked directly, not through the router)."""
        return [i for i, s in enumerate(self.servers) if s.proc.poll() is None and session_id in
                [x.session_id for x in s.stub.ListSessions(pb.ListSessionsRequest(), timeout=10).sessions]]

    def metrics(self, i):
        return metrics(self.servers[i].metrics_port)

    def stop(self):
        if self.nginx and self.nginx.poll() is None:
            self.nginx.terminate()
            self.nginx.wait(30)
            self.nginx_log.close()
        for s in self.servers:
            if s.proc and s.proc.poll() is None:
                s.terminate()
        shutil.rmtree(self.dir, ignore_errors=True)

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


SERVER_LINE = re.compile(r"^(\s*)server scenestreamer-\d+\.scenestreamer:50051( [^;]*)?;\n", re.M)


def render_nginx_replicas(upstreams, listen_port):
    """deploy/router/nginx.conf for any number of replicas: its upstream server lines replaced by one line per address
    in `upstreams` (each with the file's own parameters), and its listen port."""
    with open(NGINX_CONF) as f:
        text = f.read()
    lines = list(SERVER_LINE.finditer(text))
    if not lines:
        raise RuntimeError(f"{NGINX_CONF}: no 'server scenestreamer-N.scenestreamer:50051' lines")
    indent, params = lines[0].group(1), lines[0].group(2) or ""
    block = "".join(f"{indent}server {u}{params};\n" for u in upstreams)
    text = text[:lines[0].start()] + block + text[lines[-1].end():]
    text, n = LISTEN.subn(f"listen 127.0.0.1:{listen_port} http2;", text)
    if n != 1:
        raise RuntimeError(f"{NGINX_CONF}: expected one 'listen 8080 http2;', found {n}")
    return text


class StoreCluster:
    """Replicas sharing one real redis-server (tests/integration/redis_process.py) as their session store, named
    r0, r1, ..., behind nginx with deploy/router/nginx.conf; replicas come and go, and the router's list is rewritten
    and reloaded (`nginx -s reload`) as an operator would."""

    def __init__(self, replicas=3, flags=()):
        from redis_process import Redis
        self.dir = tempfile.mkdtemp(prefix="ss-it-store-cluster-")
        self.redis = Redis()
        self.flags = list(flags)
        self.servers = {}
        self.count = 0
        self.initial = replicas
        self.router_port = free_port()
        self.prefix = os.path.join(self.dir, "router") + "/"
        self.nginx = None

    def new_replica(self):
        name = f"r{self.count}"
        self.count += 1
        self.servers[name] = Server(f"--session_store={self.redis.url}", f"--replica_id={name}", *self.flags).start()
        return name

    def write_router(self, names):
        with open(os.path.join(self.prefix, "nginx.conf"), "w") as f:
            f.write(render_nginx_replicas([self.servers[n].target for n in names], self.router_port))
        self.routed = list(names)

    def reload_router(self, names):
        """The router's list becomes `names`, and nginx reloads it (new workers; the old ones finish their calls)."""
        self.write_router(names)
        conf = os.path.join(self.prefix, "nginx.conf")
        subprocess.run(["nginx", "-p", self.prefix, "-c", conf, "-e", "stderr", "-s", "reload"], check=True,
                       capture_output=True, timeout=30)

    def start(self):
        self.redis.start()
        for _ in range(self.initial):
            self.new_replica()
        os.mkdir(self.prefix)
        self.write_router(sorted(self.servers))
        conf = os.path.join(self.prefix, "nginx.conf")
        start_nginx(self, self.prefix, conf)
        return self

    @property
    def target(self):
        return f"127.0.0.1:{self.router_port}"

    def router_output(self):
        with open(os.path.join(self.prefix, "nginx.log")) as f:
            return f.read()

    def holders(self):
        """{session id: [replica names holding it]} over the live replicas, asked directly. The replicas are asked one
        after another while the load goes on, so a session moving between two of them can be missed by one sweep
        (or seen twice): the sweep is repeated until two in a row agree (at most 20)."""
        def sweep():
            out = {}
            for name, s in self.servers.items():
                if s.proc.poll() is None:
                    for x in s.stub.ListSessions(pb.ListSessionsRequest(), timeout=30).sessions:
                        out.setdefault(x.session_id, []).append(name)
            return out
        last = sweep()
        for _ in range(20):
            now = sweep()
            if now == last:
                return now
            last = now
        return last

    def stop(self):
        if self.nginx and self.nginx.poll() is None:
            self.nginx.terminate()
            self.nginx.wait(30)
            self.nginx_log.close()
        for s in self.servers.values():
            if s.proc and s.proc.poll() is None:
                s.terminate()
        self.redis.stop()
        shutil.rmtree(self.dir, ignore_errors=True)

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


HAPROXY_SERVER_LINE = re.compile(r"^(\s*)server scenestreamer-\d+ scenestreamer-\d+\.scenestreamer:50051([^\n]*)\n",
                                 re.M)


def render_haproxy_replicas(upstreams, listen_port):
    """deploy/router/haproxy.cfg for any number of replicas: its server lines replaced by one per address (named
    scenestreamer-0, -1, ... as in the file), and its bind port."""
    with open(HAPROXY_CFG) as f:
        text = f.read()
    lines = list(HAPROXY_SERVER_LINE.finditer(text))
    if not lines:
        raise RuntimeError(f"{HAPROXY_CFG}: no 'server scenestreamer-N scenestreamer-N.scenestreamer:50051' lines")
    indent, params = lines[0].group(1), lines[0].group(2)
    block = "".join(f"{indent}server scenestreamer-{i} {u}{params}\n" for i, u in enumerate(upstreams))
    text = text[:lines[0].start()] + block + text[lines[-1].end():]
    text, n = re.subn(r"bind :8080 ", f"bind 127.0.0.1:{listen_port} ", text)
    if n != 1:
        raise RuntimeError(f"{HAPROXY_CFG}: expected one 'bind :8080', found {n}")
    return text


class HAProxyRouter:
    """HAProxy in master-worker mode with deploy/router/haproxy.cfg in front of `cluster`'s replicas; reload() rewrites
    its list and sends the master SIGUSR2 (a new worker takes new connections, the old one finishes its calls)."""

    def __init__(self, cluster, names):
        self.cluster = cluster
        self.port = free_port()
        self.cfg = os.path.join(cluster.dir, "haproxy.cfg")
        self.write(names)
        self.log = open(os.path.join(cluster.dir, "haproxy.log"), "w")
        self.proc = subprocess.Popen(["haproxy", "-W", "-db", "-f", self.cfg], stdout=self.log,
                                     stderr=subprocess.STDOUT)
        self.channel = grpc.insecure_channel(self.target)
        self.stub = rpc.SimulatorStub(self.channel)
        deadline = time.time() + 30
        while True:
            try:
                self.stub.ListScenarios(pb.ListScenariosRequest(), timeout=5)
                break
            except grpc.RpcError:
                if self.proc.poll() is not None or time.time() > deadline:
                    raise RuntimeError("haproxy did not start:\n" + self.output())
                time.sleep(0.2)

    @property
    def target(self):
        return f"127.0.0.1:{self.port}"

    def write(self, names):
        with open(self.cfg, "w") as f:
            f.write(render_haproxy_replicas([self.cluster.servers[n].target for n in names], self.port))

    def reload(self, names):
        self.write(names)
        self.proc.send_signal(signal.SIGUSR2)

    def output(self):
        with open(os.path.join(self.cluster.dir, "haproxy.log")) as f:
            return f.read()

    def stop(self):
        self.channel.close()
        if self.proc.poll() is None:
            self.proc.terminate()
            self.proc.wait(30)
        self.log.close()
