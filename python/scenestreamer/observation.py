"""An ego policy's observation of a tick, as numpy arrays in the ego's frame (x forward, y left): the ego's own state,
the k nearest agents, the lights that face the ego's way, lane centres and road edges nearby; each list padded to a
fixed size with a mask (1: real entry)."""
import dataclasses
import math

import numpy as np

from scenestreamer.client import speed_of
from scenestreamer.spaces import Box, Dict

MAX_SPEED = 80.0   # m/s: bound of every speed in the observation
MAX_SIZE = 50.0    # m: bound of agent lengths and widths


@dataclasses.dataclass
class ObservationConfig:
    max_agents: int = 16         # nearest agents kept
    agent_radius: float = 60.0   # metres
    max_lights: int = 8
    light_radius: float = 60.0
    lane_points: int = 64        # nearest lane-centre points (resampled every 2 m)
    edge_points: int = 64        # nearest road-edge points
    road_radius: float = 40.0


AGENT_FEATURES = ("dx", "dy", "cos_dheading", "sin_dheading", "vx", "vy", "length", "width", "type")
LIGHT_FEATURES = ("dx", "dy", "cos_dheading", "sin_dheading", "unknown", "green", "yellow", "red")
LANE_FEATURES = ("dx", "dy", "dir_x", "dir_y")
EGO_FEATURES = ("speed", "lateral_speed", "length", "width")


def observation_space(c):
    def box(low, high, n=None):
        low, high = np.asarray(low, np.float32), np.asarray(high, np.float32)
        if n is not None:
            low, high = np.tile(low, (n, 1)), np.tile(high, (n, 1))
        return Box(low, high, dtype=np.float32)

    def mask(n):
        return Box(0.0, 1.0, shape=(n,), dtype=np.float32)

    ra, rl, rr = c.agent_radius, c.light_radius, c.road_radius
    return Dict({
        "ego": box([-MAX_SPEED, -MAX_SPEED, 0, 0], [MAX_SPEED, MAX_SPEED, MAX_SIZE, MAX_SIZE]),
        "agents": box([-ra, -ra, -1, -1, -MAX_SPEED, -MAX_SPEED, 0, 0, 0],
                      [ra, ra, 1, 1, MAX_SPEED, MAX_SPEED, MAX_SIZE, MAX_SIZE, 2], c.max_agents),
        "agents_mask": mask(c.max_agents),
        "lights": box([-rl, -rl, -1, -1, 0, 0, 0, 0], [rl, rl, 1, 1, 1, 1, 1, 1], c.max_lights),
        "lights_mask": mask(c.max_lights),
        "lanes": box([-rr, -rr, -1, -1], [rr, rr, 1, 1], c.lane_points),
        "lanes_mask": mask(c.lane_points),
        "road_edges": box([-rr, -rr], [rr, rr], c.edge_points),
        "road_edges_mask": mask(c.edge_points),
    })


def find_agent(tick, agent_id):
    for a in tick.agents:
        if a.id == agent_id:
            return a
    return None


def observe(tick, ego_id, road, c):
    """The observation of agent `ego_id` at `tick` (a Tick proto); `road` is the session's RoadMap."""
    ego = find_agent(tick, ego_id)
    if ego is None:
        raise KeyError(f"agent {ego_id} is not in tick {tick.tick}")
    s = ego.state
    cos_h, sin_h = math.cos(s.heading), math.sin(s.heading)
    rot = np.array([[cos_h, sin_h], [-sin_h, cos_h]])  # global -> ego frame
    centre = np.array([s.x, s.y])

    def local(xy):
        return (np.asarray(xy, np.float64) - centre) @ rot.T

    obs = {"ego": np.array([speed_of(s), -s.vx * sin_h + s.vy * cos_h, s.length, s.width], np.float32)}

    agents = np.zeros((c.max_agents, len(AGENT_FEATURES)), np.float32)
    agents_mask = np.zeros(c.max_agents, np.float32)
    others = [a for a in tick.agents if a.id != ego_id]
    if others:
        xy = np.array([[a.state.x, a.state.y] for a in others])
        for row, i in enumerate(road.nearest(xy, centre, c.agent_radius, c.max_agents)):
            a = others[i].state
            dh = a.heading - s.heading
            v = rot @ np.array([a.vx, a.vy])
            agents[row] = [*local(xy[i]), math.cos(dh), math.sin(dh), *v, a.length, a.width, others[i].type]
            agents_mask[row] = 1
    obs["agents"], obs["agents_mask"] = agents, agents_mask

    lights = np.zeros((c.max_lights, len(LIGHT_FEATURES)), np.float32)
    lights_mask = np.zeros(c.max_lights, np.float32)
    # The lights that matter: stop lines facing the ego's way (within 90 degrees), nearest first.
    facing = [l for l in tick.lights if math.cos(l.stop_point.heading - s.heading) > 0]
    if facing:
        xy = np.array([[l.stop_point.x, l.stop_point.y] for l in facing])
        for row, i in enumerate(road.nearest(xy, centre, c.light_radius, c.max_lights)):
            l = facing[i]
            dh = l.stop_point.heading - s.heading
            onehot = [0.0] * 4
            onehot[int(l.state)] = 1.0
            lights[row] = [*local(xy[i]), math.cos(dh), math.sin(dh), *onehot]
            lights_mask[row] = 1
    obs["lights"], obs["lights_mask"] = lights, lights_mask

    lanes = np.zeros((c.lane_points, len(LANE_FEATURES)), np.float32)
    lanes_mask = np.zeros(c.lane_points, np.float32)
    idx = road.nearest(road.lane_points, centre, c.road_radius, c.lane_points)
    if len(idx):
        lanes[:len(idx), :2] = local(road.lane_points[idx])
        lanes[:len(idx), 2:] = road.lane_dirs[idx] @ rot.T
        lanes_mask[:len(idx)] = 1
    obs["lanes"], obs["lanes_mask"] = lanes, lanes_mask

    edges = np.zeros((c.edge_points, 2), np.float32)
    edges_mask = np.zeros(c.edge_points, np.float32)
    idx = road.nearest(road.edge_points, centre, c.road_radius, c.edge_points)
    if len(idx):
        edges[:len(idx)] = local(road.edge_points[idx])
        edges_mask[:len(idx)] = 1
    obs["road_edges"], obs["road_edges_mask"] = edges, edges_mask
    # Rounding to float32 may step a hair past a radius bound: keep every value inside its space.
    for key in ("agents", "lights", "lanes", "road_edges"):
        r = {"agents": c.agent_radius, "lights": c.light_radius}.get(key, c.road_radius)
        np.clip(obs[key][:, :2], -r, r, out=obs[key][:, :2])
    np.clip(obs["lanes"][:, 2:], -1, 1, out=obs["lanes"][:, 2:])
    np.clip(obs["agents"][:, 4:6], -MAX_SPEED, MAX_SPEED, out=obs["agents"][:, 4:6])
    np.clip(obs["ego"][:2], -MAX_SPEED, MAX_SPEED, out=obs["ego"][:2])
    return obs
