"""Scenario builders, the built-in suites and the scenario file format."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import pytest

from fleet.bench.scenarios import (
    Scenario,
    car_park,
    case_iii,
    case_iii_crossing,
    crossing_lanes,
    dump_scenarios,
    full_suite,
    load_scenarios,
    quick_suite,
    random_yard,
    rings,
    staggered_swap,
    stream,
    swap,
)
from fleet.core.geometry import segments_distance

ISSUE_SHAPE = """
{"name": "my-yard", "named": true,
 "robots": [{"start": [-3, 0, 0], "goal": [3, 0, 0], "arrival_s": 0.0},
            {"start": [3, 0.5, 3.14], "goal": [-3, 0.5, 3.14], "arrival_s": 2.5}],
 "obstacles": [{"x": 0.0, "y": 5.0, "radius": 1.0}]}
"""


@pytest.mark.parametrize("n", [2, 4, 8, 16, 32])
def test_swaps_are_antipodal_and_the_two_chiralities_mirror_each_other(n: int) -> None:
    right, left = swap(n, "right"), swap(n, "left")
    for (x, y, _), (gx, gy, _) in zip(right.starts, right.goals, strict=True):
        assert math.isclose(gx, -x, abs_tol=1e-9) and math.isclose(gy, -y, abs_tol=1e-9)

    # the mirror image in the x axis: (x, y, theta) -> (x, -y, -theta), as a set of robots
    def mirrored(p: tuple[float, float, float]) -> tuple[float, float, float]:
        return (round(p[0], 6), round(-p[1], 6) + 0.0, round(-p[2] % (2 * math.pi), 6))

    def key(p: tuple[float, float, float]) -> tuple[float, float, float]:
        return (round(p[0], 6), round(p[1], 6) + 0.0, round(p[2] % (2 * math.pi), 6))

    pairs_r = {(mirrored(s), mirrored(g)) for s, g in zip(right.starts, right.goals, strict=True)}
    pairs_l = {(key(s), key(g)) for s, g in zip(left.starts, left.goals, strict=True)}
    assert pairs_r == pairs_l and right.starts != left.starts
    neighbours = [math.dist(a[:2], b[:2]) for a, b in itertools.combinations(right.starts, 2)]
    assert min(neighbours) >= 1.5 - 1e-9


def test_random_yards_are_seeded_spaced_and_dense_enough() -> None:
    a, b = random_yard(20, 3), random_yard(20, 3)
    assert a == b and a != random_yard(20, 4) and not a.named
    points = [p[:2] for p in a.starts + a.goals]
    assert min(math.dist(p, q) for p, q in itertools.combinations(points, 2)) >= 1.5
    half = max(max(abs(x), abs(y)) for x, y in points)
    assert 20 / (2 * half) ** 2 >= 0.09  # about one robot per 10 m^2
    assert a.yard is None and a.bounds == (-10.0, 10.0, -10.0, 10.0)  # the service's yard
    for n in (40, 200):  # beyond the service's yard: the density holds in a yard of its own
        big = random_yard(n, 1)
        assert big.yard is not None
        xmin, xmax, ymin, ymax = big.bounds
        assert n / ((xmax - xmin - 1.0) * (ymax - ymin - 1.0)) == pytest.approx(0.1, rel=1e-3)
        inside = [xmin + 0.5 <= x <= xmax - 0.5 and ymin + 0.5 <= y <= ymax - 0.5
                  for x, y, _ in big.starts + big.goals]  # fmt: skip
        assert all(inside)
    assert stream(40, 1).yard == random_yard(40, 1).yard


def test_a_stream_brings_tasks_while_others_drive() -> None:
    s = stream(20, 2)
    arrivals = [r.arrival_s for r in s.robots]
    assert arrivals[0] == 0.0 and arrivals == sorted(arrivals)
    assert 20 < arrivals[-1] < 150  # ~3 s apart on average
    assert s.end_s == arrivals[-1] + s.time_limit_s
    assert [r.goal for r in s.robots] == random_yard(20, 2).goals


def test_the_car_park_has_walls_a_gate_and_two_rows_of_bays() -> None:
    s = car_park()
    posts = [(o.x, o.y) for o in s.obstacles]
    west = sorted(y for x, y in posts if x == -6.0)
    assert not [y for y in west if abs(y) < 1.2]  # the gate
    gaps = [b - a for a, b in itertools.pairwise(west) if a > 0 or b < 0]
    body = s.obstacles[0].body
    assert max(gaps) - 2 * body < 2 * 0.2  # no robot slips between two posts
    assert all(x < -6.0 for x, _, _ in s.starts)  # everyone queues outside
    rows = {round(y, 2) for _, y, _ in s.goals}
    assert rows == {3.3, -3.3} and not s.named
    assert car_park(seed=1).robots[-1].arrival_s > 0


def test_the_walled_car_park_has_the_same_bays_behind_wall_segments() -> None:
    posts, walled = car_park(), car_park(walls=True)
    assert walled.name == "carpark-walls-12" and not walled.obstacles
    assert walled.goals == posts.goals and walled.starts == posts.starts
    segments = walled.static_obstacles()
    assert len(segments) == 5 and all(o.end is not None for o in segments)
    west = [o for o in segments if o.x == -6.0 and o.far_end[0] == -6.0]
    assert sorted((o.y, o.far_end[1]) for o in west) == [(-4.5, -1.2), (1.2, 4.5)]  # the gate
    assert "carpark-walls-12" in {s.name for s in full_suite()}


def test_walls_travel_in_scenario_files_and_a_goal_in_one_is_refused(tmp_path: Path) -> None:
    data = json.loads(ISSUE_SHAPE) | {"walls": [{"points": [[-5, 2], [5, 2], [5, 3]], "body": 0.1}]}
    path = tmp_path / "s.json"
    path.write_text(json.dumps(data))
    (s,) = load_scenarios(path)
    assert [o.far_end for o in s.static_obstacles()[1:]] == [(5.0, 2.0), (5.0, 3.0)]
    data["robots"][0]["goal"] = [3, 2.1, 0]
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=r"robot 0 \(b1\): goal .* wall segment 1"):
        load_scenarios(path)


def test_case_iii_alone_and_with_four_robots() -> None:
    alone, four = case_iii(), case_iii_crossing()
    assert alone.starts == [(0.0, 2.0, 0.0)] and alone.goals == [(0.0, -2.0, 0.0)]
    assert len(four.robots) == 4 and four.obstacles == alone.obstacles
    assert four.law_gains == alone.law_gains and four.law_gains is not None


def test_every_ring_robot_has_a_post_body_across_its_straight_way() -> None:
    for ring in rings():
        obstacles = ring.static_obstacles()
        assert ring.named and obstacles
        for (x, y, heading), (gx, gy, goal_heading) in zip(ring.starts, ring.goals, strict=True):
            assert math.isclose(gx, -x, abs_tol=1e-9) and math.isclose(gy, -y, abs_tol=1e-9)
            facing = math.atan2(-y, -x)
            assert abs(math.remainder(heading - facing, 2 * math.pi)) <= 0.4
            assert math.isclose(math.remainder(goal_heading - facing, 2 * math.pi), 0, abs_tol=1e-9)
            gaps = [segments_distance((x, y), (gx, gy), (o.x, o.y), o.far_end) for o in obstacles]
            # a robot's radius: it cannot pass straight
            assert any(g < o.body_radius + 0.2 for g, o in zip(gaps, obstacles, strict=True))


def test_crossing_lanes_cross_and_the_first_row_parks_deepest() -> None:
    one, two = crossing_lanes(4), crossing_lanes(4, rows=2, row_delay_s=2.0)
    assert (one.name, len(one.robots), two.name, len(two.robots)) == ("cross-8", 8, "cross-16", 16)
    east = [r for r in two.robots if r.start[2] == 0.0]
    north = [r for r in two.robots if r.start[2] != 0.0]
    assert len(east) == len(north) == 8
    for r in east:  # driving east along its row, parking 7 m (first row) or 5.5 m east
        assert r.start[1] == r.goal[1] and r.start[0] < 0 < r.goal[0]
        assert (r.start[0], r.goal[0], r.arrival_s) in {(-7.0, 7.0, 0.0), (-8.5, 5.5, 2.0)}
    for r in north:
        assert r.start[0] == r.goal[0] and r.start[1] < 0 < r.goal[1]
    xs = {r.start[0] for r in north}
    assert not xs & {r.start[1] for r in east}  # lanes off each other's grid


def test_a_staggered_swap_is_the_swap_with_arrivals_apart() -> None:
    base, late = swap(12, "left"), staggered_swap(12, "left", gap_s=1.5)
    assert late.starts == base.starts and late.goals == base.goals
    assert [r.arrival_s for r in late.robots] == [round(1.5 * k, 2) for k in range(12)]
    assert late.name == "stagger-12-left" and late.family == "stagger-12"


def test_the_suites_cover_the_benchmark() -> None:
    names = [s.name for s in full_suite()]
    for n in (2, 4, 8, 16, 32):
        assert {f"swap-{n}-right", f"swap-{n}-left"} <= set(names)
    for n in (10, 20, 40):
        assert len([s for s in full_suite() if s.family == f"yard-{n}"]) >= 10
    assert {"carpark-12", "case-III", "case-III-4"} <= set(names)
    assert {"ring-8-post", "cross-16", "stagger-12-right", "stagger-12-left"} <= set(names)
    assert any(s.startswith("stream-") for s in names)
    assert len(set(names)) == len(names)
    assert {s.name for s in quick_suite()} <= set(names)
    assert {"swap-4-right", "swap-4-left", "carpark-12"} <= {s.name for s in quick_suite()}


def test_the_issue_shape_loads(tmp_path: Path) -> None:
    path = tmp_path / "s.json"
    path.write_text(ISSUE_SHAPE)
    (s,) = load_scenarios(path)
    assert s.name == "my-yard" and s.named and s.robot_ids == ["b1", "b2"]
    assert s.robots[1].arrival_s == 2.5 and s.obstacles[0].body == 0.1


def test_files_round_trip_and_hold_lists(tmp_path: Path) -> None:
    path = tmp_path / "s.json"
    scenarios = [swap(4, "left"), car_park(seed=2), case_iii()]
    path.write_text(dump_scenarios(scenarios))
    assert load_scenarios(path) == scenarios


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"robots": []}, "robots: List should have at least 1 item"),
        ({"name": "a/b"}, "name: String should match pattern"),
        ({"robots": [{"start": [0, 0], "goal": [1, 1, 0]}]}, "robots.0.start"),
        ({"colour": "red"}, "colour: Extra inputs are not permitted"),
        ({"obstacles": [{"x": 3, "y": 0, "radius": 1.0}]}, "influence zone of obstacle 0"),
        ({"obstacles": [{"x": 9, "y": 9, "radius": 1, "body": 2}]}, "must be smaller"),
        (
            {"robots": [{"start": [0, 0, 0], "goal": [3, 0, 0]}] * 2},
            "robot 1 \\(b2\\): goal \\(3.00, 0.00\\) is 0.00 m from the goal of robot 0",
        ),
        ({"robots": [{"start": [0, 0, 0], "goal": [30, 0, 0]}]}, "outside the yard"),
    ],
)
def test_bad_files_say_what_is_wrong(
    tmp_path: Path, change: dict[str, object], message: str
) -> None:
    data = json.loads(ISSUE_SHAPE) | change
    path = tmp_path / "s.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=message):
        load_scenarios(path)


def test_unreadable_files(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        load_scenarios(tmp_path / "none.json")
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(ValueError, match="not JSON"):
        load_scenarios(tmp_path / "bad.json")
    with pytest.raises(ValueError, match="chirality"):
        swap(4, "up")
    assert isinstance(Scenario.model_validate(json.loads(ISSUE_SHAPE)), Scenario)
