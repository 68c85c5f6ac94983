"""Load a site file (TOML or JSON, by its suffix) into a :class:`fleet.core.site.Site`.

Every error names the file and the line: a syntax error where the parser stopped; a
validation error at the line where the offending value (or the nearest enclosing key,
table or array element) is written, e.g.::

    carpark.toml:31: bays[4].pose.x: Input should be a finite number
    carpark.toml:40: bays[6]: bays A3 and A4 are 0.80 m apart: bays must be more than ...

Lines are found by :func:`toml_lines` / :func:`json_lines`, which map the path of every
key, table and array element to the line it starts on (the standard parsers keep none).
"""

from __future__ import annotations

import bisect
import json
import re
import tomllib
from json.decoder import scanstring  # type: ignore[attr-defined]
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from fleet.core.site import Loc, Site, SiteError

#: Largest site file read [bytes].
MAX_SITE_BYTES = 4 * 1024 * 1024


class SiteFileError(ValueError):
    """A site file that cannot be used; ``problems`` are ``(line, message)`` (line 0:
    unknown), ``str()`` lists them as ``file:line: message``."""

    def __init__(self, path: Path, problems: list[tuple[int, str]]) -> None:
        self.path = path
        self.problems = problems
        super().__init__(
            "invalid site file:\n"
            + "\n".join(
                f"  {path}:{line}: {message}" if line else f"  {path}: {message}"
                for line, message in problems
            )
        )


def load_site(
    path: Path, *, robot_radius: float | None = None, peer_radius: float | None = None
) -> Site:
    """Read, parse and validate a site file; with the radii [m], also check that every bay
    is usable (:meth:`Site.problems`). Raises :class:`SiteFileError` or FileNotFoundError."""
    if not path.is_file():
        raise FileNotFoundError(f"site file not found: {path}")
    raw = path.read_bytes()
    if len(raw) > MAX_SITE_BYTES:
        raise SiteFileError(path, [(0, f"{len(raw)} bytes: larger than {MAX_SITE_BYTES}")])
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SiteFileError(path, [(0, f"not UTF-8 text: {exc}")]) from None
    return parse_site(text, path, robot_radius=robot_radius, peer_radius=peer_radius)


def parse_site(
    text: str, path: Path, *, robot_radius: float | None = None, peer_radius: float | None = None
) -> Site:
    """Parse site-file ``text``; ``path`` names the file in errors and its suffix the format
    (``.json``: JSON, anything else: TOML)."""
    is_json = path.suffix.lower() == ".json"
    try:
        data: Any = json.loads(text) if is_json else tomllib.loads(text)
    except json.JSONDecodeError as exc:
        raise SiteFileError(path, [(exc.lineno, f"invalid JSON: {exc.msg}")]) from None
    except tomllib.TOMLDecodeError as exc:
        match = re.search(r"\(at line (\d+), column \d+\)", str(exc))
        line = int(match.group(1)) if match else 0
        message = re.sub(r"\s*\(at line \d+, column \d+\)", "", str(exc))
        raise SiteFileError(path, [(line, f"invalid TOML: {message}")]) from None
    lines = json_lines(text) if is_json else toml_lines(text)
    try:
        site = Site.model_validate(data)
    except ValidationError as exc:
        problems = []
        for error in exc.errors():
            loc: Loc = tuple(error["loc"])
            cause = error.get("ctx", {}).get("error")
            if isinstance(cause, SiteError):
                loc += cause.loc
                message = str(cause)
            else:
                message = error["msg"]
            where = _dotted(loc)
            problems.append((_line_of(loc, lines), f"{where}: {message}" if where else message))
        raise SiteFileError(path, problems) from None
    if robot_radius is not None and peer_radius is not None:
        found = site.problems(robot_radius, peer_radius)
        if found:
            raise SiteFileError(
                path, [(_line_of(p.loc, lines), f"{_dotted(p.loc)}: {p}") for p in found]
            )
    return site


def _dotted(loc: Loc) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _line_of(loc: Loc, lines: dict[Loc, int]) -> int:
    """Line of ``loc``, or of its nearest enclosing item that has one (0: none)."""
    for end in range(len(loc), -1, -1):
        line = lines.get(loc[:end])
        if line is not None:
            return line
    return 0


# --- TOML -------------------------------------------------------------------------------

