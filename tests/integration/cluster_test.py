"""Three real replicas behind nginx with deploy/router/nginx.conf, all on loopback: every call of a session reaches
the replica that holds it, a replica killed with SIGKILL takes only its own sessions, and a replica stopped with
SIGTERM drains, saves, restarts, and its sessions continue through the router as a fork taken before does."""
import json
import os
import subprocess
import threading
import time
import unittest

import grpc

from cluster import Cluster, routed
from scenestreamer.v1 import simulator_pb2 as pb
from scenestreamer.v1 import simulator_pb2_grpc as rpc
from server_process import ego_pose

C = grpc.StatusCode
SESSIONS, STEPS = 48, 5


def create(stub, name, sid, seed):
    return stub.CreateSession(pb.CreateSessionRequest(scenario_name=name, seed=seed, session_id=sid),
                              metadata=routed(sid), timeout=120)


def step(stub, sid, tick, route=None):
    """One step with the ego keeping its heading and speed; `route` is the x-session-id (the session's own by
    default; a fork's calls carry its source's, since a fork lives on its source's replica)."""
    pose = ego_pose(tick)
    r = stub.StepScene(pb.StepSceneRequest(session_id=sid, poses=[pose] if pose else []),
                       metadata=routed(route or sid), timeout=120)
    return r.ticks[-1]


class ClusterTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        # Two compute threads each (Server's default), as three replicas on one host would run by default.
        cls.cluster = Cluster(3).start()
        cls.stub = cls.cluster.stub
        cls.name = cls.stub.ListScenarios(pb.ListScenariosRequest(), timeout=30).scenarios[0].name

    @classmethod
    def tearDownClass(cls):
        cls.cluster.stop()

    def sessions_on(self, replica, prefix):
        """Sessions whose id starts with `prefix`, created and stepped once through the router until `replica`
        holds at least one of them; returns ({id: tick}, {id: replica})."""
        ticks, where = {}, {}
        for i in range(64):
            sid = f"{prefix}-{i}"
            ticks[sid] = step(self.stub, sid, create(self.stub, self.name, sid, i).initial)
            held = self.cluster.holder(sid)
            self.assertEqual(len(held), 1, f"{sid} is held by replicas {held}")
            where[sid] = held[0]
            if i >= 8 and replica in where.values():
                break
        self.assertIn(replica, where.values(), "64 random ids never hashed to one replica")
        return ticks, where

    def test_0_haproxy_routes_by_session_too(self):
        # deploy/router/haproxy.cfg, the same rule for HAProxy users: each routed session lives on one replica and
        # all its calls reach it.
        proc, target = self.cluster.start_haproxy()
        try:
            channel = grpc.insecure_channel(target)
            stub = rpc.SimulatorStub(channel)
            deadline = time.time() + 30
            while True:
                try:
                    stub.ListScenarios(pb.ListScenariosRequest(), timeout=5)
                    break
                except grpc.RpcError:
                    self.assertLess(time.time(), deadline, "haproxy did not start")
                    time.sleep(0.2)
            r = subprocess.run([os.environ["SS_LOAD"], "--clients", "12", "--steps", "2", "--target", target,
                                "--scenario", self.name, "--route", "--json"], capture_output=True, text=True,
                               timeout=600)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            self.assertEqual(json.loads(r.stdout)["errors"], 0)
            sid = "haproxy-kept"
            tick = step(stub, sid, create(stub, self.name, sid, 1).initial)
            for _ in range(2):
                tick = step(stub, sid, tick)
            self.assertEqual(tick.tick, 3)
            self.assertEqual(len(self.cluster.holder(sid)), 1)
            stub.CloseSession(pb.CloseSessionRequest(session_id=sid), metadata=routed(sid), timeout=60)
            channel.close()
        finally:
            proc.terminate()
            proc.wait(30)

    def test_1_load_through_router_one_replica_per_session(self):
        load = os.environ["SS_LOAD"]
        before = [self.cluster.metrics(i) for i in range(3)]
        r = subprocess.run([load, "--clients", str(SESSIONS), "--steps", str(STEPS), "--target", self.cluster.target,
                            "--scenario", self.name, "--route", "--json"], capture_output=True, text=True, timeout=600)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr + self.cluster.router_output())
        routed_run = json.loads(r.stdout)
        self.assertEqual((routed_run["errors"], len(set(routed_run["session_ids"]))), (0, SESSIONS))
        # Per replica: sessions created there, and every one of their steps and closes served there too (a call that
        # reached another replica would have been refused with NOT_FOUND and counted as rejected).
        created = []
        for i in range(3):
            after = self.cluster.metrics(i)
            delta = {k: after.get(k, 0) - before[i].get(k, 0) for k in after}
            n = delta.get('scenestreamer_calls_total{method="CreateSession"}', 0)
            created.append(n)
            self.assertEqual(delta.get('scenestreamer_calls_total{method="StepScene"}', 0), n * STEPS, f"replica {i}")
            self.assertEqual(delta.get('scenestreamer_calls_total{method="CloseSession"}', 0), n, f"replica {i}")
            self.assertFalse({k: v for k, v in delta.items() if k.startswith("scenestreamer_rejected") and v},
                             f"replica {i}")
        self.assertEqual(sum(created), SESSIONS)
        self.assertTrue(all(created), f"sessions per replica {created}: the hash left a replica out")
        # The same load on one replica directly (the others idle), for the figures only: two timed runs on a shared
        # 2-core VM are not a pass/fail check (a 0.73x ratio failed CI once), so the router's cost is printed, not
        # asserted.
        r = subprocess.run([load, "--clients", str(SESSIONS), "--steps", str(STEPS), "--target",
                            self.cluster.servers[0].target, "--scenario", self.name, "--json"],
                           capture_output=True, text=True, timeout=600)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        alone = json.loads(r.stdout)
        print(f"\n{SESSIONS} sessions x {STEPS} steps: 3 replicas through nginx {routed_run['steps_per_second']:.1f} "
              f"steps/s (p50 {routed_run['latency_ms_p50']:.1f} ms, p99 {routed_run['latency_ms_p99']:.1f} ms, "
              f"sessions per replica {[int(n) for n in created]}); one replica direct {alone['steps_per_second']:.1f} "
              f"steps/s (p50 {alone['latency_ms_p50']:.1f} ms, p99 {alone['latency_ms_p99']:.1f} ms)", flush=True)
        self.assertEqual(alone["errors"], 0)

    def test_2_sigterm_drains_saves_restarts_and_sessions_continue(self):
        victim = 1
        ticks, where = self.sessions_on(victim, "term")
        mine = [s for s in ticks if where[s] == victim]
        others = [s for s in ticks if where[s] != victim]
        # A fork of each of the victim's sessions, taken now and rolled 3 steps ahead before anything happens: what
        # the sessions must do after the restart. The fork lives on its source's replica, so its calls carry the
        # source's id.
        expected = {}
        for sid in mine:
            fork = self.stub.ForkSession(pb.ForkSessionRequest(session_id=sid, new_session_id=f"{sid}-fork"),
                                         metadata=routed(sid), timeout=120).session_id
            t, out = ticks[sid], []
            for _ in range(3):
                t = step(self.stub, fork, t, route=sid)
                out.append(t.SerializeToString())
            expected[sid] = out
            self.stub.CloseSession(pb.CloseSessionRequest(session_id=fork), metadata=routed(sid), timeout=60)
        # The other sessions keep stepping through the router while the victim drains and restarts: none loses a step.
        stop, failures = threading.Event(), []

        def drive(sid):
            t = ticks[sid]
            while not stop.is_set():
                try:
                    n = step(self.stub, sid, t)
                except grpc.RpcError as e:
                    failures.append(f"{sid}: {e.code()} {e.details()}")
                    return
                if n.tick != t.tick + 1:
                    failures.append(f"{sid}: tick {t.tick} -> {n.tick}")
                t = n
            ticks[sid] = t

        drivers = [threading.Thread(target=drive, args=(s,)) for s in others]
        for d in drivers:
            d.start()
        server = self.cluster.servers[victim]
        self.assertEqual(server.terminate(), 0)
        self.assertIn(f"saved {len(mine)} sessions", server.output())
        server.start()
        self.assertIn(f"restored {len(mine)} sessions", server.output())
        time.sleep(1.0)
        stop.set()
        for d in drivers:
            d.join(120)
        self.assertEqual(failures, [])
        for sid in mine:
            t, out = ticks[sid], []
            for _ in range(3):
                t = step(self.stub, sid, t)
                out.append(t.SerializeToString())
            self.assertEqual(out, expected[sid], f"session {sid} after the restart differs from its fork")
        self.assertEqual({s: self.cluster.holder(s) for s in ticks}, {s: [where[s]] for s in ticks})
        for sid in ticks:
            self.stub.CloseSession(pb.CloseSessionRequest(session_id=sid), metadata=routed(sid), timeout=60)

    def test_3_kill9_loses_only_that_replicas_sessions(self):
        victim = 2
        ticks, where = self.sessions_on(victim, "kill")
        lost = {s for s in ticks if where[s] == victim}
        results, progress = {}, {s: 0 for s in ticks}
        killed = threading.Event()

        def drive(sid):
            # Steps until the kill (so calls are in flight when it happens), then 4 more.
            t, n, after = ticks[sid], 0, None
            while after is None or n < after + 4:
                if after is None and killed.is_set():
                    after = n
                try:
                    nxt = step(self.stub, sid, t)
                except grpc.RpcError as e:
                    results[sid] = (e.code(), e.details(), n)
                    return
                if nxt.tick != t.tick + 1:
                    results[sid] = ("skipped", f"tick {t.tick} -> {nxt.tick}", n)
                    return
                t, n = nxt, n + 1
                progress[sid] = n
            results[sid] = ("ok", "", n)

        drivers = [threading.Thread(target=drive, args=(s,)) for s in ticks]
        for d in drivers:
            d.start()
        deadline = time.time() + 300
        while min(progress.values()) < 2 and not results and time.time() < deadline:
            time.sleep(0.05)
        self.assertEqual(results, {}, "a session failed before the kill")
        self.cluster.servers[victim].proc.kill()
        self.cluster.servers[victim].proc.wait(30)
        killed.set()
        for d in drivers:
            d.join(300)
        for sid in ticks:
            code, details, n = results[sid]
            if sid in lost:
                # A call in flight at the kill: the router says the session's replica is gone (UNAVAILABLE). A later
                # call reaches another replica (nginx leaves the dead one out), which does not know the session.
                self.assertIn(code, (C.UNAVAILABLE, C.NOT_FOUND), f"{sid}: {code} {details}")
                if code == C.NOT_FOUND:
                    self.assertIn(f"'{sid}' is not an open session", details)
                else:
                    self.assertIn(f"session '{sid}': the replica holding it did not answer", details)
                    self.assertIn("the session is gone", details)
                self.assertGreaterEqual(n, 2)
            else:
                self.assertEqual(code, "ok", f"{sid}: {details}")
                self.assertGreaterEqual(n, 6)
        print(f"\nkill -9 of replica {victim}: its {len(lost)} sessions failed with "
              f"{sorted({str(results[s][0]) for s in lost})}; the other {len(ticks) - len(lost)} made every step",
              flush=True)


if __name__ == "__main__":
    unittest.main(verbosity=2)
