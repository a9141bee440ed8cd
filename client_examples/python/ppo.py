"""Trains an ego driving policy with PPO against the SceneStreamer server, in plain PyTorch and numpy, then compares it
with the cruise policy and a random policy on held-out scenarios.

Two servers: one serving the training scenarios, one serving the held-out ones (the script checks that no scenario
name is on both, so the policy never drives a held-out scenario while it learns). Each serves the trained default
model, which drives every other agent and the lights and reacts to the ego.

    B=build/server/scenestreamer-server
    $B --host 127.0.0.1 --port 50061 --threads 2 --metrics_port -1 --scenario_dir ../shared/data/womd/json/train &
    $B --host 127.0.0.1 --port 50062 --threads 2 --metrics_port -1 --scenario_dir ../shared/data/womd/json/val &
    /usr/bin/python3 client_examples/python/ppo.py --train-target 127.0.0.1:50061 --eval-target 127.0.0.1:50062 \\
        --minutes 38 --out docs/ppo

--quick: one tiny PPO iteration (2 environments x 8 steps) and a 2-episode evaluation of each policy, for the test
(tests/integration/ppo_example_test.py). Needs the scenestreamer package (docs/rl.md) and Debian's
python3-torch.

Writes to --out: log.jsonl (one line per iteration), eval.json (the comparison), curves.svg (return and event rates
per iteration, drawn here without matplotlib) and policy.pt (the trained weights).
"""
import argparse
import concurrent.futures
import json
import math
import os
import time

import numpy as np
import torch
import torch.nn as nn

from scenestreamer import RewardConfig, SceneStreamerEnv, SceneStreamerVectorEnv, cruise
from scenestreamer.client import connect
from scenestreamer.v1 import simulator_pb2 as pb
from scenestreamer.env import ACTION_HIGH, ACTION_LOW


def reward(args):
    """The reward the policy is trained and evaluated with: metres of progress along the lane, minus penalties for the
    events the server's engine reports. An episode ends on a collision or going off road, and is truncated at
    --max-steps. --collision-penalty sets the collision term (default -20: twice the package's default)."""
    return RewardConfig(progress=1.0, collision=args.collision_penalty, off_road=-10.0, red_light=-5.0)


# Network actions are in normalised units: acceleration = 2 u0 m/s^2, yaw rate = 0.5 u1 rad/s (u = 0: hold speed and
# heading). Then clipped to the env's action space ([-8, 4] m/s^2, [-1, 1] rad/s).
ACTION_SCALE = np.array([2.0, 0.5], np.float32)


LOOKAHEAD = (5.0, 10.0, 20.0)  # metres: where the policy sees the lane ahead


