"""SceneStreamerParallelEnv: several egos in one session, with PettingZoo's ParallelEnv API (agents are named
"agent_<id>"; observations, rewards, terminations, truncations and infos are dicts keyed by agent name). Background
traffic and the other egos are part of each ego's observation. One StepScene per tick carries every ego's pose; an ego
whose episode ended is held in place (the session still has it as a controlled agent, and its tick waits for every
controller's pose).

It subclasses pettingzoo.ParallelEnv where PettingZoo is installed, else a stand-in with the same attributes
(scenestreamer.spaces), so PettingZoo's parallel_api_test and parallel_seed_test accept it. The same seed gives equal
observations, rewards and infos; the server's session id (new each episode) is env.session_id, not in the infos."""
import math

import numpy as np

from scenestreamer.client import advance, connect, hold, scenario_names
from scenestreamer.env import MODES, action_space, check_action
from scenestreamer.observation import ObservationConfig, find_agent, observation_space, observe
from scenestreamer.reward import RewardConfig, events_of, reward_and_termination
from scenestreamer.road import RoadMap
from scenestreamer.spaces import ParallelEnv
from scenestreamer.v1 import simulator_pb2 as pb


class SceneStreamerParallelEnv(ParallelEnv):
    """scenario: a bundled scenario name (default: the server's first); agent_ids: the track ids to control (default:
    the SDC and the num_agents - 1 vehicles nearest it at the scenario's current frame, found by a short probe
    session at construction); normalize_actions: every agent's action space is Box(-1, 1, (2,)), mapped onto the
    physical range as in SceneStreamerEnv."""

    metadata = {"name": "scenestreamer_parallel_v0", "render_modes": []}

    def __init__(self, target="127.0.0.1:50051", scenario=None, agent_ids=None, num_agents=2, max_steps=80,
                 mode="motion", observation=None, reward=None, channel=None, timeout=60.0, route=False, token=None,
                 tls_root=None, normalize_actions=False):
        if mode not in MODES:
            raise ValueError(f"mode {mode!r}: expected one of {sorted(MODES)}")
        self._own_channel = channel is None
        self.channel, self.stub = connect(target, channel, route, token=token, tls_root=tls_root)
        self.timeout = timeout
        self.scenario = scenario or scenario_names(self.stub, timeout, with_sdc=True)[0]
        self.mode = mode
        self.max_steps = int(max_steps)
        self.observation_config = observation or ObservationConfig()
        self.reward_config = reward or RewardConfig()
        self._road = None
        if agent_ids is None:
            agent_ids = self._pick_agents(num_agents)
        self.agent_ids = [int(i) for i in agent_ids]
        self.possible_agents = [f"agent_{i}" for i in self.agent_ids]
        self._ids = dict(zip(self.possible_agents, self.agent_ids))
        self.agents = []
        self.normalize_actions = bool(normalize_actions)
        # One space object for all agents: observation_space(agent) is the same object at every call, as PettingZoo
        # requires (its action-space seeding relies on it).
        self._observation_space = observation_space(self.observation_config)
        self._action_space = action_space(self.normalize_actions)
        self.observation_spaces = {a: self._observation_space for a in self.possible_agents}
        self.action_spaces = {a: self._action_space for a in self.possible_agents}
        self.session_id = None
        self.tick = None
        self.steps = 0
        self._np_random = np.random.default_rng()

    def _pick_agents(self, n):
        r = self.stub.CreateSession(pb.CreateSessionRequest(scenario_name=self.scenario, include_map=True),
                                    timeout=self.timeout)
        self.stub.CloseSession(pb.CloseSessionRequest(session_id=r.session_id), timeout=self.timeout)
        self._road = RoadMap(r.map)
        sdc = [a for a in r.initial.agents if a.controlled]
        if not sdc:
            raise RuntimeError(f"scenario {self.scenario!r} has no SDC: pass agent_ids")
        s = sdc[0].state
        vehicles = sorted((a for a in r.initial.agents if not a.controlled and a.type == pb.AGENT_TYPE_VEHICLE),
                          key=lambda a: math.hypot(a.state.x - s.x, a.state.y - s.y))
        if len(vehicles) < n - 1:
            raise RuntimeError(f"scenario {self.scenario!r} has {len(vehicles) + 1} vehicles, {n} asked")
        return [sdc[0].id] + [a.id for a in vehicles[:n - 1]]

    def observation_space(self, agent):
        return self._observation_space

    def action_space(self, agent):
        return self._action_space

    def _observe(self, name):
        return observe(self.tick, self._ids[name], self._road, self.observation_config)

    def reset(self, seed=None, options=None):
        if seed is not None:
            self._np_random = np.random.default_rng(seed)
        self._close_session()
        r = self.stub.CreateSession(pb.CreateSessionRequest(
            scenario_name=self.scenario, seed=int(self._np_random.integers(2**63)), mode=MODES[self.mode],
            controlled_agent_ids=self.agent_ids, include_map=self._road is None), timeout=self.timeout)
        if r.map:
            self._road = RoadMap(r.map)
        self.session_id, self.tick, self.steps = r.session_id, r.initial, 0
        missing = [i for i in self.agent_ids if find_agent(self.tick, i) is None]
        if missing:
            self._close_session()
            raise RuntimeError(f"agents {missing} are not in scenario {self.scenario!r} at its current frame")
        self.agents = list(self.possible_agents)
        return ({a: self._observe(a) for a in self.agents},
                {a: {"agent_id": self._ids[a]} for a in self.agents})

    def step(self, actions):
        if self.session_id is None:
            raise RuntimeError("step() before reset() (or after close())")
        unknown = set(actions) - set(self.agents)
        if unknown:
            raise ValueError(f"actions for agents that are not live: {sorted(unknown)} (live: {self.agents})")
        missing = set(self.agents) - set(actions)
        if missing:
            raise ValueError(f"no action for live agents {sorted(missing)}")
        poses = []
        for name in self.possible_agents:
            agent = find_agent(self.tick, self._ids[name])
            if name in actions:
                poses.append(advance(agent, check_action(actions[name], f"actions[{name!r}]", self.normalize_actions)))
            else:
                poses.append(hold(agent))
        r = self.stub.StepScene(pb.StepSceneRequest(session_id=self.session_id, poses=poses), timeout=self.timeout)
        self.tick = r.ticks[-1]
        self.steps += 1
        obs, rewards, terminations, truncations, infos = {}, {}, {}, {}, {}
        for name in self.agents:
            events = events_of(self.tick, self._ids[name])
            if events is None:
                raise RuntimeError(f"session {self.session_id}: tick {self.tick.tick} has no events for {name}")
            rewards[name], terminations[name], infos[name] = reward_and_termination(events, self.reward_config)
            truncations[name] = self.steps >= self.max_steps
            obs[name] = self._observe(name)
        self.agents = [a for a in self.agents if not (terminations[a] or truncations[a])]
        return obs, rewards, terminations, truncations, infos

    def _close_session(self):
        if self.session_id is not None:
            session_id, self.session_id = self.session_id, None
            self.stub.CloseSession(pb.CloseSessionRequest(session_id=session_id), timeout=self.timeout)

    def close(self):
        self._close_session()
        if self._own_channel:
            self.channel.close()
