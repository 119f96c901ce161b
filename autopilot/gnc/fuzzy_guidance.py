"""Fuzzy waypoint guidance (thesis chapter 6, SPEC section 7): the outer loop.

Two waypoints are targeted at once. Each cycle, with the boat at (X0, Y0),
heading psi, next waypoint W_i and the one after W_{i+1}:

    psi_1 = bearing of W_i,  psi_2 = bearing of W_{i+1}              (Eq 6.1)
    D     = distance to W_i                                          (Eq 6.2)
    theta = bearing of W_i,  alpha = theta - psi                     (Eq 6.3, 6.4)
    DCPA  = |D sin alpha|,   TCPA = D cos alpha / U                  (Eq 6.5, 6.6)
    DCPA' = DCPA / L,        TCPA' = TCPA / (L / U) = D cos alpha / L (Eq 6.7, 6.8)
    CDH   = Mamdani(TCPA', DCPA') with the rules of Table 6.1        (Eq 6.9)
    psi_d = psi_1 + wrap(psi_2 - psi_1) * CDH

W_i is passed when TCPA' < 0 (the waypoint is abaft the beam).

Corner cases, guarded here:

- speed near zero: TCPA = D cos(alpha) / U is undefined, but the speed
  cancels in TCPA' (Eq 6.8), so TCPA' is computed as D cos(alpha) / L and
  stays finite at rest; still, a boat (nearly) at rest is not "passing"
  anything: below ``min_speed_m_s`` TCPA' < 0 does not switch, and alpha is
  taken from the heading because the course over ground is noise;
- alpha from the course over ground (default) rather than the heading of
  Eq 6.4: in a current the boat crabs, and the closest point of approach
  lies along the track, not along the bow;
- a boat spun round by current or wind far from W_i, or set past it more
  than a boat length off, has not passed it: TCPA' < 0 only switches within
  ``pass_radius_nd`` (1) boat lengths, and the boat turns back for it;
- the boat on top of the waypoint: the bearing is undefined; the base class
  counts the waypoint reached within ``capture_radius_m`` before it is used;
- a waypoint behind the boat (at the start, or right after a switch to a
  waypoint back the way we came): TCPA' < 0 at once, which must not count as
  "passed". Switching is armed only with way on (below ``min_speed_m_s`` the
  reference is the heading, which points at the target the law steers for)
  and once this target has been ahead, within
  ``arm_bearing_deg`` (45) of the course or at most ``arm_abeam_nd`` (1) boat
  length abeam (a boat set sideways past it passes it close). Armed on
  TCPA' >= 0 alone, a target nearly abeam at the switch (a sharp corner)
  armed on a TCPA' just above 0 and was counted "passed" 10.8 m off two
  cycles later, as the turn swung the course (a clean-clone run of 08d271a);
- two waypoints closer than a boat length (pond set 9.2): the same arming
  keeps a switch from cascading through both at once;
- the last waypoint has no W_{i+1}: psi_2 = psi_1, so CDH has no effect.

The membership-function universes of Fig 6.3 cannot be read from the thesis;
they are configuration (:class:`FuzzyConfig`), defaults chosen in simulation
(``autopilot evaluate``): TCPA' in [0, 1] and DCPA' in [0, 1] boat lengths,
so CDH starts to rise about one boat length (4 m) before W_i. Re-checked
with the speed trim and the PID defaults of ``autopilot.gnc.pid`` (worst
closest approach over every shipped mission, calm / 0.2 m/s current from
any side): TCPA' to 0.8 L 1.00 / 1.37 m, 1.0 L 1.00 / 1.35 m, 1.25 L
1.12 / 1.31 m; DCPA' to 0.7 L 1.00 / 1.37 m, 1.5 L 1.00 / 1.33 m. With the
re-tuned PID the universes matter little; 1.0 / 1.0 is kept (best in calm
water). The calm 1.00 m is the capture radius at the last waypoint (the
run stops there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

from autopilot.geo import wrap_pi
from autopilot.gnc.fuzzy import Mamdani, rule_indices, uniform_partition
from autopilot.gnc.waypoints import Steer, WaypointGuidance
from autopilot.mathutil import clamp
from autopilot.schema import param

SETS = ("SA", "SM", "ME", "ML", "LA")  # small, small-medium, medium, medium-large, large

# Table 6.1: rows DCPA', columns TCPA'; entries CDH. THE rule table, nowhere else.
RULE_TABLE: tuple[tuple[str, ...], ...] = (
    # TCPA':  SA    SM    ME    ML    LA
    ("LA", "ML", "ME", "SM", "SA"),  # DCPA' SA
    ("ML", "ME", "SM", "SA", "SA"),  # DCPA' SM
    ("ME", "SM", "SA", "SA", "SA"),  # DCPA' ME
    ("SM", "SA", "SA", "SA", "SA"),  # DCPA' ML
    ("SA", "SA", "SA", "SA", "SA"),  # DCPA' LA
)


@dataclass(frozen=True)
class FuzzyConfig:
    """Universes of the fuzzy sets (Fig 6.3 is not legible: chosen in simulation)."""

    tcpa_max_nd: float = param(
        1.0, unit="-", lo=0.05, hi=50.0, source="chosen in simulation (Fig 6.3 unreadable)",
        doc="TCPA' universe is [0, tcpa_max_nd] boat lengths, five evenly spaced triangles; LA from here on",
    )
    dcpa_max_nd: float = param(
        1.0, unit="-", lo=0.05, hi=50.0, source="chosen in simulation (Fig 6.3 unreadable)",
        doc="DCPA' universe is [0, dcpa_max_nd] boat lengths, five evenly spaced triangles; LA from here on",
    )
    cpa_reference: str = param(
        "course", choices=("course", "heading"), source="Eq 6.4 uses heading; course chosen in simulation",
        doc="alpha = bearing - this: 'course' (over ground, the direction the CPA really lies along; "
        "differs from heading when a current sets the boat) or 'heading' (thesis Eq 6.4)",
    )
    min_speed_m_s: float = param(
        0.15, unit="m/s", lo=0.0, hi=3.0, source="guard: TCPA (Eq 6.6) is undefined at U = 0",
        doc="below this speed the course is not used for alpha and TCPA' < 0 does not switch waypoints",
    )
    pass_radius_nd: float = param(
        1.0, unit="-", lo=0.5, hi=100.0, source="guard, chosen in simulation (benchmarks/fuzzy_arming.py; 3 before)",
        doc="TCPA' < 0 counts as 'passed' only within this many boat lengths: a boat set past W_i farther off, or "
        "spun round by current or wind far from it, has not passed it and turns back for it",
    )
    arm_bearing_deg: float = param(
        45.0, unit="deg", lo=5.0, hi=90.0, source="guard, chosen in simulation (benchmarks/fuzzy_arming.py; 90: armed on TCPA' >= 0)",
        doc="TCPA' < 0 counts as 'passed' only once the waypoint has lain ahead within this angle of the course "
        "(the boat was heading for it) or within arm_abeam_nd: a waypoint far abeam at the switch is not "
        "passed by the turn towards it",
    )
    arm_abeam_nd: float = param(
        1.0, unit="-", lo=0.0, hi=100.0, source="guard, chosen in simulation (benchmarks/fuzzy_arming.py)",
        doc="a waypoint ahead (TCPA' >= 0) at most this many boat lengths abeam (DCPA') arms the pass test "
        "whatever its bearing: a boat set sideways past it by wind or current passes it close",
    )
    defuzz_points: int = param(
        61, unit="-", lo=11, hi=2001, source="Eq 6.9 (61 samples: CDH within 0.005 of a 2001-sample CoG)", doc="samples of the CDH universe [-0.25, 1.25] for the centre of gravity (rounded up to 6k+1 so 0..1 peaks are samples)",
    )


@lru_cache(maxsize=32)
def cdh_engine(tcpa_max_nd: float, dcpa_max_nd: float, n_points: int = 201) -> Mamdani:
    """The Mamdani system of Table 6.1 with the given universes.

    Inputs: in1 = DCPA' (rows of Table 6.1), in2 = TCPA' (columns). The CDH
    output sets are five triangles over [0, 1] whose end sets are symmetric
    (reaching a quarter beyond 0 and 1) and the centre of gravity is taken
    over that extended range and clipped to [0, 1]: a fully fired SA then
    gives exactly CDH = 0 (steer to W_i only) and LA exactly CDH = 1, which
    one-sided end triangles cannot (they bias CDH by 1/12 towards the middle).
    """
    # the sampled CDH grid must hold the set peaks (0, 0.25, ..., 1) for an exact 0 and 1:
    # 1.5 / (n - 1) must divide 0.25, i.e. n - 1 a multiple of 6
    n_points = 6 * -(-(n_points - 1) // 6) + 1
    return Mamdani(
        in1_sets=uniform_partition(0.0, dcpa_max_nd, len(SETS)),
        in2_sets=uniform_partition(0.0, tcpa_max_nd, len(SETS)),
        out_sets=uniform_partition(0.0, 1.0, len(SETS), extend=True),
        rules=rule_indices(RULE_TABLE, SETS),
        in1_range=(0.0, dcpa_max_nd),
        in2_range=(0.0, tcpa_max_nd),
        out_range=(-0.25, 1.25),
        n_points=n_points,
    )


def cdh(tcpa_nd, dcpa_nd, config: FuzzyConfig = FuzzyConfig()):
    """CDH (0..1) for TCPA', DCPA' (scalars or arrays): the control surface of Fig 6.5."""
    import numpy as np

    engine = cdh_engine(config.tcpa_max_nd, config.dcpa_max_nd, config.defuzz_points)
    return np.clip(engine.evaluate(dcpa_nd, tcpa_nd), 0.0, 1.0)


def cpa_geometry(north_m: float, east_m: float, psi_rad: float, wp_n: float, wp_e: float, length_m: float):
    """(D, theta, alpha, TCPA', DCPA') of Eq 6.2-6.8 for one waypoint, plain floats."""
    dn, de = wp_n - north_m, wp_e - east_m
    d_m = math.hypot(dn, de)
    theta = math.atan2(de, dn) if d_m > 0.0 else psi_rad
    alpha = theta - psi_rad
    tcpa_nd = d_m * math.cos(alpha) / length_m  # Eq 6.6 + 6.8: the speed cancels
    dcpa_nd = abs(d_m * math.sin(alpha)) / length_m  # Eq 6.5 + 6.7
    return d_m, theta, alpha, tcpa_nd, dcpa_nd


class FuzzyGuidance(WaypointGuidance):
    """The thesis's double-waypoint fuzzy guidance (chapter 6)."""

    law_name = "fuzzy"

    def reset(self) -> None:
        cfg = self.config.fuzzy
        self._engine = cdh_engine(cfg.tcpa_max_nd, cfg.dcpa_max_nd, cfg.defuzz_points)
        self._arm_cos = math.cos(math.radians(cfg.arm_bearing_deg))

    def _steer(self, nav, dt_s: float, i: int) -> Steer:
        cfg = self.config.fuzzy
        wn, we = self.waypoints[i]
        moving = nav.speed_m_s >= cfg.min_speed_m_s
        ref = nav.course_rad if (moving and cfg.cpa_reference == "course") else nav.psi_rad
        d_m, psi_1, _, tcpa_nd, dcpa_nd = cpa_geometry(nav.north_m, nav.east_m, ref, wn, we, self.boat_length_m)
        # ahead along the course, to be passed close or within the arm bearing (cos(alpha) >= its cosine); with no
        # way on the reference is the heading, which points at the target the law steers for: it proves nothing
        if moving and tcpa_nd >= 0.0 and (dcpa_nd <= cfg.arm_abeam_nd
                                          or tcpa_nd * self.boat_length_m >= d_m * self._arm_cos):
            self._armed = True
        passed = self._armed and tcpa_nd < 0.0 and moving and d_m <= cfg.pass_radius_nd * self.boat_length_m
        if i + 1 < len(self.waypoints):
            n2, e2 = self.waypoints[i + 1]
            dn2, de2 = n2 - nav.north_m, e2 - nav.east_m
            psi_2 = math.atan2(de2, dn2) if (dn2 or de2) else psi_1
        else:
            psi_2 = psi_1
        if tcpa_nd < 0.0:
            # W_i behind and not (yet) passed: turn back to it, do not blend towards W_{i+1}
            c = 0.0
        else:
            c = self._engine.evaluate_scalar(dcpa_nd, tcpa_nd)
            c = clamp(c, 0.0, 1.0)
        # wrap the difference so the blend turns the short way (SPEC 7)
        delta = wrap_pi(psi_2 - psi_1)
        psi_d = psi_1 + delta * c
        return Steer(
            psi_d_rad=psi_d, passed=passed, tcpa_nd=tcpa_nd, dcpa_nd=dcpa_nd, cdh=c
        )
