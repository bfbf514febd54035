"""What a process actually exposes on the network (Linux ``/proc``), for ``pushbot doctor``.

The DDS rule itself (profiles, ``dds_environment``, ``apply_default_profile``) lives in
:mod:`push_ros.dds`, where the nodes, the launch file and the CLI reach it.
"""

from __future__ import annotations

import ipaddress
import os
import socket
import struct
from dataclasses import dataclass
from pathlib import Path

# --- what a process actually exposes (Linux /proc) -------------------------------------------


@dataclass(frozen=True)
class UdpSocket:
    """One UDP socket of a process: its bound address and port, and whether DDS reads it.

    ``receiving`` is true when Fast DDS runs a receive thread on the port (its threads are
    named ``dds.udp.<port>``, Fast DDS >= 2.13); the others are send sockets.
    """

    address: str
    port: int
    receiving: bool

    @property
    def loopback(self) -> bool:
        """Bound to a loopback address or to a multicast group (joined per interface)."""
        ip = ipaddress.ip_address(self.address)
        return ip.is_loopback or ip.is_multicast

    def __str__(self) -> str:
        return f'{self.address}:{self.port}{"" if self.receiving else " (send)"}'


def _hex_address(text: str) -> str:
    if len(text) == 8:
        return socket.inet_ntoa(struct.pack("<I", int(text, 16)))
    raw = b"".join(struct.pack("<I", int(text[i:i + 8], 16)) for i in range(0, 32, 8))
    return str(ipaddress.ip_address(raw))


def _receive_ports(pid: int | str) -> set[int]:
    ports = set()
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            name = (task / "comm").read_text().strip()
        except OSError:
            continue
        if name.startswith("dds.udp.") and name[8:].isdigit():
            ports.add(int(name[8:]))
    return ports


def udp_sockets(pid: int | str = "self") -> list[UdpSocket]:
    """The UDP sockets (IPv4 and IPv6) process ``pid`` holds, from ``/proc`` (Linux only).

    Matches the socket inodes of ``/proc/<pid>/fd`` against ``/proc/<pid>/net/udp[6]``.

    Raises
    ------
    OSError
        No ``/proc`` for that process (not Linux, or the process is gone).
    """
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    receiving = _receive_ports(pid)
    found = []
    for table in ("udp", "udp6"):
        try:
            lines = Path(f"/proc/{pid}/net/{table}").read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if len(fields) > 9 and fields[9] in inodes:
                address, port = fields[1].split(":")
                found.append(UdpSocket(_hex_address(address), int(port, 16),
                                       int(port, 16) in receiving))
    return sorted(found, key=lambda s: (s.port, s.address))
