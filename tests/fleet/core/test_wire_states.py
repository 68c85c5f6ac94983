"""The hot message: compact state encoding (msgspec), JSON still accepted, and the
neighbourhood key scheme (grid cells of the peer stream)."""

from __future__ import annotations

import math

import msgspec
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fleet.core.wire import (
    COMPACT_STATE_V1,
    Ahead,
    Keys,
    Pose,
    Rejected,
    RobotError,
    RobotMode,
    RobotState,
    as_json,
    cell_of,
    cells_around,
    encode,
    encode_age,
    encode_state,
    parse,
    parse_age,
    parse_state,
)
from fleet.io.decoder import Decoder

finite = st.floats(-1e6, 1e6, allow_nan=False)
poses = st.builds(Pose, x=finite, y=finite, theta=finite)
errors = st.builds(
    RobotError,
    code=st.from_regex(r"^[a-z][a-z0-9_]{0,10}$", fullmatch=True),
    level=st.sampled_from(["warning", "error", "fatal"]),
    message=st.text(max_size=40),
    since=finite,
)
states = st.builds(
    RobotState,
    robot_id=st.from_regex(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,20}$", fullmatch=True),
    seq=st.integers(0, 2**62),
    stamp=finite,
    pose=poses,
    u=finite,
    omega=finite,
    mode=st.sampled_from(list(RobotMode)),
    task_id=st.none() | st.text(max_size=20),
    revision=st.integers(0, 1000),
    law=st.sampled_from([None, "cw", "ccw"]),
    goal=st.none() | poses,
    radius=st.floats(0.01, 5.0),
    detail=st.none() | st.text(max_size=50),
    errors=st.lists(errors, max_size=3),
    ahead=st.none()
    | st.builds(
        Ahead,
        x=finite,
        y=finite,
        theta=finite,
        lead_s=st.floats(0.0, 1.0),
        spread_m=st.floats(0.0, 1.0),
        heading_rad=st.floats(0.0, 1.0),
        speed_m_s=st.floats(0.0, 5.0),
    ),
)


@given(states)
def test_a_compact_state_decodes_to_the_same_state(state: RobotState) -> None:
    raw = encode_state(state)
    assert raw[0] == COMPACT_STATE_V1
    decoded = parse_state(raw)
    assert decoded == state
    assert isinstance(decoded, RobotState)
    assert decoded.model_dump_json() == state.model_dump_json()  # tools print the same JSON
    assert parse(RobotState, raw) == state  # every decoder of states takes both encodings


@given(states)
def test_json_states_are_still_accepted_and_as_json_prints_either(state: RobotState) -> None:
    assert parse_state(encode(state)) == state
    assert parse_state(b"\n " + encode(state)) == state
    assert as_json(encode_state(state)) == state.model_dump_json()
    assert as_json(encode(state)) == encode(state).decode()


def test_the_compact_state_is_smaller_than_its_json() -> None:
    state = RobotState(robot_id="robot-17", seq=123456, stamp=1.7e9, pose=Pose(x=1.5, y=-2.0))
    assert len(encode_state(state)) < len(encode(state)) / 2


def _frame(*fields: object) -> bytes:
    return bytes([COMPACT_STATE_V1]) + msgspec.msgpack.encode(list(fields))


#: A whole layout-0x01 state with defaults: id, seq, stamp, x, y, theta, u, omega, mode,
#: task, revision, law, goal, radius, detail, errors, ahead.
FULL: list[object] = ["r1", 1, 10.0, 1.0, 2.0, 0.5, 0.1, 0.0, "driving", None, 0, None, None,
                      0.2, None, [], None]  # fmt: skip


def _full(**changes: object) -> bytes:
    names = "id seq stamp x y theta u omega mode task revision law goal radius detail errors ahead"
    fields = dict(zip(names.split(), FULL, strict=True)) | changes
    return _frame(*fields.values())


def test_appended_fields_of_a_newer_sender_are_ignored_missing_ones_default() -> None:
    state = parse_state(_frame(*FULL, "a field from the future", 42))
    assert isinstance(state, RobotState)
    assert (state.robot_id, state.pose.as_tuple(), state.mode) == ("r1", (1.0, 2.0, 0.5), "driving")
    short = parse_state(_frame("r1", 1, 10.0, 1.0, 2.0, 0.5))
    assert isinstance(short, RobotState)
    assert (short.u, short.mode, short.errors, short.radius) == (0.0, RobotMode.IDLE, [], 0.2)
    older = parse_state(_frame(*FULL[:-1]))  # a sender from before the prediction
    assert isinstance(older, RobotState) and older.ahead is None


def test_a_prediction_travels_in_both_encodings_and_an_older_receiver_skips_it() -> None:
    ahead = Ahead(x=1.0, y=2.0, theta=0.5, lead_s=0.1, spread_m=0.03, heading_rad=0.02,
                  speed_m_s=0.8)  # fmt: skip
    state = RobotState(robot_id="r1", seq=3, stamp=1.0, pose=Pose(x=1.0, y=2.0), ahead=ahead)
    assert parse_state(encode_state(state)) == state == parse_state(encode(state))

    class OlderFrame(msgspec.Struct, array_like=True):  # layout 0x01 before the prediction
        robot_id: str
        seq: int
        stamp: float

    older = msgspec.msgpack.decode(encode_state(state)[1:], type=OlderFrame)
    assert (older.robot_id, older.seq) == ("r1", 3)
    assert RobotState.model_validate_json(encode(state)).ahead == ahead


