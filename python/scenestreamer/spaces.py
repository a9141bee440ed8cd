"""Observation and action spaces: gymnasium's Box and Dict when gymnasium is installed, else minimal stand-ins with the
same constructor, attributes (shape, dtype, low, high, spaces) and methods (sample, contains, seed), so code written
for gymnasium runs unchanged. Debian has no gymnasium package; the project's tests run with the stand-ins."""
import numpy as np

try:
    import gymnasium
    from gymnasium.spaces import Box, Dict
    HAVE_GYMNASIUM = True
    Env = gymnasium.Env
except ImportError:  # the stand-ins below
    HAVE_GYMNASIUM = False

    class Env:
        """What gymnasium.Env provides that the environments use: np_random seeded by reset(seed=...)."""
        metadata = {}
        _np_random = None

        @property
        def np_random(self):
            if self._np_random is None:
                self._np_random = np.random.default_rng()
            return self._np_random

        def reset(self, *, seed=None, options=None):
            if seed is not None:
                self._np_random = np.random.default_rng(seed)

        @property
        def unwrapped(self):
            return self

    class Box:
        def __init__(self, low, high, shape=None, dtype=np.float32, seed=None):
            self.dtype = np.dtype(dtype)
            shape = tuple(shape) if shape is not None else np.shape(low)
            self.low = np.broadcast_to(np.asarray(low, dtype=self.dtype), shape).copy()
            self.high = np.broadcast_to(np.asarray(high, dtype=self.dtype), shape).copy()
            self.shape = shape
            self._rng = np.random.default_rng(seed)

        def seed(self, seed=None):
            self._rng = np.random.default_rng(seed)

        def sample(self):
            low = np.where(np.isfinite(self.low), self.low, -1.0)
            high = np.where(np.isfinite(self.high), self.high, 1.0)
            return self._rng.uniform(low, high).astype(self.dtype)

        def contains(self, x):
            x = np.asarray(x)
            return (x.shape == self.shape and np.can_cast(x.dtype, self.dtype) and
                    bool(np.all(x >= self.low)) and bool(np.all(x <= self.high)))

        def __contains__(self, x):
            return self.contains(x)

        def __repr__(self):
            return f"Box({self.low.min()}, {self.high.max()}, {self.shape}, {self.dtype})"

    class Dict:
        def __init__(self, spaces, seed=None):
            self.spaces = dict(spaces)
            if seed is not None:
                self.seed(seed)

        def seed(self, seed=None):
            for i, s in enumerate(self.spaces.values()):
                s.seed(None if seed is None else seed + i)

        def sample(self):
            return {k: s.sample() for k, s in self.spaces.items()}

        def contains(self, x):
            return isinstance(x, dict) and x.keys() == self.spaces.keys() and all(
                s.contains(x[k]) for k, s in self.spaces.items())

        def __contains__(self, x):
            return self.contains(x)

        def __getitem__(self, key):
            return self.spaces[key]

        def keys(self):
            return self.spaces.keys()

        def items(self):
            return self.spaces.items()

        def __repr__(self):
            return "Dict(" + ", ".join(f"{k}: {s}" for k, s in self.spaces.items()) + ")"


def batch_space(space, n):
    """The space of n stacked samples of `space` (Box and Dict of Box), as gymnasium.vector batches them."""
    if isinstance(space, Dict):
        return Dict({k: batch_space(s, n) for k, s in space.spaces.items()})
    return Box(np.repeat(space.low[None], n, axis=0), np.repeat(space.high[None], n, axis=0),
               dtype=space.dtype)
