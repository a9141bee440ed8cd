"""Client faults against the real server binary on 127.0.0.1: a client killed mid-call and mid-stream, cancelled
streams, a WatchSession consumer that stops reading, deadlines that pass during a long call and during a multi-client
tick. After each: no session leaks (they are reclaimed by --idle_timeout_s), no worker keeps computing for a client
that is gone, the server still serves steps, and its memory (VmRSS from /proc) stays flat over rounds of the same
faults."""
import os
import re
import subprocess
import sys
import textwrap
import threading
import time
import unittest
import urllib.request

import grpc

from scenestreamer.v1 import simulator_pb2 as pb
from scenestreamer.v1 import simulator_pb2_grpc as rpc
from server_process import ServerTestCase, error_of

C = grpc.StatusCode
IDLE_S = 4  # --idle_timeout_s: orphaned sessions are closed this long after their last call
ROUNDS = 5  # of the same faults, for the memory check
MAX_SPREAD_MB = 16  # RSS after rounds 2..ROUNDS: the spread allowed


def rss_mb(pid):
    with open(f"/proc/{pid}/status") as f:
        return int(re.search(r"VmRSS:\s+(\d+) kB", f.read()).group(1)) / 1024


def wait_for(predicate, timeout, what):
    deadline = time.time() + timeout
    while time.time() < deadline:
        if predicate():
            return
        time.sleep(0.1)
    raise AssertionError(f"not within {timeout} s: {what}")


