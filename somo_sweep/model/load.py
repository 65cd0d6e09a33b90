"""Model files: a ``manipulator:`` or an ``assembly:`` section, from YAML, JSON or a dict.

Inside an assembly, a mount may say ``file: other.yaml`` instead of giving its
``manipulator`` inline; the path is relative to the including file and must stay inside
that file's folder tree (unless ``allow_outside``). Top-level keys starting with ``_``
are ignored: they hold YAML anchors reused below (``&link`` / ``*link``).

Every body must fit in one PyBullet multibody: at most :data:`MAX_BODY_LINKS` links.
"""

from __future__ import annotations

import copy
import hashlib
import json
from pathlib import Path
from typing import Any

from pydantic import model_validator

from somo_sweep.errors import DescriptionError, Problem
from somo_sweep.model.description import Assembly, Manipulator, Mount, Spec
from somo_sweep.model.files import is_file, load_mapping, missing_or_special
from somo_sweep.model.tables import bundled_if_missing, not_found
from somo_sweep.model.validation import validate

__all__ = ["MAX_BODY_LINKS", "Model", "body_links", "load_model", "model_from_dict"]

#: Links of one PyBullet multibody, its base included. Measured with pybullet 3.2.7: with
#: 128 joints (129 links) or more, every joint and link state query fails.
MAX_BODY_LINKS = 128


