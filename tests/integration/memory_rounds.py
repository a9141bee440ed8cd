"""Measures the server's memory over identical rounds of load (issue 13; not a ctest). One real server on
127.0.0.1; each round: the load generator's sessions (created, stepped, closed), then faults_test's faults (a client
killed mid-call and mid-stream, a deadline passing in a 1000-tick call, 20 cancelled WatchSession streams), every
session closed. After each round (and a pause for the reaper) it prints the server's RSS and malloc's figures.

  SS_SERVER=... SS_TOOL=... SS_LOAD=... SS_WOMD_DIR=... PYTHONPATH=build/python:tests/integration \\
    /usr/bin/python3 tests/integration/memory_rounds.py --rounds 8 [--env MALLOC_CONF=narenas:2] [-- --server_flag ...]
"""
import argparse
import json
import os
import re
import subprocess
import sys
import time
import urllib.request

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import faults_test  # noqa: E402  (its fault helpers)
from scenestreamer.v1 import simulator_pb2 as pb  # noqa: E402
from server_process import Server  # noqa: E402


def metrics(server):
    text = urllib.request.urlopen(f"http://127.0.0.1:{server.metrics_port}/metrics", timeout=10).read().decode()
    out = {}
    for m in re.finditer(r"^(\w+)(?:{[^}]*})? (\S+)$", text, re.M):
        out[m.group(1)] = out.get(m.group(1), 0) + float(m.group(2))
    return out


class Driver(faults_test.FaultsTest):
    """faults_test's helpers bound to our server (not run as a test)."""

    def runTest(self):
        pass


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=8)
    ap.add_argument("--clients", type=int, default=16)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--settle", type=float, default=3.0, help="seconds after each round before reading RSS")
    ap.add_argument("--env", action="append", default=[], help="NAME=VALUE for the server's environment")
    ap.add_argument("--no-faults", action="store_true")
    ap.add_argument("--json", help="write the per-round figures here")
    ap.add_argument("flags", nargs="*", help="server flags (after --)")
    a = ap.parse_args()
    for kv in a.env:
        k, v = kv.split("=", 1)
        os.environ[k] = v
    server = Server(f"--idle_timeout_s={faults_test.IDLE_S}", *a.flags).start()
    for kv in a.env:
        del os.environ[kv.split("=", 1)[0]]
    rows = []
    try:
        Driver.server = server
        Driver.name = server.stub.ListScenarios(pb.ListScenariosRequest()).scenarios[0].name
        d = Driver()
        m = metrics(server)
        print(f"start: RSS {faults_test.rss_mb(server.proc.pid):.0f} MB", flush=True)
        for r in range(a.rounds):
            t = time.time()
            load = subprocess.run([os.environ["SS_LOAD"], "--clients", str(a.clients), "--steps", str(a.steps),
                                   "--target", server.target, "--json"], capture_output=True, text=True, timeout=900)
            assert load.returncode == 0, load.stdout + load.stderr
            peak = faults_test.rss_mb(server.proc.pid)
            lj = json.loads(load.stdout)
            if not a.no_faults:
                ids = d.kill_a_client_mid_call(f"round{r}")
                sid = d.create()
                faults_test.error_of(server.stub.StepScene, pb.StepSceneRequest(session_id=sid, num_ticks=1000),
                                     timeout=1.0)
                streams = [server.stub.WatchSession(pb.WatchSessionRequest(session_id=sid), timeout=60)
                           for _ in range(20)]
                for st in streams:
                    next(st)
                    st.cancel()
                try:
                    faults_test.wait_for(lambda: d.metric("scenestreamer_watchers") == 0, 30, "the streams to go")
                except AssertionError:
                    print(f"watchers left: {d.metric('scenestreamer_watchers')}; log tail:\n{server.output()[-3000:]}")
                    raise
                for s in (*ids, sid):
                    faults_test.error_of(server.stub.CloseSession, pb.CloseSessionRequest(session_id=s))
            time.sleep(a.settle)
            m = metrics(server)
            row = {"round": r + 1, "rss_mb": faults_test.rss_mb(server.proc.pid), "peak_after_load_mb": peak,
                   "in_use_mb": m.get("scenestreamer_malloc_in_use_bytes", 0) / 2**20,
                   "free_held_mb": m.get("scenestreamer_malloc_free_bytes", 0) / 2**20,
                   "sessions": m["scenestreamer_sessions"], "threads": len(os.listdir(f"/proc/{server.proc.pid}/task")),
                   "seconds": time.time() - t, "steps_per_second": lj["steps_per_second"],
                   "p50_ms": lj["latency_ms_p50"], "p99_ms": lj["latency_ms_p99"], "load_errors": lj["errors"]}
            rows.append(row)
            print(f"round {r + 1}: RSS {row['rss_mb']:.0f} MB (after the load {peak:.0f}), malloc in use "
                  f"{row['in_use_mb']:.0f} MB, free held {row['free_held_mb']:.0f} MB, sessions {row['sessions']:.0f}, "
                  f"threads {row['threads']}, {row['seconds']:.0f} s; load {row['steps_per_second']:.1f} steps/s, "
                  f"p50 {row['p50_ms']:.0f} ms, p99 {row['p99_ms']:.0f} ms, {row['load_errors']} errors", flush=True)
    finally:
        server.stop()
        if os.environ.get("SS_KEEP_LOG"):
            with open(os.environ["SS_KEEP_LOG"], "w") as f:
                f.write(server.output())
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f)


if __name__ == "__main__":
    main()
