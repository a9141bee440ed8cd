"""SceneStreamerVectorEnv: N SceneStreamerEnv sessions stepped together, with Gymnasium's vector API shapes (batched
observation dicts, rewards, terminations and truncations of shape (N,), infos as dicts of arrays with "_key" masks).

One round trip per tick: step() sends the N StepScene calls at once (gRPC futures on one channel) and then waits for
them, so a tick costs the slowest session's step, not the sum. Autoreset mode "same-step" (gymnasium 1.x naming): an
environment whose episode ended is reset inside the same step() call; the observation returned for it is the new
episode's first, and the last observation and info of the ended episode are in infos["final_obs"] and
infos["final_info"] (masks "_final_obs", "_final_info"). Ticks where episodes end take a second round trip: the
ended sessions' CloseSession and the new sessions' CreateSession calls, also sent at once. The sessions' ids are
session_ids (not in the infos, which the same seeds make equal)."""
import numpy as np

from scenestreamer.client import connect, scenario_names
from scenestreamer.env import SceneStreamerEnv
from scenestreamer.spaces import Env, batch_space
from scenestreamer.v1 import simulator_pb2 as pb


def _stack(observations):
    return {k: np.stack([o[k] for o in observations]) for k in observations[0]}


def _batch_infos(infos):
    """Gymnasium's vector info layout: each key's values in an array over envs, with a boolean "_key" mask."""
    out = {}
    n = len(infos)
    for i, info in enumerate(infos):
        for k, v in info.items():
            if k not in out:
                numeric = isinstance(v, (bool, int, float, np.number))
                out[k] = np.zeros(n, dtype=type(v) if numeric else object)
                out["_" + k] = np.zeros(n, dtype=bool)
            out[k][i] = v
            out["_" + k][i] = True
    return out


class SceneStreamerVectorEnv:
    metadata = {"autoreset_mode": "same-step"}

    def __init__(self, num_envs, target="127.0.0.1:50051", channel=None, route=False, token=None, tls_root=None,
                 **env_kwargs):
        if num_envs < 1:
            raise ValueError(f"num_envs {num_envs}: at least 1")
        self._own_channel = channel is None
        self.channel, self.stub = connect(target, channel, route, token=token, tls_root=tls_root)
        roads = {}  # one map per scenario for all the sub-environments
        self.envs = [SceneStreamerEnv(target, channel=self.channel, roads=roads, route=route, token=token,
                                      **env_kwargs)
                     for _ in range(num_envs)]
        self.num_envs = num_envs
        self.single_observation_space = self.envs[0].observation_space
        self.single_action_space = self.envs[0].action_space
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.timeout = self.envs[0].timeout

    @property
    def session_ids(self):
        """The server session id of each env (None before reset and after close)."""
        return [e.session_id for e in self.envs]

    def _restart(self, indices, options=None):
        """Closes the sessions of envs `indices` and starts new ones, all calls in flight at once."""
        closing = [self.stub.CloseSession.future(pb.CloseSessionRequest(session_id=self.envs[i].session_id),
                                                 timeout=self.timeout)
                   for i in indices if self.envs[i].session_id is not None]
        for i in indices:
            self.envs[i].session_id = None
        if self.envs[0].scenarios is None:  # the server's list, asked once for every env
            names = scenario_names(self.stub, self.timeout, with_sdc=True)
            if not names:
                raise RuntimeError("the server lists no bundled scenario with an SDC: pass scenarios= or start it "
                                   "with some")
            for e in self.envs:
                e.scenarios = names
        requests = [self.envs[i]._create_request(options) for i in indices]
        # Only one env asks for a scenario's map; the others in this batch wait for it from the shared cache.
        asked = set()
        for name, r in requests:
            if r.include_map:
                r.include_map = name not in asked
                asked.add(name)
        futures = [self.stub.CreateSession.future(r, timeout=self.timeout) for _, r in requests]
        errors = [f.exception() for f in futures] + [f.exception() for f in closing]
        if any(errors):
            # No session left behind: close the ones that did start, then report the first failure.
            for f in futures:
                if f.exception() is None:
                    self.stub.CloseSession(pb.CloseSessionRequest(session_id=f.result().session_id),
                                           timeout=self.timeout)
            raise next(e for e in errors if e is not None)
        responses = [f.result() for f in futures]
        # Envs whose response carries a map go first, so the others find it cached.
        order = sorted(range(len(indices)), key=lambda k: not responses[k].map)
        out = [None] * len(indices)
        for k in order:
            out[k] = self.envs[indices[k]]._started(requests[k][0], responses[k])
        return out

    def reset(self, *, seed=None, options=None):
        """seed: None, an int (env i gets seed + i) or a list of N seeds."""
        if seed is None or isinstance(seed, int):
            seeds = [None if seed is None else seed + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed: {len(seeds)} seeds for {self.num_envs} environments")
        for e, s in zip(self.envs, seeds):
            Env.reset(e, seed=s)
        started = self._restart(list(range(self.num_envs)), options)
        return _stack([o for o, _ in started]), _batch_infos([i for _, i in started])

    def step(self, actions):
        actions = np.asarray(actions)
        if actions.shape != (self.num_envs, 2):
            raise ValueError(f"actions: expected shape ({self.num_envs}, 2), got {actions.shape}")
        requests = [e._step_request(a, f"actions[{i}]") for i, (e, a) in enumerate(zip(self.envs, actions))]
        futures = [self.stub.StepScene.future(r, timeout=self.timeout) for r in requests]
        results = [e._stepped(f.result()) for e, f in zip(self.envs, futures)]
        obs = [r[0] for r in results]
        infos = [dict(r[4]) for r in results]
        rewards = np.array([r[1] for r in results], np.float64)
        terminated = np.array([r[2] for r in results], bool)
        truncated = np.array([r[3] for r in results], bool)
        ended = [i for i in range(self.num_envs) if terminated[i] or truncated[i]]
        if ended:
            for i in ended:
                infos[i] = {"final_obs": obs[i], "final_info": infos[i]}
            for i, (o, info) in zip(ended, self._restart(ended)):
                obs[i] = o
                infos[i].update(info)
        return _stack(obs), rewards, terminated, truncated, _batch_infos(infos)

    def close(self):
        closing = [self.stub.CloseSession.future(pb.CloseSessionRequest(session_id=e.session_id),
                                                 timeout=self.timeout)
                   for e in self.envs if e.session_id is not None]
        for e in self.envs:
            e.session_id = None
        for f in closing:
            f.result()
        if self._own_channel:
            self.channel.close()
