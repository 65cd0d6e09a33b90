"""The exception tree of somo-sweep.

Every error a user can cause derives from :class:`SomoError`; the CLI prints its
message and exits with code 2 (1 for a :class:`StorageError`). Errors carry structured fields so that callers
(and tests) can inspect them without parsing text.
"""

from __future__ import annotations

import difflib
import errno
import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "MAX_LISTED",
    "SHOWN_CHARS",
    "ClusterError",
    "DescriptionError",
    "FolderInUse",
    "Interrupted",
    "ManifestError",
    "MeasurementError",
    "Problem",
    "SimulationError",
    "SomoError",
    "StorageError",
    "StudyChanged",
    "UnstableSimulation",
    "did_you_mean",
    "os_cause",
    "os_error_for",
    "printable",
    "quoted",
    "shown",
]


class SomoError(Exception):
    """Base class of every error somo-sweep raises on purpose."""


#: Problems an error message lists; the others are counted in one line ("… and 88 more problem(s)").
MAX_LISTED = 20


def _listing(source: str, rendered: Sequence[str]) -> str:
    """``SOURCE: N problem(s)`` (N counts every problem) and the first :data:`MAX_LISTED` of them."""
    lines = [f"{source}: {len(rendered)} problem(s)", *(f"  - {p}" for p in rendered[:MAX_LISTED])]
    if len(rendered) > MAX_LISTED:
        lines.append(f"  … and {len(rendered) - MAX_LISTED} more problem(s)")
    return "\n".join(lines)


@dataclass(frozen=True)
class Problem:
    """One problem found in a user file.

    Attributes:
        path: Key path inside the file, e.g. ``manipulator.actuators[0].length_m``.
        message: What is wrong and what is allowed.
        line: 1-based line number in the file, when known.
    """

    path: str
    message: str
    line: int | None = None

    def render(self) -> str:
        where = shown(self.path, 4 * SHOWN_CHARS) if self.path else "<top level>"
        if self.line is not None:
            where = f"line {self.line}: {where}"
        return f"{where}: {self.message}"


class DescriptionError(SomoError):
    """A description or study file is invalid; lists every problem at once.

    The message counts every problem and lists the first :data:`MAX_LISTED`.

    Args:
        source: File name (or ``<dict>`` for Python input).
        problems: All problems found, in file order.
    """

    def __init__(self, source: str | Path, problems: Sequence[Problem]):
        self.source = str(source)
        self.problems = list(problems)
        super().__init__(_listing(self.source, [p.render() for p in self.problems]))

    def __reduce__(self) -> tuple[type, tuple[str, list[Problem]]]:
        # Rebuilt from its fields when it crosses a process boundary (joblib, Dask).
        return type(self), (self.source, self.problems)


class MeasurementError(SomoError):
    """A measurement CSV is invalid (missing columns, bad cells, unknown tests).

    The message counts every problem and lists the first :data:`MAX_LISTED`.

    Args:
        source: CSV file name.
        problems: Every problem found (human-readable, each naming row and column).
    """

    def __init__(self, source: str | Path, problems: Sequence[str]):
        self.source = str(source)
        self.problems = list(problems)
        super().__init__(_listing(self.source, self.problems))

    def __reduce__(self) -> tuple[type, tuple[str, list[str]]]:
        return type(self), (self.source, self.problems)


class SimulationError(SomoError):
    """A simulation could not be set up or run."""


class StorageError(SomoError):
    """Results could not be written (disk full, permissions); what was written is intact.

    The CLI exits with code 1 (a failed run), not 2 (bad input).
    """


class UnstableSimulation(SimulationError):
    """The integration blew up (speeds at Bullet's cap, NaN, or bodies thrown).

    Attributes:
        reason: Short machine-readable reason (``speed_cap``, ``nan``, ``thrown``).
        time_s: Simulated time at which it was detected, in s.
    """

    def __init__(self, reason: str, time_s: float, detail: str = ""):
        self.reason = reason
        self.time_s = time_s
        self.detail = detail
        super().__init__(f"simulation unstable at t={time_s:.4f} s ({reason}) {detail}".strip())

    def __reduce__(self) -> tuple[type, tuple[str, float, str]]:
        return type(self), (self.reason, self.time_s, self.detail)


