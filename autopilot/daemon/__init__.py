"""The onboard daemon: configuration, fixed-rate control loop, failsafes, logs, systemd glue.

``gnc/`` decides what to do; the drivers talk to the devices; this package
wires them together on one asyncio event loop, on absolute deadlines of an
injected :class:`autopilot.clock.Clock`, and decides when it is *not safe*
to do what the GNC asks (:mod:`autopilot.daemon.failsafe`).
"""
