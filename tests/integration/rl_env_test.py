"""The RL package (python/scenestreamer) against the real server on loopback: the Gymnasium-style env's API contract
and the determinism Gymnasium's checker asks of it (whole infos), the normalised actions and the flat observation,
the vector env (one round trip per tick, counted), the multi-agent env under the checks of PettingZoo's
parallel_api_test and parallel_seed_test, and the engine's events with a scripted ego driven into another agent, off
the road and through a red light."""
import inspect
import math
import threading
import time
import unittest

import grpc
import numpy as np

from scenestreamer import (HAVE_GYMNASIUM, HAVE_PETTINGZOO, FlatObservation, RewardConfig, SceneStreamerEnv,
                           SceneStreamerParallelEnv, SceneStreamerVectorEnv, cruise)
from scenestreamer.env import check_action
from scenestreamer.spaces import flatten
from scenestreamer.v1 import simulator_pb2 as pb
from server_process import ServerTestCase


class CallLog(grpc.UnaryUnaryClientInterceptor):
    """Records every unary call on a channel: method, when it was sent and when its answer arrived."""

    def __init__(self):
        self.calls = []
        self.lock = threading.Lock()

    def intercept_unary_unary(self, continuation, details, request):
        entry = {"method": details.method.rsplit("/", 1)[-1], "sent": time.monotonic(), "done": None}
        with self.lock:
            self.calls.append(entry)
        future = continuation(details, request)
        future.add_done_callback(lambda f: entry.__setitem__("done", time.monotonic()))
        return future

    def since(self, n, method):
        return [c for c in self.calls[n:] if c["method"] == method]


NO_ENDING = RewardConfig(end_on_collision=False, end_on_off_road=False)  # episodes end by truncation only


