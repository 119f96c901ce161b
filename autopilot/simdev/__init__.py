"""Simulated twins of the SC-30 and the Mbed behind real pseudo-terminals, and the boat behind them."""

from autopilot.simdev.boat import SimBoat
from autopilot.simdev.mbed import SimulatedMbed
from autopilot.simdev.pty import PtyEndpoint
from autopilot.simdev.rig import SimRig
from autopilot.simdev.sc30 import SimulatedSC30, default_sentences

__all__ = ["PtyEndpoint", "SimBoat", "SimulatedSC30", "SimulatedMbed", "SimRig", "default_sentences"]
