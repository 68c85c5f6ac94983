"""Opaque page cursors of ``GET /tasks``: a task's ``(created_at, id)``, base64url JSON.

A cursor names a position in the task list, not a page number, so pages stay consistent
while tasks are added: the next page starts right after the last task the client saw.
"""

from __future__ import annotations

import base64
import binascii
import json
import math

from fleet.core.tasks import Task
from fleet.service.store import TaskCursor


def encode_cursor(task: Task) -> str:
    """The cursor just past ``task`` (repr keeps the float exact through JSON)."""
    raw = json.dumps([task.created_at, task.id], separators=(",", ":")).encode()
    return base64.urlsafe_b64encode(raw).rstrip(b"=").decode()


def decode_cursor(text: str) -> TaskCursor:
    """The position a cursor names; ``ValueError`` if it is not one this API made."""
    try:
        raw = base64.urlsafe_b64decode(text + "=" * (-len(text) % 4))
        created_at, task_id = json.loads(raw)
    except (binascii.Error, UnicodeDecodeError, json.JSONDecodeError, TypeError, ValueError):
        raise ValueError("not a cursor of this API (take it from the Link header)") from None
    if (
        not isinstance(created_at, int | float)
        or isinstance(created_at, bool)
        or not math.isfinite(created_at)
        or not isinstance(task_id, str)
    ):
        raise ValueError("not a cursor of this API (take it from the Link header)")
    return (float(created_at), task_id)