class ManifestError(SomoError):
    """A results folder's manifest is missing (not a results folder) or damaged.

    Attributes:
        folder: The results folder.
        missing: True when there is no manifest; False when it is there and damaged.
    """

    def __init__(self, message: str, folder: str | Path, missing: bool):
        self.folder = str(folder)
        self.missing = missing
        super().__init__(message)

    def __reduce__(self) -> tuple[type, tuple[str, str, bool]]:
        return type(self), (str(self), self.folder, self.missing)


class FolderInUse(SomoError):
    """Another run holds a results folder's lock.

    Attributes:
        folder: The results folder.
        holder: Who holds it (``pid … on HOST since …``), as its lock file says.
    """

    def __init__(self, folder: str | Path, holder: str):
        self.folder = str(folder)
        self.holder = holder
        super().__init__(
            f"{self.folder} is in use by another somo-sweep run ({holder}); "
            "wait for it to finish or stop it, or use another --out folder"
        )

    def __reduce__(self) -> tuple[type, tuple[str, str]]:
        return type(self), (self.folder, self.holder)


class StudyChanged(SomoError):
    """A results folder holds results of a different study (results are never mixed).

    Attributes:
        folder: The results folder.
        stored_hash: The hash of the study whose results it holds (as the message shows it).
        study_hash: The hash of the study being run.
        changed: What differs between the two, in words.
    """

    def __init__(self, folder: str | Path, stored_hash: str, study_hash: str, changed: str):
        self.folder = str(folder)
        self.stored_hash = stored_hash
        self.study_hash = study_hash
        self.changed = changed
        super().__init__(
            f"{self.folder} holds results of a different study (hash {stored_hash}, this one is "
            f"{study_hash}); changed: {changed}. Results are never mixed: run with --out NEW_FOLDER, "
            "or with --overwrite to delete them and start over"
        )

    def __reduce__(self) -> tuple[type, tuple[str, str, str, str]]:
        return type(self), (self.folder, self.stored_hash, self.study_hash, self.changed)


class ClusterError(SomoError):
    """A Dask cluster stopped running a sweep's trials; finished trials are kept.

    Attributes:
        trial: The trial it stopped at (its number in the study's grid).
        reason: ``worker`` (a worker could not run it: another somo-sweep there), ``lost`` (the
            connection to the scheduler is gone) or ``cancelled`` (another client, or a restart).
    """

    def __init__(self, message: str, trial: int, reason: str):
        self.trial = trial
        self.reason = reason
        super().__init__(message)

    def __reduce__(self) -> tuple[type, tuple[str, int, str]]:
        return type(self), (str(self), self.trial, self.reason)


class Interrupted(KeyboardInterrupt):
    """A run was stopped (SIGINT, or SIGTERM where it is taken as one) before its first trial.

    A :class:`KeyboardInterrupt`, so that a caller's Ctrl-C handling still applies.

    Attributes:
        stage: What the run was doing: ``step`` (choosing the time step), ``jobs`` (building the
            job table) or ``folder`` (opening the results folder).
        signum: The signal that stopped it.
    """

    def __init__(self, stage: str, signum: int):
        super().__init__(stage, signum)
        self.stage = stage
        self.signum = signum


#: Longest user value echoed whole in a message; longer ones are cut (see :func:`shown`).
SHOWN_CHARS = 60


def shown(value: str, limit: int = SHOWN_CHARS) -> str:
    """A user value as a message quotes it: cut to ``limit`` characters with its length said.

    A hostile file's 50-MB cell must not become a 50-MB error message, nor its escape sequences
    commands to the terminal: control characters are shown escaped (:func:`printable`).
    """
    if len(value) <= limit:
        return printable(value)
    return f"{printable(value[:limit])}… ({len(value)} characters)"


