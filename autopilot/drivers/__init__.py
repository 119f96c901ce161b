"""Device drivers: pure codecs (nmea, mbed_protocol) and thin async transports (sc30, mbed).

Import the submodules: ``autopilot.drivers.sc30.SC30Driver``,
``autopilot.drivers.mbed.MbedDriver`` (see docs/mbed-protocol.md).
"""
