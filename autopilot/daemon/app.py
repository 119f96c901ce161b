"""Start-up and shut-down of ``autopilot run``: everything checked first, then ports, then the loop.

Order matters for safety: configuration and mission are loaded and checked
(ConfigError, exit 2) before any serial port is opened; the log is opened
before the devices so that everything they report is recorded; the loop
starts at zero thrust (failsafe ``waiting``) and the GNC drives only once
both data streams have been valid for ``failsafe.start_valid_s``.
"""

from __future__ import annotations

import asyncio
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

from autopilot.clock import Clock
from autopilot.daemon.config import DaemonConfig
from autopilot.daemon.loop import ControlLoop
from autopilot.daemon.missionlog import MissionLog, log_path
from autopilot.daemon.sd_notify import Notifier
from autopilot.daemon.state import StateStore, file_sha256
from autopilot.geo import latlon_to_local
from autopilot.schema import ConfigError, to_dict

__all__ = ["RunOptions", "prepare", "run_daemon"]


@dataclass(frozen=True)
class RunOptions:
    mission_path: str
    sim: bool = False
    speedup: float = 1.0
    log_dir: str | None = None
    state_dir: str | None = None
    fresh: bool = False


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("wamv-autopilot")
    except PackageNotFoundError:  # pragma: no cover - running from a bare checkout
        return "unknown"


def _fence_ne_m(cfg: DaemonConfig, origin_lat_deg: float, origin_lon_deg: float):
    g = cfg.geofence
    if g.frame == "none":
        return None
    if g.frame == "local":
        return tuple(g.polygon)
    return tuple(latlon_to_local(lat, lon, origin_lat_deg, origin_lon_deg) for lat, lon in g.polygon)


def prepare(cfg: DaemonConfig, opts: RunOptions):
    """Load and check the mission and the directories; no device is touched. Raises ConfigError."""
    from autopilot.mission import load_mission

    if not (math.isfinite(opts.speedup) and 0.01 <= opts.speedup <= 100.0):
        raise ConfigError(f"--speedup: {opts.speedup!r} is outside the allowed range [0.01, 100]")
    mission = load_mission(
        opts.mission_path,
        origin_lat_deg=cfg.origin_lat_deg,
        origin_lon_deg=cfg.origin_lon_deg,
        max_range_m=cfg.max_mission_range_m,
    )
    if mission.origin_lat_deg is None or mission.origin_lon_deg is None:
        if not opts.sim:
            raise ConfigError(
                f"{opts.mission_path}: local-frame mission without an origin: the compass reports latitude/longitude, "
                "so set origin_lat_deg/origin_lon_deg in the configuration (the launch point) or add 'origin' to the mission"
            )
        mission = load_mission(
            opts.mission_path,
            origin_lat_deg=cfg.sim.origin_lat_deg,
            origin_lon_deg=cfg.sim.origin_lon_deg,
            max_range_m=cfg.max_mission_range_m,
        )
    log_dir = Path(opts.log_dir or cfg.log_dir)
    state_dir = Path(opts.state_dir or cfg.state_dir)
    for name, d in (("log directory", log_dir), ("state directory", state_dir)):
        try:
            d.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError(f"{name} {d}: cannot create ({exc.strerror})") from exc
        if not os.access(d, os.W_OK | os.X_OK):
            raise ConfigError(f"{name} {d}: not writable by this user")
    return mission, log_dir, state_dir


