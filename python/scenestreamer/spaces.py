"""The base classes of the environments and their spaces: gymnasium's Env, ObservationWrapper, Box and Dict when
gymnasium is installed, and PettingZoo's ParallelEnv when pettingzoo is; else minimal stand-ins with the same
constructors, attributes (shape, dtype, low, high, spaces; unwrapped, metadata, possible_agents, agents, ...) and
methods (sample, contains, seed; observation_space(agent), action_space(agent), ...), so code written for gymnasium
and PettingZoo runs unchanged. Debian packages neither; the project's tests run with the stand-ins."""
import numpy as np

try:
    import gymnasium
    from gymnasium.spaces import Box, Dict
    HAVE_GYMNASIUM = True
    Env = gymnasium.Env
    ObservationWrapper = gymnasium.ObservationWrapper
except ImportError:  # the stand-ins below
    HAVE_GYMNASIUM = False

    class Env:
        """What gymnasium.Env provides that the environments use: np_random seeded by reset(seed=...), unwrapped,
        metadata, render_mode and spec."""
        metadata = {}
        render_mode = None
        spec = None
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

        def close(self):
            pass

    class ObservationWrapper:
        """What gymnasium.ObservationWrapper provides: reset() and step() pass the wrapped env's observation through
        observation(); the spaces are the wrapped env's unless the wrapper sets its own; unwrapped is the innermost
        env. Like gymnasium 1.x, other attributes are not forwarded (read them from env.unwrapped)."""
        _observation_space = None
        _action_space = None

        def __init__(self, env):
            self.env = env

        @property
        def observation_space(self):
            return self.env.observation_space if self._observation_space is None else self._observation_space

        @observation_space.setter
        def observation_space(self, space):
            self._observation_space = space

        @property
        def action_space(self):
            return self.env.action_space if self._action_space is None else self._action_space

        @action_space.setter
        def action_space(self, space):
            self._action_space = space

        @property
        def metadata(self):
            return self.env.metadata

        @property
        def np_random(self):
            return self.env.np_random

        @property
        def unwrapped(self):
            return self.env.unwrapped

        def observation(self, observation):
            raise NotImplementedError

        def reset(self, *, seed=None, options=None):
            obs, info = self.env.reset(seed=seed, options=options)
            return self.observation(obs), info

        def step(self, action):
            obs, reward, terminated, truncated, info = self.env.step(action)
            return self.observation(obs), reward, terminated, truncated, info

        def close(self):
            return self.env.close()

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


try:
    from pettingzoo import ParallelEnv
    HAVE_PETTINGZOO = True
except ImportError:
    HAVE_PETTINGZOO = False

    class ParallelEnv:
        """What pettingzoo.ParallelEnv provides and its parallel_api_test reads: metadata, possible_agents, agents,
        observation_spaces and action_spaces (dicts by agent), observation_space(agent) and action_space(agent),
        num_agents, max_num_agents, unwrapped, state(), render() and close()."""
        metadata = {}
        possible_agents = []
        agents = []
        observation_spaces = {}
        action_spaces = {}

        def reset(self, seed=None, options=None):
            raise NotImplementedError

        def step(self, actions):
            raise NotImplementedError

        def observation_space(self, agent):
            return self.observation_spaces[agent]

        def action_space(self, agent):
            return self.action_spaces[agent]

        @property
        def num_agents(self):
            return len(self.agents)

        @property
        def max_num_agents(self):
            return len(self.possible_agents)

        @property
        def unwrapped(self):
            return self

        def state(self):
            raise NotImplementedError(f"state() is not implemented by {self.metadata.get('name', type(self).__name__)}")

        def render(self):
            raise NotImplementedError

        def close(self):
            pass

        def __str__(self):
            return self.metadata.get("name", type(self).__name__)


def flat_box(space):
    """The Box of a Dict of Box spaces' entries, each flattened (row-major) and concatenated in the Dict's order."""
    boxes = list(space.spaces.values())
    return Box(np.concatenate([b.low.ravel() for b in boxes]).astype(np.float32),
               np.concatenate([b.high.ravel() for b in boxes]).astype(np.float32), dtype=np.float32)


def flatten(space, observation, batch_dims=0):
    """An observation of the Dict of Box `space` as one float32 array: its entries flattened and concatenated in the
    space's order (flat_box(space)'s layout). batch_dims: leading dimensions to keep, e.g. 1 for a vector env's
    batched observation (N, ...) -> (N, size)."""
    if not isinstance(observation, dict) or observation.keys() != space.spaces.keys():
        got = sorted(observation) if isinstance(observation, dict) else type(observation).__name__
        raise ValueError(f"observation: expected a dict of {sorted(space.spaces)}, got {got}")
    parts = []
    for key, box in space.spaces.items():
        a = np.asarray(observation[key], np.float32)
        lead, entry = a.shape[:batch_dims], a.shape[batch_dims:]
        if entry != box.shape:
            raise ValueError(f"observation[{key!r}]: expected shape {box.shape} after {batch_dims} batch "
                             f"dimensions, got {a.shape}")
        parts.append(a.reshape(lead + (-1,)))
    return np.concatenate(parts, axis=-1)


def batch_space(space, n):
    """The space of n stacked samples of `space` (Box and Dict of Box), as gymnasium.vector batches them."""
    if isinstance(space, Dict):
        return Dict({k: batch_space(s, n) for k, s in space.spaces.items()})
    return Box(np.repeat(space.low[None], n, axis=0), np.repeat(space.high[None], n, axis=0),
               dtype=space.dtype)
