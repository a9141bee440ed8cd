"""The gRPC side shared by the environments: stubs, the ego's kinematics (action -> pose), scenario listing."""
import math
import uuid

import grpc

from scenestreamer.v1 import simulator_pb2 as pb
from scenestreamer.v1 import simulator_pb2_grpc as rpc

STEP_SECONDS = 0.5  # the model's 2 Hz step: one env step is one server tick at tick_hz 2
SESSION_ID_HEADER = "x-session-id"  # what the session-affine routers hash (deploy/router/)


class _Route(grpc.UnaryUnaryClientInterceptor, grpc.UnaryStreamClientInterceptor):
    """Sends each call's session id as x-session-id metadata, CreateSession included (it proposes a fresh id when the
    request has none), so a session-affine router sends every call of a session to the replica that holds it. A fork
    routes by its source's id, where the fork is made."""

    def _route(self, continuation, details, request):
        sid = getattr(request, "session_id", "")
        if isinstance(request, pb.CreateSessionRequest) and not sid:
            proposed = pb.CreateSessionRequest()
            proposed.CopyFrom(request)
            proposed.session_id = sid = uuid.uuid4().hex
            request = proposed
        if sid:
            details = details._replace(metadata=tuple(details.metadata or ()) + ((SESSION_ID_HEADER, sid),))
        return continuation(details, request)

    intercept_unary_unary = _route
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


def scenario_names(stub, timeout=60.0, with_sdc=False):
    """The server's bundled scenarios, in its order; with_sdc: only those with an SDC (the ego of an env: a scenario
    without one, as some WOMD JSON files are, cannot be driven)."""
    listed = stub.ListScenarios(pb.ListScenariosRequest(), timeout=timeout).scenarios
    return [s.name for s in listed if s.has_sdc or not with_sdc]


def speed_of(state):
    """Signed speed along the heading."""
    return state.vx * math.cos(state.heading) + state.vy * math.sin(state.heading)


def advance(agent, action, dt=STEP_SECONDS):
    """The agent's pose after `dt` under action (acceleration m/s^2, yaw rate rad/s), by the engine's kinematic rule
    (docs/design.md, section 5): v' = max(0, v + a dt), psi' = psi + w dt, and the position advances by the mean of the old and new
    speeds along the mean of the old and new headings. The server tokenizes the resulting motion."""
    accel, yaw_rate = float(action[0]), float(action[1])
    s = agent.state
    v0 = speed_of(s)
    v1 = max(0.0, v0 + accel * dt)
    h1 = math.atan2(math.sin(s.heading + yaw_rate * dt), math.cos(s.heading + yaw_rate * dt))
    hm = math.atan2(math.sin(s.heading) + math.sin(h1), math.cos(s.heading) + math.cos(h1))
    d = 0.5 * (v0 + v1) * dt
    return pb.ControlledPose(agent_id=agent.id, x=s.x + d * math.cos(hm), y=s.y + d * math.sin(hm), heading=h1,
                             speed=v1)


def hold(agent):
    """A pose that stops the agent where it is (for agents whose episode ended in a shared session)."""
    s = agent.state
    return pb.ControlledPose(agent_id=agent.id, x=s.x, y=s.y, heading=s.heading, speed=0.0)
