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


def connect(target, channel=None, route=False):
    """A SimulatorStub on `channel`, or on a new insecure channel to `target` ("host:port"). route: send x-session-id
    metadata on every call (behind deploy/router/)."""
    channel = channel or grpc.insecure_channel(target)
    stub_channel = grpc.intercept_channel(channel, _Route()) if route else channel
    return channel, rpc.SimulatorStub(stub_channel)


def scenario_names(stub, timeout=60.0):
    """The server's bundled scenarios, in its order."""
    return [s.name for s in stub.ListScenarios(pb.ListScenariosRequest(), timeout=timeout).scenarios]


def speed_of(state):
    """Signed speed along the heading."""
    return state.vx * math.cos(state.heading) + state.vy * math.sin(state.heading)


def advance(agent, action, dt=STEP_SECONDS):
    """The agent's pose after `dt` under action (acceleration m/s^2, yaw rate rad/s), by the engine's kinematic rule
    (DESIGN.md 4): v' = max(0, v + a dt), psi' = psi + w dt, and the position advances by the mean of the old and new
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
