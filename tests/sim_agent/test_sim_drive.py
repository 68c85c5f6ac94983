"""SimDrive: the same forward-Euler unicycle as the batch simulator; noise; limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fleet.core.params import Avoidance, Gains, RobotProfile, Tolerance
from fleet.core.simulate import BatchProblem, simulate
from fleet.core.wire import ParkAssignment, Pose, RobotMode
from robot_agent.clock import SteppedClock
from robot_agent.logic import NO_PEERS, AgentTask, decide, obstacle_arrays
from sim_agent.drive import SimDrive

DT = 0.02


@pytest.mark.parametrize(
    ("start", "goal", "law"),
    [
        ((0.0, 0.0, 0.0), (1.5, 1.0, math.pi / 2), "ccw"),
        ((0.0, 2.0, 0.0), (0.0, -2.0, 0.0), "cw"),
        ((4.0, 1.0, -0.2), (0.0, 0.0, 0.0), "ccw"),
    ],
)
def test_agent_ticks_on_sim_drive_reproduce_the_batch_simulator(
    start: tuple[float, float, float], goal: tuple[float, float, float], law: str
) -> None:
    profile = RobotProfile()  # wheel-speed limited
    gains = Gains(kx=1.0, ky=2.0, ktheta=1.0)
    tol = Tolerance(position=0.1, heading=0.1)
    a = ParkAssignment(
        robot_id="r", task_id="t", goal=Pose(x=goal[0], y=goal[1], theta=goal[2]),
        law=law, gains=gains, tolerance=tol,  # type: ignore[arg-type]
    )  # fmt: skip
    clock = SteppedClock()
    drive = SimDrive(start, profile, clock, max_step=DT)
    task: AgentTask | None = AgentTask(a)
    poses = []
    step = 0
    for step in range(5000):  # noqa: B007
        pose, stamp = drive.read_pose()
        poses.append(pose.as_tuple())
        d = decide(pose.as_tuple(), clock.now() - stamp, task, NO_PEERS,
                   obstacle_arrays([]), profile, Avoidance(), 0.5)  # fmt: skip
        task = d.task
        if d.mode is RobotMode.ARRIVED:
            break
        drive.command_wheels(d.right, d.left)
        clock.advance(DT)
    problem = BatchProblem.build(start, goal, gains, law, tol, profile)  # type: ignore[arg-type]
    result = simulate(problem, dt=DT, max_time=200.0, record=True)
    assert result.done[0]
    # the agent stops at the step the simulator marks done (which it still applies)
    assert step == round(result.time[0] / DT) - 1
    assert result.trajectory is not None
    np.testing.assert_allclose(np.array(poses), result.trajectory.poses[: step + 1, 0], atol=1e-9)


def test_lazy_integration_splits_long_intervals_into_euler_steps() -> None:
    clock = SteppedClock()
    profile = RobotProfile()
    drive = SimDrive((0.0, 0.0, 0.0), profile, clock, max_step=0.01)
    drive.command_wheels(10.0, 10.0)  # u = 0.5 m/s straight
    clock.advance(1.0)
    pose, stamp = drive.read_pose()
    assert stamp == 1.0
    assert pose.x == pytest.approx(0.5) and pose.y == pytest.approx(0.0)
    drive.stop()
    clock.advance(5.0)
    assert drive.read_pose()[0].x == pytest.approx(0.5)


def test_noise_only_affects_the_reported_pose() -> None:
    clock = SteppedClock()
    drive = SimDrive((1.0, 1.0, 0.0), RobotProfile(), clock, noise_std=(0.1, 0.1, 0.02),
                     rng=np.random.default_rng(1))  # fmt: skip
    readings = np.array([drive.read_pose()[0].as_tuple() for _ in range(2000)])
    assert drive.true_pose == (1.0, 1.0, 0.0)
    assert readings[:, 0].std() == pytest.approx(0.1, rel=0.1)
    assert readings[:, 2].std() == pytest.approx(0.02, rel=0.1)
    assert readings[:, 0].mean() == pytest.approx(1.0, abs=0.01)


def test_commands_above_the_wheel_limit_are_refused() -> None:
    drive = SimDrive((0.0, 0.0, 0.0), RobotProfile(max_wheel_speed=5.0), SteppedClock())
    with pytest.raises(ValueError, match="exceeds"):
        drive.command_wheels(5.1, 0.0)
    drive.command_wheels(5.0, -5.0)


def test_a_hair_of_time_is_integrated_not_divided_by_zero_steps() -> None:
    clock = SteppedClock()
    drive = SimDrive((0.0, 0.0, 0.0), RobotProfile(), clock, max_step=0.02)
    drive.command_wheels(10.0, 10.0)
    clock.advance(1e-12)
    pose, _ = drive.read_pose()
    assert 0.0 < pose.x < 1e-9
