"""Which heading the loop steers on: the compass's while fresh and valid, COG only as the configured fallback."""

import pytest

from autopilot.daemon.config import FailsafeConfig
from autopilot.daemon.loop import choose_heading
from autopilot.drivers.sc30 import NavData, Stamped


def nav(heading=(90.0, 10.0, True), cog=(45.0, 9.5, True), sog_kn=2.0) -> NavData:
    n = NavData()
    if heading is not None:
        n.heading_deg = Stamped(heading[0], heading[1], "HDT", heading[2])
    if cog is not None:
        n.cog_deg = Stamped(cog[0], cog[1], "RMC", cog[2])
        n.sog_kn = Stamped(sog_kn, cog[1], "RMC", True)
    return n


@pytest.mark.parametrize("fallback, data, now_s, expected", [
    (False, nav(), 10.5, (90.0, "HDT", 0.5, True)),
    (False, nav(), 11.5, (90.0, "HDT", 1.5, True)),  # stale: the failsafe sees the age
    (True, nav(), 11.5, (45.0, "COG", 2.0, True)),  # stale heading, moving: COG, logged as such
    (True, nav(sog_kn=0.5), 11.5, (90.0, "HDT", 1.5, True)),  # too slow for COG to mean anything
    (True, nav(heading=(90.0, 10.0, False)), 10.2, (45.0, "COG", 0.7, True)),
    (False, nav(heading=(90.0, 10.0, False)), 10.2, (90.0, "HDT", pytest.approx(0.2), False)),
    (False, nav(heading=None), 10.2, (None, None, float("inf"), False)),
])
def test_heading_choice(fallback, data, now_s, expected):
    got = choose_heading(data, now_s, FailsafeConfig(cog_fallback=fallback, cog_fallback_min_sog_m_s=0.5))
    assert got[0] == expected[0] and got[1] == expected[1] and got[3] == expected[3]
    assert got[2] == pytest.approx(expected[2])
