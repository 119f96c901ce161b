"""Robustness campaigns: thousands of simulated missions over parameter and disturbance spreads (issue 17).

    spec.py        the spec (YAML) checked with the parameter schema; resolve() -> Campaign (data only)
    draw.py        draw_run(campaign, seed, index) -> RunSetup: one run from (seed, index) alone
    faults.py      a run's dropouts and faults, between the simulated devices and the daemon's steps
    lockstep.py    fly(campaign, seed, indices): many runs in lockstep, one batched plant
                   (the daemon's cycle per run: autopilot.closed_loop)
    backends.py    run_chunks(): this process, a local process pool, or a Dask cluster
    results.py     the runs table, Wilson intervals, distributions, sensitivity (summary.json)
    report.py      report.html
    run.py         run_campaign(campaign, DIR): all of it into a directory
    replay_run.py  replay(DIR, INDEX): re-fly one run, write its mission log
    cli.py         autopilot campaign
"""

from autopilot.lazy import lazy_exports

# Loaded on first use (PEP 562): `autopilot` builds every command's parser at start, and the daemon
# must not carry the campaign's (and through it the identification's) modules.
_OWNERS = {
    "RunSetup": "draw", "draw_run": "draw", "fly": "lockstep", "fly_chunk": "lockstep", "replay": "replay_run",
    "run_campaign": "run", "Campaign": "spec", "CampaignSpec": "spec", "load_spec": "spec", "resolve": "spec",
}


__getattr__, __dir__ = lazy_exports(__name__, _OWNERS, globals())


__all__ = sorted(_OWNERS)
