"""A gym-style environment over the SceneStreamer server: the ego vehicle is yours, the background traffic (lights,
other agents, newcomers) comes from the server's session, which reacts to the ego every step.

    env = SceneStreamerEnv("127.0.0.1:50051")
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step((0.5, 0.0))   # (acceleration m/s^2, yaw rate rad/s)

Plain Python (no gym or numpy needed): observations are dicts of floats. Stubs come from the build
(build/client_examples/python on PYTHONPATH).
"""
import math

import grpc

from scenestreamer.v1 import simulator_pb2 as pb
from scenestreamer.v1 import simulator_pb2_grpc as rpc

STEP_SECONDS = 0.5  # the server's 2 Hz tick


class SceneStreamerEnv:
    def __init__(self, target="127.0.0.1:50051", scenario=None, max_steps=40, nearest=16, mode=pb.MODE_MOTION,
                 channel=None, timeout=60.0):
        self.channel = channel or grpc.insecure_channel(target)
        self.stub = rpc.SimulatorStub(self.channel)
        self.scenario = scenario
        self.max_steps = max_steps
        self.nearest = nearest
        self.mode = mode
        self.timeout = timeout
        self.session_id = None
        self.tick = None
        self.steps = 0

    # The ego's pose follows a kinematic model of the action; the server tokenizes the resulting motion.
    def _ego(self):
        for a in self.tick.agents:
            if a.controlled:
                return a
        raise RuntimeError(f"session {self.session_id} has no controlled agent")

    def _observe(self):
        ego = self._ego()
        s = ego.state
        c, n = math.cos(-s.heading), math.sin(-s.heading)
        others = []
        for a in self.tick.agents:
            if a.controlled:
                continue
            dx, dy = a.state.x - s.x, a.state.y - s.y
            others.append((math.hypot(dx, dy), [dx * c - dy * n, dx * n + dy * c, a.state.heading - s.heading,
                                                a.state.vx, a.state.vy, float(a.type)]))
        others.sort(key=lambda t: t[0])
        return {
            "ego": [s.x, s.y, s.heading, math.hypot(s.vx, s.vy)],
            "agents": [o for _, o in others[: self.nearest]],  # ego frame: dx, dy, dheading, vx, vy, type
            "lights": [[l.stop_point.x - s.x, l.stop_point.y - s.y, float(l.state)] for l in self.tick.lights],
        }

    def reset(self, seed=None, options=None):
        if self.session_id:
            self.close()
        if self.scenario is None:
            self.scenario = self.stub.ListScenarios(pb.ListScenariosRequest(), timeout=self.timeout).scenarios[0].name
        r = self.stub.CreateSession(pb.CreateSessionRequest(scenario_name=self.scenario, seed=seed or 0,
                                                            mode=self.mode), timeout=self.timeout)
        self.session_id, self.tick, self.steps = r.session_id, r.initial, 0
        return self._observe(), {"session_id": self.session_id, "sim_time": self.tick.sim_time}

    def step(self, action):
        accel, yaw_rate = action
        s = self._ego().state
        speed = max(0.0, math.hypot(s.vx, s.vy) + accel * STEP_SECONDS)
        heading = s.heading + yaw_rate * STEP_SECONDS
        pose = pb.ControlledPose(agent_id=self._ego().id, x=s.x + speed * math.cos(heading) * STEP_SECONDS,
                                 y=s.y + speed * math.sin(heading) * STEP_SECONDS,
                                 heading=math.atan2(math.sin(heading), math.cos(heading)), speed=speed)
        r = self.stub.StepScene(pb.StepSceneRequest(session_id=self.session_id, poses=[pose]), timeout=self.timeout)
        self.tick = r.ticks[-1]
        self.steps += 1
        obs = self._observe()
        # Reward: progress, minus a crash (another agent's centre within 2 m of the ego's).
        gap = min((math.hypot(a[0], a[1]) for a in obs["agents"]), default=math.inf)
        crashed = gap < 2.0
        reward = speed * STEP_SECONDS - (10.0 if crashed else 0.0)
        return obs, reward, crashed, self.steps >= self.max_steps, {"sim_time": self.tick.sim_time,
                                                                    "agents": len(self.tick.agents)}

    def close(self):
        if self.session_id:
            try:
                self.stub.CloseSession(pb.CloseSessionRequest(session_id=self.session_id), timeout=self.timeout)
            except grpc.RpcError:
                pass
            self.session_id = None


def cruise(obs, target_speed=8.0):
    """A simple controller: approach a target speed, brake for a close agent ahead, keep the heading."""
    speed = obs["ego"][3]
    ahead = [a for a in obs["agents"] if 0 < a[0] < 15 and abs(a[1]) < 2.5]
    accel = -3.0 if ahead else max(-2.0, min(1.5, 0.5 * (target_speed - speed)))
    return accel, 0.0
