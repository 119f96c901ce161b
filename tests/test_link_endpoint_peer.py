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
