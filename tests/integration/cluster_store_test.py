"""Replicas sharing a real redis-server as their session store, behind nginx with deploy/router/nginx.conf, all on
loopback, under load: 48 sessions stepping back to back through the router, each client retrying UNAVAILABLE.

- kill -9 of one of 3 replicas: every session continues (its calls go to the next replica on the ring, which takes the
  lease once it runs out and restores the session from the store), none restarts from scratch, and each loses at most
  the ticks of one snapshot interval.
- 3 -> 4 -> 2 replicas, the router's list rewritten and reloaded each time (the two removed replicas then stopped with
  SIGTERM): no session lost, no tick lost (a moved session is handed over, not restored from an old snapshot), and no
  error but a retried UNAVAILABLE; about 1/4 of the sessions move to the added replica.
- The same with HAProxy (deploy/router/haproxy.cfg, reloaded through its master) and 16 sessions: 3 -> 4 -> 3.

SS_CLUSTER_STEP_PAUSE_S (default 0: back to back) pauses each client between its steps. Back to back, the kill -9
promise needs background snapshots of busy sessions (issue 50's first defect: the periodic snapshot skips a session
whose lock a call holds); with a pause of 2 s it holds without them."""
import collections
import os
import re
import threading
import time
import unittest

import grpc

from cluster import HAProxyRouter, StoreCluster, routed
from scenestreamer.v1 import simulator_pb2 as pb
from server_process import ego_pose

C = grpc.StatusCode
SESSIONS = 48
INTERVAL_S = 1.0
LEASE_MS = 2000
FLAGS = (f"--snapshot_interval_s={INTERVAL_S}", f"--lease_ms={LEASE_MS}", "--max_sessions=64")
PAUSE_S = float(os.environ.get("SS_CLUSTER_STEP_PAUSE_S", "0"))


class Load:
    """SESSIONS sessions, each created and stepped back to back through the router by a thread of its own. Every
    acknowledged tick is kept with its time; a tick that does not follow the one before is a jump; UNAVAILABLE is
    retried (and counted by message), any other error is kept."""

    def __init__(self, stub, scenario, prefix, sessions=SESSIONS):
        self.stub, self.scenario = stub, scenario
        self.ids = [f"{prefix}-{i}" for i in range(sessions)]
        self.acks = {sid: [] for sid in self.ids}  # [(time, tick)]
        self.jumps = {sid: [] for sid in self.ids}  # [(time, acknowledged tick before, tick returned)]
        self.retried = collections.Counter()
        self.errors = []
        self.stopping = threading.Event()
        self.threads = [threading.Thread(target=self.drive, args=(sid, i)) for i, sid in enumerate(self.ids)]

    def call(self, fn, sid):
        while not self.stopping.is_set():
            try:
                return fn()
            except grpc.RpcError as e:
                if e.code() == C.UNAVAILABLE:
                    self.retried[re.sub(r"session '[^']*'", "session S", e.details())[:90]] += 1
                    time.sleep(0.05)
                    continue
                self.errors.append((sid, e.code(), e.details()))
                time.sleep(0.2)
        return None

    def drive(self, sid, seed):
        r = self.call(lambda: self.stub.CreateSession(pb.CreateSessionRequest(
            scenario_name=self.scenario, seed=seed, session_id=sid), metadata=routed(sid), timeout=120), sid)
        if r is None:
            return
        last = r.initial
        self.acks[sid].append((time.time(), last.tick))
        while not self.stopping.is_set():
            pose = ego_pose(last)
            req = pb.StepSceneRequest(session_id=sid, poses=[pose] if pose else [])
            r = self.call(lambda: self.stub.StepScene(req, metadata=routed(sid), timeout=120), sid)
            if r is None:
                return
            t = r.ticks[-1]
            if t.tick != last.tick + 1:
                self.jumps[sid].append((time.time(), last.tick, t.tick))
            self.acks[sid].append((time.time(), t.tick))
            last = t
            if PAUSE_S:
                time.sleep(PAUSE_S)

    def start(self):
        for t in self.threads:
            t.start()
        return self

    def steps_since(self, when):
        return {sid: sum(1 for t, _ in a if t > when) for sid, a in self.acks.items()}

    def wait_steps(self, when, n, timeout):
        """Until every session acknowledged `n` ticks after `when` (or `timeout` s passed)."""
        deadline = time.time() + timeout
        while time.time() < deadline and min(self.steps_since(when).values()) < n:
            time.sleep(0.1)
        return min(self.steps_since(when).values())

    def stop(self):
        self.stopping.set()
        for t in self.threads:
            t.join(180)

    def close_all(self, stub):
        for sid in self.ids:
            stub.CloseSession(pb.CloseSessionRequest(session_id=sid), metadata=routed(sid), timeout=120)