def quoted(value: object, limit: int = SHOWN_CHARS) -> str:
    """A user value as ``got …`` quotes it: text in quotes, cut as :func:`shown` cuts it, the length
    said being the text's own (not that of its ``repr``, two quotes longer); others as ``repr``."""
    if not isinstance(value, str) or len(value) <= limit:
        return shown(repr(value), limit)
    cut = repr(value[:limit])
    return f"{printable(cut[:-1])}…{cut[-1]} ({len(value)} characters)"


#: Characters a terminal acts on rather than shows: C0 and C1 controls (escape sequences
#: that retitle the window or clear the screen start with them) and bidirectional overrides.
_UNPRINTABLE = re.compile("[\x00-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069]")


def printable(value: str) -> str:
    """A stored value made safe to print: control characters shown escaped (``\\x1b``)."""
    return _UNPRINTABLE.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), value)


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """Return a ``" (did you mean 'x'?)"`` hint, or an empty string.

    Words much longer than every choice get no hint (and cost no time: difflib is quadratic).
    """
    options = list(choices)
    if not options or len(word) > 2 * max(len(c) for c in options) + 8:
        return ""
    close = difflib.get_close_matches(word, options, n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


#: What an operating-system error means for the user, and what to do about it, by errno.
_OS_CAUSES: dict[int, tuple[str, str]] = {
    errno.ENOSPC: ("the disk is full", "free space on that disk"),
    errno.EDQUOT: ("the disk quota is used up", "free space within the quota"),
    errno.EROFS: (
        "the file system is read-only",
        "remount it read-write, or give a folder on a writable disk",
    ),
    errno.EACCES: ("permission denied", "give yourself write access there, or give a folder of yours"),
    errno.EPERM: ("operation not permitted", "give yourself write access there, or give a folder of yours"),
    errno.ELOOP: (
        "a symbolic link on the way leads back to itself, a link loop",
        "remove or repair that link",
    ),
    errno.ENAMETOOLONG: ("the name is longer than the file system allows", "give a shorter name"),
    errno.ENOTDIR: ("a step of the path is a file, not a folder", "move that file away or give another path"),
    errno.EISDIR: ("it is a folder", "give a file name"),
    errno.ENOENT: (
        "a folder of the path is gone (removed while the command ran?)",
        "give a folder that exists",
    ),
    errno.EIO: (
        "input/output error (a failing disk, or a network disk that went away)",
        "check the disk or the network mount",
    ),
    errno.EFBIG: ("the file is larger than the file system allows", "give a folder on another disk"),
    errno.EMFILE: ("too many files are open", "raise the limit (ulimit -n) or use fewer --jobs"),
    errno.ENFILE: ("the system has too many files open", "close other programs or use fewer --jobs"),
}
_ERRNO_IN_TEXT = re.compile(r"\[errno (\d+)\]", re.IGNORECASE)


def os_cause(exc: OSError) -> tuple[str, str]:
    """What an operating-system error means and what fits as advice, in words (no path).

    The cause keeps the system's own words (``the disk is full (No space left on device)``),
    so that it can be looked up. A pyarrow error carries its errno only in its text.

    Returns:
        (cause, advice); advice is a phrase the caller completes (e.g. "…, then run again").
    """
    code = exc.errno if isinstance(exc.errno, int) else None
    if code is None and (found := _ERRNO_IN_TEXT.search(str(exc))):
        code = int(found.group(1))
    # pyarrow's strerror is a sentence around the system's words: the words alone, by errno.
    system = os.strerror(code) if code is not None else exc.strerror or str(exc).splitlines()[0]
    if code in _OS_CAUSES:
        cause, advice = _OS_CAUSES[code]
        return f"{cause} ({system})", advice
    return system, "fix that"


def os_error_for(exc: OSError, path: str | os.PathLike[str]) -> OSError:
    """``exc`` as raised for ``path``: a temporary file's error named as the file it stands for
    (the errno kept, also when pyarrow gives it only in its text)."""
    code = exc.errno if isinstance(exc.errno, int) else None
    if code is None and (found := _ERRNO_IN_TEXT.search(str(exc))):
        code = int(found.group(1))
    if not isinstance(code, int):
        return OSError(None, exc.strerror or str(exc).splitlines()[0], str(path))
    return OSError(code, os.strerror(code), str(path))
