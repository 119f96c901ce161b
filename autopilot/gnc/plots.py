"""Figures of the thesis for one evaluated run and for the fuzzy surface (matplotlib, imported lazily).

- trajectory with waypoints (Fig 7.5), reference and actual heading (Fig 7.6),
  TCPA', DCPA' and CDH over time (Fig 7.7-7.8), port/starboard thrust (Fig 9.x c);
- the CDH control surface over TCPA' x DCPA' (Fig 6.5).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from autopilot.geo import wrap_pi
from autopilot.plotting import pyplot, track_frame
from autopilot.userfile import writing


def plot_run(result, path: Path, waypoints_ne_m=None) -> None:
    """Four panels of one closed-loop run (RunResult with a recorded trace)."""
    plt = pyplot()
    tr = result.trace
    t = tr["t_s"]
    fig, ax = plt.subplots(2, 2, figsize=(12, 9))
    a = ax[0, 0]
    a.plot(tr["east_m"], tr["north_m"], label="track")
    wps = waypoints_ne_m if waypoints_ne_m is not None else tr.get("waypoints")
    if wps is not None:
        a.plot([w[1] for w in wps], [w[0] for w in wps], "rx--", label="waypoints")
    track_frame(a, tr["north_m"], tr["east_m"], title=f"{result.mission} / {result.guidance} / {result.condition} (Fig 7.5)")
    a = ax[0, 1]
    # heading unwrapped (no 0-360-0 spikes at north), psi_d drawn beside it: psi + wrap(psi_d - psi)
    psi = np.unwrap(np.asarray(tr["psi_rad"], dtype=float))
    psi_d = psi + wrap_pi(np.asarray(tr["psi_d_rad"], dtype=float) - psi)
    a.plot(t, np.degrees(psi), label="heading psi")
    a.plot(t, np.degrees(psi_d), "--", label="reference psi_d")
    a.set_xlabel("t (s)"), a.set_ylabel("deg (unwrapped; 360 = a full turn)"), a.legend(fontsize=8)
    a.set_title("heading (Fig 7.6)")
    a.grid(True, alpha=0.3)
    a = ax[1, 0]
    nan = float("nan")
    for key, lab in (("tcpa_nd", "TCPA'"), ("dcpa_nd", "DCPA'"), ("cdh", "CDH")):
        a.plot(t, [nan if v is None else v for v in tr[key]], label=lab)
    a.set_xlabel("t (s)"), a.legend(), a.set_title("TCPA', DCPA', CDH (Fig 7.7-7.8)")
    a = ax[1, 1]
    a.plot(t, tr["thrust_port_n"], label="T port")
    a.plot(t, tr["thrust_stbd_n"], label="T starboard")
    a.set_xlabel("t (s)"), a.set_ylabel("N"), a.legend(), a.set_title("thrust")
    fig.tight_layout()
    with writing(path):  # a full disk names the file
        fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_surface(path: Path, config=None) -> None:
    """The CDH control surface of Table 6.1 (Fig 6.5)."""
    import numpy as np

    from autopilot.gnc.fuzzy_guidance import FuzzyConfig, cdh

    config = config or FuzzyConfig()
    plt = pyplot()
    tt, dd = np.meshgrid(np.linspace(0, config.tcpa_max_nd, 61), np.linspace(0, config.dcpa_max_nd, 61))
    z = cdh(tt, dd, config)
    fig = plt.figure(figsize=(8, 6))
    a = fig.add_subplot(projection="3d")
    a.plot_surface(tt, dd, z, cmap="viridis")
    a.set_xlabel("TCPA' (-)"), a.set_ylabel("DCPA' (-)"), a.set_zlabel("CDH (-)")
    a.set_title("Fuzzy control surface, Table 6.1 (Fig 6.5)")
    with writing(path):  # a full disk names the file
        fig.savefig(path, dpi=90)
    plt.close(fig)