class Model(Spec):
    """A model file: exactly one of ``manipulator`` or ``assembly``."""

    manipulator: Manipulator | None = None
    assembly: Assembly | None = None
    #: Free-form record of where the model's values came from (e.g. a calibration).
    provenance: dict[str, Any] | None = None

    @model_validator(mode="after")
    def _exactly_one(self) -> Model:
        if (self.manipulator is None) == (self.assembly is None):
            raise ValueError("a model file needs exactly one of 'manipulator' or 'assembly'")
        return self

    def as_assembly(self) -> Assembly:
        """The model as an assembly (a lone manipulator becomes a one-mount assembly)."""
        if self.assembly is not None:
            return self.assembly
        assert self.manipulator is not None
        m = self.manipulator
        return Assembly(
            name=m.name,
            base=m.base.model_copy(update={"link": None}),
            manipulators=[Mount(name=m.name, manipulator=m)],
        )

    def content_hash(self) -> str:
        """Stable hash of the resolved model content (for job ids and caches)."""
        text = json.dumps(self.model_dump(mode="json", exclude={"provenance"}), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _chain_links(manip: Manipulator, extra_anchor: bool) -> int:
    """Links :func:`somo_sweep.sim.planner.plan_manipulator` makes for one manipulator's chain."""
    n = 1 if manip.base.link is not None or extra_anchor else 0
    for act in manip.actuators:
        n += act.segments + (1 if act.joint_placement == "midpoint" else 0)
    return n + len(manip.tip_links)


def body_links(assembly: Assembly) -> dict[str, int]:
    """Links of every PyBullet body the assembly becomes (manipulators only), by body name."""
    if assembly.base.link is not None:
        total = 1 + sum(
            _chain_links(m.manipulator, m.manipulator.base.link is None and any(m.pose.rpy_rad))
            for m in assembly.manipulators
        )
        return {assembly.name: total}
    out = {}
    for mount in assembly.manipulators:
        anchor = mount.manipulator.base.link is None and assembly.base.mode == "fixed"
        out[mount.name] = _chain_links(mount.manipulator, anchor)
    return out


def _check_bodies(model: Model, source: str, lines: dict[str, int] | None) -> None:
    key = "manipulator" if model.manipulator is not None else "assembly"
    problems = [
        Problem(
            key,
            f"body '{name}' has {n} links; allowed: at most {MAX_BODY_LINKS} links per body (PyBullet's "
            f"multibody limit: a base and {MAX_BODY_LINKS - 1} jointed links); use fewer segments",
            (lines or {}).get(key),
        )
        for name, n in body_links(model.as_assembly()).items()
        if n > MAX_BODY_LINKS
    ]
    if problems:
        raise DescriptionError(source, problems)


def _include_path(ref: Path, folder: Path, allow_outside: bool) -> Path | str:
    """The file an include names, or why it is refused."""
    if allow_outside:
        return ref if ref.is_absolute() else folder / ref
    hint = "allowed: a path inside the model file's folder (or pass --allow-outside)"
    if ref.is_absolute():
        return f"'{ref}' is an absolute path; {hint}"
    path = folder / ref
    try:
        inside = path.resolve().is_relative_to(folder.resolve())
    except (OSError, ValueError, RuntimeError):  # a name no file can have, a symlink loop
        inside = False
    if not inside:
        return f"'{ref}' leaves the folder {folder}; {hint}"
    return path


def _resolve_includes(
    data: dict[str, Any],
    folder: Path | None,
    source: str,
    allow_outside: bool = False,
    lines: dict[str, int] | None = None,
) -> dict[str, Any]:
    # Top-level keys starting with "_" hold YAML anchors (&link ... *link) and are not part of the model.
    data = {k: copy.deepcopy(v) for k, v in data.items() if not str(k).startswith("_")}
    assembly = data.get("assembly")
    if not isinstance(assembly, dict):
        return data
    problems: list[Problem] = []
    for i, mount in enumerate(assembly.get("manipulators") or []):
        if not isinstance(mount, dict) or "file" not in mount:
            continue
        value = mount.pop("file")
        key = f"assembly.manipulators[{i}].file"
        line = (lines or {}).get(key)
        if not isinstance(value, str) or not value.strip():
            problems.append(
                Problem(
                    key, f"must be a model file's path, got a {type(value).__name__}: {value!r:.60}", line
                )
            )
            continue
        ref = Path(value)
        if "manipulator" in mount:
            problems.append(Problem(key, "give either 'file' or 'manipulator', not both", line))
            continue
        path = _include_path(ref, folder or Path("."), allow_outside)
        if isinstance(path, str):
            problems.append(Problem(key, f"cannot include {path}", line))
            continue
        try:
            included, included_lines = load_mapping(path)
        except DescriptionError as exc:
            problems.append(Problem(key, f"cannot include {path}: {exc.problems[0].message}", line))
            continue
        if "manipulator" not in included:
            problems.append(Problem(key, f"{path} has no 'manipulator' section", line))
            continue
        try:  # on its own first, so that a problem is named by the included file's own line
            model_from_dict(
                {"manipulator": included["manipulator"]},
                str(path),
                path.parent,
                included_lines,
                allow_outside,
            )
        except DescriptionError as exc:
            shown = "; ".join(p.render() for p in exc.problems[:3])
            more = f" (and {len(exc.problems) - 3} more)" if len(exc.problems) > 3 else ""
            problems.append(Problem(key, f"{path}: {shown}{more}", line))
            continue
        mount["manipulator"] = included["manipulator"]
    if problems:
        raise DescriptionError(source, problems)
    return data


def model_from_dict(
    data: dict[str, Any],
    source: str = "<dict>",
    folder: Path | None = None,
    lines: dict[str, int] | None = None,
    allow_outside: bool = False,
) -> Model:
    """Validate a model given as a Python dict (same schema as the files).

    Args:
        data: The parsed content.
        source: Name used in error messages.
        folder: Folder that relative ``file:`` includes are resolved against (default: the
            current directory); includes may not leave it.
        lines: Key-path → line map for messages.
        allow_outside: Let ``file:`` includes name any file (absolute, or up with ``..``).

    Raises:
        DescriptionError: Listing every problem.
    """
    model = validate(Model, _resolve_includes(data, folder, source, allow_outside, lines), source, lines)
    _check_bodies(model, source, lines)
    return model


def load_model(path: str | Path, allow_outside: bool = False, *, bundled: bool = True) -> Model:
    """Load and validate a model file (YAML or JSON); see :func:`model_from_dict`.

    Args:
        path: The model file.
        allow_outside: Let the file include files outside its own folder.
        bundled: A relative ``path`` that does not exist but spells a bundled model
            (``ihm_finger``, ``ihm_finger.yaml``, ``studies/models/ihm_finger.yaml``) loads the
            bundled one (:func:`~somo_sweep.model.tables.bundled_if_missing`), so the README's
            examples run from any folder. A study's own model references pass False.

    Raises:
        DescriptionError: Every problem of the file (a missing file's names the bundled models).
    """
    path = bundled_if_missing(path, "models") if bundled else Path(path)
    if bundled and not is_file(path) and missing_or_special(path) == "file not found":
        raise DescriptionError(path, [Problem("", not_found(path, "models"))])
    data, lines = load_mapping(path)
    return model_from_dict(data, str(path), path.parent, lines, allow_outside)
