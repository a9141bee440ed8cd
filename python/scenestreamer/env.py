"""SceneStreamerEnv: one ego vehicle in a SceneStreamer session, with the Gymnasium Env API. The server's model drives
the lights and every other agent and reacts to the ego each 0.5 s step; the server's engine reports the events the
reward is built from (overlaps, off road, red lights, progress along the lane)."""

import grpc
import numpy as np

from scenestreamer.client import advance, connect, scenario_names
from scenestreamer.observation import ObservationConfig, find_agent, observation_space, observe
from scenestreamer.reward import RewardConfig, events_of, reward_and_termination
from scenestreamer.road import RoadMap
from scenestreamer.spaces import Box, Env
from scenestreamer.v1 import simulator_pb2 as pb

# (acceleration m/s^2, yaw rate rad/s): hard braking to brisk acceleration, up to ~57 degrees a second.
ACTION_LOW = np.array([-8.0, -1.0], np.float32)
ACTION_HIGH = np.array([4.0, 1.0], np.float32)
MODES = {"motion": pb.MODE_MOTION, "full": pb.MODE_FULL, "densify": pb.MODE_DENSIFY, "log": pb.MODE_LOG,
         "idm": pb.MODE_IDM}


def check_action(action, where="action", normalized=False):
    """The action as a float32 (2,) array of physical units (acceleration m/s^2, yaw rate rad/s) clipped to
    ACTION_LOW..ACTION_HIGH; ValueError for a wrong shape or a non-finite value (the server would refuse the pose
    anyway, with less context). normalized: the action is in [-1, 1] (clipped to it), mapped linearly onto
    ACTION_LOW..ACTION_HIGH (-1: ACTION_LOW, 1: ACTION_HIGH, 0: their midpoint, -2 m/s^2 and 0 rad/s)."""
    a = np.asarray(action, dtype=np.float64)
    if a.shape != (2,):
        raise ValueError(f"{where}: expected shape (2,) (acceleration, yaw rate), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{where}: {a.tolist()} is not finite")
    if normalized:
        a = ACTION_LOW + (np.clip(a, -1.0, 1.0) + 1.0) * 0.5 * (ACTION_HIGH - ACTION_LOW)
    return np.clip(a, ACTION_LOW, ACTION_HIGH).astype(np.float32)


def action_space(normalized):
    """The action space: Box(ACTION_LOW, ACTION_HIGH), or Box(-1, 1) of the same shape when normalized."""
    if normalized:
        return Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
    return Box(ACTION_LOW, ACTION_HIGH, dtype=np.float32)


