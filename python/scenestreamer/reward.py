"""Reward and termination from the events the server reports for an agent at a tick (Tick.events)."""
import dataclasses


@dataclasses.dataclass
class RewardConfig:
    progress: float = 1.0        # per metre driven along the lane (negative when reversing)
    collision: float = -10.0     # when the agent's box overlaps another agent's
    off_road: float = -5.0       # when a box corner is beyond the road edge
    red_light: float = -5.0      # when it crossed a red light's stop line
    end_on_collision: bool = True
    end_on_off_road: bool = True
    end_on_red_light: bool = False


def events_of(tick, agent_id):
    """The AgentEvents of `agent_id` at `tick`, or None (the initial tick has none)."""
    for e in tick.events:
        if e.agent_id == agent_id:
            return e
    return None


def reward_and_termination(events, c):
    """(reward, terminated, info) for one agent's events under RewardConfig `c`."""
    collided = len(events.overlapping) > 0
    reward = (c.progress * events.progress + c.collision * collided + c.off_road * events.off_road +
              c.red_light * events.ran_red_light)
    terminated = ((c.end_on_collision and collided) or (c.end_on_off_road and events.off_road) or
                  (c.end_on_red_light and events.ran_red_light))
    info = {"collision": collided, "collided_with": list(events.overlapping), "off_road": events.off_road,
            "road_edge_distance": events.road_edge_distance, "ran_red_light": events.ran_red_light,
            "lane_id": events.lane_id, "lane_s": events.lane_s, "progress": events.progress}
    return float(reward), bool(terminated), info
