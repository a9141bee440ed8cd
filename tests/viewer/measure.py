"""The viewer's measurements for docs/viewer.md (not a test: the figures depend on the machine and its load).

  measure.py fps [--agents 300 --roads 2000 --seconds 5 --runs 3]
      frames per second of the page in headless Chromium on a synthetic rollout file (synthetic.py)
  measure.py ab [--runs 4 --clients 32 --steps 30 --densify 64 --viewers 10 --scenario_dir D] [--tabs]
      scenestreamer-load's steps per second against the server with 0 and with N viewers open (WebSocket watchers
      of the load's sessions through the gateway), interleaved; the load of bench/server_ab.sh (docs/performance.md)
      on the real val scenarios by default
  measure.py screenshots OUT_DIR
      a live session and a rollout file, as PNG

Run from the build tree's environment, e.g.
  SS_SERVER=build/server/scenestreamer-server SS_TOOL=build/tools/scenestreamer SS_VIEWER=build/viewer/scenestreamer-viewer \\
  SS_WOMD_DIR=data SS_SOURCE_DIR=. PYTHONPATH=build/python:tests/viewer /usr/bin/python3 tests/viewer/measure.py fps
The servers use the bundled default model (models/default.safetensors) and --threads 2."""
import argparse
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "integration"))

from server_process import Server, ego_pose  # noqa: E402
from scenestreamer.v1 import simulator_pb2 as pb  # noqa: E402

from browser import SOURCE, Browser  # noqa: E402
from viewer_process import Viewer  # noqa: E402
import synthetic  # noqa: E402

MODEL = os.path.join(SOURCE, "models", "default.safetensors")
LOAD = os.environ.get("SS_LOAD", os.path.join(SOURCE, "build", "client_examples", "scenestreamer-load"))
WATCHERS = os.path.join(SOURCE, "viewer", "web", "tests", "watchers.mjs")


def machine():
    cpu = ""
    with open("/proc/cpuinfo") as f:
        m = re.search(r"model name\s*:\s*(.*)", f.read())
        cpu = m.group(1) if m else ""
    chromium = subprocess.run(["/usr/bin/chromium", "--version"], capture_output=True, text=True).stdout.strip()
    return {"cpu": cpu, "cores": os.cpu_count(), "load_average": os.getloadavg(), "chromium": chromium,
            "kernel": platform.release()}


def servers(scenario_dir):
    server = Server(f"--model={MODEL}", f"--scenario_dir={scenario_dir}").start()
    viewer = Viewer(server.target, f"--scenario_dir={scenario_dir}").start()
    return server, viewer


def fps(args):
    server, viewer = servers(os.path.join(SOURCE, "data"))
    browser = Browser()
    try:
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "synthetic.json")
            with open(path, "w") as f:
                json.dump(synthetic.scenario(args.agents, args.roads), f)
            page = browser.open(viewer.url, 1280, 800)
            page.files("#file", [path])
            page.wait("window.__viewer.mode() === 'file'", 120000)
            page.eval("window.__viewer.setFrame(40)")
            agents = page.eval("window.__viewer.lastDrawn.agents")
            runs = [page.eval(f"window.__viewer.bench({int(args.seconds * 1000)})") for _ in range(args.runs)]
            if args.screenshot:
                page.screenshot(args.screenshot)
        print(json.dumps({"agents_at_frame_40": agents, "roads": args.roads, "runs": runs, "machine": machine()},
                         indent=1))
    finally:
        browser.close()
        viewer.stop()
        server.stop()


def load_command(target, clients, steps, densify):
    return [LOAD, "--clients", str(clients), "--steps", str(steps), "--target", target, "--json",
            "--densify", str(densify)]


def load_run(target, clients, steps, densify):
    r = subprocess.run(load_command(target, clients, steps, densify), capture_output=True, text=True, check=True)
    return json.loads(r.stdout)


