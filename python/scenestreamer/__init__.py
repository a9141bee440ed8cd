"""SceneStreamer RL clients: a Gymnasium-style environment over the SceneStreamer server, a vector environment
(one round trip per tick over N sessions) and a PettingZoo-style parallel environment (several egos in one session).

    from scenestreamer import SceneStreamerEnv
    env = SceneStreamerEnv("127.0.0.1:50051")
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

For libraries whose standard policies want a vector observation and normalised actions (Stable-Baselines3, most PPO
implementations): FlatObservation(SceneStreamerEnv(target, normalize_actions=True)).

The gRPC stubs are scenestreamer.v1.simulator_pb2 and simulator_pb2_grpc (generated from proto/ when the package is
built)."""
from scenestreamer.env import SceneStreamerEnv
from scenestreamer.observation import ObservationConfig
from scenestreamer.parallel_env import SceneStreamerParallelEnv
from scenestreamer.policies import cruise
from scenestreamer.reward import RewardConfig
from scenestreamer.spaces import HAVE_GYMNASIUM, HAVE_PETTINGZOO
from scenestreamer.vector_env import SceneStreamerVectorEnv
from scenestreamer.wrappers import FlatObservation

__all__ = ["SceneStreamerEnv", "SceneStreamerVectorEnv", "SceneStreamerParallelEnv", "ObservationConfig",
           "RewardConfig", "cruise", "FlatObservation", "HAVE_GYMNASIUM", "HAVE_PETTINGZOO"]
