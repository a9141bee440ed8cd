"""Integration tests: the real server binary over loopback gRPC. Every RPC, multi-client ticks, watch streams,
fork, eviction, SIGTERM save and restore, and every error code with a bad input."""
import os
import shutil
import tempfile
import threading
import time
import unittest
import urllib.request

import grpc

from scenestreamer.v1 import simulator_pb2 as pb
from server_process import DATA, Server, ego_pose, error_of, eventually, womd_records

C = grpc.StatusCode


def first_scenario(stub):
    return stub.ListScenarios(pb.ListScenariosRequest()).scenarios[0].name


def rollout(stub, sid, tick, n):
    """n ticks driven by ego_pose; returns the ticks."""
    out = []
    for _ in range(n):
        pose = ego_pose(tick)
        r = stub.StepScene(pb.StepSceneRequest(session_id=sid, poses=[pose] if pose else []))
        tick = r.ticks[-1]
        out.append(tick)
    return out


def health(channel):
    # grpc.health.v1.Health/Check with an empty request; the response's field 1 is the status (1 SERVING).
    check = channel.unary_unary("/grpc.health.v1.Health/Check", request_serializer=lambda b: b,
                                response_deserializer=lambda b: b)
    return check(b"", timeout=5)


def reflected_services(channel):
    # grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo with list_services (field 7) = "": the answer
    # holds the service names as strings.
    info = channel.stream_stream("/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
                                 request_serializer=lambda b: b, response_deserializer=lambda b: b)
    return b"".join(info(iter([b"\x3a\x00"]), timeout=5))


class RpcTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.server = Server("--max_message_mb=4", "--max_sessions=6", "--evict_idle_s=1000").start()
        cls.stub = cls.server.stub
        cls.name = first_scenario(cls.stub)

    @classmethod
    def tearDownClass(cls):
        cls.server.stop()

    def code(self, fn, *args, **kw):
        with self.assertRaises(grpc.RpcError) as e:
            fn(*args, **kw)
        return e.exception.code(), e.exception.details()

    def test_every_rpc(self):
        s = self.stub
        scenarios = s.ListScenarios(pb.ListScenariosRequest()).scenarios
        self.assertGreaterEqual(len(scenarios), 1)
        self.assertGreater(scenarios[0].num_tracks, 0)
        self.assertEqual(health(self.server.channel), b"\x08\x01")
        self.assertIn(b"scenestreamer.v1.Simulator", reflected_services(self.server.channel))

        c = s.CreateSession(pb.CreateSessionRequest(scenario_name=self.name, seed=5, session_id="rpc-proposed"))
        self.assertEqual(c.session_id, "rpc-proposed")
        self.assertTrue(any(a.controlled for a in c.initial.agents))
        ticks = rollout(s, c.session_id, c.initial, 2)
        self.assertEqual([t.tick for t in ticks], [1, 2])
        self.assertEqual(ticks[1].step, c.initial.step + 2)
        self.assertAlmostEqual(ticks[1].sim_time, ticks[1].step * 0.5)
        self.assertGreater(len(ticks[1].agents), 0)
        for light in ticks[1].lights:
            self.assertEqual(light.id, light.lane)

        ids = s.InjectAgent(pb.InjectAgentRequest(session_id=c.session_id, count=1)).agent_ids
        ego = [a for a in ticks[-1].agents if a.controlled][0]
        placed = s.InjectAgent(pb.InjectAgentRequest(
            session_id=c.session_id, type=pb.AGENT_TYPE_VEHICLE,
            state=pb.AgentState(x=ego.state.x + 15, y=ego.state.y + 15, heading=ego.state.heading, length=4.5,
                                width=2, height=1.6))).agent_ids
        self.assertEqual(len(placed), 1)
        got = s.GetSession(pb.GetSessionRequest(session_id=c.session_id))
        present = {a.id for a in got.current.agents}
        for i in list(ids) + list(placed):
            self.assertIn(i, present)
        other = [a for a in got.current.agents if not a.controlled][0]
        moved = pb.AgentState(x=other.state.x + 1, y=other.state.y, heading=other.state.heading,
                              length=other.state.length, width=other.state.width, height=other.state.height)
        s.StateForce(pb.StateForceRequest(session_id=c.session_id,
                                          agents=[pb.ForcedAgent(agent_id=other.id, state=moved)]))
        after = rollout(s, c.session_id, got.current, 1)[0]
        forced = [a for a in after.agents if a.id == other.id]
        if forced:
            self.assertAlmostEqual(forced[0].state.x, moved.x, places=3)

        info = s.GetSession(pb.GetSessionRequest(session_id=c.session_id)).info
        self.assertEqual(info.tick, 3)
        self.assertEqual(info.scenario_name, self.name)
        self.assertGreater(info.memory_bytes, 0)
        self.assertIn(c.session_id, [x.session_id for x in s.ListSessions(pb.ListSessionsRequest()).sessions])
        # Reject sampling of motion is on unless the request turns it off; the session's info says which.
        self.assertFalse(info.sampling.no_motion_reject)
        raw = s.CreateSession(pb.CreateSessionRequest(scenario_name=self.name, seed=5,
                                                      sampling=pb.SamplingOptions(no_motion_reject=True)))
        self.assertTrue(s.GetSession(pb.GetSessionRequest(session_id=raw.session_id)).info.sampling.no_motion_reject)
        self.assertEqual(len(rollout(s, raw.session_id, raw.initial, 1)), 1)
        s.CloseSession(pb.CloseSessionRequest(session_id=raw.session_id))

        # Fork: both branches continue identically with the same inputs (RNG and cache copied).
        f = s.ForkSession(pb.ForkSessionRequest(session_id=c.session_id)).session_id
        self.assertEqual(len(f), 32)
        now = s.GetSession(pb.GetSessionRequest(session_id=c.session_id)).current
        a = rollout(s, c.session_id, now, 2)
        b = rollout(s, f, now, 2)
        self.assertEqual([t.SerializeToString() for t in a], [t.SerializeToString() for t in b])

        s.CloseSession(pb.CloseSessionRequest(session_id=c.session_id))
        s.CloseSession(pb.CloseSessionRequest(session_id=f))
        self.assertEqual(self.code(s.GetSession, pb.GetSessionRequest(session_id=f))[0], C.NOT_FOUND)

        metrics = urllib.request.urlopen(f"http://127.0.0.1:{self.server.metrics_port}/metrics", timeout=5).read()
        self.assertIn(b"scenestreamer_steps_total", metrics)
        self.assertIn(b"scenestreamer_step_seconds_bucket", metrics)

    def test_rule_modes(self):
        # MODE_LOG replays the log (the same ticks whatever the seed), MODE_IDM moves vehicles along their logged
        # paths; both refuse InjectAgent with FAILED_PRECONDITION and fork like any session.
        s = self.stub
        runs = {}
        for mode in (pb.MODE_LOG, pb.MODE_IDM):
            for seed in (1, 2):
                c = s.CreateSession(pb.CreateSessionRequest(scenario_name=self.name, seed=seed, mode=mode))
                self.assertEqual(s.GetSession(pb.GetSessionRequest(session_id=c.session_id)).info.mode, mode)
                runs[mode, seed] = [t.SerializeToString() for t in rollout(s, c.session_id, c.initial, 4)]
                code, details = self.code(s.InjectAgent, pb.InjectAgentRequest(session_id=c.session_id, count=1))
                self.assertEqual(code, C.FAILED_PRECONDITION)
                self.assertIn("inject needs a model mode", details)
                f = s.ForkSession(pb.ForkSessionRequest(session_id=c.session_id)).session_id
                now = s.GetSession(pb.GetSessionRequest(session_id=c.session_id)).current
                self.assertEqual([t.SerializeToString() for t in rollout(s, c.session_id, now, 2)],
                                 [t.SerializeToString() for t in rollout(s, f, now, 2)])
                s.CloseSession(pb.CloseSessionRequest(session_id=c.session_id))
                s.CloseSession(pb.CloseSessionRequest(session_id=f))
            self.assertEqual(runs[mode, 1], runs[mode, 2])  # deterministic: the seed does not matter
        self.assertNotEqual(runs[pb.MODE_LOG, 1], runs[pb.MODE_IDM, 1])

    def test_client_sent_scenario_and_ten_hz(self):
        record = womd_records(os.path.join(DATA, sorted(os.listdir(DATA))[0]))[0]
        c = self.stub.CreateSession(pb.CreateSessionRequest(womd_scenario=record, tick_hz=10, seed=2))
        r = self.stub.StepScene(pb.StepSceneRequest(session_id=c.session_id, num_ticks=5))
        self.assertEqual([t.tick for t in r.ticks], [1, 2, 3, 4, 5])
        self.assertEqual([t.step for t in r.ticks], [c.initial.step] * 4 + [c.initial.step + 1])
        for i, t in enumerate(r.ticks):
            self.assertAlmostEqual(t.sim_time, c.initial.sim_time + 0.1 * (i + 1))
        self.stub.CloseSession(pb.CloseSessionRequest(session_id=c.session_id))

    def test_watch_stream(self):
        c = self.stub.CreateSession(pb.CreateSessionRequest(scenario_name=self.name, seed=9))
        got = []
        stream = self.stub.WatchSession(pb.WatchSessionRequest(session_id=c.session_id), timeout=60)

        registered = threading.Event()  # the stream has its first tick: it is registered for the next ones

        def read():
            for t in stream:
                got.append(t.tick)
                registered.set()
                if t.tick >= 3:
                    stream.cancel()
                    return

        reader = threading.Thread(target=read)
        reader.start()
        self.assertTrue(registered.wait(30), "the watch stream gave no first tick")
        rollout(self.stub, c.session_id, c.initial, 3)
        reader.join(30)
        self.assertEqual(got, [0, 1, 2, 3])
        self.stub.CloseSession(pb.CloseSessionRequest(session_id=c.session_id))

    def test_multi_client_session(self):
        init = self.stub.CreateSession(pb.CreateSessionRequest(scenario_name=self.name, seed=4)).initial
        sdc = [a for a in init.agents if a.controlled][0]
        others = [a.id for a in init.agents if not a.controlled and a.type == pb.AGENT_TYPE_VEHICLE][:2]
        c = self.stub.CreateSession(pb.CreateSessionRequest(scenario_name=self.name, seed=4,
                                                            controlled_agent_ids=[sdc.id] + others,
                                                            tick_deadline_ms=400))
        controlled = [a for a in c.initial.agents if a.controlled]
        self.assertEqual(len(controlled), 3)
        results = {}

        def drive(agent, delay):
            time.sleep(delay)
            s = agent.state
            r = self.stub.StepScene(pb.StepSceneRequest(session_id=c.session_id, poses=[pb.ControlledPose(
                agent_id=agent.id, x=s.x + 0.5 * s.vx, y=s.y + 0.5 * s.vy, heading=s.heading)]))
            results[agent.id] = r.ticks[0].SerializeToString()

        threads = [threading.Thread(target=drive, args=(a, 0.1 * i)) for i, a in enumerate(controlled)]
        [t.start() for t in threads]
        [t.join(60) for t in threads]
        self.assertEqual(len(results), 3)
        self.assertEqual(len(set(results.values())), 1)  # every controller got the same tick
        # A late controller: the tick advances after the session's tick deadline without it.
        t0 = time.time()
        threads = [threading.Thread(target=drive, args=(a, 0)) for a in controlled[:2]]
        results.clear()
        [t.start() for t in threads]
        [t.join(60) for t in threads]
        self.assertEqual(len(results), 2)
        self.assertGreaterEqual(time.time() - t0, 0.35)
        self.assertEqual(self.stub.GetSession(pb.GetSessionRequest(session_id=c.session_id)).info.tick, 2)
        # A controller waiting for the others when the session is closed: FAILED_PRECONDITION.
        waiting = []

        def wait_for_others():
            try:
                drive(controlled[0], 0)
            except grpc.RpcError as e:
                waiting.append((e.code(), e.details()))

        t = threading.Thread(target=wait_for_others)
        t.start()
        time.sleep(0.15)
        self.stub.CloseSession(pb.CloseSessionRequest(session_id=c.session_id))
        t.join(30)
        self.assertEqual(waiting[0][0], C.FAILED_PRECONDITION)
        self.assertIn("closed", waiting[0][1])
        self.stub.CloseSession(pb.CloseSessionRequest(session_id=self.stub.ListSessions(
            pb.ListSessionsRequest()).sessions[0].session_id))

    def test_error_codes(self):
        s = self.stub
        c = s.CreateSession(pb.CreateSessionRequest(scenario_name=self.name))
        ego = [a for a in c.initial.agents if a.controlled][0]
        code, msg = self.code(s.StepScene, pb.StepSceneRequest(session_id=c.session_id, poses=[
            pb.ControlledPose(agent_id=ego.id, x=float("nan"), y=0, heading=0)]))
        self.assertEqual(code, C.INVALID_ARGUMENT)
        self.assertIn(f"agent {ego.id}: x is nan, not a finite number", msg)  # checked once, by the engine
        code, msg = self.code(s.StepScene, pb.StepSceneRequest(session_id=c.session_id, poses=[
            pb.ControlledPose(agent_id=ego.id, x=ego.state.x, y=ego.state.y, heading=0)] * 2))
        self.assertEqual(code, C.INVALID_ARGUMENT)
        self.assertIn("poses[1].agent_id", msg)
        self.assertIn("given twice", msg)
        # A 1 km jump, then a retry with a good pose goes through.
        code, msg = self.code(s.StepScene, pb.StepSceneRequest(session_id=c.session_id, poses=[
            pb.ControlledPose(agent_id=ego.id, x=ego.state.x + 1000, y=ego.state.y, heading=0)]))
        self.assertEqual(code, C.INVALID_ARGUMENT)
        self.assertIn("from the last one", msg)
        self.assertEqual(len(rollout(s, c.session_id, c.initial, 1)), 1)
        code, msg = self.code(s.StepScene, pb.StepSceneRequest(session_id="no-such-session"))
        self.assertEqual(code, C.NOT_FOUND)
        self.assertIn("no-such-session", msg)
        self.assertEqual(self.code(s.CreateSession, pb.CreateSessionRequest(scenario_name="nope"))[0], C.NOT_FOUND)
        code, msg = self.code(s.CreateSession, pb.CreateSessionRequest(womd_scenario=b"\x0a\x05abc"))
        self.assertEqual(code, C.INVALID_ARGUMENT)
        self.assertIn("womd_bytes", msg)
        # Larger than --max_message_mb=4: refused before it reaches the engine.
        code, _ = self.code(s.CreateSession, pb.CreateSessionRequest(womd_scenario=b"\x00" * (5 << 20)))
        self.assertEqual(code, C.RESOURCE_EXHAUSTED)
        self.assertEqual(self.code(s.CreateSession, pb.CreateSessionRequest(scenario_name=self.name,
                                                                            session_id="bad/id"))[0],
                         C.INVALID_ARGUMENT)
        self.assertEqual(self.code(s.CreateSession, pb.CreateSessionRequest(scenario_name=self.name,
                                                                            tick_hz=7))[0], C.INVALID_ARGUMENT)
        # Concurrent steps on one session: one runs, the other is ABORTED (the session stays consistent).
        codes = []

        def step():
            try:
                s.StepScene(pb.StepSceneRequest(session_id=c.session_id, num_ticks=4))
                codes.append("OK")
            except grpc.RpcError as e:
                codes.append(e.code())

        threads = [threading.Thread(target=step) for _ in range(2)]
        [t.start() for t in threads]
        [t.join(60) for t in threads]
        self.assertEqual(sorted(map(str, codes)), sorted(["OK", str(C.ABORTED)]))
        self.assertEqual(s.GetSession(pb.GetSessionRequest(session_id=c.session_id)).info.tick, 5)
        # Cap reached: --max_sessions=6 and nothing idle long enough (--evict_idle_s=1000) to evict.
        opened = [s.CreateSession(pb.CreateSessionRequest(scenario_name=self.name)).session_id
                  for _ in range(6 - len(s.ListSessions(pb.ListSessionsRequest()).sessions))]
        code, msg = self.code(s.CreateSession, pb.CreateSessionRequest(scenario_name=self.name))
        self.assertEqual(code, C.RESOURCE_EXHAUSTED)
        self.assertIn("max_sessions", msg)
        for sid in opened + [c.session_id]:
            s.CloseSession(pb.CloseSessionRequest(session_id=sid))
        self.assertEqual(self.code(s.CloseSession, pb.CloseSessionRequest(session_id=c.session_id))[0], C.NOT_FOUND)


