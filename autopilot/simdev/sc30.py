"""A simulated Furuno SC-30 behind a pseudo-terminal, writing NMEA from the boat's state.

Rates (SPEC section 10): heading-type sentences every 100 ms, the others
every 1 s, on absolute deadlines. Output is paced to the baud rate (10 bits
per character, 8N1): a sentence reaches the driver when its last character
would have, and the line carries at most ``baudrate / 10`` characters per
second, so at 4800 baud only a few sentences fit per 100 ms. The default
sentence sets are chosen to fit: at 4800 baud HDT at 10 Hz and ROT, GGA,
RMC, VTG, ZDA at 1 Hz; at >= 9600 baud also PFEC,GPatt and ROT at 10 Hz.
A sentence that would leave more than 0.5 s of backlog is dropped, as a
real device's output buffer overflows (counted in ``overruns``).

Heading: true heading plus Gaussian noise, quantised to 0.1 deg (the SC-30's
resolution, SPEC section 1). Position: Gaussian noise in metres north/east.
With ``position_error`` / ``heading_error`` (:mod:`autopilot.sim.gps_error`,
the same model as the identification's realistic trials) the errors are the
realistic ones instead: one GPS fix per second (GGA, RMC and GLL of that
second carry the same fix, with wandering error and single-fix outliers) and
a wandering, quantised heading with lost sentences.

Fault controls (set at any time): ``heading_dropout`` (no heading
sentences), ``heading_invalid`` (empty HDT, THS mode V, empty GPatt),
``position_dropout`` (no GGA/RMC/GLL/VTG), ``fix_lost`` (GGA quality 0 and
RMC status V with empty fields), ``drop_rate`` (probability a sentence is
dropped), ``delay_s`` (extra latency of every sentence), ``split`` (write
each sentence in 1-7 byte fragments paced at the character time),
``corrupt_next(n)`` (the next n sentences get a wrong checksum),
``inject(data)`` (raw bytes as fast as the pty takes them), ``unplug()``,
``replug()``.
"""

from __future__ import annotations

import asyncio
from collections import deque

import numpy as np

from autopilot.clock import Clock
from autopilot.drivers.nmea import checksum
from autopilot.sim.gps_error import GpsErrorModel, HeadingErrorModel, HeadingErrorStream, PositionErrorStream
from autopilot.simdev.boat import SimBoat
from autopilot.simdev.pty import PtyEndpoint

__all__ = ["SimulatedSC30", "default_sentences"]

KN_PER_M_S = 1.0 / 0.514444
HEADING_SENTENCES = ("HDT", "THS", "PFEC_GPatt")
POSITION_SENTENCES = ("GGA", "RMC", "GLL", "VTG")
MAX_BACKLOG_S = 0.5


def default_sentences(baudrate: int) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(10 Hz sentences, 1 Hz sentences) that fit in the baud rate's ~baud/10 chars/s."""
    if baudrate >= 9600:
        return ("HDT", "PFEC_GPatt", "ROT"), ("GGA", "RMC", "VTG", "ZDA")
    return ("HDT",), ("ROT", "GGA", "RMC", "VTG", "ZDA")


def _ddmm(value_deg: float, deg_digits: int) -> str:
    a = abs(value_deg)
    d = int(a)
    m = (a - d) * 60.0
    if m >= 59.999995:  # rounding would print 60.00000
        d, m = d + 1, 0.0
    return f"{d:0{deg_digits}d}{m:08.5f}"


