"""Scenarios of ``parkfleet bench fleet``: data, builders, the JSON file format, the suites.

A :class:`Scenario` is plain data -- robots (start, goal, arrival time), static obstacles,
gains, tolerance, time limit -- and the same object is what a scenario file holds::

    {"name": "my-yard", "named": true,
     "robots": [{"start": [x, y, theta], "goal": [x, y, theta], "arrival_s": 0.0}],
     "obstacles": [{"x": 0.0, "y": 0.0, "radius": 1.0}]}

Units: metres, radians, simulated seconds, world frame. ``named``: each task names its
robot (robot k parks at goal k); otherwise the fleet assigns goals to robots. ``arrival_s``:
when the task is submitted, after the run's start. Optional fields: ``robots[].id``;
``obstacles[].body`` (physical radius [m], default 0.1: what counts as hitting it; ``radius``
is the influence radius of Eq. 27, as in the API); ``walls`` (as in a site file:
``[{"points": [[x, y], ...], "closed": false, "body": 0.05, "radius": 0.3}]``, every edge
a segment with a body); ``zones`` (single-robot zones as in a site file:
``[{"name": "gate", "rect": {"xmin", "xmax", "ymin", "ymax"}}]`` or a ``polygon``; the
narrow passages the walls make are found without it); ``lanes`` (as in a site file:
``[{"points": [[x, y], ...], "one_way": false}]``: routes follow them); ``law_gains``
(``{"ccw": {"kx", "ky", "ktheta"}, "cw": {...}}``); ``tolerance``
(``{"position", "heading"}``, default 0.1 m / 0.1 rad); ``time_limit_s`` (default 120:
the run stops this long after the last arrival);
``family`` and ``seed`` (group seeds of one family in the summary); ``yard``
(``[xmin, xmax, ymin, ymax]``, the service's yard for the run; default 20 m x 20 m around
the origin). Built-in scenarios
of 30 robots or more get 180 s. A file holds one
scenario or a list. Goals are checked as the fleet service checks them (inside the yard,
outside every influence zone, more than the peer radius apart), so a bad file fails early
with the reason.

Built-in families (:func:`full_suite`, :func:`quick_suite`):

* ``swap-N-right`` / ``swap-N-left`` -- N robots on a circle (radius 6 m, larger for N = 32
  so neighbours stay 1.5 m apart) park at the antipodal point; start heading towards the
  centre turned right by pi/4 and goal heading turned left (``right``), or the mirror image
  (``left``). Named.
* ``yard-N-sS`` -- N random starts and goals (seed S) at one robot per 10 m^2, points at
  least 1.5 m apart; fleet-assigned.
* ``stream-N-sS`` -- a yard whose tasks arrive as a Poisson stream (mean gap 3 s) while
  others drive; fleet-assigned.
* ``carpark-12`` (and ``carpark-12-stream-sS``) -- two rows of bays along the walls of a
  car park built of posts, robots queued outside entering through a 2.4 m gate;
  fleet-assigned. ``carpark-walls-12``: the same car park with walls (segments with a
  body) instead of posts.
* ``garage-12`` -- a parking garage with two gates (west and east) and three aisles, bays
  along its north and south walls; six robots queued outside each gate; fleet-assigned.
* ``corridor-6`` -- two 8 x 10 m rooms joined by an 8 m corridor 1.2 m wide (two robots
  cannot pass in it: a narrow passage, held by one robot at a time); three robots in each
  room, each bound for a bay in the other room. Named.
* ``ring-8-post``, ``ring-12-post``, ``ring-16-post``, ``ring-6-posts``, ``ring-8-wall``
  -- robots on a circle round posts or a short wall park at the antipodal point
  (:func:`rings`); named.
* ``cross-8``, ``cross-16`` -- two lanes crossing, one and two rows deep
  (:func:`crossing_lanes`); named.
* ``stagger-12-right`` / ``-left`` -- a 12-robot swap whose tasks arrive 1.5 s apart;
  named.
* ``case-III`` -- the paper's comparative case III with two obstacles at (+-0.8, 0) (the
  paper gives only the figure), Table 8 gains; ``case-III-4`` -- four robots crossing the
  same pair of obstacles.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from fleet.core.goals import Occupied, validate_goal
from fleet.core.params import Avoidance, Gains, Tolerance
from fleet.core.site import Lane, Site, Wall, Yard, Zone
from fleet.core.tasks import GoalRejected
from fleet.core.types import Law, Posture
from fleet.core.wire import Obstacle, Pose, RobotId
from fleet.paper.scenarios import SCENARIOS

Finite = Annotated[float, Field(allow_inf_nan=False)]
#: The yard the fleet service accepts goals in by default (x_min, x_max, y_min, y_max) [m].
YARD = (-10.0, 10.0, -10.0, 10.0)
#: Tolerance of the benchmark's tasks unless a scenario says otherwise: 0.1 m, 0.1 rad.
BENCH_TOLERANCE = Tolerance(position=0.1, heading=0.1)
#: Robots per square metre of the random yards (one per 10 m^2).
YARD_DENSITY = 0.1
#: Mean gap [s] between task arrivals of the stream scenarios.
STREAM_GAP_S = 3.0


class RobotSpec(BaseModel):
    """One robot: start and goal postures (x [m], y [m], theta [rad]), task arrival [s]."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    start: tuple[Finite, Finite, Finite]
    goal: tuple[Finite, Finite, Finite]
    arrival_s: Annotated[float, Field(ge=0.0, allow_inf_nan=False)] = 0.0
    id: RobotId | None = None