@pytest.mark.parametrize(
    ("payload", "reason"),
    [
        (b"", "invalid"),
        (b"\x01", "invalid"),
        (b"\x01\x93\x01\x02", "invalid"),  # truncated
        (b"\x01" + b"\xff" * 20, "invalid"),
        (_frame("r/1", 1, 10.0, 1.0, 2.0, 0.5), "invalid"),  # not a key chunk
        (_frame("r1", -1, 10.0, 1.0, 2.0, 0.5), "invalid"),  # negative seq
        (_frame("r1", 1, 10.0, math.nan, 2.0, 0.5), "invalid"),
        (_frame("r1", 1, 10.0, 1.0, math.inf, 0.5), "invalid"),
        (_full(ahead=[1.0, 2.0, 0.5, 0.1, -0.03, 0.0, 0.5]), "invalid"),  # negative spread
        (_full(ahead=[1.0, 2.0, math.nan, 0.1, 0.03, 0.0, 0.5]), "invalid"),
        (_full(ahead=[1.0, 2.0, 0.5]), "invalid"),  # truncated prediction
        (_frame("r1", 1, 10.0, 1.0, 2.0, 0.5, 0, 0, "flying"), "invalid"),  # unknown mode
        (_frame("r1", 1, 10.0, 1.0, 2.0, 0.5, 0, 0, "idle", None, 0, "left"), "invalid"),
        (_frame("r1", 1, "soon", 1.0, 2.0, 0.5), "invalid"),
        (_full(radius=-0.2), "invalid"),
        (_full(errors=[["c", "error", "m", 1.0]] * 17), "invalid"),  # more than 16 faults
        (_full(errors=[["Bad code", "error", "m", 1.0]]), "invalid"),
        (_full(goal=[1.0, 2.0]), "invalid"),
        (b"\x02" + msgspec.msgpack.encode([]), "version"),  # a layout this release lacks
        (b'{"v": 1, "kind": "state"}', "invalid"),
        (b"\x01" + b"\x00" * (64 * 1024), "oversized"),
    ],
)
def test_malformed_states_are_rejected_and_counted(payload: bytes, reason: str) -> None:
    result = parse_state(payload)
    assert isinstance(result, Rejected)
    assert result.reason == reason
    decoder = Decoder("test")
    assert decoder.decode(RobotState, payload) is None
    assert decoder.dropped[reason] == 1


def test_keys_of_the_two_state_streams() -> None:
    keys = Keys("yard", cell_m=2.0)
    assert keys.state("r1") == "parkfleet/yard/robot/r1/state"  # the fleet rate, as before
    assert keys.cell(-0.5, 3.9) == (-1, 1)
    assert keys.peer_state("r1", (-1, 1)) == "parkfleet/yard/cell/-1/1/r1"
    assert keys.cell_states((-1, 1)) == "parkfleet/yard/cell/-1/1/*"
    assert keys.all_peer_states == "parkfleet/yard/cell/*/*/*"
    assert keys.robot_of("parkfleet/yard/cell/-1/1/r1") == "r1"
    assert keys.robot_of("parkfleet/yard/cell/-1/1/r*") is None
    assert keys.robot_of("parkfleet/other/cell/-1/1/r1") is None
    with pytest.raises(ValueError, match="cell size"):
        Keys("yard", cell_m=0.0)


coords = st.floats(-500.0, 500.0, allow_nan=False)


@given(
    x=coords,
    y=coords,
    angle=st.floats(0.0, 2 * math.pi),
    fraction=st.floats(0.0, 1.0),
    cell_m=st.sampled_from([0.5, 1.0, 2.0, 2.5, 3.0]),
    reach=st.floats(0.1, 3.0),
)
def test_no_peer_within_reach_is_outside_the_subscribed_cells(
    x: float, y: float, angle: float, fraction: float, cell_m: float, reach: float
) -> None:
    distance = reach * fraction
    px, py = x + distance * math.cos(angle), y + distance * math.sin(angle)
    assert cell_of(px, py, cell_m) in cells_around(x, y, reach, cell_m)


@given(k=st.integers(-1000, 1000), j=st.integers(-1000, 1000), cell_m=st.sampled_from([1.0, 2.0]))
def test_peers_exactly_on_cell_borders_and_corners_are_seen(k: int, j: int, cell_m: float) -> None:
    x, y = k * cell_m, j * cell_m  # a robot on a cell corner
    around = cells_around(x, y, cell_m, cell_m)
    assert len(around) == 9  # the 3 x 3 block: never more subscriptions than that
    for dx, dy in [(-1, 0), (1, 0), (0, -1), (0, 1), (-0.7, -0.7), (0.7, 0.7), (0.7, -0.7)]:
        peer = (x + dx * cell_m, y + dy * cell_m)
        assert cell_of(*peer, cell_m) in around


@given(st.floats(0.0, 1e6, allow_nan=False))
def test_a_replayed_state_s_age_survives_its_attachment(age: float) -> None:
    parsed = parse_age(encode_age(age))
    assert parsed is not None and abs(parsed - age) <= 0.0005 + 1e-12 * age


@pytest.mark.parametrize("attachment", [None, b"", b"-1", b"nan", b"inf", b"x", b"\xff", b"1" * 40])
def test_a_replay_without_a_sane_age_is_refused(attachment: bytes | None) -> None:
    assert parse_age(attachment) is None