class ScenarioLimitTest(unittest.TestCase):
    def test_client_scenario_above_the_limits(self):
        record = womd_records(os.path.join(DATA, sorted(os.listdir(DATA))[0]))[0]
        with Server("--max_scenario_tracks=10", "--idle_timeout_s=1") as srv:
            with self.assertRaises(grpc.RpcError) as e:
                srv.stub.CreateSession(pb.CreateSessionRequest(womd_scenario=record))
            self.assertEqual(e.exception.code(), C.RESOURCE_EXHAUSTED)
            self.assertIn("tracks, above the limit of 10", e.exception.details())
            # Bundled scenarios are not held to the client limits; an idle session closes after --idle_timeout_s.
            c = srv.stub.CreateSession(pb.CreateSessionRequest(scenario_name=first_scenario(srv.stub)))
            # ListSessions does not use a session (GetSession would, and keep it open).
            eventually(lambda: c.session_id not in [x.session_id for x in srv.stub.ListSessions(
                pb.ListSessionsRequest()).sessions], "the idle session closed")
            with self.assertRaises(grpc.RpcError) as e:
                srv.stub.GetSession(pb.GetSessionRequest(session_id=c.session_id))
            self.assertEqual(e.exception.code(), C.NOT_FOUND)


class SnapshotTest(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="ss-it-snap-")

    def tearDown(self):
        shutil.rmtree(self.dir, ignore_errors=True)

    def reference(self, stub, name, seed, n):
        c = stub.CreateSession(pb.CreateSessionRequest(scenario_name=name, seed=seed))
        ticks = rollout(stub, c.session_id, c.initial, n)
        stub.CloseSession(pb.CloseSessionRequest(session_id=c.session_id))
        return [t.SerializeToString() for t in ticks]

    def test_sigterm_save_and_restore_continue_identically(self):
        srv = Server(snapshot_dir=self.dir).start()
        name = first_scenario(srv.stub)
        expected = self.reference(srv.stub, name, 3, 4)
        c = srv.stub.CreateSession(pb.CreateSessionRequest(scenario_name=name, seed=3, session_id="survivor"))
        before = rollout(srv.stub, "survivor", c.initial, 2)
        self.assertEqual(srv.terminate(), 0)
        self.assertIn("saved 1 sessions", srv.output())
        srv2 = Server(snapshot_dir=self.dir).start()
        try:
            self.assertIn("restored 1 sessions", srv2.output())
            now = srv2.stub.GetSession(pb.GetSessionRequest(session_id="survivor")).current
            last = pb.Tick()
            last.CopyFrom(before[-1])
            del last.events[:]  # StepScene's ticks carry events; GetSession's do not
            self.assertEqual(now.SerializeToString(), last.SerializeToString())
            after = rollout(srv2.stub, "survivor", now, 2)
            self.assertEqual([t.SerializeToString() for t in before + after], expected)
        finally:
            self.assertEqual(srv2.terminate(), 0)

    def test_eviction_saves_and_restores_on_next_call(self):
        with Server("--max_sessions=2", "--evict_idle_s=0.5", snapshot_dir=self.dir) as srv:
            s = srv.stub
            name = first_scenario(s)
            expected = self.reference(s, name, 7, 4)
            a = s.CreateSession(pb.CreateSessionRequest(scenario_name=name, seed=7, session_id="a"))
            first = rollout(s, "a", a.initial, 2)
            s.CreateSession(pb.CreateSessionRequest(scenario_name=name, session_id="b"))
            time.sleep(1.0)
            s.CreateSession(pb.CreateSessionRequest(scenario_name=name, session_id="c"))  # evicts "a" (LRU)
            self.assertIn("session a: evicted", srv.output())
            self.assertNotIn("a", [x.session_id for x in s.ListSessions(pb.ListSessionsRequest()).sessions])
            time.sleep(1.0)
            now = s.GetSession(pb.GetSessionRequest(session_id="a")).current  # restored, evicting another
            rest = rollout(s, "a", now, 2)
            self.assertEqual([t.SerializeToString() for t in first + rest], expected)

    def test_draining_refuses_new_sessions(self):
        srv = Server().start()
        name = first_scenario(srv.stub)
        c = srv.stub.CreateSession(pb.CreateSessionRequest(scenario_name=name))
        # A long call in flight while SIGTERM arrives: it finishes; a new session is refused meanwhile.
        results = []
        t = threading.Thread(target=lambda: results.append(
            srv.stub.StepScene(pb.StepSceneRequest(session_id=c.session_id, num_ticks=30))))
        t.start()
        eventually(lambda: srv.stub.GetSession(pb.GetSessionRequest(session_id=c.session_id)).info.tick > 0,
                   "the long call computed a tick")
        srv.proc.send_signal(15)

        def refused():  # creates that come before the signal is handled succeed; the drain then refuses them
            code, details = error_of(srv.stub.CreateSession, pb.CreateSessionRequest(scenario_name=name), timeout=10)
            return details if code == C.UNAVAILABLE else None

        self.assertIn("draining", eventually(refused, "the drain began"))
        self.assertEqual(health(srv.channel), b"\x08\x02")  # NOT_SERVING
        t.join(60)
        self.assertEqual(len(results), 1)
        self.assertEqual(len(results[0].ticks), 30)
        self.assertEqual(srv.proc.wait(60), 0)
        srv.log.close()


if __name__ == "__main__":
    unittest.main(verbosity=2)
