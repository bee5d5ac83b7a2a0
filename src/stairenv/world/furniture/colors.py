"""Display colours of furniture parts (``part_rgba``)."""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

# --- colours -------------------------------------------------------------------------------------
# Per family: (frame / wood colour, upholstery / soft colour), RGBA in [0, 1].
FAMILY_RGBA: Mapping[str, tuple[tuple[float, ...], tuple[float, ...]]] = MappingProxyType({
    "chair": ((0.55, 0.36, 0.20, 1.0), (0.62, 0.42, 0.25, 1.0)),
    "armchair": ((0.30, 0.22, 0.16, 1.0), (0.35, 0.50, 0.62, 1.0)),
    "stool": ((0.50, 0.34, 0.20, 1.0), (0.72, 0.55, 0.35, 1.0)),
    "sofa": ((0.25, 0.20, 0.16, 1.0), (0.55, 0.30, 0.30, 1.0)),
    "bed": ((0.48, 0.33, 0.22, 1.0), (0.90, 0.90, 0.86, 1.0)),
    "double_bed": ((0.40, 0.28, 0.20, 1.0), (0.86, 0.88, 0.93, 1.0)),
    "table": ((0.45, 0.30, 0.18, 1.0), (0.60, 0.42, 0.26, 1.0)),
    "cabinet": ((0.70, 0.62, 0.50, 1.0), (0.78, 0.70, 0.58, 1.0)),
    "wardrobe": ((0.60, 0.50, 0.40, 1.0), (0.68, 0.58, 0.47, 1.0)),
    "bookshelf": ((0.52, 0.38, 0.26, 1.0), (0.60, 0.45, 0.32, 1.0)),
    "lamp": ((0.20, 0.20, 0.22, 1.0), (0.95, 0.90, 0.72, 1.0)),
})
_SOFT_LABELS = frozenset({"seat", "bed_surface", "pillow", "lamp_shade", "table_top", "door", "top"})
_UPHOLSTERED = frozenset({"armchair", "sofa"})
_BOOK_RGBA = ((0.60, 0.15, 0.15, 1.0), (0.15, 0.35, 0.55, 1.0), (0.20, 0.50, 0.25, 1.0), (0.75, 0.60, 0.20, 1.0))
HANDLE_RGBA = (0.75, 0.75, 0.78, 1.0)


def part_rgba(family: str, label: str, k: int = 0) -> tuple[float, ...]:
    """Display colour of part ``k`` of ``label`` of a ``family`` piece."""
    if label == "books":
        return _BOOK_RGBA[k % len(_BOOK_RGBA)]
    if label == "handle":
        return HANDLE_RGBA
    frame, soft = FAMILY_RGBA.get(family, ((0.5, 0.5, 0.5, 1.0), (0.6, 0.6, 0.6, 1.0)))
    if label == "pillow":
        return (1.0, 1.0, 1.0, 1.0)
    if label in _SOFT_LABELS or (family in _UPHOLSTERED and label in ("backrest", "armrest", "base")):
        return soft
    return frame
