"""The example clients against the real server: the Python example (8 environments in one vector environment), the
C++ closed-loop client and the load generator. The Python package itself is tested in rl_env_test.py."""
import json
import os
import subprocess
import sys
import unittest

import grpc

from scenestreamer.v1 import simulator_pb2 as pb
from server_process import ServerTestCase

PY_CLIENT_DIR = os.environ["SS_PY_CLIENT_DIR"]


class ClientsTest(ServerTestCase):
    def test_python_example_eight_envs(self):
        r = subprocess.run([sys.executable, os.path.join(PY_CLIENT_DIR, "run_parallel_envs.py"), "--target",
                            self.server.target, "--envs", "8", "--steps", "3"], capture_output=True, text=True,
                           timeout=120)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("8 environments", r.stdout)

    def test_cpp_closed_loop(self):
        r = subprocess.run([os.environ["SS_CLOSED_LOOP"], "--target", self.server.target, "--steps", "3"],
                           capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("tick 3", r.stdout)

    def test_cpp_load_generator(self):
        r = subprocess.run([os.environ["SS_LOAD"], "--clients", "4", "--steps", "3", "--target", self.server.target,
                            "--json"], capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        out = json.loads(r.stdout)
        self.assertEqual(set(out), {"clients", "steps", "scenarios", "densify", "motion_reject", "errors",
                                    "steps_per_second", "latency_ms_p50", "latency_ms_p99", "agents_last_tick_mean"})
        self.assertEqual((out["clients"], out["steps"], out["scenarios"], out["densify"], out["errors"]),
                         (4, 3, 1, 0, 0))
        self.assertTrue(out["motion_reject"])
        self.assertGreater(out["steps_per_second"], 0)
        self.assertLessEqual(out["latency_ms_p50"], out["latency_ms_p99"])
        self.assertGreater(out["agents_last_tick_mean"], 0)

    def test_cpp_load_generator_densifies(self):
        # --densify A: densify-mode sessions topped up to A agents (the speed figures' 64-agent sessions).
        args = [os.environ["SS_LOAD"], "--clients", "2", "--steps", "2", "--target", self.server.target, "--json"]
        plain = json.loads(subprocess.run(args, capture_output=True, text=True, timeout=120, check=True).stdout)
        r = subprocess.run(args + ["--densify", "40"], capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        dense = json.loads(r.stdout)
        self.assertEqual((dense["densify"], dense["errors"]), (40, 0))
        self.assertGreater(dense["agents_last_tick_mean"], plain["agents_last_tick_mean"])
        self.assertGreaterEqual(dense["agents_last_tick_mean"], 30)
        # --no-motion-reject: the sessions are created without reject sampling (what it costs a server).
        r = subprocess.run(args + ["--densify", "40", "--no-motion-reject"], capture_output=True, text=True,
                           timeout=120)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        off = json.loads(r.stdout)
        self.assertEqual((off["motion_reject"], off["errors"]), (False, 0))
        bad = subprocess.run(args + ["--densify", "0"], capture_output=True, text=True, timeout=60)
        self.assertEqual(bad.returncode, 2)
        self.assertIn("--densify must be positive", bad.stderr)

    def test_cpp_load_generator_spreads_over_scenarios(self):
        # --scenarios K: client c on the server's (c mod K)-th scenario, so K maps are held at once.
        names = [s.name for s in self.server.stub.ListScenarios(pb.ListScenariosRequest()).scenarios]
        self.assertGreaterEqual(len(names), 2)
        args = [os.environ["SS_LOAD"], "--clients", "4", "--steps", "2", "--target", self.server.target, "--json"]
        before = len(self.server.output())  # the server is the class's: other tests' sessions are in its log too
        r = subprocess.run(args + ["--scenarios", "2"], capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        out = json.loads(r.stdout)
        self.assertEqual((out["scenarios"], out["errors"]), (2, 0))
        log = self.server.output()[before:]
        for name in names[:2]:
            self.assertEqual(log.count(f": created on {name} "), 2, name)
        for flags, code, message in ((["--scenarios", "0"], 2, "--scenarios must be positive"),
                                     (["--scenarios", "2", "--scenario", names[0]], 2,
                                      "--scenario and --scenarios exclude each other"),
                                     (["--scenarios", str(len(names) + 1)], 1,
                                      f"has {len(names)} scenarios; the load asks for {len(names) + 1}")):
            bad = subprocess.run(args + flags, capture_output=True, text=True, timeout=60)
            self.assertEqual(bad.returncode, code, bad.stderr)
            self.assertIn(message, bad.stderr)

    def test_routing_metadata(self):
        # What a session-affine router needs: with route=True the Python package proposes the id and sends it as
        # x-session-id on every call, CreateSession included, and the server keeps that id.
        from scenestreamer.client import connect
        seen = []

        class Recorder(grpc.UnaryUnaryClientInterceptor):
            def intercept_unary_unary(self, continuation, details, request):
                seen.append((details.method.rsplit("/", 1)[-1], dict(details.metadata or ()).get("x-session-id"),
                             getattr(request, "session_id", None)))
                return continuation(details, request)

        recorded = grpc.intercept_channel(grpc.insecure_channel(self.server.target), Recorder())
        _, routed = connect(None, recorded, route=True)
        name = routed.ListScenarios(pb.ListScenariosRequest()).scenarios[0].name
        sid = routed.CreateSession(pb.CreateSessionRequest(scenario_name=name)).session_id
        routed.CloseSession(pb.CloseSessionRequest(session_id=sid))
        self.assertRegex(sid, r"^[0-9a-f]{32}$")
        self.assertEqual(seen[1:], [("CreateSession", sid, sid), ("CloseSession", sid, sid)])
        # The server takes the metadata's id when the request proposes none, and refuses two ids that differ.
        stub = self.server.stub
        name = stub.ListScenarios(pb.ListScenariosRequest()).scenarios[0].name
        r = stub.CreateSession(pb.CreateSessionRequest(scenario_name=name), metadata=(("x-session-id", "by-meta"),))
        self.assertEqual(r.session_id, "by-meta")
        stub.CloseSession(pb.CloseSessionRequest(session_id="by-meta"))
        with self.assertRaises(grpc.RpcError) as e:
            stub.CreateSession(pb.CreateSessionRequest(scenario_name=name, session_id="a"),
                               metadata=(("x-session-id", "b"),))
        self.assertEqual(e.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("session_id 'a' differs from the x-session-id metadata 'b'", e.exception.details())

    def test_cpp_load_generator_routes(self):
        r = subprocess.run([os.environ["SS_LOAD"], "--clients", "3", "--steps", "2", "--target", self.server.target,
                            "--json", "--route"], capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        ids = json.loads(r.stdout)["session_ids"]
        self.assertEqual(len(set(ids)), 3)
        for sid in ids:
            self.assertRegex(sid, r"^[0-9a-f]{32}$")
            self.assertIn(f"session {sid}: created", self.server.output())


if __name__ == "__main__":
    unittest.main(verbosity=2)
