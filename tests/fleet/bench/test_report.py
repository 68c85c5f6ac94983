"""The benchmark tables of a run (docs/benchmarks.md): policies side by side, auto's misses
spelled out."""

from __future__ import annotations

from fleet.bench.fleet import FleetBenchRow
from fleet.bench.report import (
    auto_table,
    law_alone_table,
    planning_wait_table,
    policy_table,
    smoothness_table,
)


def _row(family: str, policy: str, seed: int | None = None, **figures: float) -> FleetBenchRow:
    values: dict[str, float] = {"success_rate": 1.0, "collisions": 0, "makespan_s": 50.0}
    values |= figures
    return FleetBenchRow(
        scenario=family if seed is None else f"{family}-s{seed}",
        family=family,
        seed=seed,
        robots=4,
        policy=policy,
        success_rate=values["success_rate"],
        collisions=int(values["collisions"]),
        min_separation_m=0.6,
        makespan_s=values["makespan_s"],
        path_ratio=1.2,
        deadlocks=0,
        plan_p50_ms=10.0 if policy == "auto" else None,
        plan_p99_ms=30.0 if policy == "auto" else None,
        obstacle_hits=int(values.get("obstacle_hits", 0)),
        min_obstacle_clearance_m=None,
        tasks=4,
        arrived=round(4 * values["success_rate"]),
        rejected=0,
        time_limit_s=120.0,
        wall_s=1.0,
        stops_per_trip=figures.get("stops_per_trip"),
        cusps_per_trip=figures.get("cusps_per_trip"),
        plan_wait_s=figures.get("plan_wait_s"),
        planning_sim_s=figures.get("planning_sim_s"),
        time_scale=figures.get("time_scale"),
    )


ROWS = [
    # "good": auto meets every target (the collision-free ORCA is only a bit faster)
    _row("good", "auto", makespan_s=60.0),
    _row("good", "orca", makespan_s=50.0),
    _row("good", "cw", makespan_s=20.0, collisions=2),  # fastest, but it collides
    # "bad" over two seeds: auto collides once, fails a task, is slow, HL does better
    _row("bad", "auto", 1, makespan_s=100.0, collisions=1, success_rate=0.75),
    _row("bad", "auto", 2, makespan_s=100.0),
    _row("bad", "hl", 1, makespan_s=40.0),
    _row("bad", "hl", 2, makespan_s=40.0),
]


def test_the_policy_table_has_a_line_per_family_and_a_column_per_policy() -> None:
    lines = policy_table(ROWS).splitlines()
    assert lines[0] == "| scenario | N | runs | auto | orca | cw | hl |"
    good, bad = lines[2], lines[3]
    assert good.startswith("| good | 4 | 1 | 100% · 0 · 60 s | 100% · 0 · 50 s | 100% · 2 · 20 s")
    # two seeds: means, then the worst success and most collisions in brackets
    assert "| bad | 4 | 2 | 88% (75%) · 0.5 (1) · 100 s |" in bad


def test_auto_verdicts_name_every_missed_target_and_only_those() -> None:
    lines = auto_table(ROWS).splitlines()
    good = next(line for line in lines if line.startswith("| good "))
    bad = next(line for line in lines if line.startswith("| bad "))
    assert good.endswith("| orca 50 s | 1.20 | 0 | 10 / 30 | none |")
    assert bad.endswith(
        "| success 75%; 1 colliding pair; less success than hl; makespan 2.5x hl's |"
    )


def test_robots_through_obstacles_are_a_miss_and_never_the_clean_reference() -> None:
    rows = [
        _row("park", "auto", makespan_s=60.0, obstacle_hits=3),
        _row("park", "hl", makespan_s=30.0, obstacle_hits=1),  # fast, through a post
        _row("park", "orca", makespan_s=55.0),
    ]
    park = policy_table(rows).splitlines()[2]
    assert park.startswith("| park | 4 | 1 | 100% · 0 · 60 s · **3 robots hit obstacles** |")
    assert "| 100% · 0 · 55 s |" in park  # none hit: nothing added
    assert "| 100% · 0 · 30 s · **1 robot hit obstacles** |" in park
    verdict = auto_table(rows).splitlines()[2]
    assert verdict.endswith("| orca 55 s | 1.20 | 0 | 10 / 30 | 3 robots hit obstacles |")


def test_the_smoothness_table_gives_stops_and_cusps_per_trip_for_every_policy() -> None:
    rows = [
        _row("swap", "auto", stops_per_trip=2.0, cusps_per_trip=1.0),
        _row("swap", "orca", stops_per_trip=0.25, cusps_per_trip=0.0),
        _row("old", "auto"),  # a row of an older --json output: nothing measured
    ]
    lines = smoothness_table(rows).splitlines()
    assert lines[0] == "| scenario (stops / cusps per trip) | auto | orca |"
    assert lines[2] == "| swap | 2.0 / 1.0 | 0.2 / 0.0 |"
    assert lines[3] == "| old |  |  |"


def test_the_planning_wait_table_shows_the_service_s_share_of_the_fleet_makespan() -> None:
    rows = [
        _row("swap", "auto", makespan_s=40.0, plan_wait_s=4.0, planning_sim_s=6.5, time_scale=5),
        _row("swap", "orca", makespan_s=20.0),  # no service: no line
    ]
    lines = planning_wait_table(rows).splitlines()
    assert "plans' wall time x 5 [s]" in lines[0]
    assert lines[2:] == ["| swap | auto | 40.0 | 4.0 | 10% | 6.5 |"]


def test_the_law_alone_stands_beside_auto_and_the_fastest_clean_policy() -> None:
    """auto's makespan, the law's own solo estimate and the fastest collision-free policy,
    with both ratios; families whose rows carry no estimate (older runs) are left out, and
    without any estimate there is no table."""
    assert law_alone_table(ROWS) == ""
    rows = [r.model_copy(update={"law_solo_s": 40.0}) if r.family == "good" else r for r in ROWS]
    lines = law_alone_table(rows).splitlines()
    assert lines[0].startswith("| scenario | auto makespan [s] | the law alone [s] |")
    assert lines[2:] == ["| good | 60.0 | 40.0 | orca 50.0 | 0.80x | 1.50x |"]
