"""Vessel parameters of the WAM-V MMG model (SPEC sections 1-5).

One frozen dataclass, every field with its unit, allowed range and source.
Hydrodynamic derivatives are kept non-dimensional as the thesis prints them
(Table 5.1, standard MMG scaling by 1/2 rho L d U^2 and 1/2 rho L^2 d U^2);
everything else is SI. Two files shipped in ``autopilot/data/`` (``config/`` in a checkout) hold the two sets:
``vessel-thesis.yaml`` (Table 5.1 as printed) and ``vessel.yaml`` (calibrated
against the measured table, written by ``autopilot model calibrate``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from autopilot.measured import HULL_LENGTH_M, MAX_THRUST_N
from autopilot.resources import default_params_path, thesis_params_path  # noqa: F401 - the model's files, re-exported
from autopilot.schema import ConfigError, load_yaml, param

_T51 = "Table 5.1 (x 1e-3 as printed)"
_ZERO_SPEED = "project: damping at zero speed (SPEC 3, file 003 Eq 4-6); MMG terms vanish with U"


@dataclass(frozen=True)
class VesselParams:
    """Physical and hydrodynamic parameters of the WAM-V (SI; `_nd` = non-dimensional MMG)."""

    name: str = param("wamv", doc="name of this parameter set")
    description: str = param("", doc="where these numbers come from")
    # -- hull and mass (thesis ch. 2, Table 2.1) --
    length_m: float = param(HULL_LENGTH_M, unit="m", lo=0.5, hi=20.0, source="thesis ch. 2 (papers: 3.91 m)", doc="hull length L")
    draft_m: float = param(0.165, unit="m", lo=0.01, hi=2.0, source="thesis ch. 2", doc="draft d")
    beam_m: float = param(2.44, unit="m", lo=0.1, hi=10.0, source="thesis ch. 2", doc="overall width")
    mass_kg: float = param(255.0, unit="kg", lo=1.0, hi=10000.0, source="thesis ch. 2, full load", doc="displacement m")
    yaw_inertia_kg_m2: float = param(
        249.9, unit="kg m^2", lo=0.01, hi=1e6, source="SPEC 3: I_z = m (L/4)^2", doc="yaw moment of inertia I_z"
    )
    water_density_kg_m3: float = param(1000.0, unit="kg/m^3", lo=990.0, hi=1030.0, source="fresh-water pond", doc="rho")
    # -- added masses (text below Table 5.1) --
    added_mass_x_ratio: float = param(0.05321, unit="-", lo=0.0, hi=10.0, source="text below Table 5.1", doc="m_x / m")
    added_mass_y_ratio: float = param(0.32, unit="-", lo=0.0, hi=10.0, source="text below Table 5.1", doc="m_y / m")
    added_inertia_ratio: float = param(0.5, unit="-", lo=0.0, hi=10.0, source="SPEC 3: J_z = I_z / 2", doc="J_z / I_z")
    # -- propulsion (Eq 3.6) --
    y_p_m: float = param(1.0, unit="m", lo=0.1, hi=5.0, source="SPEC 1: pontoon centre lines ~2 m apart", doc="thrust line to centre line")
    thrust_deduction: float = param(0.25, unit="-", lo=0.0, hi=0.9, source="Eq 3.6, t_P", doc="t_P")
    moment_deduction: float = param(0.25, unit="-", lo=0.0, hi=0.9, source="Eq 3.6, d_NP", doc="d_NP")
    max_thrust_n: float = param(MAX_THRUST_N, unit="N", lo=0.1, hi=1000.0, source="Table 4.2 level F", doc="largest forward thrust per side")
    # -- resistance (thesis 4.2, SPEC 5): R(U) = r1 u + r2 |u| u --
    resistance_linear_n_s_m: float = param(14.07, unit="N s/m", lo=0.0, hi=1000.0, source="SPEC 5: R/U from straight rows", doc="linear resistance")
    resistance_quadratic_n_s2_m2: float = param(0.0, unit="N s^2/m^2", lo=0.0, hi=1000.0, source="SPEC 5: ~0 over trial range", doc="quadratic resistance")
    # -- hull manoeuvring derivatives (Eq 3.19-3.21, Table 5.1) --
    x_vv_nd: float = param(-0.880, unit="-", lo=-50.0, hi=50.0, source=_T51, doc="X'_vv")
    y_v_nd: float = param(-1.155, unit="-", lo=-50.0, hi=0.0, source=_T51, doc="Y'_v")
    y_r_nd: float = param(-0.500, unit="-", lo=-50.0, hi=50.0, source=_T51, doc="Y'_r")
    y_vvv_nd: float = param(-0.00080, unit="-", lo=-50.0, hi=50.0, source=_T51, doc="Y'_vvv")
    n_v_nd: float = param(-0.265, unit="-", lo=-50.0, hi=50.0, source=_T51, doc="N'_v")
    n_r_nd: float = param(-0.177, unit="-", lo=-50.0, hi=0.0, source=_T51, doc="N'_r")
    n_vvv_nd: float = param(1.659, unit="-", lo=-50.0, hi=50.0, source=_T51, doc="N'_vvv")
    # -- damping that stays at zero speed (spinning in place, Fig 4.12) --
    sway_damping_linear_n_s_m: float = param(5.0, unit="N s/m", lo=0.0, hi=1e5, source=_ZERO_SPEED, doc="-Y per v")
    sway_damping_quadratic_n_s2_m2: float = param(
        653.0, unit="N s^2/m^2", lo=0.0, hi=1e5, source=_ZERO_SPEED + "; cross-flow C_D = 1 on two hulls: rho C_D L d", doc="-Y per |v| v"
    )
    yaw_damping_linear_nm_s: float = param(5.0, unit="N m s", lo=0.0, hi=1e5, source=_ZERO_SPEED, doc="-N per r")
    yaw_damping_quadratic_nm_s2: float = param(
        1268.0, unit="N m s^2", lo=0.0, hi=1e5, source=_ZERO_SPEED + "; cross-flow C_D = 1: rho C_D d L^4 / 32", doc="-N per |r| r"
    )
    # -- windage (simple area-and-coefficient model, see autopilot.sim.environment) --
    air_density_kg_m3: float = param(1.225, unit="kg/m^3", lo=1.0, hi=1.5, source="ISA sea level", doc="rho_air")
    frontal_area_m2: float = param(1.5, unit="m^2", lo=0.0, hi=100.0, source="estimate: 2.44 m x ~0.6 m above water", doc="A_F")
    lateral_area_m2: float = param(2.4, unit="m^2", lo=0.0, hi=100.0, source="estimate: 3.96 m x ~0.6 m above water", doc="A_L")
    wind_cx: float = param(0.7, unit="-", lo=0.0, hi=3.0, source="typical small craft (Fossen 2021 ch. 10)", doc="longitudinal drag coefficient")
    wind_cy: float = param(0.9, unit="-", lo=0.0, hi=3.0, source="typical small craft (Fossen 2021 ch. 10)", doc="lateral drag coefficient")
    wind_cn: float = param(0.05, unit="-", lo=-1.0, hi=1.0, source="typical small craft (Fossen 2021 ch. 10)", doc="yaw moment coefficient")

    # Derived quantities, in the open (SPEC 3 non-dimensionalisation).
    @property
    def force_scale_kg_m(self) -> float:
        """1/2 rho L d (kg/m): multiplies U^2 and a force coefficient."""
        return 0.5 * self.water_density_kg_m3 * self.length_m * self.draft_m

    @property
    def moment_scale_kg(self) -> float:
        """1/2 rho L^2 d (kg): multiplies U^2 and a moment coefficient."""
        return self.force_scale_kg_m * self.length_m

    @property
    def mass_x_kg(self) -> float:
        """m + m_x (kg)."""
        return self.mass_kg * (1.0 + self.added_mass_x_ratio)

    @property
    def mass_y_kg(self) -> float:
        """m + m_y (kg)."""
        return self.mass_kg * (1.0 + self.added_mass_y_ratio)

    @property
    def inertia_z_kg_m2(self) -> float:
        """I_z + J_z (kg m^2)."""
        return self.yaw_inertia_kg_m2 * (1.0 + self.added_inertia_ratio)


# Each axis needs a damping term: any one field below may be 0 (a set fitted without it), but with all of an
# axis's at 0 a steady thrust or moment speeds the boat up without bound. Such a set used to load:
# `model manoeuvre speed` printed 21.8 m/s, AF and `model check` stopped on "internal error: the simulation
# diverged", the zig-zag on a division by zero, and `evaluate` flew it without a word.
# Sway is not among them: with all its terms at 0 the simulated boat stays bounded (side-slip is turned into
# surge, which the resistance damps); with yaw's at 0 a constant moment spins it ever faster (-4 rad/s after
# 200 s of AC, -20 after 1000 s).
# axis -> the fields that damp it, each with the sign that damps (an MMG derivative damps when negative)
DAMPING_FIELDS = {
    "surge": (("resistance_linear_n_s_m", 1.0), ("resistance_quadratic_n_s2_m2", 1.0)),
    # n_r_nd scales with the speed (zero at rest: _ZERO_SPEED): with only it, a spin in place sped up to 130 rad/s
    # in 1000 s (a review)
    "yaw": (("yaw_damping_linear_nm_s", 1.0), ("yaw_damping_quadratic_nm_s2", 1.0)),
}


def undamped_axis(params: VesselParams) -> str | None:
    """A message naming the first axis of ``params`` that nothing damps, or None when every axis has a term."""
    for axis, fields in DAMPING_FIELDS.items():
        if all(sign * getattr(params, name) <= 0.0 for name, sign in fields):
            values = ", ".join(f"{name} = {getattr(params, name):g}" for name, _ in fields)
            how = ("a positive value (SPEC 5: R/U = 14.05-14.10 N s/m was measured)" if axis == "surge" else
                   "a positive value (the damping at zero speed: n_r_nd vanishes with the speed)")
            return (f"{values}: nothing damps {axis}, so a steady {'moment' if axis == 'yaw' else 'force'} would "
                    f"speed the boat up without bound; give one of them {how}")
    return None


def load_params(path: str | Path) -> VesselParams:
    """Load a vessel parameter YAML file (refuses unknown and missing keys, NaN, out-of-range values,
    and a set with an axis that nothing damps).

    Every parameter must be given: a file with ``n_r_nd`` left out used to fly with the thesis's value
    in its place (yaw-rate error 13 % -> 96 % in ``model check``), and one with only ``mass_kg`` as
    the thesis's boat."""
    from autopilot.userfile import other_file_kind

    try:
        params = load_yaml(VesselParams, path, require_all=True)
    except ConfigError as exc:
        # the daemon's configuration or a mission given as the vessel file was refused as "ais: unknown key"
        # with the 34 vessel keys listed, not a word on what the file was
        what = other_file_kind(path)
        if what is not None and not what.startswith("a vessel") and ": unknown key (allowed: " in str(exc):
            where = ("its sim.vessel names the vessel file" if what.startswith("a daemon")
                     else "a vessel file is vessel.yaml or vessel-thesis.yaml, `autopilot files`")
            unknown = str(exc).split(" (allowed: ", 1)[0]
            raise ConfigError(f"{unknown}; {path} is {what}, not a vessel parameter set ({where})") from None
        raise
    problem = undamped_axis(params)
    if problem is not None:
        raise ConfigError(f"{path}: {problem}")
    return params


def diverged_error(path: str | Path, dt_s: float) -> ConfigError:
    """The ConfigError for a simulation of the vessel set in ``path`` that blew up at the step ``dt_s``.

    Every field can be within its range and the set still too stiff for a fixed RK4 step: a 1-kg boat
    under the shipped cross-flow damping (653 N s^2/m^2) has a sway time constant of milliseconds. That
    was "internal error: FloatingPointError ... (a bug: please report it)"; it is the set's, and fixable."""
    return ConfigError(
        f"{path}: the simulation of this vessel set diverged (a state grew without bound at the {dt_s:g} s step): "
        "a mass or inertia small against its damping (mass_kg, yaw_inertia_kg_m2 against the sway_damping_* and "
        "yaw_damping_* terms) makes the model too stiff for the simulator's fixed step; check those values "
        "against the shipped vessel.yaml (`autopilot files`)")
