"""Key expressions, id validation and the drop-and-count decoder."""

from __future__ import annotations

import json

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fleet.core.params import UNLIMITED, Avoidance, Gains, RobotProfile
from fleet.core.wire import (
    MAX_PAYLOAD_BYTES,
    CancelAssignment,
    ControlAction,
    ControlCommand,
    Keys,
    ParkAssignment,
    Pose,
    RobotDescription,
    RobotState,
    TermFence,
    encode,
    validate_id,
)
from fleet.io.decoder import Decoder


@pytest.mark.parametrize(
    "bad", ["", "a/b", "r*", "r$1", "what?", "#1", "**", "_service", "a b", "x" * 65]
)
def test_ids_with_wildcards_or_separators_are_rejected(bad: str) -> None:
    with pytest.raises(ValueError, match="invalid robot id"):
        validate_id(bad)
    with pytest.raises(ValueError):
        Keys().state(bad)


def test_keys_follow_the_design_layout() -> None:
    keys = Keys("yard-1")
    assert keys.state("robot-1") == "parkfleet/yard-1/robot/robot-1/state"
    assert keys.assignment("robot-1") == "parkfleet/yard-1/robot/robot-1/assignment"
    assert keys.alive("robot-1") == "parkfleet/yard-1/alive/robot-1"
    assert keys.service_alive == "parkfleet/yard-1/alive/_service"
    assert keys.robot_of("parkfleet/yard-1/robot/robot-1/state") == "robot-1"
    assert keys.robot_of("parkfleet/other/robot/robot-1/state") is None


def test_messages_round_trip_and_carry_the_schema_version() -> None:
    park = ParkAssignment(
        robot_id="r1",
        task_id="t1",
        goal=Pose(x=1, y=2, theta=0.5),
        law="cw",
        gains=Gains(kx=1, ky=2, ktheta=3),
    )
    decoder = Decoder()
    assert decoder.decode_assignment(encode(park)) == park
    cancel = CancelAssignment(robot_id="r1", task_id="t1")
    assert decoder.decode_assignment(encode(cancel)) == cancel
    state = RobotState(robot_id="r1", seq=3, stamp=1.5, pose=Pose(x=0, y=0))
    assert json.loads(encode(state))["v"] == 1
    assert decoder.decode(RobotState, encode(state)) == state
    assert decoder.dropped_total == 0


@given(st.binary(max_size=300))
def test_arbitrary_bytes_are_dropped_and_counted_never_raised(payload: bytes) -> None:
    decoder = Decoder()
    result = decoder.decode(RobotState, payload)
    assert result is None or isinstance(result, RobotState)
    assert decoder.dropped_total == (0 if result is not None else 1)


_STATE = (
    b'{"v": 1, "kind": "state", "robot_id": "r1", "seq": 1, "stamp": 0, "pose": {"x": 0, "y": 0}}'
)


def test_the_reference_state_payload_is_valid() -> None:
    assert Decoder().decode(RobotState, _STATE) is not None


@pytest.mark.parametrize(
    "payload",
    [
        _STATE.replace(b'"v": 1', b'"v": 2'),
        _STATE.replace(b'"r1"', b'"r*"'),
        _STATE.replace(b'"x": 0', b'"x": NaN'),
        b'{"v": 1, "kind": "teleport", "robot_id": "r1"}',
        b"\xff\xfe",
        b"x" * (MAX_PAYLOAD_BYTES + 1),
    ],
)
def test_unknown_versions_wildcards_nan_and_oversize_are_dropped(payload: bytes) -> None:
    decoder = Decoder()
    assert decoder.decode(RobotState, payload) is None
    assert decoder.decode_assignment(payload) is None
    assert decoder.dropped_total == 2


def test_unknown_top_level_fields_are_ignored_so_releases_can_mix() -> None:
    """A field added by a newer release must not make an older robot drop the message."""
    decoder = Decoder()
    newer = _STATE[:-1] + b', "battery": 0.8}'
    state = decoder.decode(RobotState, newer)
    assert state is not None and state.robot_id == "r1"
    assert decoder.dropped_total == 0


@given(
    radius=st.floats(0.01, 2.0),
    wheel_radius=st.floats(0.01, 0.5),
    half_axle=st.floats(0.01, 1.0),
    limit=st.one_of(st.just(float("inf")), st.floats(0.1, 200.0)),
    may_reverse=st.booleans(),
)
def test_a_robot_description_carries_its_profile_exactly(
    radius: float, wheel_radius: float, half_axle: float, limit: float, may_reverse: bool
) -> None:
    profile = RobotProfile(
        radius=radius, wheel_radius=wheel_radius, half_axle=half_axle, max_wheel_speed=limit
    )
    description = RobotDescription.of("r1", profile, may_reverse=may_reverse)
    received = Decoder().decode(RobotDescription, encode(description))
    assert received is not None
    assert received.profile == profile  # JSON floats round-trip; no limit travels as null
    assert received.may_reverse is may_reverse


def test_description_key_and_an_older_fleets_view_of_it() -> None:
    keys = Keys("yard-1")
    assert keys.description("robot-1") == "parkfleet/yard-1/robot/robot-1/description"
    assert keys.robot_of(keys.description("robot-1")) == "robot-1"
    unlimited = json.loads(encode(RobotDescription.of("r1", UNLIMITED)))
    assert unlimited["max_wheel_speed"] is None
    newer = encode(RobotDescription.of("r1", UNLIMITED))[:-1] + b', "max_accel": 2.0}'
    assert Decoder().decode(RobotDescription, newer) is not None


