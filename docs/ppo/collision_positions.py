"""Where the other agent is when a cruise-driven ego's episode ends in a collision: the held-out episodes of ppo.py's
evaluation (val scenario j, env seed 10,000 + j, 30 steps), against the server serving the val split.
    /usr/bin/python3 docs/ppo/collision_positions.py 127.0.0.1:50062 > docs/ppo/collision_positions.txt"""
import concurrent.futures, json, math, os, sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'client_examples', 'python'))
import numpy as np
import ppo
from scenestreamer import SceneStreamerEnv, cruise
from scenestreamer.observation import find_agent
TARGET = sys.argv[1] if len(sys.argv) > 1 else '127.0.0.1:50062'
names, _ = ppo.drivable_scenarios(TARGET)
def one(j):
    env = SceneStreamerEnv(TARGET, scenarios=[names[j]], max_steps=30, reward=ppo.REWARD)
    obs, _ = env.reset(seed=10000 + j)
    for t in range(30):
        obs, r, te, tr, info = env.step(cruise(obs))
        if te or tr: break
    out = {"j": j, "steps": t + 1, "collision": info["collision"], "off_road": info["off_road"]}
    if info["collision"]:
        ego = find_agent(env.tick, env.ego_id).state
        o = find_agent(env.tick, info["collided_with"][0]).state
        c, s = math.cos(ego.heading), math.sin(ego.heading)
        dx, dy = o.x - ego.x, o.y - ego.y
        out.update(dx=round(c * dx + s * dy, 2), dy=round(-s * dx + c * dy, 2),
                   dheading=round(math.degrees(math.atan2(math.sin(o.heading - ego.heading), math.cos(o.heading - ego.heading)))),
                   ego_speed=round(math.hypot(ego.vx, ego.vy), 1), other_speed=round(math.hypot(o.vx, o.vy), 1))
    env.close()
    return out
with concurrent.futures.ThreadPoolExecutor(12) as pool:
    res = list(pool.map(one, range(len(names))))
for r in res: print(json.dumps(r))
c = [r for r in res if r["collision"]]
print(len(res), "episodes", len(c), "collisions; at step 1:", sum(r["steps"] == 1 for r in c),
      "other behind (dx<0):", sum(r["dx"] < 0 for r in c), "ahead:", sum(r["dx"] >= 0 for r in c))
