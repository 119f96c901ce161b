"""A udpout endpoint reads only its ground station: real UDP sockets on loopback.

Found by a new user's test of the link (2026-12-07): with only `--mavlink udpout:127.0.0.1:14550`, the
daemon's socket listened on 0.0.0.0, and a DISARM sent from another host (or another port of this one) as
system 42 disarmed the boat.
"""

from __future__ import annotations

import asyncio
import socket

from autopilot.link.endpoint import open_endpoint, parse_endpoint


def test_udpout_reads_its_ground_station_and_nobody_else():
    async def run():
        gcs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        gcs.bind(("127.0.0.1", 0))
        stranger.bind(("127.0.0.1", 0))
        gcs.settimeout(2.0)
        ep = open_endpoint(parse_endpoint(f"udpout:127.0.0.1:{gcs.getsockname()[1]}"), 65536)
        await ep.open()
        try:
            ep.send(b"heartbeat")  # the vehicle speaks first: the station learns its address
            data, vehicle = gcs.recvfrom(100)
            assert data == b"heartbeat"
            stranger.sendto(b"disarm from a stranger", vehicle)
            gcs.sendto(b"command from the station", vehicle)
            for _ in range(50):
                if ep.rx:
                    break
                await asyncio.sleep(0.01)
            await asyncio.sleep(0.1)  # the stranger's datagram, had it been read, is in by now
            got = [chunk for chunk, _ in ep.take(4096)]
            assert got == [b"command from the station"], got
        finally:
            await ep.close()
            gcs.close()
            stranger.close()

    asyncio.run(run())


def test_udpout_to_a_name_not_known_yet_opens_and_waits_and_localhost_is_ipv4():
    """A review of the first fix (a socket connected to HOST:PORT): a name not known at boot stopped the daemon
    (exit 2, which systemd does not restart), and localhost resolved to ::1 first on Debian, deaf to an IPv4
    station. The name is resolved in a thread (not on the event loop, nor through asyncio's executor, which stalled
    the lockstep bench), IPv4 as the socket, and asked again later."""
    async def run():
        ep = open_endpoint(parse_endpoint("udpout:gcs-laptop.invalid:14550"), 65536)
        await ep.open()  # no error: nothing sent or read until the name is known
        try:
            ep.send(b"heartbeat")
            assert ep.station_addr is None and ep.tx_errors == 1
        finally:
            await ep.close()
        ep = open_endpoint(parse_endpoint("udpout:localhost:14550"), 65536)
        await ep.open()  # a name: resolved in a thread of its own
        try:
            for _ in range(200):
                if ep.station_addr is not None:
                    break
                await asyncio.sleep(0.01)
            assert ep.station_addr == ("127.0.0.1", 14550)
        finally:
            await ep.close()

    asyncio.run(run())