# -- fencing term -----------------------------------------------------------------------------
def _park(term: int | None, task: str = "t1") -> ParkAssignment:
    extra = {} if term is None else {"term": term}
    return ParkAssignment(
        robot_id="r1",
        task_id=task,
        goal=Pose(x=1.0, y=0.0),
        law="cw",
        gains=Gains(kx=1, ky=2, ktheta=3),
        **extra,
    )


def _control(term: int, seq: int = 1) -> ControlCommand:
    return ControlCommand(command=ControlAction.ESTOP, issuer="tool", seq=seq, stamp=0.0, term=term)


def test_a_message_without_a_term_is_term_zero_and_an_old_payload_still_parses() -> None:
    """Older senders send no term: it reads as 0, and a payload without the field parses."""
    legacy = json.loads(encode(_park(None)))
    assert legacy["term"] == 0
    del legacy["term"]
    got = Decoder().decode(ParkAssignment, json.dumps(legacy).encode())
    assert got is not None and got.term == 0
    assert CancelAssignment(robot_id="r1", task_id="t1").term == 0


def test_eq_27_smoothing_travels_and_its_absence_is_the_papers_term() -> None:
    """A service sends ``smoothing_m`` (the fleet's default 0.6 m) and the robot drives
    it; an older service sends none and plans the paper's term: read as 0; a 0 is left
    out, so a robot of an older release (Avoidance forbids unknown fields) still parses."""
    sent = _park(None)
    assert sent.avoidance.smoothing_m == 0.6
    got = Decoder().decode(ParkAssignment, encode(sent))
    assert got is not None and got.avoidance.smoothing_m == 0.6
    legacy = json.loads(encode(sent))
    del legacy["avoidance"]["smoothing_m"]
    older = Decoder().decode(ParkAssignment, json.dumps(legacy).encode())
    assert older is not None and older.avoidance.smoothing_m == 0.0
    paper = sent.model_copy(update={"avoidance": Avoidance(smoothing_m=0.0)})
    payload = json.loads(encode(paper))
    assert "smoothing_m" not in payload["avoidance"]
    assert set(payload["avoidance"]) == {"k_avoid", "peer_radius", "min_x_oa"}  # the old set
    back = Decoder().decode(ParkAssignment, encode(paper))
    assert back is not None and back.avoidance.smoothing_m == 0.0
    bad = json.loads(encode(sent))
    bad["avoidance"]["smoothing_m"] = -0.1
    assert Decoder().decode(ParkAssignment, json.dumps(bad).encode()) is None


@given(terms=st.lists(st.integers(0, 5), max_size=30))
def test_the_fence_obeys_exactly_the_messages_not_below_the_highest_term(terms: list[int]) -> None:
    fence = TermFence()
    obeyed = [t for t in terms if fence.accept(_park(t))]
    highest = 0
    expected = []
    for t in terms:
        if t >= highest:
            expected.append(t)
            highest = t
    assert obeyed == expected
    assert fence.highest == highest and fence.dropped == len(terms) - len(expected)


def test_operator_commands_without_a_term_are_always_obeyed_service_ones_are_fenced() -> None:
    fence = TermFence()
    assert fence.accept(CancelAssignment(robot_id="r1", task_id="t", term=3))
    assert fence.accept(_control(0))  # an operator tool (term 0): never fenced
    assert fence.highest == 3
    assert not fence.accept(_control(2))  # a deposed service's command
    assert fence.accept(_control(4)) and fence.highest == 4
    assert not fence.accept(_park(3))
    assert fence.dropped == 2


def test_obstacle_body_defaults_for_older_payloads_and_is_bounded() -> None:
    from fleet.core.wire import DEFAULT_OBSTACLE_BODY_M, Obstacle, ObstacleSet, parse

    older = parse(ObstacleSet, b'{"v": 1, "kind": "obstacles", "obstacles": [{"x": 1, "y": 2}]}')
    assert isinstance(older, ObstacleSet)
    assert older.obstacles[0].body is None
    assert older.obstacles[0].body_radius == DEFAULT_OBSTACLE_BODY_M
    assert Obstacle(x=0, y=0, radius=0.05).body_radius == 0.05  # never beyond the influence
    assert Obstacle(x=0, y=0, radius=1.0, body=0.4).body_radius == 0.4
    too_big = parse(
        ObstacleSet,
        b'{"v": 1, "kind": "obstacles", "obstacles": [{"x": 0, "y": 0, "radius": 0.5, "body": 1}]}',
    )
    assert not isinstance(too_big, ObstacleSet)


def test_a_wall_segment_travels_in_the_obstacle_set_and_a_post_stays_a_post() -> None:
    from fleet.core.wire import Obstacle, ObstacleSet, encode, parse

    wall = Obstacle(x=0, y=0, end=(3, 0), radius=0.3, body=0.05)
    back = parse(ObstacleSet, encode(ObstacleSet(obstacles=[wall, Obstacle(x=1, y=1)])))
    assert isinstance(back, ObstacleSet)
    assert back.obstacles[0].far_end == (3.0, 0.0) and back.obstacles[0].distance(1.5, 0.4) == 0.4
    assert back.obstacles[1].end is None and back.obstacles[1].far_end == (1.0, 1.0)
    for bad in (b'[1, "nan"]', b"[1]", b'"east"'):
        payload = b'{"v": 1, "kind": "obstacles", "obstacles": [{"x": 0, "y": 0, "end": %s}]}'
        assert not isinstance(parse(ObstacleSet, payload % bad), ObstacleSet), bad
