"""The scene the pose stages look for people in (config perception.scene), as settings, not code.

- `players` (the ping-pong lab): two slots, 'near' (+y) and 'far' (-y); a person fills a slot when it
  stands within `area_margin_m` of that player's area (|x| <= area_half_width_m, |y| in area_y_m, table
  frame). Bystanders beside the table or far behind stand outside both areas.
- `subjects` (a pose-only lab, any world frame): up to `subjects` people anywhere in the cameras' common
  view, labelled 'subject0', 'subject1', ... in a stable order (by continuity from frame to frame).
"""

from dataclasses import dataclass

import numpy as np

from pingpong.common.config import Settings

PLAYERS = ("near", "far")  # index 0: the player at +y, 1: at -y
PLAYER_SIGNS = (1.0, -1.0)


@dataclass(frozen=True)
class Scene(Settings):
    mode: str
    subjects: int
    area_half_width_m: float
    area_y_m: tuple[float, float]
    area_margin_m: float

    def __post_init__(self):
        object.__setattr__(self, "area_y_m", tuple(self.area_y_m))  # a config list compares as the tuple
        if self.mode not in ("players", "subjects"):
            raise ValueError(f"scene mode must be 'players' or 'subjects', got {self.mode!r}")

    @property
    def slots(self) -> tuple[str, ...]:
        if self.mode == "players":
            return PLAYERS
        return tuple(f"subject{k}" for k in range(self.subjects))

    def area_costs(self, floor_xy: np.ndarray) -> np.ndarray:
        """(..., 2) distance (m) of table-frame floor positions (..., 2) from the near and far players'
        areas; inf where a position is NaN."""
        floor_xy = np.asarray(floor_xy, float)
        dx = np.maximum(np.abs(floor_xy[..., 0]) - self.area_half_width_m, 0.0)
        costs = []
        for sign in PLAYER_SIGNS:
            y = sign * floor_xy[..., 1]
            dy = np.maximum(self.area_y_m[0] - y, 0.0) + np.maximum(y - self.area_y_m[1], 0.0)
            costs.append(np.hypot(dx, dy))
        return np.nan_to_num(np.stack(costs, axis=-1), nan=np.inf)


def default_players_scene() -> Scene:
    """The ping-pong lab's scene with config/schema.yaml's defaults, for tests and benchmarks."""
    return Scene("players", 1, 1.5, (1.37, 4.37), 0.3)