def _ego_features(o):
    """A compact view of one env's observation (a dict of unbatched arrays) for a small MLP: what a driver reads
    off the scene, all from the observation the env returns, scaled to about [-1, 1].
    ego: speed, lateral speed. lane: the nearest lane point running the ego's way (offset, heading error), and the
    direction to the lane point at each LOOKAHEAD distance on the lane nearest the ego's axis. road edges: the nearest
    edge point beside the ego on each side, and the nearest one in the ego's path. agents: the nearest in the ego's
    path ahead and behind (gap, closing speed) and the nearest overall. lights: the nearest facing stop line ahead
    (distance, red, yellow)."""
    f = np.zeros(24, np.float32)
    speed = float(o["ego"][0])
    f[0], f[1] = speed / 20.0, o["ego"][1] / 5.0
    lanes = o["lanes"][(o["lanes_mask"] > 0) & (o["lanes"][:, 2] > 0.7)]
    if len(lanes):
        near = lanes[np.argmin(np.hypot(lanes[:, 0], lanes[:, 1]))]
        f[2], f[3], f[4] = 1.0, np.clip(near[1] / 4.0, -2, 2), np.arctan2(near[3], near[2])
        for k, ahead in enumerate(LOOKAHEAD):
            band = lanes[np.abs(lanes[:, 0] - ahead) < 0.3 * ahead + 1.0]
            if len(band):
                p = band[np.argmin(np.abs(band[:, 1]))]
                f[5 + 2 * k], f[6 + 2 * k] = 1.0, np.arctan2(p[1], p[0])
    edges = o["road_edges"][o["road_edges_mask"] > 0]
    f[11:14] = 1.0
    if len(edges):
        side = edges[np.abs(edges[:, 0]) < 4.0]
        left, right = side[side[:, 1] > 0, 1], -side[side[:, 1] < 0, 1]
        f[11] = min(left.min(), 10.0) / 10.0 if len(left) else 1.0
        f[12] = min(right.min(), 10.0) / 10.0 if len(right) else 1.0
        path = edges[(edges[:, 0] > 0) & (np.abs(edges[:, 1]) < 2.0)]
        f[13] = min(path[:, 0].min(), 40.0) / 40.0 if len(path) else 1.0
    agents = o["agents"][o["agents_mask"] > 0]
    f[14:20] = [1.0, 0.0, 1.0, 0.0, 1.0, 0.0]
    if len(agents):
        corridor = np.abs(agents[:, 1]) < 2.5
        for k, sel in enumerate((corridor & (agents[:, 0] > 0), corridor & (agents[:, 0] <= 0))):
            if sel.any():
                a = agents[sel][np.argmin(np.abs(agents[sel, 0]))]
                gap = max(abs(a[0]) - 0.5 * (a[6] + o["ego"][2]), 0.0)
                closing = (speed - a[4]) if k == 0 else (a[4] - speed)
                f[14 + 2 * k], f[15 + 2 * k] = min(gap, 40.0) / 40.0, np.clip(closing / 10.0, -2, 2)
        a = agents[np.argmin(np.hypot(agents[:, 0], agents[:, 1]))]
        f[18], f[19] = min(np.hypot(a[0], a[1]), 40.0) / 40.0, np.clip(a[1] / 10.0, -1, 1)
    lights = o["lights"][(o["lights_mask"] > 0) & (o["lights"][:, 0] > -1.0) & (np.abs(o["lights"][:, 1]) < 6.0)]
    f[20] = 1.0
    if len(lights):
        l = lights[np.argmin(lights[:, 0])]
        f[20], f[21], f[22] = min(max(l[0], 0.0), 60.0) / 60.0, l[7], l[6]
    f[23] = 1.0  # bias-like constant
    return f


def features(obs):
    """The batched observation dict as a (n, 24) float32 array (_ego_features of each env)."""
    n = obs["ego"].shape[0]
    return np.stack([_ego_features({k: v[i] for k, v in obs.items()}) for i in range(n)])


def drivable_scenarios(target):
    """The names of the scenarios the server at `target` serves that have an SDC (the ego; the others cannot be
    driven), and the number it serves."""
    channel, stub = connect(target)
    listed = stub.ListScenarios(pb.ListScenariosRequest(), timeout=60).scenarios
    channel.close()
    return [s.name for s in listed if s.has_sdc], len(listed)


def to_env(u):
    return np.clip(u * ACTION_SCALE, ACTION_LOW, ACTION_HIGH).astype(np.float32)


class ActorCritic(nn.Module):
    def __init__(self, n_features, hidden=64):
        super().__init__()

        def mlp(out):
            return nn.Sequential(nn.Linear(n_features, hidden), nn.Tanh(), nn.Linear(hidden, hidden), nn.Tanh(),
                                 nn.Linear(hidden, out))

        self.actor, self.critic = mlp(2), mlp(1)
        self.log_std = nn.Parameter(torch.full((2,), -0.5))
        with torch.no_grad():  # start near u = 0 (keep speed and heading), the critic near 0
            self.actor[-1].weight.mul_(0.01)
            self.actor[-1].bias.zero_()
            self.critic[-1].weight.mul_(0.1)

    def dist(self, x):
        return torch.distributions.Normal(self.actor(x), self.log_std.exp())

    def value(self, x):
        return self.critic(x).squeeze(-1)