class FaultsTest(ServerTestCase):
    # --malloc_trim_s=1 rather than the default 10 s, so a round's memory is given back within a second of its last
    # close (an allocator purge: server/allocator.h).
    server_flags = (f"--idle_timeout_s={IDLE_S}", "--malloc_trim_s=1")

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.name = cls.server.stub.ListScenarios(pb.ListScenariosRequest()).scenarios[0].name
        # Warm up (the map cache, the engine's buffers) so later RSS readings compare like with like.
        sid = cls.create()
        cls.server.stub.StepScene(pb.StepSceneRequest(session_id=sid, num_ticks=4))
        cls.server.stub.CloseSession(pb.CloseSessionRequest(session_id=sid))

    @classmethod
    def create(cls, **kw):
        return cls.server.stub.CreateSession(pb.CreateSessionRequest(scenario_name=cls.name, **kw)).session_id

    def metric(self, name):
        text = urllib.request.urlopen(f"http://127.0.0.1:{self.server.metrics_port}/metrics", timeout=10).read()
        values = [float(m.group(1)) for m in re.finditer(rf"^{name}(?:{{[^}}]*}})? (\S+)$", text.decode(), re.M)]
        return sum(values)

    def assert_serves_steps(self):
        """No stuck worker: a new session is created and stepped promptly."""
        t = time.time()
        sid = self.create()
        r = self.server.stub.StepScene(pb.StepSceneRequest(session_id=sid, num_ticks=2), timeout=30)
        self.assertEqual([k.tick for k in r.ticks], [1, 2])
        self.server.stub.CloseSession(pb.CloseSessionRequest(session_id=sid))
        self.assertLess(time.time() - t, 30)

    def assert_stopped_and_continues(self, sid):
        """A 1000-tick call on `sid` stopped early (cancelled, late) and left no work behind; the session is not stuck:
        it continues from where the call stopped. Closes it."""
        self.assert_no_work_left()
        tick = self.server.stub.GetSession(pb.GetSessionRequest(session_id=sid)).info.tick
        self.assertLess(tick, 1000)
        r = self.server.stub.StepScene(pb.StepSceneRequest(session_id=sid), timeout=30)
        self.assertEqual(r.ticks[0].tick, tick + 1)
        self.server.stub.CloseSession(pb.CloseSessionRequest(session_id=sid))

    def assert_no_work_left(self):
        """Nothing computes for a client that is gone: after at most the tick in progress (and one the dying call may
        have started at that moment), the step counter stands still for 1.5 s."""
        first = prev = self.metric("scenestreamer_steps_total")
        for _ in range(4):
            time.sleep(1.5)
            now = self.metric("scenestreamer_steps_total")
            if now == prev:
                self.assertLessEqual(now - first, 2, "ticks computed after the client was gone")
                return
            prev = now
        self.fail(f"ticks still being computed: {prev - first:.0f} more in 6 s")

    def kill_a_client_mid_call(self, prefix, ticks_before_kill=3):
        """A separate process creates two sessions, watches one, starts a 1000-tick call on the other, and is killed
        with SIGKILL in the middle: its connection drops without a goodbye. Returns the two session ids."""
        ids = (f"{prefix}-a", f"{prefix}-b")
        child = textwrap.dedent(f"""
            import threading, grpc
            from scenestreamer.v1 import simulator_pb2 as pb, simulator_pb2_grpc as rpc
            stub = rpc.SimulatorStub(grpc.insecure_channel("{self.server.target}"))
            for sid in {ids!r}:
                stub.CreateSession(pb.CreateSessionRequest(scenario_name="{self.name}", session_id=sid))
            watch = stub.WatchSession(pb.WatchSessionRequest(session_id="{ids[1]}"))
            threading.Thread(target=lambda: [t for t in watch], daemon=True).start()
            print("ready", flush=True)
            stub.StepScene(pb.StepSceneRequest(session_id="{ids[1]}", num_ticks=1000))
        """)
        p = subprocess.Popen([sys.executable, "-c", child], stdout=subprocess.PIPE, env=os.environ)
        try:
            self.assertEqual(p.stdout.readline().strip(), b"ready")
            wait_for(lambda: self.server.stub.GetSession(pb.GetSessionRequest(session_id=ids[1])).info.tick >=
                     ticks_before_kill, 60, "the child's long call to start")
        finally:
            p.kill()
            p.wait()
            p.stdout.close()
        return ids

    def test_a_client_killed_mid_call_and_mid_stream(self):
        sessions_before = self.metric("scenestreamer_sessions")
        ids = self.kill_a_client_mid_call("orphan")
        # The long call stops at its next tick, the watch stream is dropped.
        wait_for(lambda: self.metric("scenestreamer_watchers") == 0, 10, "the dead client's watch stream to go")
        self.assert_no_work_left()
        tick = self.server.stub.GetSession(pb.GetSessionRequest(session_id=ids[1])).info.tick
        self.assertLess(tick, 1000, "the dead client's call ran to its end")
        self.assert_serves_steps()
        # Its sessions are reclaimed by the idle rule, not kept for ever.
        wait_for(lambda: self.metric("scenestreamer_sessions") <= sessions_before, IDLE_S + 10,
                 "the dead client's sessions to be closed by --idle_timeout_s")
        for sid in ids:
            code, _ = error_of(self.server.stub.GetSession, pb.GetSessionRequest(session_id=sid))
            self.assertEqual(code, C.NOT_FOUND)

    def test_repeated_faults_leave_memory_flat(self):
        # Flat memory: the same faults (a client killed mid-call and mid-stream, a deadline passing in a long call,
        # 20 cancelled streams) ROUNDS times over, every session closed after each and the server's malloc_trim done
        # (--malloc_trim_s): the server's RSS after rounds 2..ROUNDS stays within MAX_SPREAD_MB of each other, and
        # the malloc figures show nothing kept in use. Before the fix (glibc's 16 arenas, no trim) RSS rose round by
        # round with the bytes in use flat: 128, 186, 192 MB after 3 rounds alone, 323, 329, 369 MB in a full
        # ctest -j2. After it: 53, 53, 53, 53, 53 MB alone; 33, 34, 33, 34, 34 and 40, 41, 38, 37, 43 MB in two
        # ctest -j2 runs beside server_test and cluster_test (load average 3-4.5); 9 MB in use after every round in
        # all three. Hence a 16 MB spread, 0, 1 and 6 MB measured. Round 1 is
        # left out: it is the first with these faults (a child process's channel, 20 streams at once).
        rss, in_use = [], []
        for round_ in range(ROUNDS):
            ids = self.kill_a_client_mid_call(f"round{round_}")
            sid = self.create()
            error_of(self.server.stub.StepScene, pb.StepSceneRequest(session_id=sid, num_ticks=1000), timeout=1.0)
            streams = [self.server.stub.WatchSession(pb.WatchSessionRequest(session_id=sid), timeout=60)
                       for _ in range(20)]
            for st in streams:
                next(st)
                st.cancel()
            wait_for(lambda: self.metric("scenestreamer_watchers") == 0, 10, "the streams to go")
            self.assert_no_work_left()
            for s in (*ids, sid):  # the dead client's may be closed already by --idle_timeout_s
                self.assertIn(error_of(self.server.stub.CloseSession, pb.CloseSessionRequest(session_id=s))[0],
                              (None, C.NOT_FOUND))
            trims = self.metric("scenestreamer_malloc_trims_total")
            wait_for(lambda: self.metric("scenestreamer_malloc_trims_total") > trims, 10,
                     "the server's malloc_trim after the sessions closed")
            rss.append(rss_mb(self.server.proc.pid))
            in_use.append(self.metric("scenestreamer_malloc_in_use_bytes") / 2**20)
        print(f"\nserver RSS after each round of faults: {', '.join(f'{r:.0f}' for r in rss)} MB; malloc in use "
              f"{', '.join(f'{m:.0f}' for m in in_use)} MB", file=sys.stderr)
        self.assertLess(max(rss[1:]) - min(rss[1:]), MAX_SPREAD_MB, f"RSS grew over rounds of the same faults: {rss}")
        self.assertLess(max(in_use) - min(in_use), 8, f"bytes in use grew over rounds of the same faults: {in_use}")

    def test_cancelled_streams_and_calls_free_their_places(self):
        sid = self.create()
        streams = [self.server.stub.WatchSession(pb.WatchSessionRequest(session_id=sid), timeout=60)
                   for _ in range(20)]
        for s in streams:
            self.assertEqual(next(s).tick, 0)
        self.assertEqual(self.metric("scenestreamer_watchers"), 20)
        for s in streams:
            s.cancel()
        wait_for(lambda: self.metric("scenestreamer_watchers") == 0, 10, "cancelled streams to be dropped")
        # A long call cancelled by its client stops between ticks.
        fut = self.server.stub.StepScene.future(pb.StepSceneRequest(session_id=sid, num_ticks=1000))
        wait_for(lambda: self.server.stub.GetSession(pb.GetSessionRequest(session_id=sid)).info.tick >= 2, 60,
                 "the long call to start")
        fut.cancel()
        self.assert_stopped_and_continues(sid)

    def test_a_watcher_that_stops_reading_neither_holds_up_the_session_nor_grows(self):
        sid = self.create()
        # No BDP probing: the receive window stays at its 64 KiB, so the server soon has to hold what it cannot send.
        channel = grpc.insecure_channel(self.server.target, options=[("grpc.http2.bdp_probe", 0)])
        slow = rpc.SimulatorStub(channel).WatchSession(pb.WatchSessionRequest(session_id=sid), timeout=120)
        self.assertEqual(next(slow).tick, 0)
        time.sleep(1.5)  # the malloc_trim that earlier tests' closes are due (--malloc_trim_s=1) happens before, not in
        rss_before = rss_mb(self.server.proc.pid)
        cache_before = self.metric("scenestreamer_cache_bytes")
        # 150 ticks while the watcher reads nothing: the session is not slowed by it (the steps all return).
        t = time.time()
        for _ in range(2):
            self.server.stub.StepScene(pb.StepSceneRequest(session_id=sid, num_ticks=75), timeout=120)
        elapsed = time.time() - t
        # What the server holds beyond the session's own growth (its KV cache grows with every tick).
        session_growth = (self.metric("scenestreamer_cache_bytes") - cache_before) / 2**20
        growth = rss_mb(self.server.proc.pid) - rss_before - session_growth
        # Now it reads: it gets the newest tick, having lost older ones (at most 64 wait for a slow watcher, plus
        # what the transport's windows hold), not all 150.
        got = []
        for tick in slow:
            got.append(tick.tick)
            if tick.tick == 150:
                break
        slow.cancel()
        channel.close()
        print(f"\nslow watcher: 150 ticks in {elapsed:.1f} s, received {len(got)} of them; server RSS grew "
              f"{growth + session_growth:.1f} MB, {session_growth:.1f} MB of it the session's own", file=sys.stderr)
        self.assertEqual(got[-1], 150)
        self.assertEqual(got, sorted(got))
        self.assertLess(len(got), 120, "a watcher that does not read was sent every tick")
        self.assertLess(growth, 64)
        wait_for(lambda: self.metric("scenestreamer_watchers") == 0, 10, "the slow stream to be dropped")
        self.server.stub.CloseSession(pb.CloseSessionRequest(session_id=sid))

    def test_a_deadline_that_passes_mid_call_stops_the_work(self):
        sid = self.create()
        # A quarter of a second: the 1000 ticks (the most a call may ask for) take about 1.0 s on a Zen 5 core with
        # this random model, whose scene soon holds one agent, so a 1 s deadline would sometimes be met.
        code, msg = error_of(self.server.stub.StepScene, pb.StepSceneRequest(session_id=sid, num_ticks=1000),
                             timeout=0.25)
        self.assertEqual(code, C.DEADLINE_EXCEEDED)
        # The server's copy of the deadline is its receipt of the call plus the timeout the client sent, so it passes
        # a little after the client's: by the time the request took to be read, several ms when the cores are busy
        # (make test runs two tests at once). With ticks of a few ms, the server may start a few ticks in that gap.
        # The test is that the work stops at the server's deadline, so it starts counting once that has passed.
        time.sleep(0.1)
        self.assert_stopped_and_continues(sid)

    def test_a_deadline_that_passes_waiting_for_other_controllers(self):
        probe = self.server.stub.CreateSession(pb.CreateSessionRequest(scenario_name=self.name))
        two = [a.id for a in probe.initial.agents if a.type == pb.AGENT_TYPE_VEHICLE][:2]
        self.server.stub.CloseSession(pb.CloseSessionRequest(session_id=probe.session_id))
        c = self.server.stub.CreateSession(pb.CreateSessionRequest(scenario_name=self.name, controlled_agent_ids=two,
                                                                   tick_deadline_ms=60000))
        sid = c.session_id
        poses = {a.id: pb.ControlledPose(agent_id=a.id, x=a.state.x + 0.5 * a.state.vx,
                                         y=a.state.y + 0.5 * a.state.vy, heading=a.state.heading)
                 for a in c.initial.agents if a.id in two}
        # The other controller never comes: the call's own deadline ends the wait, and its pose is withdrawn.
        code, _ = error_of(self.server.stub.StepScene, pb.StepSceneRequest(session_id=sid, poses=[poses[two[0]]]),
                           timeout=1.0)
        self.assertEqual(code, C.DEADLINE_EXCEEDED)
        time.sleep(0.5)
        out = {}

        def send(aid):
            out[aid] = self.server.stub.StepScene(pb.StepSceneRequest(session_id=sid, poses=[poses[aid]]), timeout=60)

        threads = [threading.Thread(target=send, args=(aid,)) for aid in two]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        self.assertEqual([out[a].ticks[0].tick for a in two], [1, 1])
        self.server.stub.CloseSession(pb.CloseSessionRequest(session_id=sid))
        self.assert_serves_steps()

    def test_a_create_whose_client_gave_up_is_reclaimed(self):
        sessions_before = self.metric("scenestreamer_sessions")
        for i in range(5):
            code, _ = error_of(self.server.stub.CreateSession,
                               pb.CreateSessionRequest(scenario_name=self.name, session_id=f"gave-up-{i}"),
                               timeout=0.005)
            self.assertIn(code, (C.DEADLINE_EXCEEDED, None))
        wait_for(lambda: self.metric("scenestreamer_sessions") <= sessions_before, IDLE_S + 10,
                 "sessions created for clients that gave up to be closed by --idle_timeout_s")
        self.assert_serves_steps()


if __name__ == "__main__":
    unittest.main(verbosity=2)
