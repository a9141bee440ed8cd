"""The Python package's own logic, without a server: the stand-in spaces and base classes (gymnasium's Env and
ObservationWrapper, PettingZoo's ParallelEnv), the normalised actions, the flat observation, the ego-frame
observation, the road arrays, the kinematics of an action, and reward/termination from events."""
import math
import unittest

import numpy as np

from scenestreamer import FlatObservation, RewardConfig
from scenestreamer.client import advance, scenario_names
from scenestreamer.env import ACTION_HIGH, ACTION_LOW, action_space, check_action
from scenestreamer.observation import ObservationConfig, observation_space, observe
from scenestreamer.reward import reward_and_termination
from scenestreamer.road import RoadMap
from scenestreamer.spaces import (HAVE_GYMNASIUM, HAVE_PETTINGZOO, Box, Dict, Env, ParallelEnv, batch_space,
                                  flat_box, flatten)
from scenestreamer.v1 import simulator_pb2 as pb


def agent(i, x, y, heading, vx=0.0, vy=0.0, controlled=False, type_=pb.AGENT_TYPE_VEHICLE):
    return pb.Agent(id=i, type=type_, controlled=controlled,
                    state=pb.AgentState(x=x, y=y, heading=heading, vx=vx, vy=vy, length=4.5, width=2.0, height=1.5))


class SpacesTest(unittest.TestCase):
    def test_box_contains_checks_shape_bounds_and_nan(self):
        b = Box(np.array([-1, 0], np.float32), np.array([1, 2], np.float32), dtype=np.float32)
        self.assertTrue(b.contains(np.array([0.5, 2.0], np.float32)))
        self.assertFalse(b.contains(np.array([1.5, 1.0], np.float32)))
        self.assertFalse(b.contains(np.array([0.0, 1.0, 0.0], np.float32)))
        self.assertFalse(b.contains(np.array([np.nan, 1.0], np.float32)))
        for _ in range(20):
            self.assertTrue(b.contains(b.sample()))

    def test_dict_and_batch(self):
        d = Dict({"a": Box(0.0, 1.0, shape=(3,)), "b": Box(-1.0, 1.0, shape=(2, 2))})
        self.assertTrue(d.contains(d.sample()))
        self.assertFalse(d.contains({"a": np.zeros(3, np.float32)}))  # a key missing
        batched = batch_space(d, 5)
        self.assertEqual(batched["b"].shape, (5, 2, 2))
        self.assertTrue(batched.contains(batched.sample()))

    @unittest.skipIf(HAVE_GYMNASIUM, "the stand-ins are used only without gymnasium")
    def test_stand_ins_in_use(self):
        self.assertEqual(Box.__module__, "scenestreamer.spaces")


class ParallelEnvStandInTest(unittest.TestCase):
    """What PettingZoo's ParallelEnv gives a subclass and parallel_api_test reads, on the stand-in."""

    @unittest.skipIf(HAVE_PETTINGZOO, "the stand-in is used only without pettingzoo")
    def test_attributes(self):
        space = Box(-1.0, 1.0, shape=(2,))

        class Two(ParallelEnv):
            metadata = {"name": "two_v0"}

            def __init__(self):
                self.possible_agents = ["a", "b"]
                self.agents = ["a"]
                self.observation_spaces = {"a": space, "b": space}
                self.action_spaces = {"a": space, "b": space}

        env = Two()
        self.assertIs(env.unwrapped, env)
        self.assertEqual((env.num_agents, env.max_num_agents), (1, 2))
        self.assertIs(env.observation_space("b"), space)
        self.assertIs(env.action_space("a"), env.action_space("a"))
        self.assertEqual(str(env), "two_v0")
        with self.assertRaisesRegex(NotImplementedError, "two_v0"):
            env.state()
        with self.assertRaises(NotImplementedError):
            env.reset(seed=0, options={})
        env.close()
        self.assertEqual(ParallelEnv.__module__, "scenestreamer.spaces")


def _dict_space():
    return Dict({"ego": Box(np.array([-1, 0], np.float32), np.array([1, 5], np.float32)),
                 "points": Box(-2.0, 2.0, shape=(3, 2)), "mask": Box(0.0, 1.0, shape=(3,))})