def equivalent(a, b):
    """Gymnasium's data_equivalence: the same types, dict keys (in any order), sequence lengths, and values; arrays of
    the same dtype, shape and elements."""
    if type(a) is not type(b):
        return False
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(equivalent(a[k], b[k]) for k in a)
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(equivalent(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and bool(np.all(a == b))
    return a == b


def assert_obs_equal(test, a, b):
    test.assertEqual(a.keys(), b.keys())
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


class EnvTest(ServerTestCase):
    def sessions(self):
        return {s.session_id for s in self.server.stub.ListSessions(pb.ListSessionsRequest()).sessions}

    def test_api_contract(self):
        self.assertFalse(HAVE_GYMNASIUM, "Debian has no gymnasium: these tests cover the stand-in spaces")
        env = SceneStreamerEnv(self.server.target, max_steps=6)
        params = inspect.signature(env.reset).parameters
        self.assertEqual(params["seed"].kind, inspect.Parameter.KEYWORD_ONLY)
        self.assertIsNone(params["seed"].default)
        self.assertIsNone(params["options"].default)
        obs, info = env.reset(seed=3)
        self.assertIsInstance(info, dict)
        self.assertNotIn("session_id", info)  # new each episode: an attribute, so equal seeds give equal infos
        self.assertIn(env.session_id, self.sessions())
        self.assertTrue(env.observation_space.contains(obs), obs)
        self.assertEqual(env.action_space.shape, (2,))
        steps, seen = 0, {"lanes": 0, "road_edges": 0, "agents": 0}
        while True:
            action = cruise(obs) if steps % 2 == 0 else env.action_space.sample()
            self.assertTrue(env.action_space.contains(action))
            result = env.step(action)
            self.assertEqual(len(result), 5)
            obs, reward, terminated, truncated, info = result
            self.assertTrue(env.observation_space.contains(obs), {k: (v.min(), v.max()) for k, v in obs.items()})
            self.assertIsInstance(reward, float)
            self.assertIsInstance(terminated, bool)
            self.assertIsInstance(truncated, bool)
            for k in ("collision", "off_road", "ran_red_light", "progress", "lane_id"):
                self.assertIn(k, info)
            for k in seen:
                seen[k] += int(obs[k + "_mask"].sum())
            steps += 1
            if terminated or truncated:
                break
        self.assertLessEqual(steps, 6)
        self.assertEqual(truncated, steps == 6)  # both may be true at the last step
        # The observation carries the road and the traffic, not only padding.
        self.assertGreater(seen["lanes"], 0)
        self.assertGreater(seen["road_edges"], 0)
        self.assertGreater(seen["agents"], 0)
        env.close()

    def test_same_seed_equal_observations_rewards_and_infos(self):
        """Gymnasium's env checker (check_reset_seed, check_step_determinism): the same env reset twice with the same
        seed, and stepped with the same actions, gives equivalent observations, rewards, flags and whole infos; the
        session id, new each episode, is an attribute, not in the infos."""
        self.assertTrue(equivalent({"a": [1, np.zeros(2)]}, {"a": [1, np.zeros(2)]}))
        self.assertFalse(equivalent({"a": 1}, {"a": 1, "session_id": "x"}))
        self.assertFalse(equivalent(np.zeros(2, np.float32), np.zeros(2)))
        env = SceneStreamerEnv(self.server.target, max_steps=4, reward=NO_ENDING)
        runs, sessions = [], []
        for _ in range(2):
            env.action_space.seed(123)
            obs, info = env.reset(seed=123)
            sessions.append(env.session_id)
            self.assertIn(env.session_id, self.sessions())
            run = [(obs, info)]
            for _ in range(4):
                run.append(env.step(env.action_space.sample()))
            runs.append((run, env.np_random.bit_generator.state))
        (a, rng_a), (b, rng_b) = runs
        self.assertEqual(rng_a, rng_b)
        self.assertNotEqual(sessions[0], sessions[1])
        self.assertEqual(len(a), len(b))
        for k, (x, y) in enumerate(zip(a, b)):
            self.assertEqual(x[-1].keys(), y[-1].keys(), f"infos at step {k}")
            self.assertNotIn("session_id", x[-1])
            for part, (u, v) in enumerate(zip(x, y)):
                self.assertTrue(equivalent(u, v), f"step {k}, part {part}: {u!r} != {v!r}")
        self.assertEqual(set(a[0][1]), {"scenario", "ego_id", "sim_time"})
        for k in ("tick", "sim_time", "agents", "collision", "off_road", "ran_red_light", "progress", "lane_id"):
            self.assertIn(k, a[1][4])
        env.close()

    def test_normalized_actions(self):
        """normalize_actions: Box(-1, 1), and a normalised action drives the ego exactly as its physical value."""
        norm = SceneStreamerEnv(self.server.target, max_steps=3, reward=NO_ENDING, normalize_actions=True)
        phys = SceneStreamerEnv(self.server.target, max_steps=3, reward=NO_ENDING)
        np.testing.assert_array_equal(norm.action_space.low, [-1, -1])
        np.testing.assert_array_equal(norm.action_space.high, [1, 1])
        obs_n, _ = norm.reset(seed=8)
        obs_p, _ = phys.reset(seed=8)
        assert_obs_equal(self, obs_n, obs_p)
        speeds = [obs_n["ego"][0]]
        for u in ([1.0, 0.0], [-1.0, 0.5], [0.25, -1.0]):
            obs_n, r_n, _, _, info_n = norm.step(u)
            obs_p, r_p, _, _, info_p = phys.step(check_action(u, normalized=True))
            assert_obs_equal(self, obs_n, obs_p)
            self.assertEqual((r_n, info_n), (r_p, info_p))
            speeds.append(obs_n["ego"][0])
        # +1 is full acceleration (4 m/s^2 for 0.5 s), -1 full braking: the ego's speed goes up, then down.
        self.assertGreater(speeds[1], speeds[0])
        self.assertLess(speeds[2], speeds[1])
        with self.assertRaisesRegex(ValueError, "not finite"):
            norm.step([np.nan, 0])
        norm.close()
        phys.close()

    def test_flat_observation(self):
        """FlatObservation: one float32 vector inside its Box, the dict env's observation flattened in order."""
        flat = FlatObservation(SceneStreamerEnv(self.server.target, max_steps=2, normalize_actions=True))
        plain = SceneStreamerEnv(self.server.target, max_steps=2, normalize_actions=True)
        space = flat.observation_space
        self.assertEqual(len(space.shape), 1)
        self.assertEqual(space.shape[0], sum(b.low.size for b in plain.observation_space.spaces.values()))
        v, info = flat.reset(seed=5)
        obs, info_plain = plain.reset(seed=5)
        self.assertEqual((v.shape, v.dtype), (space.shape, np.float32))
        self.assertTrue(space.contains(v))
        np.testing.assert_array_equal(v, flatten(plain.observation_space, obs))
        self.assertEqual(info, info_plain)
        lanes = dict((k, (a, b)) for k, a, b in flat.layout())["lanes"]
        np.testing.assert_array_equal(v[lanes[0]:lanes[1]], obs["lanes"].ravel())
        v, reward, _, _, _ = flat.step([0.2, 0.0])
        obs, reward_plain, _, _, _ = plain.step([0.2, 0.0])
        self.assertTrue(space.contains(v))
        np.testing.assert_array_equal(v, flatten(plain.observation_space, obs))
        self.assertEqual(reward, reward_plain)
        self.assertIn(flat.unwrapped.session_id, self.sessions())
        flat.close()
        plain.close()
        self.assertIsNone(flat.unwrapped.session_id)

    def test_bad_actions_are_refused_with_the_reason(self):
        env = SceneStreamerEnv(self.server.target)
        with self.assertRaisesRegex(RuntimeError, "before reset"):
            env.step([0, 0])
        env.reset(seed=1)
        with self.assertRaisesRegex(ValueError, "not finite"):
            env.step([float("nan"), 0])
        with self.assertRaisesRegex(ValueError, r"shape \(2,\)"):
            env.step([0, 0, 0])
        with self.assertRaisesRegex(ValueError, "mode"):
            SceneStreamerEnv(self.server.target, mode="fast")
        env.close()

    def test_same_seed_same_episode(self):
        def episode(seed):
            env = SceneStreamerEnv(self.server.target, max_steps=5)
            obs, info = env.reset(seed=seed)
            out = [(obs, 0.0, info["scenario"])]
            for _ in range(5):
                obs, reward, terminated, truncated, _ = env.step(cruise(obs))
                out.append((obs, reward, None))
                if terminated:
                    break
            env.close()
            return out

        a, b, c = episode(11), episode(11), episode(12)
        self.assertEqual(len(a), len(b))
        for (oa, ra, sa), (ob, rb, sb) in zip(a, b):
            assert_obs_equal(self, oa, ob)
            self.assertEqual((ra, sa), (rb, sb))
        differs = any(not np.array_equal(x[0]["agents"], y[0]["agents"]) for x, y in zip(a, c))
        self.assertTrue(differs, "seeds 11 and 12 gave the same episode")

    def test_close_releases_the_session(self):
        env = SceneStreamerEnv(self.server.target)
        env.reset(seed=2)
        first = env.session_id
        self.assertIn(first, self.sessions())
        env.reset(seed=3)  # a new episode closes the previous session
        second = env.session_id
        self.assertNotIn(first, self.sessions())
        self.assertIn(second, self.sessions())
        env.close()
        self.assertNotIn(second, self.sessions())
        env.close()  # twice is harmless

    def test_vector_env_one_round_trip_per_tick(self):
        log = CallLog()
        channel = grpc.intercept_channel(grpc.insecure_channel(self.server.target), log)
        n = 4
        # Episodes end only by truncation here, so every env ends at the second step.
        venv = SceneStreamerVectorEnv(n, channel=channel, max_steps=2, reward=NO_ENDING)
        self.assertEqual(venv.metadata["autoreset_mode"], "same-step")
        mark = len(log.calls)
        obs, infos = venv.reset(seed=5)
        self.assertEqual(len(log.since(mark, "CreateSession")), n)
        self.assertTrue(venv.observation_space.contains(obs))
        self.assertEqual(obs["agents"].shape, (n,) + venv.single_observation_space["agents"].shape)
        self.assertNotIn("session_id", infos)
        self.assertEqual(len(set(venv.session_ids)), n)
        first_sessions = set(venv.session_ids)
        self.assertTrue(first_sessions <= self.sessions())

        actions = np.stack([cruise({k: v[i] for k, v in obs.items()}) for i in range(n)])
        mark = len(log.calls)
        obs, rewards, terminated, truncated, infos = venv.step(actions)
        steps = log.since(mark, "StepScene")
        self.assertEqual(len(log.calls) - mark, n, [c["method"] for c in log.calls[mark:]])
        self.assertEqual(len(steps), n)
        # One round trip: every call was sent before the first answer came back.
        self.assertLess(max(c["sent"] for c in steps), min(c["done"] for c in steps))
        self.assertEqual(rewards.shape, (n,))
        self.assertEqual(terminated.dtype, bool)
        self.assertEqual(truncated.shape, (n,))
        self.assertTrue(venv.observation_space.contains(obs))

        # Second step: max_steps reached, every episode is truncated and restarted in the same call.
        mark = len(log.calls)
        self.assertFalse(terminated.any() or truncated.any())
        obs, rewards, terminated, truncated, infos = venv.step(venv.action_space.sample())
        self.assertTrue(truncated.all())
        for i in range(n):
            self.assertTrue(infos["_final_obs"][i])
            self.assertTrue(venv.single_observation_space.contains(infos["final_obs"][i]))
        self.assertEqual(len(log.since(mark, "StepScene")), n)
        self.assertEqual(len(log.since(mark, "CreateSession")), n)
        self.assertEqual(len(log.since(mark, "CloseSession")), n)
        self.assertTrue(first_sessions.isdisjoint(self.sessions()))
        self.assertTrue(venv.observation_space.contains(obs))
        venv.close()
        self.assertTrue(set(e.session_id for e in venv.envs) == {None})
        channel.close()

    def test_parallel_env(self):
        log = CallLog()
        channel = grpc.intercept_channel(grpc.insecure_channel(self.server.target), log)
        env = SceneStreamerParallelEnv(channel=channel, num_agents=3, max_steps=3, reward=NO_ENDING)
        self.assertEqual(len(env.possible_agents), 3)
        obs, infos = env.reset(seed=4)
        self.assertEqual(set(obs), set(env.possible_agents))
        self.assertEqual(set(infos), set(env.possible_agents))
        info = self.server.stub.GetSession(pb.GetSessionRequest(session_id=env.session_id)).info
        self.assertEqual(sorted(info.controlled_agent_ids), sorted(env.agent_ids))
        for name, o in obs.items():
            self.assertTrue(env.observation_space(name).contains(o))
        steps = 0
        while env.agents:
            mark = len(log.calls)
            actions = {a: cruise(obs[a]) for a in env.agents}
            obs, rewards, terminations, truncations, infos = env.step(actions)
            self.assertEqual(len(log.since(mark, "StepScene")), 1)  # every ego's pose in one call
            self.assertEqual(set(rewards), set(actions))
            for name in actions:
                self.assertTrue(env.observation_space(name).contains(obs[name]))
                self.assertIn("collision", infos[name])
            steps += 1
        self.assertEqual(steps, 3)
        with self.assertRaisesRegex(ValueError, "not live"):
            env.step({"agent_0": [0, 0]})
        env.close()
        channel.close()

    def test_parallel_env_passes_pettingzoo_api_checks(self):
        """What PettingZoo's parallel_api_test reads and asserts, on the env as a client gets it."""
        self.assertFalse(HAVE_PETTINGZOO, "Debian has no pettingzoo: this covers the stand-in base class")
        env = SceneStreamerParallelEnv(self.server.target, num_agents=2, max_steps=4, normalize_actions=True)
        env.max_cycles = 1000  # the test sets it
        self.assertIs(env.unwrapped, env)
        self.assertEqual(env.metadata["name"], "scenestreamer_parallel_v0")
        self.assertEqual(str(env), "scenestreamer_parallel_v0")
        self.assertEqual(env.max_num_agents, 2)
        self.assertEqual(env.agents, [])
        for a in env.possible_agents:
            self.assertIs(env.observation_space(a), env.observation_space(a))
            self.assertIs(env.action_space(a), env.action_space(a))
            self.assertIs(env.observation_spaces[a], env.observation_space(a))
            self.assertIs(env.action_spaces[a], env.action_space(a))
            np.testing.assert_array_equal(env.action_space(a).high, [1, 1])
        env.reset(seed=0, options={"options": 1})  # reset takes seed and options
        for _ in range(2):
            obs, infos = env.reset()
            self.assertIsInstance(obs, dict)
            self.assertIsInstance(infos, dict)
            self.assertEqual(env.num_agents, 2)
            self.assertTrue(set(env.agents) <= set(obs) and set(env.agents) <= set(infos))
            live, finished = set(env.agents), set()
            for _ in range(1000):
                actions = {a: env.action_space(a).sample() for a in env.agents}
                obs, rewards, terminated, truncated, infos = env.step(actions)
                for a in env.agents:
                    self.assertNotIn(a, finished, "agent revived")
                for part in (obs, rewards, terminated, truncated, infos):
                    self.assertIsInstance(part, dict)
                    self.assertEqual(set(part), live)  # no entry missing for a live agent, none for a dead one
                self.assertTrue(set(env.agents) <= set(env.possible_agents))
                done = {a for a in live if terminated[a] or truncated[a]}
                finished |= done
                live -= done
                self.assertEqual(set(env.agents), live)
                if not live:
                    break
            self.assertEqual(finished, set(env.possible_agents))
        env.close()

    def test_parallel_env_same_seed_same_everything(self):
        """PettingZoo's parallel_seed_test: two envs reset with the same seed and given the same actions return
        equivalent observations, rewards, terminations, truncations and infos."""
        envs = [SceneStreamerParallelEnv(self.server.target, num_agents=2, max_steps=3, reward=NO_ENDING)
                for _ in range(2)]
        results = [[], []]
        for env, out in zip(envs, results):
            out.append(env.reset(seed=42))
            for a in env.possible_agents:
                env.action_space(a).seed(7)
            while env.agents:
                out.append(env.step({a: env.action_space(a).sample() for a in env.agents}))
        self.assertNotEqual(envs[0].session_id, envs[1].session_id)
        self.assertEqual(len(results[0]), 4)
        self.assertEqual(len(results[0]), len(results[1]))
        for k, (x, y) in enumerate(zip(*results)):
            for part, (u, v) in enumerate(zip(x, y)):
                self.assertTrue(equivalent(u, v), f"step {k}, part {part}: {u!r} != {v!r}")
        for env in envs:
            env.close()


def find(tick, agent_id):
    return next(a for a in tick.agents if a.id == agent_id)


def events(tick, agent_id):
    return next(e for e in tick.events if e.agent_id == agent_id)


def state_at(like, x, y, heading, speed):
    return pb.AgentState(x=x, y=y, heading=heading, vx=speed * math.cos(heading), vy=speed * math.sin(heading),
                         length=like.length, width=like.width, height=like.height)


def point_segment_distance(p, a, b):
    """Distances from points p (n, 2) to segments a, b (m, 2): an (n, m) array."""
    d = b - a
    dd = np.maximum(np.sum(d * d, axis=1), 1e-12)
    t = np.clip(np.einsum("nmk,mk->nm", p[:, None, :] - a[None], d) / dd, 0, 1)
    closest = a[None] + t[..., None] * d[None]
    return np.linalg.norm(p[:, None, :] - closest, axis=2)


class EventsTest(ServerTestCase):
    """A scripted ego (StateForce to put it somewhere, then poses a few metres apart) gets each event at exactly the
    tick it happens."""

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.stub = cls.server.stub
        cls.names = [s.name for s in cls.stub.ListScenarios(pb.ListScenariosRequest()).scenarios]

    def start(self, name):
        r = self.stub.CreateSession(pb.CreateSessionRequest(scenario_name=name, seed=1, include_map=True))
        self.addCleanup(self.stub.CloseSession, pb.CloseSessionRequest(session_id=r.session_id))
        ego = next(a for a in r.initial.agents if a.controlled)
        return r, ego

    def step(self, sid, pose=None, forced=(), lights=()):
        if forced or lights:
            self.stub.StateForce(pb.StateForceRequest(
                session_id=sid, agents=[pb.ForcedAgent(agent_id=i, state=s) for i, s in forced],
                lights=[pb.ForcedLight(lane=l, state=s) for l, s in lights]))
        tick = self.stub.StepScene(pb.StepSceneRequest(session_id=sid, poses=[pose] if pose else [])).ticks[-1]
        self.assertEqual(len(tick.events), 1)
        return tick

    def test_driven_into_another_agent(self):
        r, ego = self.start(self.names[0])
        sid = r.session_id
        cars = [a for a in r.initial.agents if not a.controlled and a.type == pb.AGENT_TYPE_VEHICLE and
                a.state.length < 6]
        self.assertTrue(cars)
        target = min(cars, key=lambda a: math.hypot(a.state.x - ego.state.x, a.state.y - ego.state.y))
        t = target.state
        still = state_at(t, t.x, t.y, t.heading, 0.0)  # forced every step: the target stays where it is

        def behind(d):
            return t.x - d * math.cos(t.heading), t.y - d * math.sin(t.heading)

        x, y = behind(14)
        tick = self.step(sid, forced=[(ego.id, state_at(ego.state, x, y, t.heading, 8.0)), (target.id, still)])
        hits = [target.id in events(tick, ego.id).overlapping]
        for d in (10, 6, 2):  # centre distances; boxes of at most 6 m overlap only at 2 m
            x, y = behind(d)
            pose = pb.ControlledPose(agent_id=ego.id, x=x, y=y, heading=t.heading, speed=8.0)
            tick = self.step(sid, pose, forced=[(target.id, still)])
            self.assertAlmostEqual(find(tick, ego.id).state.x, x, places=6)
            hits.append(target.id in events(tick, ego.id).overlapping)
        self.assertEqual(hits, [False, False, False, True])

    def test_driven_off_the_road(self):
        r, ego = self.start(self.names[0])
        sid = r.session_id
        length, width = ego.state.length, ego.state.width
        edges = [f for f in r.map if f.type == pb.MAP_FEATURE_ROAD_EDGE and len(f.x) >= 2]
        a = np.concatenate([np.stack([f.x[:-1], f.y[:-1]], 1) for f in edges])
        b = np.concatenate([np.stack([f.x[1:], f.y[1:]], 1) for f in edges])
        ds = (8.0, 6.0, 4.0, 2.0, 0.0, -2.0)  # the centre's distance inside the edge, driving straight at it
        # An edge segment of at least 8 m that is the nearest edge of every box corner along the path: then the most
        # off-road corner's signed distance is exactly length / 2 - d.
        chosen = None
        for k in np.argsort(-np.linalg.norm(b - a, axis=1)):
            seg = b[k] - a[k]
            if np.linalg.norm(seg) < 8:
                break
            u = seg / np.linalg.norm(seg)
            inward = np.array([-u[1], u[0]])  # road edges have the road on their left
            mid = (a[k] + b[k]) / 2
            corners = np.array([mid + inward * (d + s * length / 2) + u * w * width / 2
                                for d in ds for s in (-1, 1) for w in (-1, 1)])
            dist = point_segment_distance(corners, a, b)
            others = np.delete(dist, k, axis=1).min(axis=1)
            if np.all(dist[:, k] + 0.5 < others):
                chosen = (mid, u, inward)
                break
        self.assertIsNotNone(chosen, "no straight road edge with room around it in the scenario")
        mid, u, inward = chosen
        heading = math.atan2(-inward[1], -inward[0])  # facing the edge
        at = [mid + inward * d for d in ds]
        tick = self.step(sid, forced=[(ego.id, state_at(ego.state, *at[0], heading, 4.0))])
        got = [events(tick, ego.id)]
        for p in at[1:]:
            tick = self.step(sid, pb.ControlledPose(agent_id=ego.id, x=p[0], y=p[1], heading=heading, speed=4.0))
            got.append(events(tick, ego.id))
        for d, e in zip(ds, got):
            self.assertAlmostEqual(e.road_edge_distance, length / 2 - d, places=5, msg=f"d = {d}")
            self.assertEqual(e.off_road, length / 2 - d > 0, f"d = {d}")
        self.assertEqual([e.off_road for e in got], [False, False, False, True, True, True])

    def test_driven_through_a_red_light(self):
        for name in self.names:
            r, ego = self.start(name)
            if r.initial.lights:
                break
        self.assertTrue(r.initial.lights, "no bundled scenario has traffic lights")
        sid = r.session_id
        light = r.initial.lights[0]
        sp = light.stop_point
        u = np.array([math.cos(sp.heading), math.sin(sp.heading)])
        green = [(l.lane, pb.LIGHT_STATE_GREEN) for l in r.initial.lights]

        def lights(state):  # the light under test in `state`, every other one green (no stray red line nearby)
            return [(l, state if l == light.lane else s) for l, s in green]

        def run(state):
            r2, ego2 = self.start(name)
            start = np.array([sp.x, sp.y]) - 9 * u
            tick = self.step(r2.session_id, forced=[(ego2.id, state_at(ego2.state, *start, sp.heading, 6.0))],
                             lights=green)
            out = [events(tick, ego2.id)]
            for d in (-6.0, -3.0, 0.5, 3.5):  # the centre's distance past the stop line
                p = np.array([sp.x, sp.y]) + d * u
                pose = pb.ControlledPose(agent_id=ego2.id, x=p[0], y=p[1], heading=sp.heading, speed=6.0)
                tick = self.step(r2.session_id, pose, lights=lights(state))
                self.assertEqual(next(l.state for l in tick.lights if l.lane == light.lane), state)
                out.append(events(tick, ego2.id))
            return out

        red = run(pb.LIGHT_STATE_RED)
        self.assertEqual([e.ran_red_light for e in red], [False, False, False, True, False])
        self.assertEqual(red[3].red_light_lane, light.lane)
        self.assertEqual([e.red_light_lane for e in red if not e.ran_red_light], [-1] * 4)
        self.assertFalse(any(e.ran_red_light for e in run(pb.LIGHT_STATE_GREEN)))


if __name__ == "__main__":
    unittest.main(verbosity=2)