class EpisodeStats:
    """Returns and events of the episodes each env is in; collects the ones that end."""

    def __init__(self, n):
        self.ret = np.zeros(n)
        self.length = np.zeros(n, int)
        self.red = np.zeros(n, bool)
        self.done = []

    def add(self, i, reward, info, ended, truncated):
        self.ret[i] += reward
        self.length[i] += 1
        self.red[i] |= bool(info["ran_red_light"])
        if ended:
            self.done.append({"return": float(self.ret[i]), "length": int(self.length[i]),
                              "collision": bool(info["collision"]), "off_road": bool(info["off_road"]),
                              "red_light": bool(self.red[i]), "truncated": bool(truncated)})
            self.ret[i], self.length[i], self.red[i] = 0.0, 0, False


def step_info(infos, i, ended):
    """The events of env i's step: in final_info when its episode ended (same-step autoreset)."""
    if ended:
        return infos["final_info"][i]
    return {k: infos[k][i] for k in ("collision", "off_road", "ran_red_light")}


def summarize(episodes):
    if not episodes:
        return {"episodes": 0}
    rate = lambda k: float(np.mean([e[k] for e in episodes]))  # noqa: E731
    return {"episodes": len(episodes), "mean_return": float(np.mean([e["return"] for e in episodes])),
            "collision_rate": rate("collision"), "offroad_rate": rate("off_road"), "red_light_rate": rate("red_light"),
            "truncated_rate": rate("truncated"), "mean_length": float(np.mean([e["length"] for e in episodes]))}


def ppo_update(model, opt, batch, args):
    x, u, logp_old, adv, ret = batch
    adv = (adv - adv.mean()) / (adv.std() + 1e-8)
    n = len(x)
    stats = []
    for _ in range(args.epochs):
        for idx in torch.randperm(n).split(args.minibatch):
            d = model.dist(x[idx])
            logp = d.log_prob(u[idx]).sum(-1)
            ratio = (logp - logp_old[idx]).exp()
            pg = -torch.min(ratio * adv[idx], ratio.clamp(1 - args.clip, 1 + args.clip) * adv[idx]).mean()
            vf = 0.5 * (model.value(x[idx]) - ret[idx]).pow(2).mean()
            ent = d.entropy().sum(-1).mean()
            loss = pg + args.vf_coef * vf - args.ent_coef * ent
            opt.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(model.parameters(), 0.5)
            opt.step()
            stats.append([pg.item(), vf.item(), ent.item(), ((ratio - 1).abs() > args.clip).float().mean().item()])
    pg, vf, ent, clipped = np.mean(stats, axis=0)
    return {"policy_loss": float(pg), "value_loss": float(vf), "entropy": float(ent), "clip_fraction": float(clipped)}


