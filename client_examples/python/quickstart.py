"""The quick start (README, docs/rl.md): one episode of one environment, the ego driven by the cruise policy.

    python client_examples/python/quickstart.py 127.0.0.1:50051
"""
import sys

from scenestreamer import SceneStreamerEnv, cruise

env = SceneStreamerEnv(sys.argv[1] if len(sys.argv) > 1 else "127.0.0.1:50051", max_steps=20)
obs, info = env.reset(seed=0)
print("scenario", info["scenario"], "session", env.session_id)
print({k: v.shape for k, v in obs.items()})
episode_return = 0.0
while True:
    obs, reward, terminated, truncated, info = env.step(cruise(obs))
    episode_return += reward
    if terminated or truncated:
        break
print(f"return {episode_return:.2f} after {info['tick']} ticks; collision {info['collision']}, "
      f"off road {info['off_road']}, red light {info['ran_red_light']}")
env.close()
