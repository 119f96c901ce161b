"""End-to-end identification on the logs a real boat produces (issue 12), with fixed seeds per case.

Trials are made by the project's simulator, independent of the replay code (autopilot.sysid.truth),
then measured as issue 12 describes (autopilot.sysid.realistic: 1 Hz GPS fixes held on 10 Hz rows
or as empty cells, with or without their time column; 0.5-2 m of wandering GPS error with a 30-60 s
correlation time, 0.15 m white, 1 % of fixes jumping 10 m; a heading with 0.3 deg of wander,
0.1 deg quantisation and 0.5 % of sentences lost). The original white-noise 10 Hz trials stay as
one case (``white``). Closed-loop logs are flown by the daemon itself (autopilot run --sim).

The suite's seeds are fixed (one per case, from CI_SEED_BASE and the case's label), so that CI
does not fail by chance: each check holds at one random draw with a rate below 1, and a red CI run
with no change to the code says nothing. How often each case is right over many random draws is
measured by ``benchmarks/sysid_reliability.py`` (rates in the README). SYSID_TEST_SEED=N replays
seed N, SYSID_TEST_SEED=random draws a fresh one per test.

Checks (autopilot.sysid.cases.score): the exact set of hidden listed effects is named (none when
nothing is hidden; ``unexplained`` or a model flagged not adequate for an effect outside the list);
every hidden parameter within 3.29 sigma of its estimate (99.9 %: about fifteen parameters are
checked per run); where the effect moved the track by more than twice the noise, the held-out
error beyond the noise cut by 70 %. Each test is armed with a SIGALRM safety net (ALARM_S).

The cases of CASES are independent and CPU-bound: every selected one is started when collection ends
(under pytest-xdist, at the computing worker's first test: tests/conftest.py), in a pool of the machine's cores (at most two) at the lowest CPU priority (SCHED_IDLE), so that they use the time the
rest of the suite leaves idle (see _Background); each test then checks its own result. What each computes is what it computed run one after another: the same
case, seed and code, in a fresh interpreter.
"""

from __future__ import annotations

import json
import math
import multiprocessing
import os
import secrets
import signal
import sys
import zlib
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from autopilot.sim import default_params_path, load_params
from autopilot.sysid import identify
from autopilot.sysid.cases import DRAWS, Case, make, score
from tests.conftest import lowest_cpu_priority

VESSEL = load_params(default_params_path())
Z_MAX = 3.29  # two-sided 99.9 %
ALARM_S = 240  # per-test safety net: the identification's work is bounded, but CI must never hang on it
CI_SEED_BASE = 20261202  # changing it draws a new fixed set; the reliability benchmark draws many


class _Stalled(Exception):
    pass


@pytest.fixture(autouse=True)
def _alarm():
    """Fail (not hang) a test that runs for more than ALARM_S seconds (SIGALRM, main thread, POSIX)."""
    if not hasattr(signal, "SIGALRM"):
        yield
        return

    def fire(signum, frame):
        raise _Stalled(f"sysid workflow test stalled: still running after {ALARM_S} s (signal.alarm safety net); "
                       "rerun with the printed SYSID_TEST_SEED to reproduce")

    old = signal.signal(signal.SIGALRM, fire)
    signal.alarm(ALARM_S)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def _seed(label: str, *, quiet: bool = False) -> int:
    """The seed of one case: SYSID_TEST_SEED (an integer, or ``random``), else fixed per ``label``."""
    base = os.environ.get("SYSID_TEST_SEED", "").strip()
    if base == "random":
        seed = secrets.randbits(31)
    elif base:
        seed = int(base)
    else:
        seed = zlib.crc32(f"{CI_SEED_BASE}:{label}".encode()) & 0x7FFFFFFF
    if not quiet:
        print(f"\n[{label}] seed {seed} (SYSID_TEST_SEED={seed} reproduces it)")
    return seed


def _identify_case(case: Case, seed: int):
    """(hidden, description, result, score) of one case: the pool's task (module level, so a spawned worker
    imports it)."""
    hidden, trials, desc = make(case, seed, VESSEL)
    result = identify(trials, VESSEL)
    return hidden, desc, result, score(case, hidden, result)