def train(args, log):
    torch.manual_seed(args.seed)
    venv = SceneStreamerVectorEnv(args.envs, target=args.train_target, max_steps=args.max_steps, reward=reward(args),
                                  scenarios=args.train_names)
    obs, _ = venv.reset(seed=args.seed)
    n_features = features(obs).shape[1]
    model = ActorCritic(n_features, args.hidden)
    opt = torch.optim.Adam(model.parameters(), lr=args.lr)
    stats = EpisodeStats(args.envs)
    start = time.time()
    history = []
    for it in range(args.iterations):
        if args.minutes and it > 0 and time.time() - start > args.minutes * 60:
            break
        t0 = time.time()
        T, n = args.rollout, args.envs
        xs = np.zeros((T, n, n_features), np.float32)
        us = np.zeros((T, n, 2), np.float32)
        logps = np.zeros((T, n), np.float32)
        values = np.zeros((T + 1, n), np.float32)
        rewards = np.zeros((T, n), np.float32)
        dones = np.zeros((T, n), np.float32)
        first_done = len(stats.done)
        for t in range(T):
            x = features(obs)
            with torch.no_grad():
                xt = torch.from_numpy(x)
                d = model.dist(xt)
                u = d.sample()
                logps[t] = d.log_prob(u).sum(-1).numpy()
                values[t] = model.value(xt).numpy()
            xs[t], us[t] = x, u.numpy()
            obs, r, terminated, truncated, infos = venv.step(to_env(us[t]))
            rewards[t] = r
            for i in range(n):
                ended = bool(terminated[i] or truncated[i])
                stats.add(i, r[i], step_info(infos, i, ended), ended, truncated[i] and not terminated[i])
                if truncated[i] and not terminated[i]:  # a time limit, not an end: bootstrap from the last obs
                    final = {k: v[None] for k, v in infos["final_obs"][i].items()}
                    with torch.no_grad():
                        rewards[t, i] += args.gamma * model.value(torch.from_numpy(features(final))).item()
                dones[t, i] = float(ended)
        with torch.no_grad():
            values[T] = model.value(torch.from_numpy(features(obs))).numpy()
        adv = np.zeros((T, n), np.float32)
        last = np.zeros(n, np.float32)
        for t in reversed(range(T)):
            nonterminal = 1.0 - dones[t]
            delta = rewards[t] + args.gamma * values[t + 1] * nonterminal - values[t]
            last = delta + args.gamma * args.lam * nonterminal * last
            adv[t] = last
        ret = adv + values[:T]
        rollout_s = time.time() - t0
        batch = [torch.from_numpy(a.reshape(T * n, *a.shape[2:])) for a in (xs, us, logps, adv, ret)]
        update = ppo_update(model, opt, batch, args)
        row = {"iteration": it, "env_steps": (it + 1) * T * n, "wall_s": round(time.time() - start, 1),
               "rollout_s": round(rollout_s, 1), **summarize(stats.done[first_done:]), **update,
               "std": [round(float(s), 3) for s in model.log_std.exp()]}
        history.append(row)
        log.write(json.dumps(row) + "\n")
        log.flush()
        print(f"it {it:3d} steps {row['env_steps']:6d} {row['wall_s']:7.1f}s eps {row['episodes']:3d} "
              f"return {row.get('mean_return', float('nan')):7.2f} coll {row.get('collision_rate', float('nan')):.2f} "
              f"off {row.get('offroad_rate', float('nan')):.2f} red {row.get('red_light_rate', float('nan')):.2f} "
              f"len {row.get('mean_length', float('nan')):5.1f} ent {update['entropy']:.2f}", flush=True)
    venv.close()
    return model, history


def run_episode(policy, args, name, seed):
    """One held-out episode: scenario `name`, env seed `seed`, until it ends; its return and events."""
    env = SceneStreamerEnv(args.eval_target, scenarios=[name], max_steps=args.max_steps, reward=reward(args))
    rng = np.random.default_rng(seed)  # the random policy's draws
    try:
        obs, _ = env.reset(seed=seed)
        stats = EpisodeStats(1)
        while not stats.done:
            obs, r, terminated, truncated, info = env.step(policy({k: v[None] for k, v in obs.items()}, rng)[0])
            stats.add(0, r, info, terminated or truncated, truncated and not terminated)
    finally:
        env.close()
    return stats.done[0]


def evaluate(models, args, names):
    """Every policy drives the same episodes: episode j is held-out scenario names[j % len(names)] with env seed
    args.eval_seed + j (so the same session seed: the same start and the same model randomness until the egos'
    actions differ). Episodes run concurrently (--eval-concurrency sessions), each its own SceneStreamerEnv."""
    count = args.eval_episodes or len(names)
    jobs = [(label, j) for label in models for j in range(count)]
    with concurrent.futures.ThreadPoolExecutor(args.eval_concurrency) as pool:
        futures = {job: pool.submit(run_episode, models[job[0]], args, names[job[1] % len(names)],
                                    args.eval_seed + job[1]) for job in jobs}
        results = {}
        for label in models:
            episodes = []
            for j in range(count):
                e = futures[(label, j)].result()
                e.update(episode=j, scenario=names[j % len(names)], seed=args.eval_seed + j)
                episodes.append(e)
            summary = summarize(episodes)
            print(f"eval {label:8s} {summary['episodes']} episodes: return {summary['mean_return']:.2f} "
                  f"collision {summary['collision_rate']:.3f} off road {summary['offroad_rate']:.3f} "
                  f"red light {summary['red_light_rate']:.3f} truncated {summary['truncated_rate']:.3f} "
                  f"length {summary['mean_length']:.1f}", flush=True)
            results[label] = {"summary": summary, "episodes": episodes}
    return results


