"""The snapshot directory of the real server binary on 127.0.0.1: sessions stepped back to back survive kill -9 within
one --snapshot_interval_s, a directory that cannot be written is refused at startup, the files hold no credential and
no one else may read them, and corrupt files and temporary leftovers are moved out of the way at startup."""
import os
import shutil
import stat
import tempfile
import threading
import time
import unittest

import grpc

from scenestreamer.v1 import simulator_pb2 as pb
from server_process import DATA, SERVER, Server, error_of, small_model
import subprocess

C = grpc.StatusCode
INTERVAL_S = 1.0  # --snapshot_interval_s
STEP_S = 3.0      # how long the clients step back to back before the kill
# Ticks a call: an engine call holds its session from its first tick to its last, so with 20 the session is free only
# in the moment between two calls, and the background snapshot of old, which skipped a session it could not take at
# once, found it free in about 1 % of its passes (with one tick a call, in 5-30 %: a test that could pass by luck).
TICKS_A_CALL = 20


def first_scenario(stub):
    return stub.ListScenarios(pb.ListScenariosRequest()).scenarios[0].name


def run_to_exit(*flags, timeout=60):
    """Runs the server binary with `flags` until it exits; returns (code, output)."""
    p = subprocess.run([SERVER, "--port=0", "--metrics_port=-1", f"--model={small_model()}", f"--scenario_dir={DATA}",
                        *flags], capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stdout + p.stderr


class SnapshotDirTest(unittest.TestCase):
    def setUp(self):
        self.root = tempfile.mkdtemp(prefix="ss-it-snapdir-")
        self.dir = os.path.join(self.root, "snapshots")

    def tearDown(self):
        shutil.rmtree(self.root, ignore_errors=True)

    def crash_while_stepping(self, clients):
        """`clients` sessions, each stepped back to back by its own thread (TICKS_A_CALL ticks a call, no pause) for
        STEP_S, then kill -9 while they still step. Returns, per session, the acknowledged ticks as (wall time,
        tick) and the kill's wall time."""
        srv = Server(f"--snapshot_interval_s={INTERVAL_S}", "--evict_idle_s=1000", snapshot_dir=self.dir).start()
        name = first_scenario(srv.stub)
        ids = [srv.stub.CreateSession(pb.CreateSessionRequest(scenario_name=name, session_id=f"busy{i}",
                                                              model_drives_sdc=True)).session_id
               for i in range(clients)]
        # The first calls of fresh sessions are slow (2-3 s here for 20 ticks each of four): made before the clock runs.
        for sid in ids:
            srv.stub.StepScene(pb.StepSceneRequest(session_id=sid, num_ticks=TICKS_A_CALL), timeout=120)
        acked = {sid: [] for sid in ids}
        stop = threading.Event()

        def loop(sid):
            while not stop.is_set():
                try:
                    r = srv.stub.StepScene(pb.StepSceneRequest(session_id=sid, num_ticks=TICKS_A_CALL), timeout=30)
                except grpc.RpcError:
                    return  # the kill
                acked[sid].append((time.time(), r.ticks[-1].tick))

        threads = [threading.Thread(target=loop, args=(sid,)) for sid in ids]
        for t in threads:
            t.start()
        time.sleep(STEP_S)
        killed_at = time.time()
        srv.kill()
        stop.set()
        for t in threads:
            t.join()
        return acked, killed_at

    def check_restored(self, clients):
        acked, killed_at = self.crash_while_stepping(clients)
        with Server(f"--snapshot_interval_s={INTERVAL_S}", snapshot_dir=self.dir) as srv:
            for sid, ticks in acked.items():
                self.assertGreater(len(ticks), 3, f"{sid} was hardly stepped: {len(ticks)} calls")
                code, msg = error_of(srv.stub.GetSession, pb.GetSessionRequest(session_id=sid))
                self.assertIsNone(code, f"{sid} ({ticks[-1][1]} ticks acknowledged) was lost: {code} {msg}")
                restored = srv.stub.GetSession(pb.GetSessionRequest(session_id=sid)).current.tick
                # The promise: at most one interval lost. The last tick acknowledged an interval (and a margin for
                # the write itself on a loaded 2-core machine) before the kill must be in the restored session.
                due = [t for when, t in ticks if when <= killed_at - INTERVAL_S - 0.5]
                floor = due[-1] if due else 0
                rate = (ticks[-1][1] - ticks[0][1]) / (ticks[-1][0] - ticks[0][0])
                print(f"{clients} clients: {sid} acknowledged {ticks[-1][1]} ticks, restored at tick {restored} "
                      f"(floor {floor}): {ticks[-1][1] - restored} ticks lost, {(ticks[-1][1] - restored) / rate:.2f} "
                      f"s of its stepping at {rate:.0f} ticks/s", flush=True)
                self.assertGreaterEqual(restored, floor, sid)
                self.assertLessEqual(restored, ticks[-1][1] + TICKS_A_CALL, sid)

    def test_a_session_stepped_back_to_back_survives_kill_9(self):
        # Once the background snapshot skipped every session whose lock it could not take at that instant: a
        # session stepped back to back was never saved, and kill -9 lost it altogether.
        self.check_restored(1)

    def test_four_sessions_stepped_back_to_back_survive_kill_9(self):
        self.check_restored(4)

    def test_a_directory_that_cannot_be_written_is_refused_at_startup(self):
        # Once the server started, warned each interval, and on SIGTERM logged "saved 0 sessions" and exited 0.
        regular = os.path.join(self.root, "a-file")
        with open(regular, "w") as f:
            f.write("not a directory\n")
        for d in (regular, os.path.join(regular, "below")):
            code, out = run_to_exit(f"--snapshot_dir={d}", timeout=120)
            self.assertEqual(code, 1, out)
            self.assertIn(f"--snapshot_dir {d}", out)
            self.assertIn("cannot start", out)

    def test_snapshot_files_are_private_and_hold_no_credential(self):
        srv = Server(snapshot_dir=self.dir).start()
        name = first_scenario(srv.stub)
        c = srv.stub.CreateSession(pb.CreateSessionRequest(scenario_name=name, session_id="private"))
        ego = [a.id for a in c.initial.agents if a.controlled]
        self.assertEqual(len(ego), 1)
        credential = srv.stub.JoinSession(pb.JoinSessionRequest(session_id="private",
                                                                agent_ids=ego)).controller_credential
        self.assertEqual(srv.terminate(), 0)
        path = os.path.join(self.dir, "private.snapshot")
        self.assertEqual(stat.S_IMODE(os.stat(self.dir).st_mode), 0o700)
        self.assertEqual(stat.S_IMODE(os.stat(path).st_mode), 0o600)
        with open(path, "rb") as f:
            data = f.read()
        self.assertNotIn(credential.encode(), data)
        # The credential still works after the restore (its hash was saved), and only it.
        with Server(snapshot_dir=self.dir) as srv:
            self.assertEqual(srv.stub.JoinSession(pb.JoinSessionRequest(
                session_id="private", agent_ids=ego, controller_credential=credential)).controller_credential,
                credential)
            code, _ = error_of(srv.stub.JoinSession, pb.JoinSessionRequest(
                session_id="private", agent_ids=ego, controller_credential="x" * len(credential)))
            self.assertEqual(code, C.PERMISSION_DENIED)

    def test_corrupt_files_and_leftovers_are_moved_aside_at_startup(self):
        os.makedirs(self.dir, mode=0o700)
        with open(os.path.join(self.dir, "junk.snapshot"), "wb") as f:
            f.write(b"this is not a snapshot")
        leftover = os.path.join(self.dir, "gone.snapshot.tmp.1234.0badf00d")
        with open(leftover, "wb") as f:
            f.write(b"half a snapshot")
        with Server(snapshot_dir=self.dir) as srv:
            out = srv.output()
        self.assertIn("restored 0 sessions", out)
        self.assertFalse(os.path.exists(os.path.join(self.dir, "junk.snapshot")))
        self.assertTrue(os.path.exists(os.path.join(self.dir, "quarantine", "junk.snapshot")), os.listdir(self.dir))
        self.assertIn("quarantine", out)
        self.assertFalse(os.path.exists(leftover))
        # A second start finds nothing to complain about.
        with Server(snapshot_dir=self.dir) as srv:
            self.assertNotIn("not restored", srv.output())


if __name__ == "__main__":
    unittest.main(verbosity=2)