# Each pooled test's case from its parameters (the test's name -> case; a seed given by the test or None).
CASES = {
    "test_hidden_effect_is_named_and_recovered": lambda p: (Case((p["effect"],)), None),
    "test_nothing_hidden_gives_none_and_an_adequate_model": lambda p: (Case(()), None),
    "test_two_hidden_effects_both_named": lambda p: (Case(p["pair"]), None),
    "test_effect_outside_the_list_is_unexplained": lambda p: (Case(("thrust_fade",), duration_s=45.0), None),
    "test_white_noise_trials_current_and_thrust_lag": lambda p: (Case(("current", "thrust_lag"), kind="white", n_trials=3), None),
    "test_deadband_regression_seeds": lambda p: (Case(("thrust_deadband",), kind="white"), p["seed"]),
    "test_a_delay_and_a_lag_the_trials_cannot_tell_apart_are_not_named": lambda p: (
        Case(("sensor_delay",), small=True), 444871136),
}


def _case_of(item):
    """(case, seed) of a collected test item of CASES."""
    params = getattr(getattr(item, "callspec", None), "params", {})
    case, seed = CASES[item.originalname](params)
    return case, (seed if seed is not None else _seed(case.label, quiet=True))


class _Background:
    """The pooled cases, started when collection ends (tests/conftest.py), in worker processes at the lowest
    CPU priority: they compute in the time the rest of the suite leaves idle (its daemons mostly wait on
    simulated time) and yield the cores to anything else, so the timing of the daemon tests is not theirs
    to disturb. When this module's tests run they find their results ready or wait for them at full speed."""

    def __init__(self) -> None:
        self.pool: ProcessPoolExecutor | None = None
        self.jobs: dict = {}  # nodeid -> (case, seed, future)

    def start(self, items) -> None:
        if self.pool is not None:
            return
        mine = [it for it in items if getattr(it, "module", None) is sys.modules[__name__] and it.originalname in CASES]
        if not mine:
            return
        workers = max(1, min(2, os.cpu_count() or 1, len(mine)))
        # spawn: a forked copy of the suite's process would inherit the threads earlier tests left running
        self.pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                                        initializer=lowest_cpu_priority)
        for it in mine:
            case, seed = _case_of(it)
            self.jobs[it.nodeid] = (case, seed, self.pool.submit(_identify_case, case, seed))

    def stop(self) -> None:
        """At the session's end: cases not waited for (deselected by -x or a failure) are not run to the end."""
        if self.pool is None:
            return
        for proc in list((self.pool._processes or {}).values()):  # noqa: SLF001 - shutdown(wait=False) leaves them
            proc.terminate()
        self.pool.shutdown(wait=True, cancel_futures=True)
        self.pool = None


BACKGROUND = _Background()


def start_background(items) -> None:
    """tests/conftest.py's hook at the end of collection."""
    BACKGROUND.start(items)


def stop_background() -> None:
    BACKGROUND.stop()


@pytest.fixture(scope="module")
def identified(request):
    """nodeid -> (case, seed, future) for every selected test of CASES (started at collection's end)."""
    BACKGROUND.start(request.session.items)
    return BACKGROUND.jobs


def _outcome(request, identified):
    """The test's own (case, hidden, result, score), waiting for its pooled identification."""
    case, seed, future = identified[request.node.nodeid]
    print(f"\n[{case.label}] seed {seed} (SYSID_TEST_SEED={seed} reproduces it)")
    hidden, desc, result, s = future.result(timeout=ALARM_S)
    print(f"  hidden {hidden} ({desc})")
    print(f"  {result.status}: {result.verdict}, fitted {result.chosen.values() if result.verdict else {}}")
    print(f"  z-scores {s['z']}, error cut {s['error_cut']}, notes {result.notes}")
    return case, hidden, result, s


def check(case: Case, s: dict, *, cut: bool = True) -> None:
    """The checks of the module docstring (``cut``: also the held-out error cut)."""
    assert s["right"], s
    for key, z in s["z"].items():
        assert abs(z) < Z_MAX, f"{key}: z = {z:.2f}"
    if cut and case.effects and not case.unlisted:
        for ch, c in s["error_cut"].items():
            if c["moved_noise"] > 2.0:
                assert c["cut"] >= 0.7, (ch, c)


