"""The closed-loop ego benchmark's table (docs/closed-loop.md): every session mode and baseline under every ego policy,
one `scenestreamer eval --ego` run each, and a Markdown table of the episode shares.

    /usr/bin/python3 bench/closed_loop.py --tool build/tools/scenestreamer --data $WOMD/json/val --out runs/closed-loop

Each run writes OUT/<row>-<ego>.json (eval's --json), so a row can be compared with `eval --compare`; runs whose JSON
is already there are not run again (delete them to measure anew). The rows: log replay (MODE_LOG), IDM (MODE_IDM), the
model without reject sampling, and the model with the default sampling. --rows picks some of them."""
import argparse
import json
import os
import subprocess
import sys

ROWS = {
    "log": ("log replay (MODE_LOG)", ["--mode", "log"]),
    "idm": ("IDM (MODE_IDM)", ["--mode", "idm"]),
    "norej": ("model, no reject sampling", ["--mode", "motion", "--motion-reject=false"]),
    "model": ("model (default sampling)", ["--mode", "motion"]),
}
EGOS = ("log", "slow", "fast", "cruise")


def run(tool, data, model, rollouts, threads, row, ego, path):
    if os.path.exists(path):
        return
    cmd = [tool, "eval", "--data", *data, "--rollouts", str(rollouts), "--seed", "1", "--ego", ego,
           "--threads", str(threads), "--json", path, *ROWS[row][1]]
    if model:
        cmd += ["--model", model]
    print("+", " ".join(cmd), file=sys.stderr, flush=True)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def table(out, rows):
    lines = ["| background | ego | episodes | ego collision | rear-end | ego at fault | side | background's fault | "
             "ego off road | background collisions | realism (others) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for row in rows:
        for ego in EGOS:
            path = os.path.join(out, f"{row}-{ego}.json")
            if not os.path.exists(path):
                continue
            j = json.load(open(path))
            e = j["ego_outcome"]
            n = e["episodes"]
            count = lambda k: f"{e[k]:.3f} ({round(e[k] * n)})"
            lines.append(f"| {ROWS[row][0]} | {ego} | {n} | {count('collision')} | {count('rear_end')} | "
                         f"{count('ego_at_fault')} | {count('side')} | {count('background_fault')} | "
                         f"{count('off_road')} | {e['background_collision_rate']:.4f} | {j['realism_meta']:.4f} |")
    return "\n".join(lines)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--tool", required=True, help="the scenestreamer binary")
    p.add_argument("--data", required=True, nargs="+", help="scenario files or directories")
    p.add_argument("--model", default="", help="model weights (default: the bundled default model)")
    p.add_argument("--out", required=True, help="a directory for the runs' JSON")
    p.add_argument("--rollouts", type=int, default=8)
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--rows", nargs="+", default=list(ROWS), choices=list(ROWS))
    a = p.parse_args()
    os.makedirs(a.out, exist_ok=True)
    for row in a.rows:
        for ego in EGOS:
            run(a.tool, a.data, a.model, a.rollouts, a.threads, row, ego, os.path.join(a.out, f"{row}-{ego}.json"))
    print(table(a.out, a.rows))


if __name__ == "__main__":
    main()