_KEY = re.compile(
    r"""^\s*((?:[A-Za-z0-9_-]+|"[^"]*"|'[^']*')(?:\s*\.\s*(?:[A-Za-z0-9_-]+|"[^"]*"|'[^']*'))*)\s*="""
)


def _key_parts(dotted: str) -> list[str]:
    return [
        p.strip().strip("\"'") for p in re.findall(r"""[A-Za-z0-9_-]+|"[^"]*"|'[^']*'""", dotted)
    ]


def toml_lines(text: str) -> dict[Loc, int]:
    """Path -> line of every table, array-of-tables element and key of a TOML document.

    Elements of a multi-line inline array get the line they start on when each begins a
    line (``{...}`` or ``[...]``); otherwise errors inside fall back to the array's key.
    """
    lines: dict[Loc, int] = {}
    table: Loc = ()
    index: dict[tuple[str, ...], int] = {}  # array-of-tables name path -> current element
    array: Loc | None = None  # key path of the multi-line inline array being read
    element = -1
    depth = 0
    for number, raw in enumerate(text.splitlines(), start=1):
        line = _strip_comment(raw).strip()
        if not line:
            continue
        if array is not None:
            if depth == 1 and line[0] in "[{":
                element += 1
                lines[(*array, element)] = number
            depth += _bracket_balance(line)
            if depth <= 0:
                array = None
            continue
        if line.startswith("["):
            many = line.startswith("[[")
            name = line.strip("[] ")
            parts = _key_parts(name)
            if many:
                key = tuple(parts)
                index[key] = index.get(key, -1) + 1
                for other in [k for k in index if len(k) > len(key) and k[: len(key)] == key]:
                    del index[other]
            path: list[str | int] = []
            for k in range(len(parts)):
                path.append(parts[k])
                prefix = tuple(parts[: k + 1])
                if prefix in index:
                    path.append(index[prefix])
            table = tuple(path)
            lines[table] = number
            continue
        match = _KEY.match(line)
        if match is None:
            continue
        key_path: Loc = (*table, *_key_parts(match.group(1)))
        lines[key_path] = number
        value = line[match.end() :].strip()
        balance = _bracket_balance(value)
        if value.startswith("[") and balance > 0:
            array, element, depth = key_path, -1, balance
    return lines


def _strip_comment(line: str) -> str:
    quote = ""
    for i, c in enumerate(line):
        if quote:
            if c == quote:
                quote = ""
        elif c in "\"'":
            quote = c
        elif c == "#":
            return line[:i]
    return line


def _bracket_balance(text: str) -> int:
    """Opening minus closing brackets outside strings."""
    balance = 0
    quote = ""
    for c in text:
        if quote:
            if c == quote:
                quote = ""
        elif c in "\"'":
            quote = c
        elif c in "[{":
            balance += 1
        elif c in "]}":
            balance -= 1
    return balance


# --- JSON -------------------------------------------------------------------------------

_WHITESPACE = re.compile(r"[ \t\n\r]*")
_SCALAR = re.compile(r"-?(?:0|[1-9]\d*)(?:\.\d+)?(?:[eE][-+]?\d+)?|true|false|null|NaN|-?Infinity")


def json_lines(text: str) -> dict[Loc, int]:
    """Path -> line of every value of a JSON document that ``json.loads`` accepts."""
    starts = [0] + [m.end() for m in re.finditer("\n", text)]
    lines: dict[Loc, int] = {}

    def skip(pos: int) -> int:
        match = _WHITESPACE.match(text, pos)
        return match.end() if match else pos

    def value(pos: int, path: Loc) -> int:
        pos = skip(pos)
        lines[path] = bisect.bisect_right(starts, pos)
        c = text[pos]
        if c == "{":
            pos = skip(pos + 1)
            if text[pos] == "}":
                return pos + 1
            while True:
                key, pos = scanstring(text, skip(pos) + 1)
                pos = value(skip(pos) + 1, (*path, key))  # past the ':'
                pos = skip(pos)
                if text[pos] == "}":
                    return pos + 1
                pos += 1  # ','
        if c == "[":
            pos = skip(pos + 1)
            if text[pos] == "]":
                return pos + 1
            i = 0
            while True:
                pos = skip(value(pos, (*path, i)))
                if text[pos] == "]":
                    return pos + 1
                pos += 1
                i += 1
        if c == '"':
            return int(scanstring(text, pos + 1)[1])
        match = _SCALAR.match(text, pos)
        return match.end() if match else pos + 1

    value(0, ())
    return lines