# weak_motor's realistic case is the benchmark's (benchmarks/sysid_reliability.py, 20/20 in the README): in the suite
# its closed-loop case below names it, and a thirteenth realistic case took the suite over its 10 minutes (601 s)
SUITE_EFFECTS = [e for e in DRAWS if e != "weak_motor"]


@pytest.mark.slow
@pytest.mark.parametrize("effect", SUITE_EFFECTS)
def test_hidden_effect_is_named_and_recovered(effect, request, identified):
    case, _, result, s = _outcome(request, identified)
    assert case.effects == (effect,)
    check(case, s)
    assert all(c["adequate"] for c in result.adequacy.values())


@pytest.mark.slow
def test_nothing_hidden_gives_none_and_an_adequate_model(request, identified):
    """Held fixes of a 1 Hz GPS and its wandering error: the old workflow (noise at its 0.02 m floor,
    every held fix a new measurement) named antenna_offset + wind_force here with chi-square 1800 per
    residual; the verdict must be none because the model explains the data to the noise."""
    case, _, result, s = _outcome(request, identified)
    check(case, s)
    assert result.status == "none" and result.rmse_after == result.rmse_before
    for ch, a in result.adequacy.items():
        assert a["adequate"] and a["chi2_per_measurement"] < 1.3, (ch, a)
    pos = result.prep.noise.position
    assert 0.3 < math.hypot(pos.white, pos.wander) < 3.0, pos  # the GPS's metres, not a 0.02 m floor


@pytest.mark.slow
@pytest.mark.parametrize("pair", [("heading_bias", "wind_force"), ("thrust_asymmetry", "thrust_deadband")])
def test_two_hidden_effects_both_named(pair, request, identified):
    case, _, _, s = _outcome(request, identified)
    assert case.effects == pair
    check(case, s)


@pytest.mark.slow
def test_effect_outside_the_list_is_unexplained(request, identified):
    """A thrust that fades over the trial (a sagging battery) is not a listed effect: the old workflow
    named listed ones with 23-76 % claimed shrinks and said nothing about the fit; now the verdict is
    unexplained, with the nearest candidates and how far they fall short."""
    case, _, result, s = _outcome(request, identified)
    check(case, s)
    assert result.status == "unexplained" and result.verdict == ()
    assert result.nearest and all("adequacy" in c for c in result.nearest)
    assert any(not a["adequate"] for a in result.adequacy.values())
    # the nearest are judged as the verdict is, the sensor-bound test included (found by a sysid audit: the
    # table's cheap judgement left it out, and a nearest said "not adequate" on the terminal, "adequate" in
    # summary.json): the best of them is the chosen fit, and so not adequate either
    assert all(a["deviance_beyond_sensor"] is not None for c in result.nearest for a in c["adequacy"].values())
    assert not all(a["adequate"] for a in result.nearest[0]["adequacy"].values())


@pytest.mark.slow
def test_white_noise_trials_current_and_thrust_lag(request, identified):
    """The original test case (white position noise at 10 Hz) stays one case among these."""
    case, _, _, s = _outcome(request, identified)
    check(case, s)


# A deadband seed that once failed on white-noise trials (the deadband's cost is flat between the
# duties the manoeuvres hold; only ramps through the threshold tell): 1462085713 fitted 39 % for
# 24.2 % from every start (fixed by the profile over the threshold's grid, search.profile). Two more
# (333892304, 1610372544) are in the benchmark's history; the suite keeps the one with its own code path.
@pytest.mark.slow
@pytest.mark.parametrize("seed", (1462085713,))
def test_deadband_regression_seeds(seed, request, identified):
    case, _, _, s = _outcome(request, identified)
    assert identified[request.node.nodeid][1] == seed
    check(case, s)


@pytest.fixture(scope="module")
def current_logs(tmp_path_factory):
    """The four pond missions flown by the daemon (--sim, --speedup max: lockstep, as the README asks of logs
    to identify from; 3x took 20 s of the suite's 10 minutes) in a hidden 0.2 m/s current,
    realistic SC-30. The current flows east, across the missions' legs (they head north to
    north-west): along a leg a current is nearly a faster or slower boat, which the initial speed and
    GPS wander absorb over 30-s logs (the benchmark flies five logs at 2x, draws every direction and
    reports the rate)."""
    d = tmp_path_factory.mktemp("pond")
    case = Case(("current",), kind="closed_loop", n_trials=4, current_towards_deg=90.0, speedup="max")
    hidden, trials, _ = make(case, _seed(case.label), VESSEL, work_dir=d)
    return case, hidden, trials, d


