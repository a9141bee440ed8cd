"""The shared session store with a real redis-server on loopback and two real replicas pointed at it, called directly
(no router): a session moves to whichever replica gets its call and continues exactly (the same ticks as a fork rolled
ahead before the move), ids are unique over the store, a close on any replica closes it everywhere, another tenant's
call neither finds nor moves it, a SIGTERM hands every session over at once, a replica stopped past its lease is
refused with "lease lost" naming the replica that took the session, and bad store flags or an unreachable store stop
the server at start with a message naming what is wrong; a store gone mid-run refuses calls once their lease is too
old to trust."""
import os
import signal
import subprocess
import time
import unittest

import grpc

from redis_process import Redis
from scenestreamer.v1 import simulator_pb2 as pb
from server_process import DATA, SERVER, Server, ego_pose, error_of, eventually, small_model

C = grpc.StatusCode
LEASE_MS = 1500


def step(stub, sid, tick, timeout=60):
    pose = ego_pose(tick)
    return stub.StepScene(pb.StepSceneRequest(session_id=sid, poses=[pose] if pose else []),
                          timeout=timeout).ticks[-1]


def held(server):
    return sorted(s.session_id for s in server.stub.ListSessions(pb.ListSessionsRequest(), timeout=30).sessions)


class SessionStoreTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.redis = Redis().start()
        cls.replicas = [Server(f"--session_store={cls.redis.url}", f"--replica_id={name}", f"--lease_ms={LEASE_MS}",
                               "--snapshot_interval_s=0.3").start() for name in ("ra", "rb")]
        cls.a, cls.b = cls.replicas
        cls.name = cls.a.stub.ListScenarios(pb.ListScenariosRequest(), timeout=30).scenarios[0].name

    @classmethod
    def tearDownClass(cls):
        for r in cls.replicas:
            r.stop()
        cls.redis.stop()

    def create(self, server, sid, seed=1):
        return server.stub.CreateSession(pb.CreateSessionRequest(scenario_name=self.name, seed=seed, session_id=sid),
                                         timeout=120).initial

    def test_moves_to_the_replica_called_and_continues_exactly(self):
        sid = "move-1"
        t = self.create(self.a, sid)
        for _ in range(3):
            t = step(self.a.stub, sid, t)
        # What the session must do wherever it goes: a fork on its replica, rolled 4 steps ahead now.
        self.a.stub.ForkSession(pb.ForkSessionRequest(session_id=sid, new_session_id="move-1-fork"), timeout=60)
        f, expected = t, []
        for _ in range(4):
            f = step(self.a.stub, "move-1-fork", f)
            expected.append(f.SerializeToString())
        self.a.stub.CloseSession(pb.CloseSessionRequest(session_id="move-1-fork"), timeout=60)
        got = []
        t0 = time.time()
        t = step(self.b.stub, sid, t)  # B asks A for it; A hands it over at its next renewal
        moved_s = time.time() - t0
        got.append(t.SerializeToString())
        self.assertEqual(t.tick, 4)
        self.assertIn(sid, held(self.b))
        eventually(lambda: sid not in held(self.a), "A dropped its copy after handing it over")
        t = step(self.b.stub, sid, t)
        got.append(t.SerializeToString())
        for _ in range(2):  # and back again
            t = step(self.a.stub, sid, t)
            got.append(t.SerializeToString())
        self.assertEqual(got, expected, "the moved session's ticks differ from its fork's")
        self.assertIn(sid, held(self.a))
        eventually(lambda: sid not in held(self.b), "B dropped its copy after handing it back")
        print(f"\nsession moved A -> B on B's call in {moved_s * 1000:.0f} ms (lease {LEASE_MS} ms)", flush=True)
        self.a.stub.CloseSession(pb.CloseSessionRequest(session_id=sid), timeout=60)

    def test_ids_are_unique_over_the_store_and_close_anywhere(self):
        sid = "unique-1"
        t = self.create(self.a, sid)
        step(self.a.stub, sid, t)
        code, details = error_of(self.b.stub.CreateSession, pb.CreateSessionRequest(
            scenario_name=self.name, session_id=sid), timeout=60)
        self.assertEqual(code, C.ALREADY_EXISTS, details)
        self.assertIn(f"'{sid}' is already in use", details)
        self.assertTrue(self.redis.keys(f"ss:{{{sid}}}:*"))
        # Closed through B while A holds it: A hands it over, B deletes it from the store.
        self.b.stub.CloseSession(pb.CloseSessionRequest(session_id=sid), timeout=60)
        self.assertEqual(self.redis.keys(f"ss:{{{sid}}}:*"), [])
        for server in self.replicas:
            code, details = error_of(step, server.stub, sid, t)
            self.assertEqual(code, C.NOT_FOUND, details)
            self.assertIn(f"'{sid}' is not an open session", details)
        # The id is free again, on any replica.
        self.create(self.b, sid)
        self.b.stub.CloseSession(pb.CloseSessionRequest(session_id=sid), timeout=60)

    def test_the_store_holds_the_snapshot_and_nothing_else(self):
        sid = "keys-1"
        t = self.create(self.a, sid)
        step(self.a.stub, sid, t)
        keys = self.redis.keys(f"ss:{{{sid}}}:*")
        self.assertEqual(keys, [f"ss:{{{sid}}}:{k}" for k in ("epoch", "lease", "snap", "tenant")])
        self.assertEqual(self.redis.command("GET", f"ss:{{{sid}}}:lease"), "ra")
        ttl = self.redis.command("PTTL", f"ss:{{{sid}}}:lease")
        self.assertTrue(0 < ttl <= LEASE_MS, ttl)
        snap = self.redis.command("GET", f"ss:{{{sid}}}:snap")
        self.assertIsInstance(snap, bytes)
        self.assertIn(b"SSSNAP05", snap[:64])  # the snapshot file's format, byte for byte the same record
        self.a.stub.CloseSession(pb.CloseSessionRequest(session_id=sid), timeout=60)

    def test_sigterm_hands_every_session_over_at_once(self):
        extra = Server(f"--session_store={self.redis.url}", "--replica_id=rc", f"--lease_ms={LEASE_MS}").start()
        ticks = {}
        for i in range(3):
            sid = f"term-{i}"
            ticks[sid] = step(extra.stub, sid, self.create(extra, sid, seed=i))
        self.assertEqual(extra.terminate(), 0)
        self.assertIn("saved 3 sessions to the session store", extra.output())
        for sid, t in ticks.items():
            self.assertIsNone(self.redis.command("GET", f"ss:{{{sid}}}:lease"), "the drain released the lease")
            t0 = time.time()
            n = step(self.b.stub, sid, t)
            self.assertEqual(n.tick, t.tick + 1)
            self.assertLess(time.time() - t0, LEASE_MS / 1000, "waited for a lease the drain had released")
            self.b.stub.CloseSession(pb.CloseSessionRequest(session_id=sid), timeout=60)

    def test_other_tenants_neither_find_nor_move_a_session(self):
        tokens = os.path.join(self.redis.dir, "tokens")
        with open(tokens, "w") as f:
            f.write("token-x-0123456789 team-x\ntoken-y-0123456789 team-y\n")
        os.chmod(tokens, 0o600)
        flags = (f"--session_store={self.redis.url}", f"--lease_ms={LEASE_MS}", f"--tokens_file={tokens}")
        x = Server(*flags, "--replica_id=rx", token="token-x-0123456789").start()
        y = Server(*flags, "--replica_id=ry", token="token-y-0123456789").start()
        try:
            sid = "tenant-1"
            t = x.stub.CreateSession(pb.CreateSessionRequest(scenario_name=self.name, session_id=sid),
                                     timeout=120).initial
            code, details = error_of(step, y.stub, sid, t)
            self.assertEqual(code, C.NOT_FOUND, details)
            self.assertEqual(details, f"session_id '{sid}' is not an open session")
            self.assertIsNone(self.redis.command("GET", f"ss:{{{sid}}}:want"), "another tenant asked for it")
            self.assertEqual(self.redis.command("GET", f"ss:{{{sid}}}:lease"), "rx")
            self.assertEqual(step(x.stub, sid, t).tick, 1)
            x.stub.CloseSession(pb.CloseSessionRequest(session_id=sid), timeout=60)
        finally:
            x.stop()
            y.stop()

    def test_a_replica_that_lost_its_lease_refuses_and_never_forks(self):
        extra = Server(f"--session_store={self.redis.url}", "--replica_id=rd", f"--lease_ms={LEASE_MS}",
                       "--snapshot_interval_s=0.2").start()
        try:
            sid = "lost-1"
            t = self.create(extra, sid)
            for _ in range(3):
                t = step(extra.stub, sid, t)
            # Idle until its background snapshot holds tick 3: the stored bytes stop changing (an unchanged session
            # is not saved again).
            key, last, since = f"ss:{{{sid}}}:snap", None, time.time()
            while time.time() - since < 1.0:
                now = self.redis.command("GET", key)
                if now != last:
                    last, since = now, time.time()
                time.sleep(0.05)
            extra.proc.send_signal(signal.SIGSTOP)  # paused past its lease: it cannot renew or hand over
            try:
                t0 = time.time()
                n = step(self.b.stub, sid, t)
                took_s = time.time() - t0
                self.assertEqual(n.tick, 4, "B continues from the paused replica's last snapshot")
                self.assertGreater(took_s, LEASE_MS / 1000 / 4, "taken before the lease could have run out")
                n = step(self.b.stub, sid, n)
            finally:
                extra.proc.send_signal(signal.SIGCONT)
            code, details = error_of(step, extra.stub, sid, t)
            self.assertEqual(code, C.FAILED_PRECONDITION, details)
            self.assertIn("lease lost", details)
            self.assertIn("replica 'rb'", details)
            # B's history stands: the paused replica wrote nothing over it.
            self.assertEqual(self.redis.command("GET", f"ss:{{{sid}}}:lease"), "rb")
            self.assertEqual(step(self.b.stub, sid, n).tick, 6)
            self.b.stub.CloseSession(pb.CloseSessionRequest(session_id=sid), timeout=60)
            print(f"\nlease lost: B took the paused replica's session after {took_s * 1000:.0f} ms "
                  f"(lease {LEASE_MS} ms); the paused replica then answered FAILED_PRECONDITION: {details}", flush=True)
        finally:
            extra.stop()


