"""Runs 8 SceneStreamer environments in parallel threads against one server, each driven by the cruise controller,
and prints what each saw.

    PYTHONPATH=build/client_examples/python:client_examples/python /usr/bin/python3 \
        client_examples/python/run_parallel_envs.py --target 127.0.0.1:50051 --envs 8 --steps 20
"""
import argparse
import threading
import time

from scenestreamer_env import SceneStreamerEnv, cruise


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--target", default="127.0.0.1:50051")
    p.add_argument("--envs", type=int, default=8)
    p.add_argument("--steps", type=int, default=20)
    args = p.parse_args()
    results, errors = {}, []

    def run(i):
        env = SceneStreamerEnv(args.target, max_steps=args.steps)
        try:
            obs, info = env.reset(seed=i)
            total, steps, agents = 0.0, 0, 0
            while True:
                obs, reward, terminated, truncated, info = env.step(cruise(obs))
                total, steps, agents = total + reward, steps + 1, info["agents"]
                if terminated or truncated:
                    break
            results[i] = (steps, total, agents, terminated)
        except Exception as e:  # reported below: one failing env must not hide the others' results
            errors.append(f"env {i}: {e}")
        finally:
            env.close()

    t0 = time.time()
    threads = [threading.Thread(target=run, args=(i,)) for i in range(args.envs)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for i in sorted(results):
        steps, total, agents, crashed = results[i]
        print(f"env {i}: {steps} steps, return {total:.1f}, {agents} background agents at the end"
              f"{', crashed' if crashed else ''}")
    print(f"{len(results)} environments in {time.time() - t0:.1f} s, {len(errors)} errors")
    for e in errors:
        print(e)
    raise SystemExit(1 if errors else 0)


if __name__ == "__main__":
    main()