@pytest.mark.slow
def test_a_delay_and_a_lag_the_trials_cannot_tell_apart_are_not_named(request, identified):
    """A 0.073 s sensor delay (below the visible range, benchmarks/sysid_reliability.py --groups small) was named
    thrust_lag 0.071 s [0.064, 0.077]: under 0.1 s the two change the trials almost alike and the better by
    less than the BIC margin won. Now inconclusive, both among what the trials cannot rule out, the truth
    inside the delay's interval."""
    case, hidden, result, s = _outcome(request, identified)
    assert result.status == "inconclusive" and result.verdict == () and s["outcome"] == "inconclusive"
    rows = {r["effect"]: r for r in result.not_excluded}
    assert {"sensor_delay", "thrust_lag"} <= set(rows)
    lo, hi = rows["sensor_delay"]["ci95"]
    assert lo <= hidden["sensor_delay.delay_s"] <= hi
    assert any("cannot tell them apart" in n for n in result.notes)


@pytest.mark.slow
def test_closed_loop_current_from_pond_logs(current_logs):
    case, hidden, trials, _ = current_logs
    result = identify(trials, VESSEL)
    s = score(case, hidden, result)
    print(f"  hidden {hidden}: {result.status} {result.verdict} {result.chosen.values()} z {s['z']} {result.notes}")
    # the flights are not bit-for-bit repeatable (the daemon runs on a real event loop), and the cut of
    # a 0.2 m/s current over 30-s logs sits near the 70 % line (68-85 % seen): the benchmark counts it
    check(case, s, cut=False)


@pytest.mark.slow
def test_closed_loop_wind_is_named_wind(tmp_path):
    """Found by a sysid audit: pond logs flown by the daemon in the simulator's wind (a windage force that turns
    with the heading) came out `unexplained`: the list had only a steady earth-frame force. The `wind` effect is
    the simulator's windage with the air's velocity as its parameters, screened from a grid of starts (started near
    no wind, 5 m/s from the east fitted 4.3 m/s from the south-west)."""
    from autopilot.sysid import read_trial
    from autopilot.sysid.closed_loop import fly_pond_logs

    logs = fly_pond_logs(tmp_path, 20261205, n_logs=4, wind_speed_m_s=5.0, wind_from_deg=90.0, speedup="max")
    # the wind and what came near it or could pass for it (the audit's force, a current, the motors' two effects): the
    # whole list took the suite 19 s of its 10 minutes; the benchmark's closed_loop_wind group screens them all
    result = identify([read_trial(p) for p in logs], VESSEL,
                      candidates=("wind", "wind_force", "current", "weak_motor", "thrust_asymmetry"))
    print(f"  {result.status} {result.verdict} {result.chosen.values()} {result.notes}")
    assert result.status == "effects" and result.verdict == ("wind",), result.notes
    v = result.chosen.values()
    speed, blows_from = math.hypot(v["wind.north_m_s"], v["wind.east_m_s"]), math.degrees(
        math.atan2(-v["wind.east_m_s"], -v["wind.north_m_s"])) % 360.0
    assert abs(speed - 5.0) < 0.25 and abs(blows_from - 90.0) < 3.0, (speed, blows_from)


