"""Simple reference policies over the observation (for examples and baselines)."""
import numpy as np


def cruise(obs, target_speed=8.0):
    """Approach a target speed; brake for an agent ahead in the ego's path; steer toward the point 4-15 m ahead on the
    lane the ego is on (the lane point there nearest the ego's axis, among lanes running the ego's way)."""
    speed = float(obs["ego"][0])
    a, m = obs["agents"], obs["agents_mask"] > 0
    ahead = m & (a[:, 0] > 0) & (a[:, 0] < 15) & (np.abs(a[:, 1]) < 2.5)
    accel = -4.0 if ahead.any() else float(np.clip(0.5 * (target_speed - speed), -2.0, 1.5))
    lanes, lm = obs["lanes"], obs["lanes_mask"] > 0
    ok = lm & (lanes[:, 0] > 4) & (lanes[:, 0] < 15) & (lanes[:, 2] > 0.7)
    yaw_rate = 0.0
    if ok.any():
        i = np.flatnonzero(ok)[np.argmin(np.abs(lanes[ok, 1]))]
        yaw_rate = float(np.clip(np.arctan2(lanes[i, 1], lanes[i, 0]), -0.5, 0.5))
    return np.array([accel, yaw_rate], np.float32)
