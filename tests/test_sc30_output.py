"""Which sentences the (simulated) SC-30 sends at each baud rate, and that they fit the line."""

from __future__ import annotations

import pytest

from autopilot.daemon.app import RunOptions, prepare
from autopilot.daemon.config import load_config
from autopilot.drivers.sc30_output import TYPICAL_CHARS, check_sentences, default_sentences, line_load_cps, render_table
from autopilot.schema import ConfigError
from tests.conftest import REPO


def test_docs_table_is_the_code(repo):
    text = (repo / "docs" / "sc30.md").read_text()
    assert render_table() in text, "docs/sc30.md is out of date: paste autopilot.drivers.sc30_output.render_table()"


@pytest.mark.parametrize("baud", [4800, 9600, 19200, 38400])
def test_defaults_fit_their_line(baud):
    fast, slow = default_sentences(baud)
    check_sentences(baud, fast, slow)
    assert "HDT" in fast and {"GGA", "RMC"} <= set(slow)


def test_heading_and_rot_at_10_hz_with_position_do_not_fit_4800_baud():
    fast, slow = ("HDT", "ROT"), ("GGA", "RMC", "VTG")
    assert 540 <= line_load_cps(fast, slow) <= 600  # the ~560 characters a second of the issue
    with pytest.raises(ValueError, match="4800 baud carries 480"):
        check_sentences(4800, fast, slow)
    check_sentences(38400, fast, slow)


def test_the_daemon_refuses_a_sim_set_that_does_not_fit(tmp_path):
    cfg_path = tmp_path / "c.yaml"
    cfg_path.write_text("sim:\n  sc30_fast_sentences: [HDT, ROT]\n  sc30_slow_sentences: [GGA, RMC, VTG]\n")
    cfg = load_config(cfg_path)
    opts = RunOptions(mission_path=str(REPO / "config" / "missions" / "pond-9.1.yaml"), sim=True,
                      log_dir=str(tmp_path / "l"), state_dir=str(tmp_path / "s"))
    with pytest.raises(ConfigError, match="sim.sc30_fast_sentences.*need ~[0-9]+ characters a second; 4800 baud carries 480"):
        prepare(cfg, opts)


def test_the_simulated_sentences_are_no_longer_than_assumed(tmp_path):
    """The load figures hold: every sentence the simulated SC-30 writes, at speed and turning, fits its size."""
    import asyncio

    from autopilot.clock import Clock
    from autopilot.sim import default_params_path, load_params
    from autopilot.simdev import SimRig

    async def main():
        clock = Clock(speedup=10.0)
        fast = ("HDT", "THS", "PFEC_GPatt", "ROT")
        slow = ("GGA", "RMC", "GLL", "VTG", "ZDA")
        rig = SimRig(load_params(default_params_path()), clock, directory=tmp_path, origin_lat_deg=-33.9,
                     origin_lon_deg=-151.2, x0=(-120.0, -80.0, 3.0, 3.2, 0.4, -0.6), sc30_baudrate=38400,
                     sc30_options={"fast_sentences": fast, "slow_sentences": slow})
        await rig.start()
        rig.boat.set_thrust(32.5, -32.5)  # spinning hard, full reverse on one side
        await clock.sleep(3.0)
        await rig.stop()
        return list(rig.sc30.sent_log)

    sent = asyncio.run(main())
    kinds = set()
    for _, line in sent:
        kind = "PFEC_GPatt" if line.startswith("$PFEC,GPatt") else line[3:6]
        kinds.add(kind)
        assert len(line) <= TYPICAL_CHARS[kind], line
    assert kinds == set(TYPICAL_CHARS)