@pytest.mark.slow
def test_closed_loop_weak_motor_is_named_weak_motor(tmp_path):
    """Found by a sysid audit: three calm pond logs flown with the port motor 6 % short of the thrust table (a fouled
    propeller; the simulated Mbed's sim.thrust_gain_port) were named `wind` (2.1 m/s), or `inconclusive` between
    wind and thrust_asymmetry: the asymmetry moves both motors, and nothing in the list was one motor alone."""
    from autopilot.sysid import read_trial
    from autopilot.sysid.closed_loop import fly_pond_logs

    logs = fly_pond_logs(tmp_path, 20261206, n_logs=3, thrust_gains=(0.94, 1.0), speedup="max")
    # the effects that came near it (the audit's wind and inconclusive asymmetry, a force, a current): the whole
    # list costs the suite 5 s more for no other rival (the benchmark's closed_loop_motor group screens them all)
    result = identify([read_trial(p) for p in logs], VESSEL,
                      candidates=("weak_motor", "thrust_asymmetry", "wind", "wind_force", "current"))
    print(f"  {result.status} {result.verdict} {result.chosen.values()} {result.notes}")
    assert result.status == "effects" and result.verdict == ("weak_motor",), result.notes
    loss, sigma = result.chosen.values()["weak_motor.loss_nd"], float(result.chosen.sigma[0])
    assert abs(loss - 0.06) <= 3.29 * sigma and sigma < 0.01, (loss, sigma)
    fitted = {c["effect"]: c["delta_bic"] for c in result.candidates if c.get("delta_bic") is not None}
    assert fitted["weak_motor"] < min(v for k, v in fitted.items() if k != "weak_motor"), fitted


WEAK_MOTOR_IN_WIND = Path(__file__).parent / "data" / "closed-loop-wind-weak-motor"  # flown by the daemon: README


def _named_within(result, truth: dict) -> None:
    assert result.status == "effects" and set(result.verdict) == {"wind", "weak_motor"}, result.notes
    values, sigma = result.chosen.values(), dict(zip(result.chosen.keys, result.chosen.sigma))
    for key, true in truth.items():  # within the 99.9 % interval: the wind alone was ~7 sigma off
        assert abs(values[key] - true) <= Z_MAX * sigma[key], (key, values[key], true, sigma[key])


@pytest.mark.slow
def test_closed_loop_weak_motor_in_wind_is_screened_beside_the_wind():
    """Found by a sysid audit: in pond logs flown with one motor weak in a wind, the wind fitted alone took the motor's
    moment (east 4.93 m/s for 4.23, sigma 0.1) and was named alone in most wind directions: second effects were
    screened over whole closed-loop trials with the wind held, where the motor screened at no gain and its pair was
    never fitted. They are screened over 15-s windows too now, the wind moving with them. (The whole identification
    on these logs takes a minute: the benchmark's closed_loop_pairs group runs it.)"""
    from autopilot.sysid import read_trial, search
    from autopilot.sysid.fit import fit_model
    from autopilot.sysid.identification import BIC_MARGIN, Settings, baseline, renoise
    from autopilot.sysid.judge import Scores
    from autopilot.sysid.prediction import initial_states, prepare

    prep = prepare([read_trial(p) for p in sorted((WEAK_MOTOR_IN_WIND / "from-290").glob("*.csv"))])
    x0, quiet = initial_states(prep), (lambda msg: None)
    prep, base = baseline(prep, VESSEL, x0, Settings(), quiet)
    wind = fit_model(prep, VESSEL, ("wind",), tuple(range(prep.n_trials)), x0, theta0=[-1.6, 4.9],
                     horizons_s=search.HORIZONS_S)  # the wind alone, where the search left it
    prep, fits = renoise(prep, VESSEL, {(): base, ("wind",): wind}, Scores(prep, VESSEL, Settings().bounds), quiet)
    assert fits[("wind",)].values()["wind.east_m_s"] > 4.6  # the motor's moment taken by the wind
    # every candidate in both screenings' tops (pair_k 4): the motor's start must be the windows' (a review: the
    # whole trials' start was kept, at 21x its base cost, and the pair went to +0.25)
    seconds = search.second_effects(prep, VESSEL, fits, ("wind",), ("weak_motor", "wind_force", "hydro_refit",
                                    "thrust_asymmetry"), 4, BIC_MARGIN)
    pays = {c: p for c, _, p in seconds}
    assert pays.get("weak_motor"), seconds
    search.fit_pairs(prep, VESSEL, fits, ("wind",), [s for s in seconds if s[0] == "weak_motor"], x0,
                     search.Retries(0), quiet, base)
    pair = fits[("wind", "weak_motor")]
    truth = {"wind.north_m_s": -1.5391, "wind.east_m_s": 4.2286, "weak_motor.loss_nd": -0.09}
    assert all(abs(pair.values()[k] - v) < tol for (k, v), tol in zip(truth.items(), (0.2, 0.2, 0.01))), pair.values()


