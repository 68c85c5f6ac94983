"""``parkfleet bench zenoh``: the light state stream speaks the agents' wire format."""

from __future__ import annotations

import pytest

from fleet.bench.state_stream import templates
from fleet.core.wire import Keys, RobotState


@pytest.mark.parametrize(("seq", "stamp"), [(0, 0.0), (12, 1_764_000_000.123456), (10**9, 5e-3)])
def test_state_templates_render_valid_states(seq: int, stamp: float) -> None:
    keys = Keys("f")
    rendered = templates(keys, 30, "b")
    assert len({key for key, _ in rendered}) == 30
    for i, (key, text) in enumerate(rendered):
        state = RobotState.model_validate_json(text % (seq, stamp))
        assert (state.robot_id, state.seq, state.stamp) == (f"b{i + 1}", seq, stamp)
        assert keys.robot_of(key) == state.robot_id
        assert -10 <= state.pose.x <= 10 and -10 <= state.pose.y <= 10
