"""`make soak`: steady load through the router for SS_SOAK_MINUTES (30 by default) on 3 loopback replicas behind
nginx (deploy/router/nginx.conf). Rounds of the load generator (24 sessions x 40 steps each, every call routed by
x-session-id) run back to back; each replica's resident memory and session count are sampled every 30 s. Passes
with zero errors and flat memory: no replica's highest RSS in the last quarter of the run more than 10 % (or 64 MB,
whichever is larger) above its highest RSS in the second quarter. Peaks against peaks: since the server gives freed
memory back after sessions close (--malloc_trim_s), a replica's RSS swings with the sessions it holds and the time
since its last trim, and one sample after the first quarter may be a trough (it was, 108 MB against a swing of
50-235 MB, in the first 10-minute run with the trim)."""
import json
import os
import subprocess
import threading
import time
import unittest

from cluster import Cluster, rss_mb

MINUTES = float(os.environ.get("SS_SOAK_MINUTES", "30"))
CLIENTS, STEPS = 24, 40


class ClusterSoak(unittest.TestCase):
    def test_soak(self):
        with Cluster(3) as cluster:
            samples, rounds, stop = [], [], threading.Event()
            t0 = time.time()

            def sample():
                while not stop.wait(30):
                    samples.append((time.time() - t0, [rss_mb(s.proc.pid) for s in cluster.servers],
                                    [int(cluster.metrics(i)["scenestreamer_sessions"]) for i in range(3)]))

            sampler = threading.Thread(target=sample)
            sampler.start()
            try:
                while time.time() - t0 < MINUTES * 60:
                    r = subprocess.run([os.environ["SS_LOAD"], "--clients", str(CLIENTS), "--steps", str(STEPS),
                                        "--target", cluster.target, "--route", "--json"], capture_output=True,
                                       text=True, timeout=1800)
                    self.assertEqual(r.returncode, 0, r.stdout + r.stderr + cluster.router_output())
                    rounds.append(json.loads(r.stdout))
            finally:
                stop.set()
                sampler.join()
            elapsed = time.time() - t0
            steps = sum(r["clients"] * r["steps"] for r in rounds)
            errors = sum(r["errors"] for r in rounds)
            print(f"\nsoak: {elapsed / 60:.1f} min, {len(rounds)} rounds of {CLIENTS} sessions x {STEPS} steps, "
                  f"{steps} steps, {errors} errors, {steps / elapsed:.1f} steps/s; per round p50 "
                  f"{sorted(r['latency_ms_p50'] for r in rounds)[len(rounds) // 2]:.1f} ms, worst p99 "
                  f"{max(r['latency_ms_p99'] for r in rounds):.1f} ms")
            print("minute  RSS MB per replica       sessions per replica")
            for t, rss, sessions in samples:
                print(f"{t / 60:6.1f}  {' '.join(f'{m:7.1f}' for m in rss)}   {sessions}")
            self.assertEqual(errors, 0)
            self.assertGreaterEqual(len(samples), 4, "too short a run to judge memory")
            quarter = len(samples) // 4
            for i in range(3):
                early = max(s[1][i] for s in samples[quarter:2 * quarter])
                late = max(s[1][i] for s in samples[-quarter:])
                self.assertLessEqual(late, max(early * 1.10, early + 64), f"replica {i}: RSS {early:.1f} -> {late:.1f} MB")


if __name__ == "__main__":
    unittest.main(verbosity=2)
