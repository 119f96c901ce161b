"""Guidance, navigation and control: pure numbers in, numbers out (thesis ch. 6-8).

The public contract (used by the daemon, the simulator's evaluation and the tests):
``GncConfig`` (with ``GuidanceConfig``, ``PidConfig``, ``AllocationConfig``),
``NavInput``, ``ControlOutput`` and ``Autopilot``.
"""

from autopilot.gnc.allocation import AllocationConfig
from autopilot.gnc.autopilot import Autopilot, ControlOutput, NavInput
from autopilot.gnc.config import GncConfig, GuidanceConfig
from autopilot.gnc.fuzzy_guidance import FuzzyConfig
from autopilot.gnc.los import LosConfig
from autopilot.gnc.pid import PidConfig
from autopilot.gnc.proportional import ProportionalConfig
from autopilot.gnc.registry import GUIDANCE_LAWS
from autopilot.gnc.speed import SpeedTrimConfig

__all__ = [
    "Autopilot",
    "ControlOutput",
    "NavInput",
    "GncConfig",
    "GuidanceConfig",
    "PidConfig",
    "AllocationConfig",
    "FuzzyConfig",
    "LosConfig",
    "ProportionalConfig",
    "SpeedTrimConfig",
    "GUIDANCE_LAWS",
]