class NormalisedActionTest(unittest.TestCase):
    def test_maps_minus_one_one_onto_the_physical_range(self):
        np.testing.assert_array_equal(check_action([-1, -1], normalized=True), ACTION_LOW)
        np.testing.assert_array_equal(check_action([1, 1], normalized=True), ACTION_HIGH)
        np.testing.assert_allclose(check_action([0, 0], normalized=True), (ACTION_LOW + ACTION_HIGH) / 2)
        np.testing.assert_allclose(check_action([0.5, -0.5], normalized=True), [1.0, -0.5])
        # Outside [-1, 1]: clipped to it, so to the physical bounds.
        np.testing.assert_array_equal(check_action([7, -3], normalized=True), [ACTION_HIGH[0], ACTION_LOW[1]])
        self.assertEqual(check_action([0, 0], normalized=True).dtype, np.float32)
        # Physical units unchanged without the option.
        np.testing.assert_array_equal(check_action([-2, 0.5]), [-2, 0.5])

    def test_bad_actions_are_refused_either_way(self):
        for normalized in (False, True):
            with self.assertRaisesRegex(ValueError, r"expected shape \(2,\)"):
                check_action([0, 0, 0], normalized=normalized)
            with self.assertRaisesRegex(ValueError, "not finite"):
                check_action([np.inf, 0], "actions[1]", normalized=normalized)

    def test_spaces(self):
        n = action_space(True)
        np.testing.assert_array_equal(n.low, [-1, -1])
        np.testing.assert_array_equal(n.high, [1, 1])
        self.assertEqual((n.shape, n.dtype), ((2,), np.float32))
        p = action_space(False)
        np.testing.assert_array_equal(p.low, ACTION_LOW)
        np.testing.assert_array_equal(p.high, ACTION_HIGH)


class FlatObservationTest(unittest.TestCase):
    def test_flat_box_and_flatten(self):
        space = _dict_space()
        flat = flat_box(space)
        self.assertEqual((flat.shape, flat.dtype), ((2 + 6 + 3,), np.float32))
        np.testing.assert_array_equal(flat.low, [-1, 0] + [-2] * 6 + [0] * 3)
        np.testing.assert_array_equal(flat.high, [1, 5] + [2] * 6 + [1] * 3)
        obs = {"ego": np.array([0.5, 4], np.float32), "points": np.arange(6, dtype=np.float32).reshape(3, 2) / 4,
               "mask": np.array([1, 1, 0], np.float32)}
        v = flatten(space, obs)
        np.testing.assert_array_equal(v, [0.5, 4, 0, 0.25, 0.5, 0.75, 1, 1.25, 1, 1, 0])
        self.assertTrue(flat.contains(v))
        batched = {k: np.stack([a, a]) for k, a in obs.items()}
        np.testing.assert_array_equal(flatten(space, batched, batch_dims=1), np.stack([v, v]))

    def test_flatten_refuses_another_layout(self):
        space = _dict_space()
        obs = space.sample()
        with self.assertRaisesRegex(ValueError, r"observation\['points'\]: expected shape \(3, 2\)"):
            flatten(space, dict(obs, points=np.zeros((2, 3), np.float32)))
        with self.assertRaisesRegex(ValueError, "expected a dict of"):
            flatten(space, {"ego": obs["ego"]})
        with self.assertRaisesRegex(ValueError, "expected a dict of"):
            flatten(space, np.zeros(11, np.float32))

    def test_wrapper(self):
        space = _dict_space()

        class Fake(Env):
            observation_space = space
            action_space = Box(-1.0, 1.0, shape=(2,))
            session_id = "s-1"

            def reset(self, *, seed=None, options=None):
                super().reset(seed=seed)
                return space.sample(), {"scenario": "x"}

            def step(self, action):
                return space.sample(), 1.5, False, True, {"tick": 1}

        inner = Fake()
        env = FlatObservation(inner)
        self.assertIs(env.unwrapped, inner)
        self.assertEqual(env.unwrapped.session_id, "s-1")
        self.assertIs(env.action_space, inner.action_space)
        self.assertEqual(env.observation_space.shape, (11,))
        obs, info = env.reset(seed=3)
        self.assertEqual(info, {"scenario": "x"})
        self.assertEqual(obs.shape, (11,))
        self.assertTrue(env.observation_space.contains(obs))
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        self.assertTrue(env.observation_space.contains(obs))
        self.assertEqual((reward, terminated, truncated, info), (1.5, False, True, {"tick": 1}))
        self.assertEqual(env.layout(), [("ego", 0, 2), ("points", 2, 8), ("mask", 8, 11)])

        class NotDict(Fake):
            observation_space = Box(0.0, 1.0, shape=(3,))

        with self.assertRaisesRegex(TypeError, "not a Dict of Box"):
            FlatObservation(NotDict())