class StoreDownTest(unittest.TestCase):
    def test_a_store_gone_mid_run_refuses_calls_once_the_lease_is_too_old(self):
        with Redis() as redis:
            s = Server(f"--session_store={redis.url}", "--replica_id=rz", "--lease_ms=1000").start()
            try:
                name = s.stub.ListScenarios(pb.ListScenariosRequest(), timeout=30).scenarios[0].name
                t = s.stub.CreateSession(pb.CreateSessionRequest(scenario_name=name, session_id="down-1"),
                                         timeout=60).initial
                t = step(s.stub, "down-1", t)
                redis.proc.kill()
                redis.proc.wait(30)
                # Trusted for 3/4 of the lease after its last renewal, then refused: no call runs on a lease that
                # another replica might hold by now.
                def refused():
                    code, details = error_of(step, s.stub, "down-1", t)
                    return (code, details) if code else None

                code, details = eventually(refused, "a call refused", timeout=10)
                self.assertEqual(code, C.UNAVAILABLE, details)
                self.assertIn("session 'down-1': its lease cannot be renewed: session store redis://127.0.0.1:", details)
                self.assertIn("cannot be reached", details)
                code, details = error_of(s.stub.CreateSession, pb.CreateSessionRequest(scenario_name=name),
                                         timeout=60)
                self.assertEqual(code, C.UNAVAILABLE, details)
                self.assertIsNone(s.proc.poll())
            finally:
                s.stop()


