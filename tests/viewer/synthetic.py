"""Synthetic GPUDrive/Nocturne JSON scenarios with a known schedule, for the viewer's scrubber test and its frame-rate
measurement (300 agents on a 2,000-feature map). `python3 synthetic.py OUT.json AGENTS ROADS` writes one."""
import json
import math
import sys

FRAMES = 91
TYPES = ["vehicle", "pedestrian", "cyclist"]


def valid_frames(i, frames=FRAMES):
    """Agent i's valid frames: [start, end). Some appear late and some leave early, so counts change over time."""
    start = (i * 7) % 30 if i % 3 == 0 else 0
    end = frames - ((i * 11) % 25 if i % 4 == 1 else 0)
    return start, end


def expected_agents(num_agents, frame):
    return sum(1 for i in range(num_agents) if valid_frames(i)[0] <= frame < valid_frames(i)[1])


def scenario(num_agents, num_roads, scenario_id="synthetic-viewer", points=10):
    side = max(1, int(math.sqrt(num_roads / 2)))
    roads = []
    for r in range(num_roads):
        row, col = divmod(r // 2, side)
        x0, y0 = col * 40.0, row * 40.0
        horizontal = r % 2 == 0
        kind = ["lane", "road_edge", "road_line", "lane"][r % 4]
        geometry = [{"x": x0 + (k * 4.0 if horizontal else 0.0), "y": y0 + (0.0 if horizontal else k * 4.0), "z": 0.0}
                    for k in range(points)]
        roads.append({"id": r, "type": kind, "geometry": geometry})
    objects = []
    extent = side * 40.0
    for i in range(num_agents):
        start, end = valid_frames(i)
        x0, y0 = (i * 37.0) % extent, (i * 53.0) % extent
        h = (i * 0.7) % (2 * math.pi) - math.pi
        speed = 2.0 + i % 9
        pos, vel, heading, valid = [], [], [], []
        for f in range(FRAMES):
            ok = start <= f < end
            t = f * 0.1
            pos.append({"x": x0 + speed * t * math.cos(h), "y": y0 + speed * t * math.sin(h), "z": 0.0} if ok
                       else {"x": -10000.0, "y": -10000.0, "z": -10000.0})
            vel.append({"x": speed * math.cos(h), "y": speed * math.sin(h)} if ok else {"x": -10000.0, "y": -10000.0})
            heading.append(h if ok else -10000.0)
            valid.append(ok)
        kind = TYPES[i % 3]
        objects.append({"id": i + 1, "type": kind, "position": pos, "velocity": vel, "heading": heading,
                        "valid": valid, "length": 4.5 if kind == "vehicle" else 0.8,
                        "width": 2.0 if kind == "vehicle" else 0.8, "height": 1.6})
    return {"name": scenario_id + ".json", "scenario_id": scenario_id, "objects": objects, "roads": roads,
            "tl_states": {}, "metadata": {"sdc_track_index": 0}}


if __name__ == "__main__":
    out, agents, roads = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    with open(out, "w") as f:
        json.dump(scenario(agents, roads), f)
