"""FlatObservation: SceneStreamerEnv's dict observation as one flat float32 Box, for libraries whose standard policies
take a vector (Stable-Baselines3's MlpPolicy, most PPO implementations)."""
from scenestreamer.spaces import ObservationWrapper, flat_box, flatten


class FlatObservation(ObservationWrapper):
    """Wraps a SceneStreamerEnv (or any env with a Dict-of-Box observation space): observations become one float32
    vector, the entries of the dict flattened row-major and concatenated in the space's order ("ego", "agents",
    "agents_mask", "lights", ...), with the entries' bounds. layout() lists (key, start, stop) of each entry in the
    vector, to find one again."""

    def __init__(self, env):
        super().__init__(env)
        self.dict_space = env.observation_space
        if not hasattr(self.dict_space, "spaces"):
            raise TypeError(f"FlatObservation: the env's observation space is {self.dict_space!r}, not a Dict of Box")
        self.observation_space = flat_box(self.dict_space)

    def observation(self, observation):
        return flatten(self.dict_space, observation)

    def layout(self):
        out, start = [], 0
        for key, box in self.dict_space.spaces.items():
            size = int(box.low.size)
            out.append((key, start, start + size))
            start += size
        return out
