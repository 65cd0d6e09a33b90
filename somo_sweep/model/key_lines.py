"""Key paths as error messages print them (``a.b[0].c``), and the line of every key path of a
JSON text (YAML keeps its lines as it is composed: :mod:`somo_sweep.model.files`)."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field

from somo_sweep.errors import Problem

__all__ = ["join_path", "json_lines"]


def join_path(parent: str, key: str | int) -> str:
    """Join a key path the way error messages print it (``a.b[0].c``)."""
    if isinstance(key, int):
        return f"{parent}[{key}]"
    return f"{parent}.{key}" if parent else str(key)


#: A JSON token the line scanner steps over whole: a string, or a number or literal.
_JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')
_JSON_SCALAR = re.compile(r"[^\s,:\[\]{}]+")
_JSON_BLANK = re.compile(r"[ \t\r\n]+")


def json_lines(text: str, problems: list[Problem]) -> dict[str, int]:
    """The line of every key path of a JSON text that parsed (``a.b[0].c`` → 1-based line).

    A key's line is the line of the key, an array item's the line where it starts, as for
    YAML. A key given twice in one object is reported with both lines (in ``problems``).
    """
    return _JsonLines(text, problems).scan()


@dataclass
class _Frame:
    """An open object or array of the JSON scan.

    Attributes:
        path: Its key path.
        is_object: An object (else an array).
        index: The current item of an array.
        key: The current key of an object.
        seen: Line of every key met in an object.
    """

    path: str
    is_object: bool
    index: int = 0
    key: str = ""
    seen: dict[str, int] = field(default_factory=dict)


class _JsonLines:
    """A scan over a JSON text that parsed, token by token, keeping the current line."""

    def __init__(self, text: str, problems: list[Problem]):
        self.text = text
        self.problems = problems
        self.lines: dict[str, int] = {}
        self.stack: list[_Frame] = []
        self.line = 1
        self.expect_key = False

    def scan(self) -> dict[str, int]:
        """The line of every key path."""
        text, i, n = self.text, 0, len(self.text)
        while i < n:
            ch = text[i]
            if ch in " \t\r\n":
                blank = _JSON_BLANK.match(text, i)
                end = blank.end() if blank else i + 1
                self.line += text.count("\n", i, end)
                i = end
            elif ch in "{[}],:":
                self._punctuation(ch)
                i += 1
            else:
                i = self._token(i)
        return self.lines

    def _value_starts(self) -> str:
        """The path of the value starting here; the top level and array items get their line."""
        where = ""
        if self.stack:
            frame = self.stack[-1]
            where = join_path(frame.path, frame.key if frame.is_object else frame.index)
        if not self.stack or not self.stack[-1].is_object:
            self.lines[where] = self.line
        return where

    def _punctuation(self, ch: str) -> None:
        if ch in "{[":
            self.stack.append(_Frame(self._value_starts(), ch == "{"))
            self.expect_key = ch == "{"
        elif ch in "}]":
            self.stack.pop()
            self.expect_key = False
        elif ch == ",":
            if self.stack[-1].is_object:
                self.expect_key = True
            else:
                self.stack[-1].index += 1
        else:  # ":"
            self.expect_key = False

    def _token(self, i: int) -> int:
        """Step over the string, number or literal at ``i`` (a key, or a value); its end."""
        token = (_JSON_STRING if self.text[i] == '"' else _JSON_SCALAR).match(self.text, i)
        end = token.end() if token else i + 1
        if not self.expect_key:
            self._value_starts()
            return end
        frame = self.stack[-1]
        frame.key = key = json.loads(self.text[i:end])
        child = join_path(frame.path, key)
        if key in frame.seen:
            self.problems.append(
                Problem(
                    child,
                    f"key '{key}' is given twice (lines {frame.seen[key]} and {self.line}); "
                    "allowed: each key once per object",
                    self.line,
                )
            )
        else:
            frame.seen[key] = self.line
        self.lines[child] = self.line
        return end