class StoreFlagsTest(unittest.TestCase):
    def run_server(self, *flags):
        r = subprocess.run([SERVER, "--port=0", "--metrics_port=-1", f"--model={small_model()}",
                            f"--scenario_dir={DATA}"] + list(flags), capture_output=True, text=True, timeout=120)
        return r.returncode, r.stdout + r.stderr

    def test_bad_values_and_an_unreachable_store_stop_the_start(self):
        with socket_port() as dead:
            cases = [
                (["--session_store=http://127.0.0.1:6379"], "not a redis:// URL"),
                (["--session_store=redis://127.0.0.1"], "no port"),
                (["--session_store=redis://127.0.0.1:0"], "port '0' is not 1..65535"),
                (["--session_store=redis://127.0.0.1:6379/99"], "database '99' is not 0..15"),
                (["--session_store=redis://:secret@127.0.0.1:6379"], "--session_store_password_file"),
                ([f"--session_store=redis://127.0.0.1:{dead}", "--replica_id=a b"], "--replica_id 'a b'"),
                ([f"--session_store=redis://127.0.0.1:{dead}", "--lease_ms=10"], "--lease_ms 10: must be 300..600000"),
                ([f"--session_store=redis://127.0.0.1:{dead}", "--snapshot_dir=/tmp/x"],
                 "--snapshot_dir and --session_store both given"),
                ([f"--session_store=redis://127.0.0.1:{dead}"],
                 f"session store redis://127.0.0.1:{dead}/0 cannot be reached: Connection refused"),
                (["--session_store_password_file=/nonexistent"], "without --session_store"),
            ]
            for flags, message in cases:
                code, out = self.run_server(*flags)
                self.assertEqual(code, 1, f"{flags}: {out}")
                self.assertIn(message, out, flags)
                self.assertNotIn("serving", out, flags)

    def test_a_wrong_password_is_refused_at_start(self):
        with Redis() as redis:
            redis.command("CONFIG", "SET", "requirepass", "right")
            pw = os.path.join(redis.dir, "pw")
            with open(pw, "w") as f:
                f.write("wrong\n")
            code, out = self.run_server(f"--session_store={redis.url}", f"--session_store_password_file={pw}")
            self.assertEqual(code, 1, out)
            self.assertIn("AUTH", out)
            with open(pw, "w") as f:
                f.write("right\n")
            s = Server(f"--session_store={redis.url}", f"--session_store_password_file={pw}").start()
            try:
                self.assertIn("session store redis://127.0.0.1", s.output())
            finally:
                s.stop()


class socket_port:
    """A free loopback port that nothing listens on, for as long as the block runs."""

    def __enter__(self):
        import socket
        self.s = socket.socket()
        self.s.bind(("127.0.0.1", 0))
        return self.s.getsockname()[1]

    def __exit__(self, *exc):
        self.s.close()


if __name__ == "__main__":
    unittest.main(verbosity=2)
