"""Small numeric primitives, written once (plain floats: they sit on the per-cycle path)."""

from __future__ import annotations

__all__ = ["clamp", "polygon_problem"]


def clamp(x: float, lo: float, hi: float) -> float:
    """``x`` limited to [lo, hi] (lo <= hi)."""
    return lo if x < lo else hi if x > hi else x


def polygon_problem(points) -> str | None:
    """Why the closed polygon through ``points`` (x, y pairs, >= 3) cannot bound an area, or None: no area (all
    vertices on one line, or repeated), or edges that cross (a bow tie: its inside is not what was meant)."""
    n = len(points)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    for i in range(n):
        a, b = points[i], points[(i + 1) % n]
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue  # the closing edge shares vertex 0 with the first
            c, d = points[j], points[(j + 1) % n]
            d1, d2, d3, d4 = cross(c, d, a), cross(c, d, b), cross(a, b, c), cross(a, b, d)
            if ((d1 > 0) != (d2 > 0)) and ((d3 > 0) != (d4 > 0)) and 0 not in (d1, d2, d3, d4):
                return f"edges {i}-{(i + 1) % n} and {j}-{(j + 1) % n} cross (vertices out of order?)"
    twice_area = sum(points[i][0] * points[(i + 1) % n][1] - points[(i + 1) % n][0] * points[i][1] for i in range(n))
    scale = max(max(abs(x), abs(y)) for x, y in points) or 1.0
    if abs(twice_area) <= 1e-12 * scale * scale:
        return "encloses no area (its vertices lie on one line)"
    return None