class SceneStreamerEnv(Env):
    """reset(seed, options) -> (obs, info); step(action) -> (obs, reward, terminated, truncated, info).

    target: the server ("host:port"); scenarios: bundled scenario names to draw from (default: all the server lists
    that have an SDC, the ego);
    max_steps: episode length in 0.5 s steps (truncation); mode: "motion", "full" or "densify"; observation /
    reward: ObservationConfig / RewardConfig; channel: a grpc channel to share (the env then does not close it);
    route: send each session's id as x-session-id metadata on every call (behind a router of deploy/router/);
    token, tls_root: a bearer token and the server's TLS root certificate (scenestreamer.client.connect);
    normalize_actions: the action space is Box(-1, 1, (2,)), mapped linearly onto the physical range
    ACTION_LOW..ACTION_HIGH (check_action), as libraries that expect normalised actions want.
    options of reset: {"scenario": name} picks the scenario instead of drawing one.
    The same seed gives the same scenario, the same session seed, and so the same episode for the same actions:
    equal observations, rewards and infos. The server's session id differs each episode, so it is not in the infos:
    it is env.session_id."""

    metadata = {"render_modes": []}

    def __init__(self, target="127.0.0.1:50051", scenarios=None, max_steps=80, mode="motion", observation=None,
                 reward=None, channel=None, timeout=60.0, roads=None, route=False, token=None, tls_root=None,
                 normalize_actions=False):
        if mode not in MODES:
            raise ValueError(f"mode {mode!r}: expected one of {sorted(MODES)}")
        self._own_channel = channel is None
        self.channel, self.stub = connect(target, channel, route, token=token, tls_root=tls_root)
        self.scenarios = list(scenarios) if scenarios else None
        self.max_steps = int(max_steps)
        self.mode = mode
        self.timeout = timeout
        self.observation_config = observation or ObservationConfig()
        self.reward_config = reward or RewardConfig()
        self.observation_space = observation_space(self.observation_config)
        self.normalize_actions = bool(normalize_actions)
        self.action_space = action_space(self.normalize_actions)
        self._roads = {} if roads is None else roads  # scenario name -> RoadMap: the map is fetched once per scenario
        self.session_id = None
        self.scenario = None
        self.tick = None
        self.ego_id = None
        self.steps = 0
        self._obs = None

    # The request/response halves below let the vector env send many envs' calls at once.
    def _create_request(self, options):
        if self.scenarios is None:
            self.scenarios = scenario_names(self.stub, self.timeout, with_sdc=True)
            if not self.scenarios:
                raise RuntimeError("the server lists no bundled scenario with an SDC: pass scenarios= or start it "
                                   "with some")
        name = (options or {}).get("scenario")
        if name is None:
            name = self.scenarios[int(self.np_random.integers(len(self.scenarios)))]
        seed = int(self.np_random.integers(2**63))
        return name, pb.CreateSessionRequest(scenario_name=name, seed=seed, mode=MODES[self.mode],
                                             include_map=name not in self._roads)

    def _started(self, name, response):
        if response.map:
            self._roads[name] = RoadMap(response.map)
        self.session_id, self.scenario, self.tick, self.steps = response.session_id, name, response.initial, 0
        controlled = [a.id for a in self.tick.agents if a.controlled]
        if not controlled:
            self.close_session()
            raise RuntimeError(f"scenario {name!r} gave the session no controlled agent (no SDC): pick another")
        self.ego_id = controlled[0]
        self._obs = observe(self.tick, self.ego_id, self._roads[name], self.observation_config)
        return self._obs, {"scenario": name, "ego_id": self.ego_id, "sim_time": self.tick.sim_time}

    def _step_request(self, action, where="action"):
        if self.session_id is None:
            raise RuntimeError("step() before reset() (or after close())")
        a = check_action(action, where, self.normalize_actions)
        ego = find_agent(self.tick, self.ego_id)
        return pb.StepSceneRequest(session_id=self.session_id, poses=[advance(ego, a)])

    def _stepped(self, response):
        self.tick = response.ticks[-1]
        self.steps += 1
        info = {"tick": self.tick.tick, "sim_time": self.tick.sim_time,
                "agents": len(self.tick.agents)}
        if find_agent(self.tick, self.ego_id) is None:  # not expected: controlled agents are never retired
            info["ego_left"] = True
            return self._obs, 0.0, True, False, info
        self._obs = observe(self.tick, self.ego_id, self._roads[self.scenario], self.observation_config)
        events = events_of(self.tick, self.ego_id)
        if events is None:
            raise RuntimeError(f"session {self.session_id}: tick {self.tick.tick} carries no events for agent "
                               f"{self.ego_id} (a client-sent scenario's session after a server restart has none)")
        reward, terminated, event_info = reward_and_termination(events, self.reward_config)
        info.update(event_info)
        return self._obs, reward, terminated, self.steps >= self.max_steps, info

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.close_session()
        name, request = self._create_request(options)
        return self._started(name, self.stub.CreateSession(request, timeout=self.timeout))

    def step(self, action):
        return self._stepped(self.stub.StepScene(self._step_request(action), timeout=self.timeout))

    def close_session(self):
        """Closes the server session (reset() does this for the previous episode)."""
        if self.session_id is None:
            return
        session_id, self.session_id = self.session_id, None
        try:
            self.stub.CloseSession(pb.CloseSessionRequest(session_id=session_id), timeout=self.timeout)
        except grpc.RpcError as e:
            if e.code() != grpc.StatusCode.NOT_FOUND:  # already gone (idle timeout) is fine; anything else is not
                raise

    def close(self):
        self.close_session()
        if self._own_channel:
            self.channel.close()
