"""Robustness campaigns: thousands of simulated missions over parameter and disturbance spreads (issue 17).

    spec.py      the spec (YAML) checked with the parameter schema; resolve() -> Campaign (data only)
    draw.py      draw_run(campaign, seed, index) -> RunSetup: one run from (seed, index) alone
    faults.py    a run's dropouts and faults, between the simulated devices and the daemon's steps
    lockstep.py  fly(campaign, seed, indices): many runs in lockstep, one batched plant
                 (the daemon's cycle per run: autopilot.closed_loop)
    backends.py  run_chunks(): this process, a local process pool, or a Dask cluster
    results.py   the runs table, Wilson intervals, distributions, sensitivity (summary.json)
    report.py    report.html
    run.py       run_campaign(campaign, DIR): all of it into a directory
    replay.py    replay(DIR, INDEX): re-fly one run, write its mission log
    cli.py       autopilot campaign
"""

from autopilot.campaign.draw import RunSetup, draw_run
from autopilot.campaign.lockstep import fly, fly_chunk
from autopilot.campaign.replay import replay
from autopilot.campaign.run import run_campaign
from autopilot.campaign.spec import Campaign, CampaignSpec, load_spec, resolve

__all__ = ["Campaign", "CampaignSpec", "RunSetup", "draw_run", "fly", "fly_chunk", "load_spec", "replay", "resolve",
           "run_campaign"]
