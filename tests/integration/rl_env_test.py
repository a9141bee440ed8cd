"""The RL package (python/scenestreamer) against the real server on loopback: the Gymnasium-style env's API contract,
the vector env (one round trip per tick, counted), the multi-agent env, and the engine's events with a scripted ego
driven into another agent, off the road and through a red light."""
import inspect
import math
import threading
import time
import unittest

import grpc
import numpy as np

from scenestreamer import (HAVE_GYMNASIUM, RewardConfig, SceneStreamerEnv, SceneStreamerParallelEnv,
                           SceneStreamerVectorEnv, cruise)
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
        self.assertIn("session_id", info)
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
        _, info = env.reset(seed=2)
        first = info["session_id"]
        self.assertIn(first, self.sessions())
        _, info = env.reset(seed=3)  # a new episode closes the previous session
        self.assertNotIn(first, self.sessions())
        self.assertIn(info["session_id"], self.sessions())
        env.close()
        self.assertNotIn(info["session_id"], self.sessions())
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
        self.assertEqual(len(set(infos["session_id"])), n)
        first_sessions = set(infos["session_id"])

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