class ObstacleSpec(BaseModel):
    """A static obstacle: centre [m], influence radius of Eq. (27) [m], body radius [m]."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    x: Finite
    y: Finite
    radius: Annotated[float, Field(gt=0.0, allow_inf_nan=False)]
    body: Annotated[float, Field(ge=0.0, allow_inf_nan=False)] = 0.1

    @model_validator(mode="after")
    def _body_inside_zone(self) -> ObstacleSpec:
        if self.body >= self.radius:
            raise ValueError(f"body {self.body} m must be smaller than the radius {self.radius} m")
        return self

    def as_obstacle(self) -> Obstacle:
        return Obstacle(x=self.x, y=self.y, radius=self.radius, body=self.body)


class Scenario(BaseModel):
    """A benchmark scenario (see the module docstring for every field)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: Annotated[str, Field(min_length=1, max_length=80, pattern=r"^[A-Za-z0-9_.+-]+$")]
    named: bool = True
    robots: Annotated[list[RobotSpec], Field(min_length=1, max_length=200)]
    obstacles: list[ObstacleSpec] = []
    #: Walls (polylines, polygons) as in a site file: segments with a body.
    walls: Annotated[list[Wall], Field(max_length=100)] = []
    #: Single-robot zones as in a site file (narrow passages the walls make are found).
    zones: Annotated[list[Zone], Field(max_length=100)] = []
    #: Lanes as in a site file: routes follow them.
    lanes: Annotated[list[Lane], Field(max_length=100)] = []
    law_gains: dict[Law, Gains] | None = None
    tolerance: Tolerance = BENCH_TOLERANCE
    time_limit_s: Annotated[float, Field(gt=0.0, le=3600.0)] = 120.0
    family: str | None = None
    seed: int | None = None
    #: (xmin, xmax, ymin, ymax) [m] of the yard the service runs with; None: :data:`YARD`.
    yard: tuple[Finite, Finite, Finite, Finite] | None = None

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """The scenario's yard (xmin, xmax, ymin, ymax) [m]: the service's ``yard``."""
        return YARD if self.yard is None else self.yard

    @model_validator(mode="after")
    def _goals_are_valid(self) -> Scenario:
        ids = self.robot_ids
        if len(set(ids)) != len(ids):
            raise ValueError("robot ids must be unique")
        obstacles = self.static_obstacles()
        peer_radius = Avoidance().peer_radius
        taken: list[Occupied] = []
        for k, r in enumerate(self.robots):
            goal = Pose(x=r.goal[0], y=r.goal[1], theta=r.goal[2])
            try:
                validate_goal(goal, self.bounds, obstacles, taken, peer_radius)
            except GoalRejected as exc:
                raise ValueError(f"robot {k} ({ids[k]}): {exc}") from None
            taken.append(Occupied(goal.x, goal.y, f"the goal of robot {k} ({ids[k]})"))
        return self

    def site(self) -> Site | None:
        """The site map the fleet runs with (None: no zones or lanes, the service needs
        none)."""
        if not self.zones and not self.lanes:
            return None
        xmin, xmax, ymin, ymax = self.bounds
        return Site(
            name=self.name,
            yard=Yard(xmin=xmin, xmax=xmax, ymin=ymin, ymax=ymax),
            obstacles=[o.as_obstacle() for o in self.obstacles],
            walls=self.walls,
            zones=self.zones,
            lanes=self.lanes,
        )

    def static_obstacles(self) -> list[Obstacle]:
        """Posts and wall segments, as the fleet publishes them."""
        return [o.as_obstacle() for o in self.obstacles] + [
            segment for wall in self.walls for segment in wall.segments()
        ]

    @property
    def robot_ids(self) -> list[str]:
        """Robot ids: as given, else ``b1`` ... ``bN``."""
        return [r.id or f"b{k + 1}" for k, r in enumerate(self.robots)]

    @property
    def starts(self) -> list[Posture]:
        return [r.start for r in self.robots]

    @property
    def goals(self) -> list[Posture]:
        return [r.goal for r in self.robots]

    @property
    def group(self) -> str:
        """The family seeds are summarised under (the name when it has none)."""
        return self.family or self.name

    @property
    def end_s(self) -> float:
        """When the run stops at the latest [s after its start]: last arrival + time limit."""
        return max(r.arrival_s for r in self.robots) + self.time_limit_s