def policies(model):
    """The three policies compared, each (batched obs, rng) -> batched actions."""
    def trained(obs, rng):  # the mean action, no exploration noise
        with torch.no_grad():
            return to_env(model.dist(torch.from_numpy(features(obs))).mean.numpy())

    def cruise_policy(obs, rng):
        return np.stack([cruise({k: v[i] for k, v in obs.items()}) for i in range(len(obs["ego"]))])

    def random_policy(obs, rng):  # uniform over the action space
        return rng.uniform(ACTION_LOW, ACTION_HIGH, size=(len(obs["ego"]), 2)).astype(np.float32)

    return {"ppo": trained, "cruise": cruise_policy, "random": random_policy}


def moving_average(values, w):
    out = []
    for i in range(len(values)):
        window = [v for v in values[max(0, i - w + 1):i + 1] if v is not None]
        out.append(sum(window) / len(window) if window else None)
    return out


def plot_svg(history, path, title):
    """Four panels over iterations (mean return, collision, off-road and red-light rates): each iteration's value as a
    dot and a moving average (5 iterations) as a line. Plain SVG, no matplotlib."""
    keys = [("mean_return", "mean episode return"), ("collision_rate", "collision rate (episodes)"),
            ("offroad_rate", "off-road rate (episodes)"), ("red_light_rate", "red-light rate (episodes)")]
    W, H, pw, ph, ml, mt = 900, 640, 370, 220, 70, 60
    iters = [h["iteration"] for h in history]
    xmax = max(iters[-1], 1) if iters else 1
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" '
           f'font-size="12">', f'<rect width="{W}" height="{H}" fill="white"/>',
           f'<text x="{W / 2}" y="24" text-anchor="middle" font-size="15">{title}</text>']
    for k, (key, label) in enumerate(keys):
        ox, oy = ml + (k % 2) * (pw + 80), mt + (k // 2) * (ph + 80)
        vals = [h.get(key) for h in history]
        real = [v for v in vals if v is not None]
        if key == "mean_return":
            lo, hi = (min(real + [0.0]), max(real + [1.0])) if real else (0.0, 1.0)
        else:
            lo, hi = 0.0, max(real + [0.1]) if real else 1.0
        pad = 0.05 * (hi - lo or 1.0)
        lo, hi = (lo - pad if key == "mean_return" else 0.0), hi + pad
        sx = lambda i: ox + pw * i / xmax  # noqa: E731
        sy = lambda v: oy + ph - ph * (v - lo) / (hi - lo)  # noqa: E731
        out.append(f'<rect x="{ox}" y="{oy}" width="{pw}" height="{ph}" fill="none" stroke="#444"/>')
        out.append(f'<text x="{ox + pw / 2}" y="{oy - 8}" text-anchor="middle">{label}</text>')
        for f in (0.0, 0.25, 0.5, 0.75, 1.0):
            v = lo + f * (hi - lo)
            y = sy(v)
            out.append(f'<line x1="{ox}" y1="{y:.1f}" x2="{ox + pw}" y2="{y:.1f}" stroke="#ddd"/>')
            out.append(f'<text x="{ox - 6}" y="{y + 4:.1f}" text-anchor="end">{v:.2f}</text>')
        for f in (0.0, 0.5, 1.0):
            i = f * xmax
            out.append(f'<text x="{sx(i):.1f}" y="{oy + ph + 16}" text-anchor="middle">{i:.0f}</text>')
        out.append(f'<text x="{ox + pw / 2}" y="{oy + ph + 32}" text-anchor="middle">PPO iteration</text>')
        for i, v in zip(iters, vals):
            if v is not None:
                out.append(f'<circle cx="{sx(i):.1f}" cy="{sy(v):.1f}" r="2" fill="#9bb7d4"/>')
        pts = [(sx(i), sy(v)) for i, v in zip(iters, moving_average(vals, 5)) if v is not None]
        if pts:
            out.append('<polyline fill="none" stroke="#1f4e9c" stroke-width="2" points="' +
                       " ".join(f"{x:.1f},{y:.1f}" for x, y in pts) + '"/>')
    out.append(f'<text x="{W - 10}" y="{H - 8}" text-anchor="end" fill="#666">dots: each iteration; line: mean of the '
               f'last 5 iterations</text>')
    out.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--train-target", default="127.0.0.1:50061", help="server with the training scenarios")
    p.add_argument("--eval-target", default="127.0.0.1:50062", help="server with the held-out scenarios")
    p.add_argument("--out", default="ppo_run")
    p.add_argument("--envs", type=int, default=8)
    p.add_argument("--rollout", type=int, default=16, help="steps per env per iteration")
    p.add_argument("--iterations", type=int, default=1000)
    p.add_argument("--minutes", type=float, default=35, help="no new iteration starts after this (0: no limit)")
    p.add_argument("--max-steps", type=int, default=30, help="episode length (0.5 s steps)")
    p.add_argument("--collision-penalty", type=float, default=-20.0, help="reward on a collision (the episode ends)")
    p.add_argument("--hidden", type=int, default=64)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--gamma", type=float, default=0.97)
    p.add_argument("--lam", type=float, default=0.95)
    p.add_argument("--clip", type=float, default=0.2)
    p.add_argument("--epochs", type=int, default=8)
    p.add_argument("--minibatch", type=int, default=32)
    p.add_argument("--vf-coef", type=float, default=0.5)
    p.add_argument("--ent-coef", type=float, default=0.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--eval-episodes", type=int, default=0, help="0: one per held-out scenario")
    p.add_argument("--eval-seed", type=int, default=10_000)
    p.add_argument("--eval-concurrency", type=int, default=12, help="evaluation sessions at once")
    p.add_argument("--quick", action="store_true", help="one tiny iteration and a 2-episode evaluation (the test)")
    args = p.parse_args()
    if args.quick:
        args.envs, args.rollout, args.iterations, args.max_steps, args.minibatch = 2, 8, 1, 6, 8
        args.epochs, args.eval_episodes, args.minutes = 1, 2, 0
    torch.set_num_threads(1)
    os.makedirs(args.out, exist_ok=True)

    train_names, n_train = drivable_scenarios(args.train_target)
    eval_names, n_eval = drivable_scenarios(args.eval_target)
    shared = sorted(set(train_names) & set(eval_names))
    if shared:
        raise SystemExit(f"the evaluation server serves {len(shared)} training scenarios ({shared[:3]} ...): "
                         "start it on held-out scenarios")
    print(f"{len(train_names)} training scenarios with an SDC (of {n_train}) at {args.train_target}, "
          f"{len(eval_names)} held-out (of {n_eval}) at {args.eval_target}", flush=True)
    args.train_names = train_names

    with open(os.path.join(args.out, "log.jsonl"), "w") as log:
        model, history = train(args, log)
    torch.save(model.state_dict(), os.path.join(args.out, "policy.pt"))
    plot_svg(history, os.path.join(args.out, "curves.svg"),
             f"PPO against the SceneStreamer server: {args.envs} envs x {args.rollout} steps per iteration")
    model.eval()
    results = {"args": {k: v for k, v in vars(args).items() if k != "train_names"}, "reward": vars(reward(args)),
               "train_scenarios": len(train_names), "eval_scenarios": eval_names, "iterations": len(history)}
    t0 = time.time()
    results.update(evaluate(policies(model), args, eval_names))
    results["eval_s"] = round(time.time() - t0, 1)
    with open(os.path.join(args.out, "eval.json"), "w") as f:
        json.dump(results, f, indent=1)
    print(f"wrote {args.out}/log.jsonl, eval.json, curves.svg, policy.pt")


if __name__ == "__main__":
    main()