class ClusterStoreTest(unittest.TestCase):
    def setUp(self):
        self.cluster = StoreCluster(3, FLAGS).start()
        self.scenario = self.cluster.stub.ListScenarios(pb.ListScenariosRequest(), timeout=30).scenarios[0].name

    def tearDown(self):
        self.cluster.stop()

    def test_kill9_every_session_continues_losing_at_most_one_interval(self):
        load = Load(self.cluster.stub, self.scenario, "kill").start()
        try:
            start = time.time()
            self.assertGreaterEqual(load.wait_steps(start, 4, 180), 4, "the load did not get going")
            time.sleep(2 * INTERVAL_S)
            before = self.cluster.holders()
            victim = "r1"
            mine = sorted(s for s in load.ids if before.get(s) == [victim])
            self.assertTrue(mine, f"no session on {victim}: {before}")
            killed_at = time.time()
            self.cluster.servers[victim].kill()
            after_kill = load.wait_steps(killed_at, 3, 180)
        finally:
            load.stop()
        self.assertEqual(load.errors, [], "errors other than UNAVAILABLE")
        self.assertGreaterEqual(after_kill, 3, f"sessions stalled after the kill: {load.steps_since(killed_at)}")
        # Every figure first, then the checks, so that a failing run still prints what it measured.
        lost, ages, per_interval, from_scratch, wrong = {}, {}, {}, [], []
        for sid in load.ids:
            acks, jumps = load.acks[sid], load.jumps[sid]
            if sid not in mine:
                if jumps:
                    wrong.append(f"{sid} was not on the killed replica, yet its ticks jumped: {jumps}")
                continue
            per_interval[sid] = sum(1 for t, _ in acks if killed_at - INTERVAL_S < t <= killed_at)
            if len(jumps) > 1:
                wrong.append(f"{sid} jumped more than once: {jumps}")
            if not jumps:  # its last snapshot held its last tick (it was idle since): nothing lost
                lost[sid], ages[sid] = 0, 0.0
                continue
            _, acked, returned = jumps[0]
            restored = returned - 1  # the state the next replica took over: the store's snapshot
            if restored <= 0:
                from_scratch.append(f"{sid} (acknowledged tick {acked})")
            # The promise: every tick lost was acknowledged within one interval before the kill (the oldest lost
            # tick's age). A tick computed and saved whose answer the kill cut off is restored too: the session is
            # then one ahead of its client, and nothing is lost.
            lost_at = [t for t, k in acks if restored < k <= acked and t <= killed_at]
            lost[sid] = max(0, acked - restored)
            ages[sid] = killed_at - min(lost_at) if lost_at else 0.0
        # One interval, plus the time a pass takes to save the replica's sessions (the reaper looks every 0.1 s).
        slack = 0.5
        late = {s: round(a, 2) for s, a in ages.items() if a > INTERVAL_S + slack}
        print(f"\nkill -9 of {victim} ({len(mine)} of {SESSIONS} sessions, client pause {PAUSE_S:g} s): every session "
              f"continued; ticks lost per session {sorted(lost.values())} (ticks made per session in the "
              f"{INTERVAL_S:g} s interval before the kill: {sorted(per_interval.values())}); oldest lost tick "
              f"acknowledged {max(ages.values()):.2f} s before the kill; restarted from tick 0: {len(from_scratch)}; "
              f"UNAVAILABLE retried {sum(load.retried.values())} times: {dict(load.retried)}", flush=True)
        self.assertEqual(wrong, [])
        self.assertEqual(from_scratch, [], "sessions restarted from scratch")
        self.assertEqual(late, {}, f"lost ticks acknowledged more than {INTERVAL_S + slack:g} s before the kill")
        load.close_all(self.cluster.stub)
        self.assertEqual(self.cluster.redis.keys("ss:*"), [], "closed sessions left keys in the store")

    def test_scale_3_4_2_loses_nothing_and_moves_about_a_quarter(self):
        load = Load(self.cluster.stub, self.scenario, "scale").start()
        try:
            start = time.time()
            self.assertGreaterEqual(load.wait_steps(start, 4, 180), 4, "the load did not get going")
            h3 = self.cluster.holders()
            added = self.cluster.new_replica()
            grown_at = time.time()
            self.cluster.reload_router(["r0", "r1", "r2", added])
            self.assertGreaterEqual(load.wait_steps(grown_at, 4, 180), 4, "sessions stalled after the scale-up")
            h4 = self.cluster.holders()
            self.cluster.reload_router(["r0", "r1"])
            for name in ("r2", added):
                self.assertEqual(self.cluster.servers[name].terminate(), 0, name)
            self.assertGreaterEqual(load.wait_steps(time.time(), 4, 180), 4, "sessions stalled after the scale-down")
            h2 = self.cluster.holders()
        finally:
            load.stop()
        self.assertEqual(load.errors, [], "errors other than UNAVAILABLE")
        self.assertEqual({s: j for s, j in load.jumps.items() if j}, {}, "ticks lost or repeated")
        for h, n in ((h3, 3), (h4, 4), (h2, 2)):
            self.assertEqual(sorted(h), sorted(load.ids), f"{n} replicas: sessions missing")
            self.assertTrue(all(len(v) == 1 for v in h.values()), f"{n} replicas: a session held twice: {h}")
        moved_up = sorted(s for s in load.ids if h4[s] != h3[s])
        moved_down = sorted(s for s in load.ids if h2[s] != h4[s])
        self.assertTrue(all(h4[s] == [added] for s in moved_up), "the scale-up moved sessions between old replicas")
        self.assertTrue(all(h4[s][0] in ("r2", added) for s in moved_down), "the scale-down moved kept replicas' ones")
        self.assertTrue(all(h2[s][0] in ("r0", "r1") for s in load.ids))
        print(f"\n3 -> 4 -> 2 replicas under {SESSIONS} sessions: {len(moved_up)} moved to the added replica "
              f"(1/4 would be {SESSIONS / 4:g}); {len(moved_down)} moved off the 2 removed; 0 sessions lost, 0 ticks "
              f"lost, 0 errors; UNAVAILABLE retried {sum(load.retried.values())} times: {dict(load.retried)}; steps "
              f"{sum(len(a) for a in load.acks.values())} in {time.time() - start:.0f} s", flush=True)
        self.assertGreaterEqual(len(moved_up), SESSIONS // 12)
        self.assertLessEqual(len(moved_up), SESSIONS // 2)
        load.close_all(self.cluster.stub)


    def test_haproxy_reload_adds_and_removes_a_replica(self):
        router = HAProxyRouter(self.cluster, ["r0", "r1", "r2"])
        load = Load(router.stub, self.scenario, "hap", sessions=16).start()
        try:
            self.assertGreaterEqual(load.wait_steps(time.time(), 3, 180), 3, "the load did not get going")
            h3 = self.cluster.holders()
            added = self.cluster.new_replica()
            router.reload(["r0", "r1", "r2", added])
            self.assertGreaterEqual(load.wait_steps(time.time(), 4, 180), 4, "sessions stalled after the scale-up")
            h4 = self.cluster.holders()
            router.reload(["r0", "r1", "r2"])
            self.assertEqual(self.cluster.servers[added].terminate(), 0)
            self.assertGreaterEqual(load.wait_steps(time.time(), 4, 180), 4, "sessions stalled after the scale-down")
            h3b = self.cluster.holders()
        finally:
            load.stop()
            router.stop()
        self.assertEqual(load.errors, [], "errors other than UNAVAILABLE")
        self.assertEqual({s: j for s, j in load.jumps.items() if j}, {}, "ticks lost or repeated")
        hap = {s for s in load.ids}
        for h in (h3, h4, h3b):
            self.assertEqual({s: v for s, v in h.items() if s in hap and len(v) != 1}, {})
            self.assertEqual(hap - set(h), set(), "sessions missing")
        moved = sorted(s for s in load.ids if h4[s] != h3[s])
        self.assertTrue(all(h4[s] == [added] for s in moved), "the scale-up moved sessions between old replicas")
        self.assertTrue(all(h3b[s] == h3[s] for s in load.ids), "the scale-down did not bring them back")
        print(f"\nHAProxy 3 -> 4 -> 3 under 16 sessions: {len(moved)} moved to the added replica and back; 0 lost, "
              f"0 ticks lost, 0 errors; UNAVAILABLE retried {sum(load.retried.values())} times: {dict(load.retried)}",
              flush=True)
        self.assertGreaterEqual(len(moved), 1)
        load.close_all(self.cluster.stub)


if __name__ == "__main__":
    unittest.main(verbosity=2)
