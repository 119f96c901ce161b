"""The fixed-rate control loop: navigation data in, one thruster command and one log line out.

One asyncio process. The loop runs on absolute deadlines of the injected
:class:`autopilot.clock.Clock` (``next_due += period``: no drift); when it
falls behind by more than a period it skips to the next deadline and counts
the skipped cycles. Each cycle:

1. reads the drivers' latest :class:`NavData` and converts lat/lon to the
   local frame around the mission origin (:mod:`autopilot.geo`);
2. asks the :class:`~autopilot.daemon.failsafe.Failsafe` whether thrust is
   allowed;
3. if it is, steps :class:`autopilot.gnc.Autopilot` (guidance, PID,
   allocation; Eq 7.1, 8.5-8.6); otherwise commands zero thrust;
4. sends exactly one command to the Mbed and writes exactly one ``cycle``
   line (docs/log-schema.md).

SIGTERM/SIGINT end the loop at the next cycle: zero thrust is sent and its
acknowledgement awaited (bounded), ``stop`` logged, the log closed, exit 0.
"""

from __future__ import annotations

import asyncio
import math
import signal
from dataclasses import dataclass, field

from autopilot.clock import Clock
from autopilot.daemon.config import DaemonConfig
from autopilot.daemon.failsafe import Failsafe, Observation
from autopilot.daemon.missionlog import MissionLog
from autopilot.daemon.sd_notify import Notifier
from autopilot.daemon.state import Progress, StateStore
from autopilot.geo import latlon_to_local, wrap_180, wrap_360
from autopilot.gnc.navigation import dead_reckon_ne
from autopilot.gnc.passes import PassTracker

__all__ = ["LoopStats", "ControlLoop", "gnc_fields_null", "KN_TO_M_S"]

KN_TO_M_S = 1852.0 / 3600.0

# ControlOutput fields logged in a cycle line (log-schema), null while the GNC is not stepped
_GNC_KEYS = (
    "tcpa_nd", "dcpa_nd", "cdh", "psi_d_deg", "heading_error_deg", "xte_m", "speed_cmd_m_s",
    "pid_p_n", "pid_i_n", "pid_d_n", "tau_com_n", "tau_com_trim_n", "tau_order_n",
)


def watchdog_due(*, ready: bool, lateness_s: float, period_s: float, since_last_s: float, interval_s: float) -> bool:
    """WATCHDOG=1 is due: only once ready, only from a cycle that started on time (later than its
    deadline by less than one period), and at most every ``interval_s`` (half of WatchdogSec).
    A loop that runs late every cycle therefore stops feeding systemd, which restarts it."""
    return ready and lateness_s < period_s and since_last_s >= interval_s


def gnc_fields_null() -> dict:
    return {k: None for k in _GNC_KEYS}


def choose_heading(nav, now_s: float, fs):
    """(heading_deg, source, age_s, valid): the compass's heading while fresh and valid, else the
    course over ground when ``fs.cog_fallback`` allows it (logged as source COG), else the stale
    or invalid heading for the failsafe to judge. ``fs``: the FailsafeConfig."""
    h = nav.heading_deg
    age = nav.heading_age_s(now_s)
    if h is not None and age <= fs.heading_stale_s and h.valid:
        return float(h.value), h.source, age, True
    if fs.cog_fallback and nav.cog_deg is not None and nav.sog_kn is not None:
        cog_age = now_s - nav.cog_deg.t_s
        sog_m_s = float(nav.sog_kn.value) * KN_TO_M_S
        if cog_age <= fs.position_stale_s and nav.cog_deg.valid and sog_m_s >= fs.cog_fallback_min_sog_m_s:
            return float(nav.cog_deg.value), "COG", cog_age, True
    if h is None:
        return None, None, age, False
    return float(h.value), h.source, age, bool(h.valid)


@dataclass
class LoopStats:
    cycles: int = 0
    skipped: int = 0
    late_cycles: int = 0
    lateness_s: list = field(default_factory=list)
    heading_latency_s: list = field(default_factory=list)
    keep_samples: bool = False


def _value(stamped):
    return None if stamped is None else stamped.value


