"""Where the chunks run: this process, a local process pool, or a Dask cluster.

A chunk (``spec.chunk_runs`` consecutive runs, :func:`autopilot.campaign.lockstep.fly_chunk`)
is a pure function of ``(campaign, seed, runs, chunk)``, so any backend and any number of
workers give the same rows, bit for bit; rows are put back in index order. Results are
gathered as chunks finish, so a lost worker costs only the chunks it was flying:

- the process pool (``--jobs J``): a worker that dies breaks the pool
  (``BrokenProcessPool``); the chunks already finished are kept, the others go to a new pool;
- Dask (``--scheduler tcp://HOST:PORT``, or ``local`` for a ``LocalCluster`` on this machine):
  the scheduler runs a dead worker's tasks again elsewhere (``distributed.scheduler.allowed-failures``
  times); a chunk that still fails is submitted again under a new key.

Each chunk is tried at most ``MAX_ATTEMPTS`` times; then the campaign stops with an error
naming it. Progress goes to stderr (a bar on a terminal, a line every 10 % otherwise).
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import signal
import sys
import threading
import time

from autopilot.campaign.lockstep import chunk_indices, chunks, fly_chunk
from autopilot.schema import ConfigError

__all__ = ["run_chunks", "Progress", "MAX_ATTEMPTS", "default_jobs", "check_scheduler_address", "probe_scheduler",
           "check_backend"]

MAX_ATTEMPTS = 3
SCHEDULER_TIMEOUT_S = 20.0  # to reach a scheduler and hear it say it is one
SCHEDULER_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")


def check_backend(scheduler) -> None:
    """Before anything is written: Dask installed for --scheduler, its address well formed and a scheduler answering
    there (a refused --scheduler left DIR/campaign.json behind, and the rerun was refused as an earlier campaign)."""
    if scheduler is None or not isinstance(scheduler, str):
        return
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise ConfigError("--scheduler needs Dask: pip install 'wamv-autopilot[campaign]' "
                          "(dask[distributed])") from None
    if scheduler != "local":
        probe_scheduler(check_scheduler_address(scheduler))


def check_scheduler_address(address: str) -> str:
    """``address`` as Dask takes it (SCHEME://HOST:PORT), or ConfigError saying what is wrong with it: 'nonsense'
    and 'http://x' went into Dask and came back as an internal error, a 40 s wait and a traceback."""
    from urllib.parse import urlsplit

    text = str(address).strip()
    parts = urlsplit(text if "://" in text else "tcp://" + text)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme not in SCHEDULER_SCHEMES or not parts.hostname or port is None or parts.path not in ("", "/"):
        raise ConfigError(f"--scheduler {address}: not a Dask scheduler address (tcp://HOST:PORT, the scheduler's "
                          "port, 8786 by default; or 'local')")
    return f"{parts.scheme}://{parts.netloc}"


def probe_scheduler(address: str, timeout_s: float = SCHEDULER_TIMEOUT_S) -> None:
    """Ask ``address`` who it is, within ``timeout_s``; ConfigError unless a Dask scheduler answers. A port that
    accepted and stayed silent hung the campaign with no output (Dask's own timeout covers only the connect),
    and one that answered with something else (an SSH banner) raised from deep inside Dask."""
    import asyncio
    import socket
    from urllib.parse import urlsplit

    from distributed.core import rpc

    parts = urlsplit(address)
    if parts.scheme == "tcp":  # nothing listening: say so at once (Dask retried for 21 s, then blamed the protocol)
        try:
            socket.create_connection((parts.hostname, parts.port), timeout=min(timeout_s, 5.0)).close()
        except ConnectionRefusedError:
            raise ConfigError(f"--scheduler {address}: nothing listens at {parts.hostname}:{parts.port} (connection "
                              "refused): start the scheduler (dask scheduler), or check the port (8786 by default)") from None
        except OSError:
            pass  # unreachable or slow: Dask's own connect says so below

    async def ask():
        r = rpc(address, timeout=timeout_s)
        try:
            return await r.identity()
        finally:
            await r.close_rpc()

    try:
        info = asyncio.run(asyncio.wait_for(ask(), timeout_s))
    except (asyncio.TimeoutError, TimeoutError):
        raise ConfigError(f"--scheduler {address}: no Dask scheduler answered within {timeout_s:g} s (is it the "
                          "scheduler's port, 8786 by default, not its dashboard's?)") from None
    except Exception as exc:  # noqa: BLE001 - whatever the other end made Dask raise: not a scheduler
        raise ConfigError(f"--scheduler {address}: what answers there does not speak Dask's protocol "
                          f"({type(exc).__name__}; is it the scheduler's port, 8786 by default?)") from None
    if not isinstance(info, dict) or info.get("type") != "Scheduler":
        raise ConfigError(f"--scheduler {address}: the server there is not a Dask scheduler "
                          f"({type(info).__name__} {str(info)[:80]})")


def default_jobs() -> int:
    """The cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


class Progress:
    """Chunks and runs done, the rate and the time left, on stderr."""

    def __init__(self, total_runs: int, total_chunks: int, *, stream=None, enabled: bool = True) -> None:
        self.total_runs, self.total_chunks = total_runs, total_chunks
        self.runs = self.chunks = self.retries = 0
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.tty = enabled and hasattr(self.stream, "isatty") and self.stream.isatty()
        self.t0 = time.monotonic()
        self._last_decile = -1

    def retry(self, what: str) -> None:
        self.retries += 1
        if self.enabled:
            self.stream.write(("\n" if self.tty else "") + f"campaign: {what}; running it again\n")
            self.stream.flush()

    def done(self, runs: int) -> None:
        self.runs += runs
        self.chunks += 1
        if not self.enabled:
            return
        elapsed = time.monotonic() - self.t0
        rate = self.runs / elapsed if elapsed > 0 else math.inf
        left = (self.total_runs - self.runs) / rate if rate > 0 else math.inf
        frac = self.runs / max(self.total_runs, 1)
        text = (f"{self.chunks}/{self.total_chunks} chunks, {self.runs}/{self.total_runs} runs, "
                f"{rate:.1f} runs/s, {elapsed:.0f} s, ~{left:.0f} s left")
        if self.tty:
            bar = "#" * int(30 * frac)
            self.stream.write(f"\rcampaign [{bar:<30}] {text}")
            if self.chunks == self.total_chunks:
                self.stream.write("\n")
        elif int(frac * 10) != self._last_decile or self.chunks == self.total_chunks:
            self._last_decile = int(frac * 10)
            self.stream.write(f"campaign: {text}\n")
        self.stream.flush()


def run_chunks(campaign, seed: int, runs: int, *, jobs: int | None = None, scheduler=None,
               progress: Progress | None = None) -> list[dict]:
    """Every run's row, in index order. ``scheduler``: a Dask scheduler address, ``"local"``, or a
    ``distributed.Client``; else ``jobs`` local processes (1: this process)."""
    n_chunks = chunks(campaign, runs)
    progress = progress or Progress(runs, n_chunks, enabled=False)
    found: dict[int, list[dict]] = {}

    def done(k: int, rows: list[dict]) -> None:
        want = list(chunk_indices(campaign, runs, k))
        if [r["index"] for r in rows] != want:  # pragma: no cover - a worker running other code
            raise RuntimeError(f"chunk {k}: a worker returned runs {rows[0]['index']}.. instead of {want[0]}..")
        found[k] = rows
        progress.done(len(rows))

    if scheduler is not None:
        _dask(campaign, seed, runs, n_chunks, scheduler, done, progress)
    elif (jobs or default_jobs()) <= 1 or n_chunks == 1:
        for k in range(n_chunks):
            done(k, fly_chunk(campaign, seed, runs, k))
    else:
        _pool(campaign, seed, runs, n_chunks, min(jobs or default_jobs(), n_chunks), done, progress)
    return [r for k in range(n_chunks) for r in found[k]]


def _pool(campaign, seed, runs, n_chunks, jobs, done, progress) -> None:
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
    pending = set(range(n_chunks))
    attempts = dict.fromkeys(pending, 0)
    while pending:
        for k in pending:
            attempts[k] += 1
            if attempts[k] > MAX_ATTEMPTS:
                raise RuntimeError(f"chunk {k} failed {MAX_ATTEMPTS} times (its worker died each time)")
        pool = ProcessPoolExecutor(max_workers=jobs, mp_context=mp.get_context(method))
        try:
            futures = {pool.submit(fly_chunk, campaign, seed, runs, k): k for k in sorted(pending)}
            try:
                for f in as_completed(futures):
                    k = futures[f]
                    done(k, f.result())
                    pending.discard(k)
            except BrokenProcessPool:
                for f, k in futures.items():  # keep what finished before the pool broke
                    if k in pending and f.done() and not f.cancelled() and f.exception() is None:
                        done(k, f.result())
                        pending.discard(k)
                progress.retry(f"a worker process died; {len(pending)} chunk(s) not finished")
        except BaseException:
            # Ctrl-C (or an error): the pool's own exit would fly every queued chunk first (a minute or
            # more); drop the queue and stop the workers flying now
            workers = list((getattr(pool, "_processes", None) or {}).values())  # private, stable since 3.8
            pool.shutdown(wait=False, cancel_futures=True)  # (this forgets the workers: taken first)
            for proc in workers:
                proc.terminate()
            raise
        finally:
            pool.shutdown(wait=True)


@contextlib.contextmanager
def _sigint_held():
    """Hold SIGINT back while the local cluster spawns its worker processes.

    A terminal's Ctrl-C goes to the whole foreground group: each worker took it as a KeyboardInterrupt and
    printed a traceback. A child inherits its parent's signal mask, so workers started while SIGINT is
    blocked never see it; this process stops them itself when it is interrupted. A Ctrl-C pressed meanwhile
    stays pending and arrives here when the mask is restored.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    # multiprocessing's resource tracker, started by the first queue Dask makes, unblocks SIGINT in the thread
    # that starts it (Dask's loop thread, which then spawns the workers): started here first, it is not again
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _dask(campaign, seed, runs, n_chunks, scheduler, done, progress) -> None:
    try:
        from distributed import Client, LocalCluster
    except ImportError:  # pragma: no cover - the extra is not installed
        raise ConfigError("--scheduler needs Dask: pip install 'wamv-autopilot[campaign]' "
                          "(dask[distributed])") from None
    cluster = own = None
    try:
        if isinstance(scheduler, Client):
            client = scheduler
        else:
            if scheduler == "local":
                with _sigint_held():
                    # no dashboard, and the scheduler's own HTTP routes on a free loopback port: by default they
                    # took 8787, and a second campaign (or any Dask) on the machine printed a port-in-use warning
                    # the workers' own logs at CRITICAL: on a Ctrl-C the scheduler can go before a worker's
                    # heartbeat, and the worker process printed "Failed to communicate with scheduler during
                    # heartbeat" with its traceback on the user's terminal (a clean-clone suite run, twice over
                    # the stops); a chunk's error reaches the campaign through its future, a lost worker its retry
                    cluster = LocalCluster(n_workers=default_jobs(), threads_per_worker=1, processes=True,
                                           dashboard_address=None, silence_logs=logging.CRITICAL,
                                           scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"})
                address = cluster.scheduler_address
            else:
                address = check_scheduler_address(scheduler)
                probe_scheduler(address)
            try:
                client = own = Client(address, set_as_default=False, timeout=f"{SCHEDULER_TIMEOUT_S:g}s")
            except (OSError, TimeoutError) as exc:
                raise ConfigError(f"--scheduler {scheduler}: cannot reach the Dask scheduler ({exc})") from None
        _gather(client, campaign, seed, runs, n_chunks, done, progress)
    except BaseException:
        # stopping on a Ctrl-C or an error: the nannies' complaints about the work cancelled under them (a
        # traceback logged at ERROR, now and then) are not news; the campaign says what happened itself
        with _dask_quiet():
            _close(own, cluster)
        raise
    _close(own, cluster)


def _close(client, cluster) -> None:
    if client is not None:
        client.close()
    if cluster is not None:
        cluster.close()


@contextlib.contextmanager
def _dask_quiet():
    """Dask's loggers at CRITICAL for the block (restored after: a library caller keeps its logging)."""
    names = [n for n in logging.root.manager.loggerDict if n.split(".")[0] == "distributed"]
    before = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for n, level in before.items():
            logging.getLogger(n).setLevel(level)


def _gather(client, campaign, seed, runs, n_chunks, done, progress) -> None:
    """Submit every chunk, hand each result to ``done`` as it finishes, resubmit a lost one."""
    from distributed import as_completed

    digest = campaign.digest()
    attempts: dict[int, int] = {}

    def submit(k: int):
        attempts[k] = attempts.get(k, 0) + 1
        key = f"autopilot-campaign-{digest}-s{seed}-n{runs}-c{k}-a{attempts[k]}"
        return client.submit(fly_chunk, campaign, seed, runs, k, key=key, pure=False)

    futures = {submit(k): k for k in range(n_chunks)}
    todo = as_completed(list(futures), loop=client.loop, with_results=False, raise_errors=False)
    for f in todo:
        k = futures.pop(f)
        if f.status == "finished":
            done(k, f.result())
            f.release()
            continue
        exc = f.exception()
        if attempts[k] >= MAX_ATTEMPTS:
            raise RuntimeError(f"chunk {k} failed {attempts[k]} times: {type(exc).__name__}: {exc}")
        progress.retry(f"chunk {k} lost ({type(exc).__name__})")
        g = submit(k)
        futures[g] = k
        todo.add(g)