class ObservationTest(unittest.TestCase):
    def setUp(self):
        # An eastbound lane on y = 0 and a road edge on y = -2; the ego faces north (+y) at the origin.
        self.road = RoadMap([pb.MapFeature(id=1, type=pb.MAP_FEATURE_LANE, x=[-50, 50], y=[0, 0]),
                             pb.MapFeature(id=2, type=pb.MAP_FEATURE_ROAD_EDGE, x=[-50, 50], y=[-2, -2])])
        self.config = ObservationConfig(max_agents=2, lane_points=8, edge_points=8)

    def test_road_resampled_every_two_metres(self):
        self.assertEqual(len(self.road.lane_points), 51)
        np.testing.assert_allclose(np.diff(self.road.lane_points[:, 0]), 2.0)
        np.testing.assert_allclose(self.road.lane_dirs, [[1, 0]] * 51)

    def test_ego_frame(self):
        tick = pb.Tick(agents=[agent(1, 0, 0, math.pi / 2, vy=5, controlled=True),
                               agent(2, 0, 10, math.pi / 2, vy=3),    # 10 m ahead
                               agent(3, -4, 0, 0, vx=2),              # 4 m to the left, facing right of the ego
                               agent(4, 0, -40, 0)],                  # farther than the two kept
                       lights=[pb.TrafficLight(lane=1, stop_point=pb.Pose(x=0, y=20, heading=math.pi / 2),
                                               state=pb.LIGHT_STATE_RED),
                               pb.TrafficLight(lane=5, stop_point=pb.Pose(x=0, y=5, heading=-math.pi / 2),
                                               state=pb.LIGHT_STATE_GREEN)])  # faces the other way: left out
        obs = observe(tick, 1, self.road, self.config)
        self.assertTrue(observation_space(self.config).contains(obs))
        np.testing.assert_allclose(obs["ego"], [5, 0, 4.5, 2.0], atol=1e-6)
        np.testing.assert_allclose(obs["agents_mask"], [1, 1])
        # Nearest first: agent 3 (4 m, left, heading -90 degrees relative), then agent 2 (10 m ahead).
        np.testing.assert_allclose(obs["agents"][0, :6], [0, 4, 0, -1, 0, -2], atol=1e-6)
        np.testing.assert_allclose(obs["agents"][1, :6], [10, 0, 1, 0, 3, 0], atol=1e-6)
        np.testing.assert_allclose(obs["lights_mask"], [1] + [0] * 7)
        np.testing.assert_allclose(obs["lights"][0], [20, 0, 1, 0, 0, 0, 0, 1], atol=1e-6)
        # The lane (eastbound) runs across the ego's path from its left to its right: direction (0, -1) in its frame.
        m = obs["lanes_mask"] > 0
        self.assertEqual(m.sum(), 8)
        np.testing.assert_allclose(obs["lanes"][m, 0], 0, atol=1e-6)
        np.testing.assert_allclose(obs["lanes"][m, 2:], [[0, -1]] * 8, atol=1e-6)
        self.assertEqual(np.abs(obs["lanes"][m, 1]).min(), 0)
        np.testing.assert_allclose(obs["road_edges"][obs["road_edges_mask"] > 0, 0], -2, atol=1e-6)

    def test_unknown_ego(self):
        with self.assertRaisesRegex(KeyError, "agent 9"):
            observe(pb.Tick(agents=[agent(1, 0, 0, 0)]), 9, self.road, self.config)


class ScenarioNamesTest(unittest.TestCase):
    def test_only_scenarios_with_an_sdc_can_be_drawn(self):
        class Stub:  # ListScenarios as the server answers it: some WOMD JSON scenarios have no SDC
            def ListScenarios(self, request, timeout=None):
                return pb.ListScenariosResponse(scenarios=[pb.ScenarioInfo(name="a", has_sdc=True),
                                                           pb.ScenarioInfo(name="b", has_sdc=False),
                                                           pb.ScenarioInfo(name="c", has_sdc=True)])

        self.assertEqual(scenario_names(Stub()), ["a", "b", "c"])
        self.assertEqual(scenario_names(Stub(), with_sdc=True), ["a", "c"])


class KinematicsAndRewardTest(unittest.TestCase):
    def test_advance(self):
        a = agent(7, 10, 20, 0, vx=4, controlled=True)
        p = advance(a, (2.0, 0.0))  # 4 -> 5 m/s: 2.25 m in 0.5 s
        self.assertEqual(p.agent_id, 7)
        self.assertAlmostEqual(p.x, 12.25)
        self.assertAlmostEqual(p.y, 20)
        self.assertAlmostEqual(p.speed, 5)
        p = advance(a, (-10.0, 0.0))  # no reversing: stops
        self.assertEqual(p.speed, 0)
        self.assertAlmostEqual(p.x, 11)
        p = advance(a, (0.0, 1.0))  # turning left by 0.5 rad, along the mean heading 0.25
        self.assertAlmostEqual(p.heading, 0.5)
        self.assertAlmostEqual(math.atan2(p.y - 20, p.x - 10), 0.25)

    def test_reward_and_termination(self):
        c = RewardConfig()
        quiet = pb.AgentEvents(agent_id=1, progress=3.0)
        self.assertEqual(reward_and_termination(quiet, c)[:2], (3.0, False))
        crash = pb.AgentEvents(agent_id=1, progress=1.0, overlapping=[5])
        r, done, info = reward_and_termination(crash, c)
        self.assertEqual((r, done, info["collided_with"]), (-9.0, True, [5]))
        red = pb.AgentEvents(agent_id=1, ran_red_light=True)
        self.assertEqual(reward_and_termination(red, c)[:2], (-5.0, False))
        self.assertTrue(reward_and_termination(red, RewardConfig(end_on_red_light=True))[1])
        off = pb.AgentEvents(agent_id=1, off_road=True)
        self.assertEqual(reward_and_termination(off, RewardConfig(end_on_off_road=False))[:2], (-5.0, False))


if __name__ == "__main__":
    unittest.main(verbosity=2)
