"""Small numeric primitives, written once (plain floats: they sit on the per-cycle path)."""

from __future__ import annotations

__all__ = ["clamp"]


def clamp(x: float, lo: float, hi: float) -> float:
    """``x`` limited to [lo, hi] (lo <= hi)."""
    return lo if x < lo else hi if x > hi else x