@pytest.mark.slow
def test_closed_loop_weak_motor_in_wind_is_fitted_from_both_sides_of_its_kink():
    """A weak starboard motor in wind screened beside the wind at +0.04 (a weak port motor) and its pair's fit stayed
    on that side of the kink at no loss (+0.05, 380 BIC points worse than the truth's side), losing to the wind
    with a thrust asymmetry: `unexplained`. The pair is fitted from the mirrored value too."""
    from autopilot.sysid import read_trial

    trials = [read_trial(p) for p in sorted((WEAK_MOTOR_IN_WIND / "from-148").glob("*.csv"))]
    result = identify(trials, VESSEL, candidates=("wind", "weak_motor", "thrust_asymmetry"))
    print(f"  {result.status} {result.verdict} {result.chosen.values()} {result.notes}")
    _named_within(result, {"wind.north_m_s": 3.4033, "wind.east_m_s": -2.1104, "weak_motor.loss_nd": -0.10611})


def test_closed_loop_wind_alone_in_the_reversed_winds_basin_is_fitted_from_its_mirror():
    """5.6 m/s of wind from 087 beside a port motor 10 % weak (three pond logs, `from-087`): the wind alone stopped at
    ~5 m/s from the opposite side (the windage's moment is even in the air's velocity: the reversed wind turns the
    boat alike), under the noise it set for itself, and beside it the weak motor never screened among the second
    effects: `unexplained` in every benchmark run. The leading single is fitted from its mirror too, the better kept."""
    from autopilot.sysid import read_trial, search
    from autopilot.sysid.fit import fit_model
    from autopilot.sysid.identification import Settings, baseline, renoise
    from autopilot.sysid.judge import Scores
    from autopilot.sysid.prediction import initial_states, prepare

    prep = prepare([read_trial(p) for p in sorted((WEAK_MOTOR_IN_WIND / "from-087").glob("*.csv"))])
    x0, quiet = initial_states(prep), (lambda msg: None)
    prep, base = baseline(prep, VESSEL, x0, Settings(), quiet)
    wind = fit_model(prep, VESSEL, ("wind",), tuple(range(prep.n_trials)), x0, theta0=[0.7, 5.0],
                     horizons_s=search.HORIZONS_S)  # where the search left it
    assert wind.values()["wind.east_m_s"] > 4.0  # a minimum: the reversed wind's basin
    prep, fits = renoise(prep, VESSEL, {(): base, ("wind",): wind}, Scores(prep, VESSEL, Settings().bounds), quiet)
    assert search.polish_and_retry(prep, VESSEL, fits, x0, search.Retries(0), quiet, base) == ("wind",)
    got = fits[("wind",)].values()
    assert abs(got["wind.north_m_s"] - -0.3147) < 0.5 and abs(got["wind.east_m_s"] - -5.6194) < 0.5, got


def test_closed_loop_pair_with_a_thrust_asymmetry_is_fitted_with_a_weak_motor_in_its_place():
    """4.3 m/s of wind from 292 beside a port motor 7.6 % weak (three pond logs, `from-292`): the weak motor alone sat
    on the starboard side, the wind never screened beside it, and the pair found was wind + thrust_asymmetry (-0.04,
    the same ratio of the two sides' thrusts, a common gain apart); under the final noise the asymmetry was not clearly
    away from none and was dropped: `unexplained`. The best pair with an asymmetry is fitted with the weak motor in its
    place too."""
    from autopilot.sysid import read_trial, search
    from autopilot.sysid.fit import fit_model
    from autopilot.sysid.identification import BIC_MARGIN, Settings, baseline
    from autopilot.sysid.prediction import initial_states, prepare

    prep = prepare([read_trial(p) for p in sorted((WEAK_MOTOR_IN_WIND / "from-292").glob("*.csv"))])
    x0, quiet, everyone = initial_states(prep), (lambda msg: None), tuple(range(prep.n_trials))
    prep, base = baseline(prep, VESSEL, x0, Settings(), quiet)
    pair = fit_model(prep, VESSEL, ("thrust_asymmetry", "wind"), everyone, x0, theta0=[-0.04, -1.68, 4.06],
                     horizons_s=search.HORIZONS_S)  # where the search left it
    wind = fit_model(prep, VESSEL, ("wind",), everyone, pair.x0, theta0=list(pair.theta[1:]), max_nfev=search.BACKWARD_NFEV)
    fits = {(): base, ("wind",): wind, ("thrust_asymmetry", "wind"): pair}
    key = search.sibling_pair(prep, VESSEL, fits, [("thrust_asymmetry", "wind")], quiet, base)
    assert key == ("wind", "weak_motor")  # the member with a single first, for the tests against it
    assert fits[key].bic < pair.bic - BIC_MARGIN, (fits[key].bic - pair.bic)
    got = fits[key].values()
    assert abs(got["weak_motor.loss_nd"] - 0.0762) < 0.02 and abs(got["wind.east_m_s"] - 3.9656) < 0.3, got
    assert search.sibling_pair(prep, VESSEL, fits, [("wind", "hydro_refit")], quiet, base) is None  # nothing to swap
    fits[("weak_motor", "wind")] = fits.pop(key)  # fitted already, in the other order: that one, not a second fit
    assert search.sibling_pair(prep, VESSEL, fits, [("thrust_asymmetry", "wind")], quiet, base) == ("weak_motor", "wind")


