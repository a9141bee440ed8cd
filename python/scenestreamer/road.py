"""The session's road as arrays: lane centres resampled every `spacing` metres (with their direction) and road-edge
points, from the map features the server sends once per scenario (CreateSession include_map)."""
import numpy as np

from scenestreamer.v1 import simulator_pb2 as pb


def _resample(x, y, spacing):
    """Points every `spacing` metres along a polyline (its first and last points included), and unit directions."""
    p = np.stack([np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)], axis=1)
    if len(p) < 2:
        return np.zeros((0, 2)), np.zeros((0, 2))
    seg = np.diff(p, axis=0)
    length = np.linalg.norm(seg, axis=1)
    keep = length > 0
    if not keep.any():
        return np.zeros((0, 2)), np.zeros((0, 2))
    p = np.concatenate([p[:1], p[1:][keep]])
    seg, length = seg[keep], length[keep]
    s = np.concatenate([[0.0], np.cumsum(length)])
    at = np.append(np.arange(0.0, s[-1], spacing), s[-1])
    j = np.clip(np.searchsorted(s, at, side="right") - 1, 0, len(seg) - 1)
    t = (at - s[j]) / length[j]
    points = p[j] + t[:, None] * seg[j]
    return points, seg[j] / length[j][:, None]


class RoadMap:
    def __init__(self, features, spacing=2.0):
        lanes, lane_dirs, lane_ids, edges = [], [], [], []
        self.features = list(features)
        for f in self.features:
            if f.type == pb.MAP_FEATURE_LANE:
                pts, dirs = _resample(f.x, f.y, spacing)
                lanes.append(pts)
                lane_dirs.append(dirs)
                lane_ids.append(np.full(len(pts), f.id, dtype=np.int64))
            elif f.type == pb.MAP_FEATURE_ROAD_EDGE:
                edges.append(_resample(f.x, f.y, spacing)[0])
        self.lane_points = np.concatenate(lanes) if lanes else np.zeros((0, 2))
        self.lane_dirs = np.concatenate(lane_dirs) if lane_dirs else np.zeros((0, 2))
        self.lane_ids = np.concatenate(lane_ids) if lane_ids else np.zeros(0, dtype=np.int64)
        self.edge_points = np.concatenate(edges) if edges else np.zeros((0, 2))

    @staticmethod
    def nearest(points, centre, radius, k):
        """Indices of the at most k points within `radius` of `centre`, nearest first."""
        if len(points) == 0:
            return np.zeros(0, dtype=np.int64)
        d2 = np.sum((points - centre) ** 2, axis=1)
        inside = np.flatnonzero(d2 <= radius * radius)
        if len(inside) > k:
            inside = inside[np.argpartition(d2[inside], k - 1)[:k]]
        return inside[np.argsort(d2[inside], kind="stable")]
