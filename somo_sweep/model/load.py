"""Model files: a ``manipulator:`` or an ``assembly:`` section, from YAML, JSON or a dict.

Inside an assembly, a mount may say ``file: other.yaml`` instead of giving its
``manipulator`` inline; the path is relative to the including file. Top-level keys
starting with ``_`` are ignored: they hold YAML anchors reused below (``&link`` / ``*link``).
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
from somo_sweep.model.files import load_mapping
from somo_sweep.model.validation import validate

__all__ = ["Model", "load_model", "model_from_dict"]


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


def _resolve_includes(data: dict[str, Any], folder: Path | None, source: str) -> dict[str, Any]:
    # Top-level keys starting with "_" hold YAML anchors (&link ... *link) and are not part of the model.
    data = {k: copy.deepcopy(v) for k, v in data.items() if not str(k).startswith("_")}
    assembly = data.get("assembly")
    if not isinstance(assembly, dict):
        return data
    problems: list[Problem] = []
    for i, mount in enumerate(assembly.get("manipulators") or []):
        if not isinstance(mount, dict) or "file" not in mount:
            continue
        ref = Path(str(mount.pop("file")))
        path = ref if ref.is_absolute() or folder is None else folder / ref
        key = f"assembly.manipulators[{i}].file"
        if "manipulator" in mount:
            problems.append(Problem(key, "give either 'file' or 'manipulator', not both"))
            continue
        try:
            included, _ = load_mapping(path)
        except DescriptionError as exc:
            problems.append(Problem(key, f"cannot include {path}: {exc.problems[0].message}"))
            continue
        if "manipulator" not in included:
            problems.append(Problem(key, f"{path} has no 'manipulator' section"))
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
) -> Model:
    """Validate a model given as a Python dict (same schema as the files).

    Args:
        data: The parsed content.
        source: Name used in error messages.
        folder: Folder that relative ``file:`` includes are resolved against.
        lines: Key-path → line map for messages.

    Raises:
        DescriptionError: Listing every problem.
    """
    return validate(Model, _resolve_includes(data, folder, source), source, lines)


def load_model(path: str | Path) -> Model:
    """Load and validate a model file (YAML or JSON)."""
    path = Path(path)
    data, lines = load_mapping(path)
    return model_from_dict(data, str(path), path.parent, lines)