@pytest.mark.slow
def test_mission_log_and_its_csv_export_agree(current_logs, tmp_path):
    """The same closed-loop logs read from the .jsonl and from `autopilot review --export csv`:
    the old workflow gave wind forces whose intervals did not overlap. Fitted with the effect the
    logs hold, both give intervals that overlap."""
    from autopilot.cli import main
    from autopilot.sysid import read_trial

    d = current_logs[3]
    paths = sorted(d.rglob("*.jsonl"))
    csvs = []
    for p in paths:
        assert main(["review", str(p), "--out", str(tmp_path / p.stem), "--export", "csv", "--no-plots"]) == 0
        csvs.append(next((tmp_path / p.stem).glob("*.csv")))
    fits = []
    for files in (paths, csvs):
        result = identify([read_trial(f) for f in files], VESSEL, candidates=("current",))
        assert result.verdict == ("current",), result.notes
        fits.append(result.chosen)
    for k in fits[0].keys:
        (a, sa), (b, sb) = ((f.values()[k], float(f.sigma[list(f.keys).index(k)])) for f in fits)
        assert abs(a - b) < 1.96 * (sa + sb), (k, a, sa, b, sb)


@pytest.mark.slow
def test_cli_on_trial_files_writes_everything(tmp_path, capsys):
    """`autopilot sysid TRIAL... --out DIR` end to end on realistic CSV files (held fixes, a hidden current, and a
    3.5-deg compass offset: too small against the GPS wander to name, and said to be there beside the current)."""
    from autopilot.cli import main
    from autopilot.sim import load_params as load
    from autopilot.sysid import load_effects
    from autopilot.sysid.realistic import (
        Measurement,
        draw_models,
        measure,
        write_columns_csv,
    )
    from autopilot.sysid.truth import simulate_truth

    rng = np.random.default_rng(3)
    gps, heading = draw_models(rng)
    meas = Measurement(gps=gps, heading=heading, cells="held")
    hidden = {"current.north_m_s": 0.25, "current.east_m_s": 0.1, "heading_bias.bias_deg": 3.5}
    paths = []
    for i in range(3):
        paths.append(str(tmp_path / f"trial{i}.csv"))
        write_columns_csv(measure(simulate_truth(VESSEL, hidden, rng, duration_s=60.0), meas, rng), paths[-1])
    out = tmp_path / "out"
    capsys.readouterr()
    assert main(["sysid", *paths, "--params", str(default_params_path()), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["verdict"] == ["current"] and summary["adequate"] is True
    # the offset the search fitted beside the current and did not keep, with its interval round the truth (found by
    # a sysid audit: the current was named with nothing said of it)
    (bias,) = [c for c in summary["not_excluded"] if c["param"] == "heading_bias.bias_deg"]
    assert bias["beside"] == "current" and bias["ci95"][0] < 3.5 < bias["ci95"][1]
    assert bias["z"] < bias["z_limit"] or bias["explained_nd"] < bias["min_effect_size_nd"]
    said = capsys.readouterr().out
    assert "beside current, fitted and not named (95 %): heading_bias.bias_deg" in said
    speed = {p["name"]: p for p in summary["effects"]["current"]["params"]}["speed_m_s"]
    assert speed["ci95"][0] - 0.02 < math.hypot(0.25, 0.1) < speed["ci95"][1] + 0.02
    for key in ("candidates", "rmse_before", "rmse_after", "locate", "adequacy", "noise", "measurements"):
        assert key in summary
    assert summary["measurements"]["held_fix_rows"] > 1000 and summary["measurements"]["rejected_position_outliers"] >= 0
    assert set(summary["adequacy"]) == {"position", "heading"}
    assert (out / "report.html").read_text().count("<img") == 3
    assert load(out / "vessel-updated.yaml").name.endswith("-sysid")
    assert set(load_effects(out / "effects.yaml")) == {"current.north_m_s", "current.east_m_s"}


@pytest.mark.slow
def test_speed_over_ground_tells_a_current_from_the_gps_wander():
    """One 40-s trial, 2 m of GPS wander, a hidden 0.2 m/s current: the receiver's speed and course over ground
    (a Doppler velocity, without the position's wander) pin the current that the positions alone can barely
    tell from the wander (its interval several times wider without them)."""
    from autopilot.sim.gps_error import GpsErrorModel
    from autopilot.sysid.realistic import make_realistic_trials

    hidden = {"current.north_m_s": 0.12, "current.east_m_s": -0.16}
    gps = GpsErrorModel(wander_m=2.0, wander_time_s=45.0, white_m=0.15, outlier_rate=0.01, velocity_white_m_s=0.08)
    sigma = {}
    for velocity in (True, False):
        trials = make_realistic_trials(VESSEL, hidden, 20261204, n_trials=1, duration_s=40.0, gps=gps, velocity=velocity)
        result = identify(trials, VESSEL, candidates=("current", "wind_force", "hydro_refit"))
        print(f"  velocity {velocity}: {result.status} {result.verdict} {result.chosen.values()} {result.notes}")
        if velocity:
            assert result.verdict == ("current",) and result.status == "effects"
            assert "velocity" in result.adequacy and result.adequacy["velocity"]["adequate"]
            # one trial: no jackknife widens its intervals, and the notes say so
            assert any(n.startswith("1 trial(s): the intervals rest on the noise model alone") for n in result.notes)
            fit = result.chosen
        else:  # a candidate fitted, named or not: its interval
            from autopilot.sysid.fit import fit_model
            from autopilot.sysid.prediction import initial_states

            fit = fit_model(result.prep, VESSEL, ("current",), (0,), initial_states(result.prep))
        z = [(fit.values()[k] - v) / fit.sigma[fit.keys.index(k)] for k, v in hidden.items()]
        sigma[velocity] = float(np.hypot(*fit.sigma))
        if velocity:
            assert max(abs(x) for x in z) < Z_MAX, z
    assert sigma[False] > 3.0 * sigma[True], sigma


@pytest.mark.slow
def test_noise_at_the_sensor_bound_is_inconclusive_not_none():
    """GPS wander 2 m on a receiver the user bounded at 1 m, nothing hidden: the estimate sits at the bound and
    the data ask for more (deviance gained beyond it >= 3.84), so a missing effect of the noise's size could
    hide there; the verdict says so instead of "none", and lists what the trials cannot rule out. (At the
    bound on a flat likelihood, the wander the trials' states absorb, it stays "none".)"""
    from autopilot.sim.gps_error import GpsErrorModel
    from autopilot.sysid.noise import NoiseBounds
    from autopilot.sysid.realistic import make_realistic_trials

    gps = GpsErrorModel(wander_m=2.0, wander_time_s=45.0, white_m=0.15, outlier_rate=0.01)
    trials = make_realistic_trials(VESSEL, {}, 3, n_trials=2, duration_s=60.0, gps=gps)
    result = identify(trials, VESSEL, bounds=NoiseBounds(position_wander_max_m=1.0))
    assert result.adequacy["position"]["deviance_beyond_sensor"] >= 3.84
    assert result.status == "inconclusive" and result.verdict == (), result.notes
    assert any("position noise's wander part is at its bound" in n for n in result.notes)
    current = {c["param"]: c["ci95"] for c in result.not_excluded if c["effect"] == "current"}
    assert set(current) == {"current.north_m_s", "current.east_m_s"}
    assert all(lo < hi for lo, hi in current.values())