def cpu_seconds(pid):
    """User + system CPU time of a process so far."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def ab(args):
    server, viewer = servers(args.scenario_dir)
    ws_url = viewer.url.replace("http", "ws", 1) + "ws/watch"
    results = []
    # --tabs: the viewers are Chromium tabs of the page (drawing every tick), opened before the runs.
    browser = Browser() if args.tabs else None
    tabs = [browser.open(viewer.url, 1280, 800) for _ in range(args.viewers)] if browser else []
    try:
        for run in range(args.runs):
            for viewers in (0, args.viewers):
                watchers = None
                cpu0 = cpu_seconds(server.proc.pid), cpu_seconds(viewer.proc.pid)
                if viewers:
                    # The load's sessions exist once it has created them: watch them as soon as they do.
                    proc = subprocess.Popen(load_command(server.target, args.clients, args.steps, args.densify),
                                            stdout=subprocess.PIPE, text=True)
                    deadline = time.time() + 60
                    ids = []
                    while time.time() < deadline and len(ids) < min(viewers, args.clients):
                        ids = [s.session_id for s in server.stub.ListSessions(pb.ListSessionsRequest()).sessions]
                        time.sleep(0.02)
                    watch = [ids[i % len(ids)] for i in range(viewers)]
                    if tabs:
                        for page, sid in zip(tabs, watch):
                            page.eval(f"location.hash = 'watch={sid}'")
                        out = json.loads(proc.communicate()[0])
                        seen = {"ticks": [p.eval("window.__viewer.ticksDrawn.length") for p in tabs], "errors": []}
                        for page in tabs:
                            page.eval("location.hash = ''; window.__viewer.mode()")
                    else:
                        watchers = subprocess.Popen(["node", "--experimental-websocket", WATCHERS, ws_url, ""] + watch,
                                                    stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                                    stderr=subprocess.DEVNULL)
                        watchers.stdout.readline()  # "open"
                        out = json.loads(proc.communicate()[0])
                        seen = json.loads(watchers.communicate("")[0])
                else:
                    out = load_run(server.target, args.clients, args.steps, args.densify)
                    seen = None
                steps = args.clients * args.steps
                row = {"run": run, "viewers": viewers, "steps_per_s": out.get("steps_per_second"),
                       "server_cpu_ms_per_step": 1000 * (cpu_seconds(server.proc.pid) - cpu0[0]) / steps,
                       "viewer_cpu_ms_per_step": 1000 * (cpu_seconds(viewer.proc.pid) - cpu0[1]) / steps,
                       "load_average": os.getloadavg()[0], "load": out, "watched_ticks": seen}
                results.append(row)
                print(json.dumps({k: row[k] for k in ("run", "viewers", "steps_per_s", "server_cpu_ms_per_step",
                                                      "viewer_cpu_ms_per_step", "load_average")}), flush=True)
        print(json.dumps({"results": results, "tabs": bool(tabs), "machine": machine()}, indent=1))
    finally:
        if browser:
            browser.close()
        viewer.stop()
        server.stop()


def screenshots(args):
    os.makedirs(args.out, exist_ok=True)
    data = os.path.join(SOURCE, "data")
    server, viewer = servers(data)
    browser = Browser()
    try:
        names = [s.name for s in server.stub.ListScenarios(pb.ListScenariosRequest()).scenarios]
        r = server.stub.CreateSession(pb.CreateSessionRequest(scenario_name=names[args.scenario], seed=7,
                                                              mode=pb.MODE_DENSIFY, densify_target=40))
        server.stub.CreateSession(pb.CreateSessionRequest(scenario_name=names[1], seed=8))
        page = browser.open(f"{viewer.url}#watch={r.session_id}", 1280, 800)
        page.wait("window.__viewer.ticksDrawn.includes(0)")
        tick = r.initial
        for _ in range(args.ticks):
            pose = ego_pose(tick)
            tick = server.stub.StepScene(pb.StepSceneRequest(session_id=r.session_id,
                                                             poses=[pose] if pose else [])).ticks[-1]
            page.wait(f"window.__viewer.ticksDrawn.includes({tick.tick})")
        page.wait("document.querySelectorAll('#sessions tbody tr').length === 2 && [...document.querySelectorAll("
                  f"'#sessions tbody td')].some(td => td.textContent === '{tick.tick}')", 10000)
        page.click("#fit")
        page.screenshot(os.path.join(args.out, "viewer-live.png"))
        # A rollout file: two `simulate` rollouts of a bundled scenario, overlaid, with the logged future.
        source = os.path.join(data, sorted(f for f in os.listdir(data) if ".tfrecord" in f)[0])
        outs = []
        for k in range(2):
            out = os.path.join(args.out, f"rollout{k}.tfrecord")
            subprocess.run([os.environ["SS_TOOL"], "simulate", "--scenario", source, "--index", str(args.scenario),
                            "--model", MODEL, "--seed", "1", "--rollout", str(k), "--out", out], check=True,
                           capture_output=True)
            outs.append(out)
        page2 = browser.open(viewer.url, 1280, 800)
        page2.files("#file", outs)
        page2.wait("window.__viewer.mode() === 'file' && window.__viewer.groups()[0].rollouts === 2", 60000)
        page2.eval("(() => { const s = document.getElementById('rollout'); s.value = 'all';"
                   " s.dispatchEvent(new Event('change')); })()")
        page2.eval(f"window.__viewer.setFrame({args.frame})")
        page2.click("#fit")
        page2.screenshot(os.path.join(args.out, "viewer-rollout.png"))
        for out in outs:
            os.remove(out)
    finally:
        browser.close()
        viewer.stop()
        server.stop()


def main():
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="cmd", required=True)
    f = sub.add_parser("fps")
    f.add_argument("--agents", type=int, default=300)
    f.add_argument("--roads", type=int, default=2000)
    f.add_argument("--seconds", type=float, default=5)
    f.add_argument("--runs", type=int, default=3)
    f.add_argument("--screenshot", default="")
    a = sub.add_parser("ab")
    a.add_argument("--runs", type=int, default=4)
    a.add_argument("--clients", type=int, default=32)
    a.add_argument("--steps", type=int, default=30)
    a.add_argument("--densify", type=int, default=64)
    a.add_argument("--scenario_dir", default=os.path.join(SOURCE, "..", "shared", "data", "womd", "json", "val"))
    a.add_argument("--viewers", type=int, default=10)
    a.add_argument("--tabs", action="store_true", help="viewers as Chromium tabs of the page instead of watchers")
    s = sub.add_parser("screenshots")
    s.add_argument("out")
    s.add_argument("--scenario", type=int, default=0)
    s.add_argument("--ticks", type=int, default=12)
    s.add_argument("--frame", type=int, default=60)
    args = p.parse_args()
    {"fps": fps, "ab": ab, "screenshots": screenshots}[args.cmd](args)


if __name__ == "__main__":
    main()