async def _main(cfg: DaemonConfig, opts: RunOptions, mission, log_dir: Path, state_dir: Path, *, keep_samples=False, result=None) -> int:
    version = _version()
    from autopilot.drivers.mbed import MbedDriver
    from autopilot.drivers.sc30 import SC30Driver
    from autopilot.gnc import Autopilot

    clock = Clock(opts.speedup)
    notifier = Notifier()
    mission_path = str(Path(opts.mission_path).resolve())
    sha = file_sha256(opts.mission_path)
    store = StateStore(state_dir)
    log = MissionLog(log_path(log_dir, opts.mission_path))

    start_index, hold_zero = 0, None
    saved_index = None if opts.fresh else store.resume_index(mission_path, sha)
    if saved_index is not None:
        if cfg.failsafe.resume_after_restart:
            start_index = saved_index
        else:
            hold_zero = "interrupted mission found in the state directory and failsafe.resume_after_restart is false"

    rig = None
    sc30_port, mbed_port = cfg.serial.sc30_port, cfg.serial.mbed_port
    boat_length_m = cfg.boat_length_m
    tmpdir = None
    if opts.sim:
        from autopilot.simdev import SimRig
        from autopilot.sim import Environment, default_params_path, load_params

        params = load_params(cfg.sim.vessel or default_params_path())
        boat_length_m = float(params.length_m)
        home_ne = (0.0, 0.0)
        if mission.home_latlon is not None:
            home_ne = latlon_to_local(mission.home_latlon[0], mission.home_latlon[1], mission.origin_lat_deg, mission.origin_lon_deg)
        env = Environment(
            current_speed_m_s=cfg.sim.current_speed_m_s,
            current_towards_deg=cfg.sim.current_towards_deg,
            wind_speed_m_s=cfg.sim.wind_speed_m_s,
            wind_from_deg=cfg.sim.wind_from_deg,
        )
        tmpdir = tempfile.TemporaryDirectory(prefix="autopilot-sim-")
        rig = SimRig(
            params,
            clock,
            directory=tmpdir.name,
            env=env,
            x0=(home_ne[0], home_ne[1], 0.0, 0.0, 0.0, 0.0),
            origin_lat_deg=mission.origin_lat_deg,
            origin_lon_deg=mission.origin_lon_deg,
            heading_noise_deg=cfg.sim.heading_noise_deg,
            position_noise_m=cfg.sim.position_noise_m,
            seed=cfg.sim.seed,
            sc30_baudrate=cfg.serial.sc30_baud,
            sc30_options={"position_error": cfg.sim.position_error_model, "heading_error": cfg.sim.heading_error_model},
        )
        await rig.start()
        sc30_port, mbed_port = rig.sc30_path, rig.mbed_path

    ap = Autopilot(
        cfg.gnc,
        mission.waypoints_ne_m,
        speeds_m_s=mission.speeds_m_s,
        boat_length_m=boat_length_m,
        start_index=start_index,
    )
    loop = ControlLoop(
        cfg,
        clock=clock,
        autopilot=ap,
        mission=mission,
        mission_path=mission_path,
        mission_sha256=sha,
        sc30=None,
        mbed=None,
        log=log,
        notifier=notifier,
        store=store,
        fence_ne_m=_fence_ne_m(cfg, mission.origin_lat_deg, mission.origin_lon_deg),
        hold_zero=hold_zero,
        keep_samples=keep_samples,
    )
    sc30 = SC30Driver(
        sc30_port,
        baudrate=cfg.serial.sc30_baud,
        clock=clock,
        reconnect_min_s=cfg.serial.reconnect_min_s,
        reconnect_max_s=cfg.serial.reconnect_max_s,
        on_event=loop.on_driver_event("sc30"),
    )
    mbed = MbedDriver(
        mbed_port,
        baudrate=cfg.serial.mbed_baud,
        clock=clock,
        reconnect_min_s=cfg.serial.reconnect_min_s,
        reconnect_max_s=cfg.serial.reconnect_max_s,
        on_event=loop.on_driver_event("mbed"),
        ack_timeout_s=cfg.serial.ack_timeout_s,
    )
    loop.sc30, loop.mbed = sc30, mbed

    loop.t0_s = clock.now_s()
    log.event(
        "mission_start",
        t_s=0.0,
        mission=mission_path,
        mission_name=mission.name,
        guidance=cfg.gnc.guidance.law,
        rate_hz=cfg.rate_hz,
        sim=opts.sim,
        speedup=opts.speedup,
        origin_lat_deg=mission.origin_lat_deg,
        origin_lon_deg=mission.origin_lon_deg,
        waypoints=[[float(n), float(e)] for n, e in mission.waypoints_ne_m],
        waypoint_speeds_m_s=list(mission.speeds_m_s) if mission.speeds_m_s is not None else None,
        boat_length_m=boat_length_m,
        config=to_dict(cfg),
        version=version,
        start_index=start_index,
        sc30_port=sc30_port,
        mbed_port=mbed_port,
        pid=os.getpid(),
    )
    if hold_zero is not None:
        log.event("info", t_s=0.0, message=f"holding zero thrust: {hold_zero}")
    elif start_index:
        log.event("info", t_s=0.0, message=f"resuming interrupted mission at waypoint {start_index}")

    tasks = [asyncio.create_task(sc30.run(), name="sc30"), asyncio.create_task(mbed.run(), name="mbed")]
    loop.install_signal_handlers()
    # give the drivers their first chance to open the ports, so a normal start logs no port fault
    for _ in range(20):
        if sc30.connected and mbed.connected:
            break
        await clock.sleep(cfg.period_s / 10.0)
    reason = "error"
    try:
        reason = await loop.run()
    except Exception as exc:  # noqa: BLE001 - logged, then the boat is stopped
        log.event("info", t_s=clock.now_s() - loop.t0_s, message="control loop error", error=repr(exc))
        reason = "error"
    finally:
        code = await loop.stop(reason)
        for t in tasks:
            t.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        for dev in (sc30, mbed):
            try:
                await dev.close()
            except Exception:  # noqa: BLE001 - closing best effort
                pass
        if rig is not None:
            await rig.stop()
        if tmpdir is not None:
            tmpdir.cleanup()
        log.close()
        notifier.close()
        if result is not None:
            result["stats"] = loop.stats
            result["log_path"] = str(log.path)
    return code


def run_daemon(cfg: DaemonConfig, opts: RunOptions, *, keep_samples: bool = False, result: dict | None = None) -> int:
    """Check everything, then run until complete or signalled. Returns the process exit code."""
    mission, log_dir, state_dir = prepare(cfg, opts)
    return asyncio.run(_main(cfg, opts, mission, log_dir, state_dir, keep_samples=keep_samples, result=result))
