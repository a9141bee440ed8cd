"""Runs N SceneStreamer environments against one server as one vector environment (each tick: N StepScene calls in
flight at once), each ego driven by the cruise policy, and prints what each episode got.

    /usr/bin/python3 client_examples/python/run_parallel_envs.py --target 127.0.0.1:50051 --envs 8 --steps 20

Needs the scenestreamer package: `pip install ./python` (docs/rl.md), or PYTHONPATH=build/python.
"""
import argparse
import time

import numpy as np

from scenestreamer import SceneStreamerVectorEnv, cruise


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--target", default="127.0.0.1:50051")
    p.add_argument("--envs", type=int, default=8)
    p.add_argument("--steps", type=int, default=20)
    p.add_argument("--route", action="store_true", help="send x-session-id metadata (behind a session-affine router)")
    args = p.parse_args()
    t0 = time.time()
    venv = SceneStreamerVectorEnv(args.envs, target=args.target, max_steps=args.steps, route=args.route)
    try:
        obs, _ = venv.reset(seed=0)
        returns = np.zeros(args.envs)
        steps = np.zeros(args.envs, int)
        ended = {}  # env -> (steps, return, agents seen at the end, how it ended)
        while len(ended) < args.envs:
            actions = np.stack([cruise({k: v[i] for k, v in obs.items()}) for i in range(args.envs)])
            obs, rewards, terminated, truncated, infos = venv.step(actions)
            returns += rewards
            steps += 1
            for i in range(args.envs):
                if (terminated[i] or truncated[i]) and i not in ended:
                    final = infos["final_info"][i]
                    how = "truncated" if truncated[i] else ", ".join(
                        k for k in ("collision", "off_road", "ran_red_light") if final.get(k)) or "terminated"
                    ended[i] = (steps[i], returns[i], final["agents"], how)
    finally:
        venv.close()
    for i in sorted(ended):
        n, ret, agents, how = ended[i]
        print(f"env {i}: {n} steps, return {ret:.1f}, {agents} agents at the end, {how}")
    print(f"{len(ended)} environments in {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main()
