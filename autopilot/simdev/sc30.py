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
resolution, SPEC section 1). Position: one GNSS epoch a second (position with
Gaussian noise in metres north/east, speed, course), reported by every
position sentence of that second with the epoch's UTC time, as a receiver does.
With ``position_error`` / ``heading_error`` (:mod:`autopilot.sim.gps_error`,
the same model as the identification's realistic trials) the errors are the
realistic ones instead: each epoch's fix with wandering error and single-fix
outliers, and a wandering, quantised heading with lost sentences.

Fault controls (set at any time): ``heading_dropout`` (no heading
sentences), ``heading_invalid`` (empty HDT, THS mode V, empty GPatt), ``heading_frozen``
(a stuck compass: every heading sentence repeats the heading of the moment it froze, checksum
valid, while ROT goes on reporting the boat's turn), ``rate_frozen`` (ROT repeats the rate of the moment
it froze: with ``heading_frozen``, a compass stuck whole),
``position_dropout`` (no GGA/RMC/GLL/VTG), ``fix_lost`` (GGA quality 0 and
RMC status V with empty fields), ``fix_held`` (the position sentences keep
repeating the last epoch: its UTC time, position, speed and course), ``drop_rate`` (probability a sentence is
dropped), ``delay_s`` (extra latency of every sentence), ``split`` (write
each sentence in 1-7 byte fragments paced at the character time),
``corrupt_next(n)`` (the next n sentences get a wrong checksum),
``jump_next(north_m, east_m, epochs)`` (the next epochs' fixes displaced: a GNSS glitch,
or with many epochs a position that really moved),
``inject(data)`` (raw bytes on the line at the baud rate, displacing the
sentences), ``unplug()``, ``replug()``.
"""

from __future__ import annotations

import asyncio
import math
from collections import deque

import numpy as np

from autopilot.clock import Clock
from autopilot.drivers.nmea import checksum, encode_heading, encode_position, encode_rot, encode_zda
from autopilot.drivers.sc30_output import default_sentences
from autopilot.sim.gps_error import GpsErrorModel, HeadingErrorModel, HeadingErrorStream, PositionErrorStream
from autopilot.simdev.boat import SimBoat
from autopilot.simdev.pty import PtyEndpoint

__all__ = ["SimulatedSC30", "default_sentences"]

HEADING_SENTENCES = ("HDT", "THS", "PFEC_GPatt")
POSITION_SENTENCES = ("GGA", "RMC", "GLL", "VTG")
MAX_BACKLOG_S = 0.5
RAW = "RAW"  # a queue item of injected raw bytes (not a sentence)
RAW_CHUNK = 16  # injected bytes reach the pty this many at a time, each when its last would have


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
        self._hdg: tuple[float, float | None] = (0.0, 0.0)  # this tick's (t_s, heading error deg or None = lost)
        self._endpoint = PtyEndpoint(directory, name)
        self.path = self._endpoint.path
        # fault controls
        self.heading_dropout = False
        self.heading_invalid = False
        self.heading_frozen = False
        self._frozen_rad: float | None = None
        self.rate_frozen = False
        self._frozen_rate_rad_s: float | None = None
        self.position_dropout = False
        self.fix_lost = False
        self.fix_held = False
        self.drop_rate = 0.0
        self.delay_s = 0.0
        self.split = False
        self._corrupt = 0
        self._jumps: deque[tuple[float, float]] = deque()  # (north_m, east_m) added to the coming epochs' fixes
        # bookkeeping
        self.sentences_sent = 0
        self.bytes_sent = 0
        self.overruns = 0
        self.raw_started_s: float | None = None  # when the last injected bytes began on the wire
        self.last_heading_sent_deg: float | None = None
        self.sent_log: deque[tuple[float, str]] = deque(maxlen=2000)  # (t_s, sentence) for tests
        self.made_log: deque[tuple[float, str]] = deque(maxlen=2000)  # (the tick it was measured at, sentence)
        self._line_free_s = 0.0
        self._queue: asyncio.Queue[tuple[float, bytes, str]] | None = None
        self._epoch: dict = {}
        self._tasks: list[asyncio.Task] = []

    # ------------------------------------------------------------------ faults
    def corrupt_next(self, n: int = 1) -> None:
        self._corrupt += int(n)

    def jump_next(self, north_m: float, east_m: float, epochs: int = 1) -> None:
        self._jumps.extend([(float(north_m), float(east_m))] * int(epochs))

    def inject(self, data: bytes) -> None:
        """Raw bytes onto the line, paced at the baud rate like everything on it (10 kB at 4800
        baud take ~21 s); sentences that wait behind them longer than MAX_BACKLOG_S are lost."""
        assert self._queue is not None, "start() first"
        self._queue.put_nowait((self.clock.now_s(), bytes(data), RAW))

    @property
    def line_busy_until_s(self) -> float:
        """Clock time the line finishes sending what it has started (injected bytes included)."""
        return self._line_free_s

    def unplug(self) -> None:
        self._endpoint.unplug()

    def replug(self) -> None:
        self._endpoint.replug()

    @property
    def plugged(self) -> bool:
        return self._endpoint.plugged

    @property
    def endpoint(self) -> PtyEndpoint:
        """The pseudo-terminal underneath (its byte counters)."""
        return self._endpoint

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
    def _heading_rad(self) -> float | None:
        """What the compass measures now: the true heading plus its noise (None: reported invalid)."""
        if self.heading_invalid:
            return None
        if not self.heading_frozen:
            self._frozen_rad = None
        elif self._frozen_rad is not None:
            return self._frozen_rad
        if self._hdg_error is not None:
            noise_rad = math.radians(self._hdg[1])
        else:
            noise_rad = math.radians(self._rng.normal(0.0, self.heading_noise_deg)) if self.heading_noise_deg else 0.0
        h = self.boat.psi_rad + noise_rad
        self.last_heading_sent_deg = round(math.degrees(h) % 360.0, 1) % 360.0  # the 0.1 deg the sentence carries
        if self.heading_frozen:
            self._frozen_rad = h
        return h

    def _body(self, kind: str, t_s: float) -> str | None:
        if kind in HEADING_SENTENCES:
            if self.heading_dropout or (self._hdg_error is not None and self._hdg[1] is None):
                return None  # dropped, or lost (realistic heading error model)
            return encode_heading(kind, self._heading_rad(), self.talker)
        if kind == "ROT":
            if not self.rate_frozen:
                self._frozen_rate_rad_s = None
            elif self._frozen_rate_rad_s is None:
                self._frozen_rate_rad_s = self.boat.r_rad_s
            return encode_rot(self.boat.r_rad_s if self._frozen_rate_rad_s is None else self._frozen_rate_rad_s,
                              self.talker)
        # UTC from the clock: the simulated day starts at 00:00:00 on 2024-06-01
        if kind == "ZDA":
            return encode_zda(t_s, self.talker)
        if self.position_dropout:
            return None
        ep = self._epoch  # the position sentences of one second report one epoch
        return encode_position(
            kind, t_of_day_s=ep["t_s"], lat_deg=None if self.fix_lost else ep["lat_deg"], lon_deg=ep["lon_deg"],
            sog_m_s=ep["sog_m_s"], cog_rad=ep["cog_rad"], talker=self.talker,
        )

    def _take_epoch(self, t_s: float) -> None:
        """The GNSS fix of this second: position (with its error), speed and course, reported by every
        position sentence of the second (a receiver computes one solution per epoch)."""
        b = self.boat
        sog, cog = b.sog_m_s, b.cog_rad
        if self._pos_error is not None:
            n_m, e_m = self._pos_error.next(t_s)
            sog, cog = self._pos_error.velocity(sog * math.cos(cog), sog * math.sin(cog))
        else:
            n_m, e_m = (self._rng.normal(0.0, self.position_noise_m, 2) if self.position_noise_m else (0.0, 0.0))
        if self._jumps:
            jump_n_m, jump_e_m = self._jumps.popleft()
            n_m, e_m = n_m + jump_n_m, e_m + jump_e_m
        lat, lon = b.latlon_deg(n_m, e_m)
        self._epoch = {"t_s": t_s, "lat_deg": lat, "lon_deg": lon, "sog_m_s": sog, "cog_rad": cog}

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
        t0 = self.clock.now_s()
        while True:
            t_s = t0 + tick * self.fast_period_s
            await self.clock.sleep_until(t_s)
            self.boat.advance_to(t_s)
            if self._hdg_error is not None:  # one heading measurement a tick, whichever sentences carry it
                self._hdg = (t_s, self._hdg_error.next(t_s))
            kinds = list(self.fast_sentences)
            # One slow sentence per tick, after the heading, as a real compass interleaves them:
            # a 1 Hz burst at 4800 baud would hold the line ~0.5 s and starve the 10 Hz heading.
            slot = tick % self.slow_every
            if slot == 0 and not (self.fix_held and self._epoch):
                self._take_epoch(t_s)
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
            if kind == RAW:
                start_s = max(t_s, self._line_free_s)
                self.raw_started_s = start_s
                self._line_free_s = start_s + len(line) * char_s
                for pos in range(0, len(line), RAW_CHUNK):
                    await self.clock.sleep_until(start_s + min(pos + RAW_CHUNK, len(line)) * char_s)
                    self._endpoint.write(line[pos : pos + RAW_CHUNK])
                self.bytes_sent += len(line)
                continue
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
            self.made_log.append((t_s, line.decode("ascii")))
