"""What a paper figure returns: figures, numbers and tables, for the command line to save.

Nothing in :mod:`somo_sweep.paper` writes files; each ``build`` function returns an
:class:`Artifacts` and ``somo-sweep paper …`` writes it into ``--out``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["Artifacts"]


@dataclass
class Artifacts:
    """The outputs of one figure, keyed by file name relative to the output folder.

    Attributes:
        figures: File stem → figure, saved in every format of ``formats`` at ``dpi``.
        formats: Figure file formats.
        dpi: Figure resolution, dots per inch.
        json: File name → JSON-serialisable numbers.
        tables: File name → table, saved as CSV without the index.
        texts: File name → text (Markdown tables, notes), saved as UTF-8.
        images: File name → RGB image (H × W × 3, uint8), saved as PNG.
        animations: File name → RGB frames, saved as an animated GIF (0.1 s a frame).
        lines: What to print when done (headline numbers).
    """

    figures: dict[str, Figure] = field(default_factory=dict)
    formats: tuple[str, ...] = ("png", "svg")
    dpi: int = 120
    json: dict[str, Any] = field(default_factory=dict)
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    texts: dict[str, str] = field(default_factory=dict)
    images: dict[str, np.ndarray] = field(default_factory=dict)
    animations: dict[str, list[np.ndarray]] = field(default_factory=dict)
    lines: list[str] = field(default_factory=list)