def load_scenarios(path: str | Path) -> list[Scenario]:
    """The scenarios of a JSON file (one object or a list); ValueError naming the problem."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"scenario file not found: {path}")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not JSON: {exc}") from None
    items = data if isinstance(data, list) else [data]
    scenarios = []
    for k, item in enumerate(items):
        try:
            scenarios.append(Scenario.model_validate(item))
        except ValidationError as exc:
            where = f"{path}" if len(items) == 1 else f"{path} [{k}]"
            problems = "; ".join(
                f"{'.'.join(str(p) for p in e['loc']) or 'scenario'}: {e['msg']}"
                for e in exc.errors()
            )
            raise ValueError(f"{where}: {problems}") from None
    if not scenarios:
        raise ValueError(f"{path}: no scenario")
    return scenarios


def dump_scenarios(scenarios: Sequence[Scenario]) -> str:
    """JSON text of ``scenarios`` that :func:`load_scenarios` reads back."""
    return json.dumps([s.model_dump(exclude_defaults=True) for s in scenarios], indent=1)


# -- builders ------------------------------------------------------------------------------


def swap(n: int, chirality: str = "right", radius: float = 6.0) -> Scenario:
    """Antipodal swap of ``n`` robots on a circle of ``radius`` [m] (grown so neighbours
    are >= 1.5 m apart); ``chirality`` ``right`` or ``left`` (the mirror image)."""
    if chirality not in ("right", "left"):
        raise ValueError(f"chirality must be right or left, got {chirality!r}")
    if n >= 2:
        radius = max(radius, 1.5 / (2 * math.sin(math.pi / n)))
    turn = -math.pi / 4 if chirality == "right" else math.pi / 4
    robots = []
    for i in range(n):
        a = 2 * math.pi * i / n
        c, s = radius * math.cos(a), radius * math.sin(a)
        robots.append(
            RobotSpec(start=(c, s, a + math.pi + turn), goal=(-c, -s, a + math.pi - turn))
        )
    return Scenario(
        name=f"swap-{n}-{chirality}", robots=robots, family=f"swap-{n}", time_limit_s=_limit(n)
    )


def _limit(n: int) -> float:
    """Time limit [s] of an n-robot scenario: 120 s, 180 s from 30 robots on."""
    return 180.0 if n >= 30 else 120.0


def _spaced_points(
    rng: np.random.Generator, count: int, half_x: float, half_y: float, spacing: float
) -> list[tuple[float, float]]:
    points: list[tuple[float, float]] = []
    for _ in range(10_000 * count):
        if len(points) == count:
            return points
        x, y = float(rng.uniform(-half_x, half_x)), float(rng.uniform(-half_y, half_y))
        if all(math.hypot(x - px, y - py) >= spacing for px, py in points):
            points.append((x, y))
    raise ValueError(f"cannot place {count} points {spacing} m apart in the yard")


def random_yard(n: int, seed: int, spacing: float = 1.5, half: float | None = None) -> Scenario:
    """``n`` random starts and goals (seeded) in a square of half-side ``half`` [m]
    (default: :data:`YARD_DENSITY`), points ``spacing`` apart; fleet-assigned. A square
    wider than the service's yard less 0.5 m (more than 36 robots) comes with a yard of its
    own, 0.5 m beyond it."""
    half = math.sqrt(n / YARD_DENSITY) / 2 if half is None else half
    own_yard = None
    if half > YARD[1] - 0.5:
        edge = round(half + 0.5, 3)
        own_yard = (-edge, edge, -edge, edge)
    rng = np.random.default_rng(seed)
    points = _spaced_points(rng, 2 * n, half, half, spacing)
    heads = rng.uniform(-math.pi, math.pi, size=2 * n)
    poses = [(x, y, float(t)) for (x, y), t in zip(points, heads, strict=True)]
    robots = [RobotSpec(start=s, goal=g) for s, g in zip(poses[:n], poses[n:], strict=True)]
    return Scenario(
        name=f"yard-{n}-s{seed}",
        named=False,
        robots=robots,
        family=f"yard-{n}",
        seed=seed,
        time_limit_s=_limit(n),
        yard=own_yard,
    )


def _arrivals(rng: np.random.Generator, n: int, mean_gap_s: float) -> list[float]:
    """``n`` task arrival times [s]: the first at 0, then exponential gaps (a Poisson stream)."""
    gaps = rng.exponential(mean_gap_s, size=n - 1)
    return [0.0, *(round(float(t), 2) for t in np.cumsum(gaps))]


def stream(n: int, seed: int, mean_gap_s: float = STREAM_GAP_S) -> Scenario:
    """A random yard whose tasks arrive as a Poisson stream (mean gap ``mean_gap_s`` [s])."""
    yard = random_yard(n, seed)
    arrivals = _arrivals(np.random.default_rng(seed + 10_000), n, mean_gap_s)
    robots = [
        r.model_copy(update={"arrival_s": t}) for r, t in zip(yard.robots, arrivals, strict=True)
    ]
    return Scenario(
        name=f"stream-{n}-s{seed}",
        named=False,
        robots=robots,
        family=f"stream-{n}",
        seed=seed,
        yard=yard.yard,
    )


def _wall(x0: float, y0: float, x1: float, y1: float, pitch: float) -> list[tuple[float, float]]:
    count = max(1, round(math.hypot(x1 - x0, y1 - y0) / pitch))
    return [
        (round(x0 + (x1 - x0) * k / count, 6), round(y0 + (y1 - y0) * k / count, 6))
        for k in range(count + 1)
    ]


def car_park(seed: int | None = None, mean_gap_s: float = 4.0, *, walls: bool = False) -> Scenario:
    """Twelve robots queued outside a walled car park park in its two rows of bays.

    The park spans x in [-6, 8], y in [-4.5, 4.5] m with a gate |y| < 1.2 m in the west
    wall. Its walls are posts (body 0.25 m, influence 0.6 m, 0.6 m apart: no robot fits
    between two; 1.9 m of gate between the posts' bodies) or, with ``walls``, wall segments
    (``carpark-walls-12``: body 0.1 m, 2.2 m of gate). Bays: six per row, 1.4 m apart, 1.2 m
    from the north and south walls, nose to the wall. The robots wait in two columns west
    of the gate, facing it. With ``seed`` the tasks arrive as a Poisson stream (mean gap
    ``mean_gap_s`` [s]), else all at once.
    """
    pitch, body, zone = 0.6, 0.25, 0.6
    posts = [
        *_wall(-6.0, 4.5, 8.0, 4.5, pitch),
        *_wall(-6.0, -4.5, 8.0, -4.5, pitch),
        *_wall(8.0, -4.5 + pitch, 8.0, 4.5 - pitch, pitch),
        *_wall(-6.0, 1.2, -6.0, 4.5 - pitch, pitch),
        *_wall(-6.0, -4.5 + pitch, -6.0, -1.2, pitch),
    ]
    obstacles = [ObstacleSpec(x=x, y=y, radius=zone, body=body) for x, y in posts]
    outline: list[Wall] = []
    if walls:
        obstacles = []
        corners = [(-6.0, 1.2), (-6.0, 4.5), (8.0, 4.5), (8.0, -4.5), (-6.0, -4.5), (-6.0, -1.2)]
        outline = [Wall(name="outer", points=corners, body=0.1)]
    bays = [(-2.2 + 1.4 * k, side * 3.3, side * math.pi / 2) for side in (1, -1) for k in range(6)]
    queue = [(x, 0.75 + 1.5 * row, 0.0) for row in range(-3, 3) for x in (-7.8, -9.3)]
    n = len(bays)
    arrivals = (
        [0.0] * n
        if seed is None
        else _arrivals(np.random.default_rng(seed + 20_000), n, mean_gap_s)
    )
    robots = [
        RobotSpec(start=s, goal=g, arrival_s=t)
        for s, g, t in zip(queue, bays, arrivals, strict=True)
    ]
    base = "carpark-walls-12" if walls else "carpark-12"
    name = base if seed is None else f"{base}-stream-s{seed}"
    return Scenario(
        name=name,
        named=False,
        robots=robots,
        obstacles=obstacles,
        walls=outline,
        time_limit_s=180.0,
        family=None if seed is None else f"{base}-stream",
        seed=seed,
    )


def garage() -> Scenario:
    """Twelve robots queued outside a parking garage's two gates park along its walls.

    The garage spans x in [-8, 8], y in [-6, 6] m (walls of body 0.1 m) with a gate
    |y| < 1.2 m in its west and its east wall, and two islands (walls along y = +-2 m for
    |x| < 4.5 m) that make three aisles: north, middle (gate to gate) and south. Bays: six
    along the north wall and six along the south wall, 1.4 m apart, 1.2 m from the wall,
    nose to it. Six robots wait west of the west gate facing east, six east of the east
    gate facing west; fleet-assigned, all at once.
    """
    north = [(-8.0, 1.2), (-8.0, 6.0), (8.0, 6.0), (8.0, 1.2)]
    south = [(-8.0, -1.2), (-8.0, -6.0), (8.0, -6.0), (8.0, -1.2)]
    walls = [
        Wall(name="north", points=north, body=0.1),
        Wall(name="south", points=south, body=0.1),
        Wall(name="north-island", points=[(-4.5, 2.0), (4.5, 2.0)], body=0.1),
        Wall(name="south-island", points=[(-4.5, -2.0), (4.5, -2.0)], body=0.1),
    ]
    bays = [(-3.5 + 1.4 * k, side * 4.8, side * math.pi / 2) for side in (1, -1) for k in range(6)]
    queue = [
        (side * x, y, 0.0 if side < 0 else math.pi)
        for side in (-1, 1)
        for x in (9.3, 10.8)
        for y in (-1.5, 0.0, 1.5)
    ]
    return Scenario(
        name="garage-12",
        named=False,
        robots=[RobotSpec(start=s, goal=g) for s, g in zip(queue, bays, strict=True)],
        walls=walls,
        yard=(-12.0, 12.0, -8.0, 8.0),
        time_limit_s=180.0,
    )


def corridor() -> Scenario:
    """Three robots in each of two rooms cross to bays in the other through a corridor
    too narrow for two robots to pass in.

    The rooms are 8 x 10 m (x in [-12, -4] and [4, 12], |y| < 5), joined by a corridor
    |x| < 4, |y| < 0.6 (wall centre lines; walls of body 0.05 m: 1.1 m between them). The
    west robots stand at x = -10.5 facing east, the east robots at x = 10.5 facing west, at
    y = -2, 0, 2; each parks nose to the north or south wall of the other room, clear of
    the ways of the robots waiting there."""
    outline = [(-12, 5), (-4, 5), (-4, 0.6), (4, 0.6), (4, 5), (12, 5), (12, -5), (4, -5),
               (4, -0.6), (-4, -0.6), (-4, -5), (-12, -5)]  # fmt: skip
    up, down = math.pi / 2, -math.pi / 2
    starts = [(side * 10.5, y, 0.0 if side < 0 else math.pi) for side in (-1, 1)
              for y in (-2.0, 0.0, 2.0)]  # fmt: skip
    goals = [(-side * x, y, heading) for side in (-1, 1)
             for x, y, heading in ((6.5, -3.5, down), (6.5, 3.5, up), (8.5, 3.5, up))]  # fmt: skip
    return Scenario(
        name="corridor-6",
        robots=[RobotSpec(start=s, goal=g) for s, g in zip(starts, goals, strict=True)],
        walls=[Wall(name="rooms", points=outline, closed=True, body=0.05)],
        yard=(-13.0, 13.0, -6.0, 6.0),
        time_limit_s=300.0,
    )


def _case_iii_obstacles() -> list[ObstacleSpec]:
    return [
        ObstacleSpec(x=0.8, y=0.0, radius=1.0, body=0.2),
        ObstacleSpec(x=-0.8, y=0.0, radius=1.0, body=0.2),
    ]


def case_iii() -> Scenario:
    """The paper's comparative case III, (0, 2, 0) -> (0, -2, 0), two obstacles (Section 6)."""
    case = SCENARIOS["III"]
    return Scenario(
        name="case-III",
        robots=[RobotSpec(start=case.start, goal=case.goal)],
        obstacles=_case_iii_obstacles(),
        law_gains=dict(case.gains),
        tolerance=case.tolerance,
    )


def case_iii_crossing() -> Scenario:
    """Case III with four robots crossing the obstacle pair: the paper's robot, one going
    the other way through the gap, two diagonals (Table 8 gains)."""
    case = SCENARIOS["III"]
    pi = math.pi
    moves = [
        (case.start, case.goal),
        ((0.0, -3.2, 0.0), (0.0, 3.2, 0.0)),
        ((-2.5, 1.2, 0.0), (2.5, -1.2, 0.0)),
        ((2.5, 1.2, pi), (-2.5, -1.2, pi)),
    ]
    return Scenario(
        name="case-III-4",
        robots=[RobotSpec(start=s, goal=g) for s, g in moves],
        obstacles=_case_iii_obstacles(),
        law_gains=dict(case.gains),
        tolerance=case.tolerance,
    )


def ring_round_posts(
    n: int, radius: float, posts: Sequence[ObstacleSpec], name: str, seed: int = 0
) -> Scenario:
    """``n`` robots on a circle of ``radius`` [m] round ``posts`` park at the antipodal
    point, facing the way they cross; each starts facing the centre within +-0.4 rad
    (seeded): every straight way is blocked, the ways round the posts meet. Named."""
    rng = np.random.default_rng(seed)
    robots = []
    for i in range(n):
        a = 2 * math.pi * i / n
        c, s = radius * math.cos(a), radius * math.sin(a)
        heading = a + math.pi
        robots.append(
            RobotSpec(start=(c, s, heading + float(rng.uniform(-0.4, 0.4))), goal=(-c, -s, heading))
        )
    return Scenario(name=name, robots=robots, obstacles=list(posts), family=name, seed=seed)


def rings() -> list[Scenario]:
    """The rings round posts: 8 robots round one post (body 0.6 m, influence 1.2 m), 12 round
    a larger one (0.8 m, 1.6 m), 16 round the same on a wider circle (8 m: more robots than
    the circle round its zone holds at once), 6 round three small ones (0.3 m, 0.7 m) 1.2 m
    off centre, 8 round a wall 1.6 m long (body 0.2 m, influence 0.9 m)."""
    small = [
        ObstacleSpec(x=1.2 * math.cos(a), y=1.2 * math.sin(a), radius=0.7, body=0.3)
        for a in (0.3, 2.4, 4.5)
    ]
    return [
        ring_round_posts(8, 5.0, [ObstacleSpec(x=0.0, y=0.0, radius=1.2, body=0.6)], "ring-8-post"),
        ring_round_posts(
            12, 6.0, [ObstacleSpec(x=0.0, y=0.0, radius=1.6, body=0.8)], "ring-12-post"
        ),
        ring_round_posts(
            16, 8.0, [ObstacleSpec(x=0.0, y=0.0, radius=1.6, body=0.8)], "ring-16-post"
        ),
        ring_round_posts(6, 5.0, small, "ring-6-posts"),
        ring_round_posts(8, 5.0, [], "ring-8-wall").model_copy(
            update={"walls": [Wall(points=[(-0.8, 0.0), (0.8, 0.0)], body=0.2, radius=0.9)]}
        ),
    ]


def crossing_lanes(per_lane: int, rows: int = 1, row_delay_s: float = 2.0) -> Scenario:
    """Two crossing lanes: ``per_lane`` robots 1.5 m apart drive east across the yard and as
    many north, ``rows`` deep (each row 1.5 m behind the one before, its tasks
    ``row_delay_s`` [s] later, parking 1.5 m short of it: the first row parks deepest);
    the northbound lane 0.3 m off the eastbound one's grid. Named."""
    robots = []
    offsets = [(k - (per_lane - 1) / 2) * 1.5 for k in range(per_lane)]
    north = math.pi / 2
    for row in range(rows):
        start, goal, at = 7.0 + 1.5 * row, 7.0 - 1.5 * row, row * row_delay_s
        for o in offsets:
            robots.append(RobotSpec(start=(-start, o, 0.0), goal=(goal, o, 0.0), arrival_s=at))
            robots.append(
                RobotSpec(start=(o + 0.3, -start, north), goal=(o + 0.3, goal, north), arrival_s=at)
            )
    name = f"cross-{len(robots)}"
    return Scenario(name=name, robots=robots, family=name)


def staggered_swap(n: int, chirality: str = "right", gap_s: float = 1.5) -> Scenario:
    """:func:`swap` with the tasks arriving one by one, ``gap_s`` [s] apart round the circle:
    robots start while others are under way. Named."""
    base = swap(n, chirality)
    robots = [
        r.model_copy(update={"arrival_s": round(k * gap_s, 2)}) for k, r in enumerate(base.robots)
    ]
    name = f"stagger-{n}-{chirality}"
    return Scenario(name=name, robots=robots, family=f"stagger-{n}")


# -- suites --------------------------------------------------------------------------------

SWAP_SIZES = (2, 4, 8, 16, 32)
YARD_SIZES = (10, 20, 40)
YARD_SEEDS = tuple(range(1, 11))
STREAM_SEEDS = tuple(range(1, 6))


def full_suite() -> list[Scenario]:
    """Every built-in scenario: swaps in both chiralities, yards x 10 seeds, streams, the car
    park (at once, as a stream, with walls), the garage, the corridor, case III alone and
    with four robots, rings round posts, crossing lanes, staggered swaps."""
    return [
        *(swap(n, c) for n in SWAP_SIZES for c in ("right", "left")),
        *(random_yard(n, s) for n in YARD_SIZES for s in YARD_SEEDS),
        *(stream(20, s) for s in STREAM_SEEDS),
        car_park(),
        car_park(seed=1),
        car_park(walls=True),
        garage(),
        corridor(),
        case_iii(),
        case_iii_crossing(),
        *rings(),
        crossing_lanes(4),
        crossing_lanes(4, rows=2),
        staggered_swap(12, "right"),
        staggered_swap(12, "left"),
    ]


def quick_suite() -> list[Scenario]:
    """A daily subset of the full suite: a swap in both chiralities, a yard, the car park,
    case III with four robots."""
    return [
        swap(4, "right"),
        swap(4, "left"),
        random_yard(10, 1),
        car_park(),
        case_iii_crossing(),
    ]