class SimulatedSC30:
    """Writes NMEA for ``boat`` on a pty at ``<directory>/<name>``."""

    def __init__(
        self,
        boat: SimBoat,
        clock: Clock,
        *,
        directory,
        baudrate: int = 4800,
        heading_noise_deg: float = 0.1,
        position_noise_m: float = 0.3,
        seed: int = 0,
        talker: str = "GP",
        fast_sentences: tuple[str, ...] | None = None,
        slow_sentences: tuple[str, ...] | None = None,
        fast_period_s: float = 0.1,
        slow_every: int = 10,
        name: str = "sc30",
        position_error: GpsErrorModel | None = None,
        heading_error: HeadingErrorModel | None = None,
    ) -> None:
        self.boat = boat
        self.clock = clock
        self.baudrate = int(baudrate)
        self.heading_noise_deg = float(heading_noise_deg)
        self.position_noise_m = float(position_noise_m)
        self.talker = talker
        fast, slow = default_sentences(self.baudrate)
        self.fast_sentences = tuple(fast_sentences) if fast_sentences is not None else fast
        self.slow_sentences = tuple(slow_sentences) if slow_sentences is not None else slow
        self.fast_period_s = float(fast_period_s)
        self.slow_every = int(slow_every)
        self._rng = np.random.default_rng(seed)
        # realistic errors (autopilot.sim.gps_error): own generators, so the sentence draws above are unchanged
        self._pos_error = None if position_error is None else PositionErrorStream(position_error, np.random.default_rng([seed, 1]))
        self._hdg_error = None if heading_error is None else HeadingErrorStream(heading_error, np.random.default_rng([seed, 2]))
        self._fix: tuple[int, float, float] | None = None  # (fix epoch, north error m, east error m)
        self._fix_state = np.zeros(2)  # where the boat was when this epoch's fix was taken
        self._t0_s = 0.0  # clock time of the first tick (fix epochs count ticks from it)
        self._hdg: tuple[float, float | None] | None = None  # (t_s, heading error deg or None = lost)
        self._endpoint = PtyEndpoint(directory, name)
        self.path = self._endpoint.path
        # fault controls
        self.heading_dropout = False
        self.heading_invalid = False
        self.position_dropout = False
        self.fix_lost = False
        self.drop_rate = 0.0
        self.delay_s = 0.0
        self.split = False
        self._corrupt = 0
        # bookkeeping
        self.sentences_sent = 0
        self.bytes_sent = 0
        self.overruns = 0
        self.last_heading_sent_deg: float | None = None
        self.sent_log: deque[tuple[float, str]] = deque(maxlen=2000)  # (t_s, sentence) for tests
        self._line_free_s = 0.0
        self._queue: asyncio.Queue[tuple[float, bytes, str]] | None = None
        self._tasks: list[asyncio.Task] = []

    # ------------------------------------------------------------------ faults
    def corrupt_next(self, n: int = 1) -> None:
        self._corrupt += int(n)

    def inject(self, data: bytes) -> None:
        """Raw bytes onto the line now (ahead of the paced sentences)."""
        self._tasks.append(asyncio.get_running_loop().create_task(self._write_all(bytes(data))))

    def unplug(self) -> None:
        self._endpoint.unplug()

    def replug(self) -> None:
        self._endpoint.replug()

    @property
    def plugged(self) -> bool:
        return self._endpoint.plugged

    # ------------------------------------------------------------------ lifecycle
    async def start(self) -> None:
        self._queue = asyncio.Queue()
        loop = asyncio.get_running_loop()
        self._tasks += [loop.create_task(self._produce()), loop.create_task(self._transmit())]

    async def stop(self) -> None:
        for t in self._tasks:
            t.cancel()
        for t in self._tasks:
            try:
                await t
            except (asyncio.CancelledError, Exception):
                pass
        self._tasks.clear()
        self._endpoint.close()

    # ------------------------------------------------------------------ sentences
    def _heading_error_deg(self, t_s: float) -> float | None:
        """The realistic model's error of this tick's heading (one draw per tick), None when lost."""
        if self._hdg is None or self._hdg[0] != t_s:
            self._hdg = (t_s, self._hdg_error.next(t_s))
        return self._hdg[1]

    def _position_error_m(self, t_s: float) -> tuple[float, float]:
        """The realistic model's error of the fix of this second (one fix per second)."""
        epoch = int(round((t_s - self._t0_s) / self.fast_period_s)) // self.slow_every
        if self._fix is None or self._fix[0] != epoch:
            self._fix = (epoch, *self._pos_error.next(t_s))
            self._fix_state = self.boat.state[:2].copy()  # the fix is of where the boat was at its epoch
        n_m, e_m = self._fix[1:]
        return n_m + self._fix_state[0] - self.boat.state[0], e_m + self._fix_state[1] - self.boat.state[1]

    def _heading_text(self, t_s: float | None = None) -> str | None:
        if self._hdg_error is not None and t_s is not None:
            err = self._heading_error_deg(t_s)
            if err is None:
                return None
            h = round((self.boat.heading_deg + err) % 360.0, 1) % 360.0
            self.last_heading_sent_deg = h
            return f"{h:.1f}"
        h = self.boat.heading_deg + self._rng.normal(0.0, self.heading_noise_deg) if self.heading_noise_deg else self.boat.heading_deg
        h = round(h % 360.0, 1) % 360.0  # 0.1 deg resolution
        self.last_heading_sent_deg = h
        return f"{h:.1f}"

    def _body(self, kind: str, t_s: float) -> str | None:
        b, tk = self.boat, self.talker
        if kind in HEADING_SENTENCES and self.heading_dropout:
            return None
        if kind in POSITION_SENTENCES and self.position_dropout:
            return None
        # UTC from the clock: the simulated day starts at 00:00:00 on 2024-06-01
        secs = t_s % 86400.0
        hh, mm, ss = int(secs // 3600), int(secs % 3600 // 60), secs % 60
        utc = f"{hh:02d}{mm:02d}{ss:05.2f}"
        if kind in HEADING_SENTENCES and not self.heading_invalid:
            text = self._heading_text(t_s)
            if text is None:  # lost (realistic heading error model)
                return None
        if kind == "HDT":
            return f"{tk}HDT,,T" if self.heading_invalid else f"{tk}HDT,{text},T"
        if kind == "THS":
            return f"{tk}THS,,V" if self.heading_invalid else f"{tk}THS,{text},A"
        if kind == "PFEC_GPatt":
            if self.heading_invalid:
                return "PFEC,GPatt,,,"
            return f"PFEC,GPatt,{text},+0.0,+0.0"
        if kind == "ROT":
            return f"{tk}ROT,{b.yaw_rate_deg_min:.1f},A"
        if self._pos_error is not None:
            n_m, e_m = self._position_error_m(t_s)
        else:
            n_m, e_m = (self._rng.normal(0.0, self.position_noise_m, 2) if self.position_noise_m else (0.0, 0.0))
        lat, lon = b.latlon_deg(n_m, e_m)
        pos = f"{_ddmm(lat, 2)},{'N' if lat >= 0 else 'S'},{_ddmm(lon, 3)},{'E' if lon >= 0 else 'W'}"
        sog = f"{b.sog_m_s * KN_PER_M_S:.2f}"
        cog = f"{b.cog_deg:.1f}"
        if kind == "GGA":
            if self.fix_lost:
                return f"{tk}GGA,{utc},,,,,0,00,,,M,,M,,"
            return f"{tk}GGA,{utc},{pos},1,10,0.9,1.0,M,30.0,M,,"
        if kind == "RMC":
            if self.fix_lost:
                return f"{tk}RMC,{utc},V,,,,,,,010624,,,N"
            return f"{tk}RMC,{utc},A,{pos},{sog},{cog},010624,,,A"
        if kind == "GLL":
            if self.fix_lost:
                return f"{tk}GLL,,,,,{utc},V,N"
            return f"{tk}GLL,{pos},{utc},A,A"
        if kind == "VTG":
            if self.fix_lost:
                return f"{tk}VTG,,T,,M,,N,,K,N"
            return f"{tk}VTG,{cog},T,,M,{sog},N,{b.sog_m_s * 3.6:.2f},K,A"
        if kind == "ZDA":
            return f"{tk}ZDA,{utc},01,06,2024,00,00"
        raise ValueError(f"unknown sentence kind {kind!r}")

    def _frame(self, body: str) -> bytes:
        cs = checksum(body)
        if self._corrupt > 0:
            self._corrupt -= 1
            cs = f"{int(cs, 16) ^ 0x5A:02X}"
        return f"${body}*{cs}\r\n".encode("ascii")

    async def _produce(self) -> None:
        """Compose each tick's sentences on absolute deadlines (never drifting)."""
        assert self._queue is not None
        tick = 0
        t0 = self._t0_s = self.clock.now_s()
        while True:
            t_s = t0 + tick * self.fast_period_s
            await self.clock.sleep_until(t_s)
            self.boat.advance_to(t_s)
            kinds = list(self.fast_sentences)
            # One slow sentence per tick, after the heading, as a real compass interleaves them:
            # a 1 Hz burst at 4800 baud would hold the line ~0.5 s and starve the 10 Hz heading.
            slot = tick % self.slow_every
            if len(self.slow_sentences) > self.slow_every:
                kinds += list(self.slow_sentences[slot :: self.slow_every])
            elif slot < len(self.slow_sentences):
                kinds.append(self.slow_sentences[slot])
            for kind in kinds:
                if self.drop_rate > 0 and self._rng.random() < self.drop_rate:
                    continue
                body = self._body(kind, t_s)
                if body is None:
                    continue
                self._queue.put_nowait((t_s, self._frame(body), kind))
            tick += 1

    async def _transmit(self) -> None:
        """Put queued sentences on the line at the baud rate."""
        assert self._queue is not None
        char_s = 10.0 / self.baudrate
        while True:
            t_s, line, kind = await self._queue.get()
            start_s = max(t_s + self.delay_s, self._line_free_s)
            if start_s - t_s - self.delay_s > MAX_BACKLOG_S:
                self.overruns += 1
                continue
            self._line_free_s = start_s + len(line) * char_s
            if self.split:
                pos = 0
                while pos < len(line):
                    n = int(self._rng.integers(1, 8))
                    frag = line[pos : pos + n]
                    pos += n
                    await self.clock.sleep_until(start_s + pos * char_s)
                    self._endpoint.write(frag)
            else:
                await self.clock.sleep_until(self._line_free_s)
                self._endpoint.write(line)
            self.sentences_sent += 1
            self.bytes_sent += len(line)
            self.sent_log.append((self.clock.now_s(), line.decode("ascii")))

    async def _write_all(self, data: bytes) -> None:
        pos = 0
        while pos < len(data) and self._endpoint.plugged:
            n = self._endpoint.write(data[pos : pos + 1024])
            pos += n
            if n == 0:
                await asyncio.sleep(0.002)  # pty full: let the reader drain it
            else:
                await asyncio.sleep(0)
