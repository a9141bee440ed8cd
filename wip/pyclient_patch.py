import sys
root = sys.argv[1]
def patch(path, pairs):
    p = f"{root}/{path}"
    s = open(p).read()
    for a, b in pairs:
        assert s.count(a) == 1, (path, a)
        s = s.replace(a, b)
    open(p, "w").write(s)

patch("python/scenestreamer/client.py", [
('''    intercept_unary_unary = _route
    intercept_unary_stream = _route


def connect(target, channel=None, route=False):
    """A SimulatorStub on `channel`, or on a new insecure channel to `target` ("host:port"). route: send x-session-id
    metadata on every call (behind deploy/router/)."""
    channel = channel or grpc.insecure_channel(target)
    stub_channel = grpc.intercept_channel(channel, _Route()) if route else channel
    return channel, rpc.SimulatorStub(stub_channel)
''', '''    intercept_unary_unary = _route
    intercept_unary_stream = _route


class _Token(grpc.UnaryUnaryClientInterceptor, grpc.UnaryStreamClientInterceptor):
    """Sends `authorization: Bearer <token>` on every call (servers run with --tokens_file). Metadata rather than
    gRPC call credentials, which refuse plaintext channels: a server behind a TLS-terminating router, or on
    loopback, checks tokens too."""

    def __init__(self, token):
        self.header = ("authorization", f"Bearer {token}")

    def _add(self, continuation, details, request):
        details = details._replace(metadata=tuple(details.metadata or ()) + (self.header,))
        return continuation(details, request)

    intercept_unary_unary = _add
    intercept_unary_stream = _add


def _pem(tls_root):
    """The PEM bytes of `tls_root`: bytes as they are, a str or path-like naming a file read."""
    if isinstance(tls_root, bytes):
        pem = tls_root
    else:
        try:
            with open(tls_root, "rb") as f:
                pem = f.read()
        except OSError as e:
            raise ValueError(f"tls_root {tls_root!r}: cannot read it: {e.strerror}") from None
    if b"-----BEGIN CERTIFICATE-----" not in pem:
        raise ValueError(f"tls_root: {'the bytes' if isinstance(tls_root, bytes) else repr(tls_root)} hold no PEM "
                         "certificate (-----BEGIN CERTIFICATE-----)")
    return pem


def connect(target, channel=None, route=False, token=None, tls_root=None):
    """A SimulatorStub on `channel`, or on a new channel to `target` ("host:port"). route: send x-session-id
    metadata on every call (behind deploy/router/). token: the bearer token for servers run with --tokens_file.
    tls_root: the PEM certificate (bytes, or a file's path) of the CA that signed the server's (or of the server
    itself, self-signed), for servers run with --tls_cert; True: TLS with the system's trusted roots. Without it the
    channel is plaintext. `channel`, when given, is used as it is (tls_root then does not apply)."""
    if token is not None and (not isinstance(token, str) or not token or any(c.isspace() for c in token)):
        raise ValueError("token: a non-empty string without spaces (a line of the server's --tokens_file)")
    if channel is None:
        if tls_root is None or tls_root is False:
            channel = grpc.insecure_channel(target)
        else:
            roots = None if tls_root is True else _pem(tls_root)
            channel = grpc.secure_channel(target, grpc.ssl_channel_credentials(root_certificates=roots))
    interceptors = ([_Token(token)] if token is not None else []) + ([_Route()] if route else [])
    stub_channel = grpc.intercept_channel(channel, *interceptors) if interceptors else channel
    return channel, rpc.SimulatorStub(stub_channel)
'''),
])
patch("python/scenestreamer/env.py", [
('''    route: send each session's id as x-session-id metadata on every call (behind a router of deploy/router/).''',
 '''    route: send each session's id as x-session-id metadata on every call (behind a router of deploy/router/);
    token, tls_root: a bearer token and the server's TLS root certificate (scenestreamer.client.connect).'''),
('''                 reward=None, channel=None, timeout=60.0, roads=None, route=False):''',
 '''                 reward=None, channel=None, timeout=60.0, roads=None, route=False, token=None, tls_root=None):'''),
('''        self.channel, self.stub = connect(target, channel, route)''',
 '''        self.channel, self.stub = connect(target, channel, route, token=token, tls_root=tls_root)'''),
])
patch("python/scenestreamer/parallel_env.py", [
('''                 mode="motion", observation=None, reward=None, channel=None, timeout=60.0, route=False):''',
 '''                 mode="motion", observation=None, reward=None, channel=None, timeout=60.0, route=False, token=None,
                 tls_root=None):'''),
('''        self.channel, self.stub = connect(target, channel, route)''',
 '''        self.channel, self.stub = connect(target, channel, route, token=token, tls_root=tls_root)'''),
])
patch("python/scenestreamer/vector_env.py", [
('''    def __init__(self, num_envs, target="127.0.0.1:50051", channel=None, route=False, **env_kwargs):''',
 '''    def __init__(self, num_envs, target="127.0.0.1:50051", channel=None, route=False, token=None, tls_root=None,
                 **env_kwargs):'''),
('''        self.channel, self.stub = connect(target, channel, route)''',
 '''        self.channel, self.stub = connect(target, channel, route, token=token, tls_root=tls_root)'''),
('''        self.envs = [SceneStreamerEnv(target, channel=self.channel, roads=roads, route=route, **env_kwargs)''',
 '''        self.envs = [SceneStreamerEnv(target, channel=self.channel, roads=roads, route=route, token=token,
                                      **env_kwargs)'''),
])
print("patched")