class ControlLoop:
    """Wires drivers, failsafe, GNC, log and notifier together. See the module docstring."""

    def __init__(
        self,
        cfg: DaemonConfig,
        *,
        clock: Clock,
        autopilot,
        mission,
        mission_path: str,
        mission_sha256: str,
        sc30,
        mbed,
        log: MissionLog,
        notifier: Notifier,
        store: StateStore,
        fence_ne_m=None,
        hold_zero: str | None = None,
        keep_samples: bool = False,
        console=None,
    ) -> None:
        self.cfg = cfg
        self.console = console  # callable(str): a sentence for the person at the terminal (stderr)
        self.clock = clock
        self.ap = autopilot
        self.mission = mission
        self.mission_path = mission_path
        self.mission_sha256 = mission_sha256
        self.sc30 = sc30
        self.mbed = mbed
        self.log = log
        self.notifier = notifier
        self.store = store
        self.failsafe = Failsafe(cfg.failsafe, fence_ne_m=fence_ne_m)
        self.hold_zero = hold_zero  # a reason to never drive (e.g. interrupted mission, no resume)
        self.stats = LoopStats(keep_samples=keep_samples)
        self.stop_signal: str | None = None
        self.t0_s = 0.0
        self.ready = False
        self.complete = False
        self.completed_t_s: float | None = None  # mission time the last waypoint was reached
        self.passes_done = False  # the last pass has ended (final_pass_s after completion)
        self.reached: list[int] = []  # waypoints reached, in order
        self.failsafe_causes: list[str] = []  # the cause of every failsafe taken, in order
        self.passes = PassTracker(mission.waypoints_ne_m, start_index=autopilot.wp_index)
        self.closest_m: dict[int, float] = {}  # wp -> closest approach of its finished pass (m)
        self._last_fix_t_s: float | None = None
        self._last_watchdog_s = -math.inf
        self._last_step_t_s: float | None = None
        self._was_auto = False
        self._prev_heading: tuple[float, float] | None = None
        self._seq = -1
        self._ready_warned = False

    # ---- driver callbacks -------------------------------------------------------------
    def on_driver_event(self, device: str):
        def handler(name: str, **fields) -> None:
            now = self.clock.now_s()
            if name == "port_open_failed" and self.console is not None:
                self.console(
                    f"{device}: cannot open {fields.get('path')} ({fields.get('error')}); thrust stays at zero and the "
                    f"port is retried every {self.cfg.serial.reconnect_min_s:g}-{self.cfg.serial.reconnect_max_s:g} s "
                    "until it appears. Stop with Ctrl-C (or: systemctl stop wamv-autopilot)."
                )
            fields.pop("device", None)
            self.log.event("info", t_s=now - self.t0_s, message=name, device=device, **fields)

        return handler

    def request_stop(self, signame: str) -> None:
        if self.stop_signal is None:
            self.stop_signal = signame

    def install_signal_handlers(self) -> None:
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGTERM, signal.SIGINT):
            loop.add_signal_handler(sig, self.request_stop, sig.name)

    # ---- one cycle ----------------------------------------------------------------------
    def cycle(self, now_s: float, lateness_s: float) -> None:
        nav = self.sc30.nav
        t_s = now_s - self.t0_s
        heading_deg, heading_src, heading_age_s, heading_valid = choose_heading(nav, now_s, self.cfg.failsafe)
        pos = _value(nav.position)
        lat_deg, lon_deg = (pos if pos is not None else (None, None))
        north_m = east_m = None
        if pos is not None:
            north_m, east_m = latlon_to_local(lat_deg, lon_deg, self.mission.origin_lat_deg, self.mission.origin_lon_deg)
        position_age_s = nav.position_age_s(now_s)
        fix = _value(nav.fix_quality)
        fix_quality = int(fix) if fix is not None else 0
        if nav.position is not None and not nav.position.valid:
            fix_quality = 0
        sog = _value(nav.sog_kn)
        sog_m_s = None if sog is None else float(sog) * KN_TO_M_S
        cog_deg = _value(nav.cog_deg)
        yaw_rate_deg_s = None
        rot = nav.rot_deg_min
        if rot is not None and now_s - rot.t_s <= self.cfg.failsafe.heading_stale_s and rot.valid:
            yaw_rate_deg_s = float(rot.value) / 60.0
        elif heading_deg is not None and self._prev_heading is not None and now_s > self._prev_heading[0]:
            yaw_rate_deg_s = float(wrap_180(heading_deg - self._prev_heading[1])) / (now_s - self._prev_heading[0])
        if heading_deg is not None:
            self._prev_heading = (now_s, heading_deg)

        obs = Observation(
            t_s=now_s,
            heading_age_s=heading_age_s,
            heading_valid=heading_valid,
            position_age_s=position_age_s,
            fix_quality=fix_quality,
            ack_consecutive_missing=int(self.mbed.consecutive_missing),
            compass_connected=bool(self.sc30.connected),
            mbed_connected=bool(self.mbed.connected),
            last_garbage_t_s=self.sc30.last_garbage_s,
            last_mbed_garbage_t_s=self.mbed.last_garbage_s,
            north_m=north_m,
            east_m=east_m,
            mission_time_s=t_s,
        )
        decision = self.failsafe.update(obs)
        for ev in decision.events:
            self.log.event(ev.name, t_s=t_s, **ev.fields)
            if ev.name == "failsafe":
                self.failsafe_causes.append(ev.fields.get("cause"))

        mode = decision.mode
        est_north_m = est_east_m = None
        fields = gnc_fields_null()
        thrust = (0.0, 0.0)
        pwm = (0.0, 0.0)
        sat = (False, False)
        saturation: tuple = ()
        holds = self.cfg.gnc.guidance.final_action == "hold"
        drive = decision.thrust_allowed and self.hold_zero is None and (not self.complete or holds)
        if drive:
            if not self._was_auto:
                self.ap.reset_integrator()
                self._last_step_t_s = None
            dt_s = self.cfg.period_s if self._last_step_t_s is None else min(max(now_s - self._last_step_t_s, 1e-3), 1.0)
            self._last_step_t_s = now_s
            psi_rad = math.radians(heading_deg)
            est_north_m, est_east_m = dead_reckon_ne(
                north_m, east_m, position_age_s, sog_m_s, None if cog_deg is None else math.radians(float(cog_deg)), psi_rad,
                max_age_s=self.cfg.dead_reckon_max_s,
            )
            nav_in = self._nav_input(est_north_m, est_east_m, psi_rad, sog_m_s, yaw_rate_deg_s, cog_deg)
            out = self.ap.step(nav_in, dt_s)
            fields = {
                "tcpa_nd": out.tcpa_nd,
                "dcpa_nd": out.dcpa_nd,
                "cdh": out.cdh,
                "psi_d_deg": float(wrap_360(math.degrees(out.psi_d_rad))),
                "heading_error_deg": float(wrap_180(math.degrees(out.heading_error_rad))),
                "xte_m": out.xte_m,
                "speed_cmd_m_s": out.speed_cmd_m_s,
                "pid_p_n": out.pid_p_n,
                "pid_i_n": out.pid_i_n,
                "pid_d_n": out.pid_d_n,
                "tau_com_n": out.tau_com_n,
                "tau_com_trim_n": out.tau_com_trim_n,
                "tau_order_n": out.tau_order_n,
            }
            thrust = (out.thrust_port_n, out.thrust_stbd_n)
            pwm = (out.pwm_port_pct, out.pwm_stbd_pct)
            sat = (out.sat_port, out.sat_stbd)
            saturation = tuple(out.saturation)
            if out.reached_index is not None:
                self.reached.append(out.reached_index)
                self.log.event(
                    "waypoint_reached", t_s=t_s, wp_index=out.reached_index, north_m=est_north_m, east_m=est_east_m,
                    distance_m=out.reached_distance_m, how=out.reached_how,
                )
                self._log_passes(self.passes.on_target(self.ap.wp_index), t_s)
                self._save("running")
        self._track_fix(nav.position, north_m, east_m, t_s)
        if drive:
            if out.complete and not self.complete:
                self.complete = True
                self.completed_t_s = t_s
                self.log.event("mission_complete", t_s=t_s, wp_count=len(self.mission.waypoints_ne_m))
                self._save("complete")
                if self.cfg.gnc.guidance.final_action != "hold":
                    thrust, pwm = (0.0, 0.0), (0.0, 0.0)
            mode = "auto"
        if self.complete:
            mode = "hold" if holds and drive else "complete"
        elif mode == "auto" and not drive:
            mode = "waiting"
        self._was_auto = drive

        port_pct, stbd_pct = float(pwm[0]), float(pwm[1])
        self._seq = self.mbed.send(abs(port_pct), port_pct < 0, abs(stbd_pct), stbd_pct < 0)
        sent_s = self.clock.now_s()
        h = nav.heading_deg
        heading_latency_s = None if h is None else sent_s - h.t_s
        self.stats.cycles += 1
        if self.stats.keep_samples:
            self.stats.lateness_s.append(lateness_s)
            if heading_latency_s is not None:
                self.stats.heading_latency_s.append(heading_latency_s)
        self.log.event(
            "cycle",
            t_s=t_s,
            cycle=self.stats.cycles - 1,
            mode=mode,
            lat_deg=lat_deg,
            lon_deg=lon_deg,
            north_m=north_m,
            east_m=east_m,
            est_north_m=est_north_m,
            est_east_m=est_east_m,
            heading_deg=None if heading_deg is None else float(wrap_360(heading_deg)),
            heading_source=heading_src,
            yaw_rate_deg_s=yaw_rate_deg_s,
            sog_m_s=sog_m_s,
            cog_deg=None if cog_deg is None else float(cog_deg),
            fix_quality=fix_quality,
            heading_age_s=heading_age_s,
            position_age_s=position_age_s,
            wp_index=int(self.ap.wp_index),
            **fields,
            thrust_port_n=float(thrust[0]),
            thrust_stbd_n=float(thrust[1]),
            pwm_port_pct=port_pct,
            pwm_stbd_pct=stbd_pct,
            sat_port=bool(sat[0]),
            sat_stbd=bool(sat[1]),
            saturation=list(saturation),
            lateness_ms=lateness_s * 1e3,
            skipped_cycles=self.stats.skipped,
            heading_latency_ms=None if heading_latency_s is None else heading_latency_s * 1e3,
            seq=self._seq,
            ack_missing=int(self.mbed.ack_missing),
            nmea_dropped=int(self._nmea_dropped()),
            active_faults=list(decision.active),
        )
        self._notify(now_s, lateness_s)

    def _track_fix(self, position, north_m, east_m, t_s: float) -> None:
        """A new position fix goes to the pass tracker, attributed to the waypoint steered to now.

        After the last waypoint the fixes still count for ``final_pass_s``: the boat coasts
        (or holds) past it, and its pass ends then (autopilot.gnc.passes).
        """
        if self.complete and not self.passes_done and t_s - self.completed_t_s >= self.cfg.gnc.guidance.final_pass_s:
            self.passes_done = True
            self._log_passes(self.passes.finish(), t_s)
        if position is None or north_m is None or self.passes_done or position.t_s == self._last_fix_t_s:
            return
        self._last_fix_t_s = position.t_s
        self._log_passes(self.passes.on_fix(position.t_s - self.t0_s, north_m, east_m, self.ap.wp_index),
                         self.clock.now_s() - self.t0_s)

    def _log_passes(self, passes, t_s: float) -> None:
        for p in passes:
            self.closest_m[p.wp_index] = p.closest_approach_m
            self.log.event("waypoint_pass", t_s=t_s, wp_index=p.wp_index, closest_approach_m=p.closest_approach_m,
                           closest_t_s=p.t_s, closest_north_m=p.north_m, closest_east_m=p.east_m, fixes=p.fixes)

    def _nav_input(self, north_m, east_m, psi_rad, sog_m_s, yaw_rate_deg_s, cog_deg):
        from autopilot.gnc import NavInput

        return NavInput(
            north_m=float(north_m),
            east_m=float(east_m),
            psi_rad=psi_rad,
            speed_m_s=0.0 if sog_m_s is None else float(sog_m_s),
            yaw_rate_rad_s=0.0 if yaw_rate_deg_s is None else math.radians(yaw_rate_deg_s),
            course_rad=psi_rad if cog_deg is None else math.radians(float(cog_deg)),
        )

    def _nmea_dropped(self) -> int:
        st = self.sc30.stats
        if isinstance(st, dict):
            return int(st.get("dropped", 0))
        return int(getattr(st, "dropped", 0))

    def _notify(self, now_s: float, lateness_s: float) -> None:
        if not self.ready:
            nav = self.sc30.nav
            heard_compass = nav.heading_deg is not None or nav.position is not None
            heard_mbed = self.mbed.last_ack_seq is not None and self.mbed.last_ack_seq >= 0
            if heard_compass and heard_mbed:
                self.ready = True
                self.notifier.ready(status="both devices answer")
                self.log.event("info", t_s=now_s - self.t0_s, message="ready: SC-30 and Mbed answer")
            elif not self._ready_warned and now_s - self.t0_s > self.cfg.ready_timeout_s:
                self._ready_warned = True
                self.log.event(
                    "info", t_s=now_s - self.t0_s, message="devices not answering",
                    sc30_heard=heard_compass, mbed_heard=heard_mbed,
                )
        if lateness_s >= self.cfg.period_s:
            self.stats.late_cycles += 1
        interval_s = (Notifier.watchdog_interval_s() or 0.5) * self.clock.speedup / 2.0
        if watchdog_due(
            ready=self.ready, lateness_s=lateness_s, period_s=self.cfg.period_s,
            since_last_s=now_s - self._last_watchdog_s, interval_s=interval_s,
        ):
            self.notifier.watchdog()
            self._last_watchdog_s = now_s

    def _save(self, status: str) -> None:
        try:
            self.store.save(Progress(self.mission_path, self.mission_sha256, int(self.ap.wp_index), status, 0.0))
        except OSError as exc:
            self.log.event("info", t_s=self.clock.now_s() - self.t0_s, message="state not saved", error=str(exc))

    # ---- the loop -----------------------------------------------------------------------
    async def run(self) -> str:
        """Cycle until a stop reason appears; returns it (``signal``, ``complete``, ``max_mission_time``)."""
        period_s = self.cfg.period_s
        next_due = self.clock.now_s()
        if self.hold_zero is None:
            self._save("running")
        while True:
            await self.clock.sleep_until(next_due)
            now_s = self.clock.now_s()
            lateness_s = now_s - next_due
            if lateness_s > period_s:
                skip = int(lateness_s // period_s)
                self.stats.skipped += skip
                next_due += skip * period_s
                lateness_s = now_s - next_due
            if self.stop_signal is not None:
                return "signal"
            self.cycle(now_s, lateness_s)
            next_due += period_s
            if self.passes_done and self.cfg.gnc.guidance.final_action != "hold":
                return "complete"
            if "max_mission_time" in self.failsafe.latched:
                return "max_mission_time"

    def speedup_held(self) -> float:
        """Simulated control time per wall second: ``--speedup`` scaled by the share of deadlines kept."""
        total = self.stats.cycles + self.stats.skipped
        return self.clock.speedup * (self.stats.cycles / total if total else 1.0)

    async def stop(self, reason: str) -> int:
        """Zero thrust, bounded wait for its ack, ``stop`` line, STOPPING=1. Returns the exit code."""
        self.notifier.stopping(status=f"stopping: {reason}")
        ack = False
        try:
            seq = self.mbed.send(0.0, False, 0.0, False)
            if seq >= 0:
                ack = bool(await self.mbed.wait_ack(seq, self.cfg.stop_ack_timeout_s))
        except Exception as exc:  # noqa: BLE001 - stopping must finish
            self.log.event("info", t_s=self.clock.now_s() - self.t0_s, message="zero-thrust on stop failed", error=repr(exc))
        if not self.passes_done:  # the passes still open end with the mission
            self.passes_done = True
            self._log_passes(self.passes.finish(), self.clock.now_s() - self.t0_s)
        status = {"complete": "complete", "signal": "stopped"}.get(reason, "aborted")
        if self.hold_zero is None or status != "stopped":
            self._save(status)
        self.log.event(
            "stop",
            t_s=self.clock.now_s() - self.t0_s,
            reason=reason,
            signal=self.stop_signal,
            ack_received=ack,
            cycles=self.stats.cycles,
            skipped_cycles=self.stats.skipped,
            late_cycles=self.stats.late_cycles,
            speedup_held=self.speedup_held(),
            nmea_dropped=self._nmea_dropped(),
            ack_missing=int(self.mbed.ack_missing),
            closest_approach_m=[self.closest_m.get(i) for i in range(len(self.mission.waypoints_ne_m))],
        )
        return 1 if reason == "error" else 0
