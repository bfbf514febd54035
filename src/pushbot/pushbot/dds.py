"""The project's default DDS settings for processes started by ``pushbot`` and by the tests.

The bundled profile (``pushbot/data/fastdds.xml``; its comment explains every setting) gives
each participant shared-memory segments of 32 MB and UDPv4 sockets with 4 MB buffers, so that
640 x 480 camera images (2.1 MB per frame) reach other processes, and 100 ms heartbeats for
reliable writers. It replaces Fast DDS's builtin transports, so ``FASTDDS_BUILTIN_TRANSPORTS``
has no effect on processes that use it.

**A closed graph by default.** The profile's UDPv4 transport is restricted to the loopback
interface (``interfaceWhiteList`` 127.0.0.1): its sockets bind 127.0.0.1, multicast
discovery runs on ``lo`` only and the participant announces loopback locators only. With it,
:func:`dds_environment` sets ``ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT`` when the user set
no range, which leaves discovery to the profile: rmw_fastrtps (Jazzy) would otherwise, under
``LOCALHOST``, add a UDPv4 transport of its own without an allowlist (send sockets on every
interface and the LAN address announced, though nothing listens there). A profile of the
user's own is left alone, range included: pushbot cannot tell what it binds (``pushbot doctor``
measures it).

**Opening the graph to the network** is an explicit choice: ``PUSHBOT_DDS_NETWORK=1``, or a
``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET`` the user set, selects ``fastdds_network.xml`` (the same
profile without the allowlist) and prints :data:`NETWORK_WARNING`: DDS without security lets
any peer that can reach the sockets command the robot.

Fast DDS reads ``FASTRTPS_DEFAULT_PROFILES_FILE`` and rcl reads
``ROS_AUTOMATIC_DISCOVERY_RANGE`` when a participant is created, so
:func:`apply_default_profile` must run before ``rclpy.init``. Values the user already set win.
"""

from __future__ import annotations

import ipaddress
import os
import socket
import struct
import sys
from collections.abc import Mapping, MutableMapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

PROFILE_ENV = 'FASTRTPS_DEFAULT_PROFILES_FILE'
RANGE_ENV = 'ROS_AUTOMATIC_DISCOVERY_RANGE'
NETWORK_ENV = 'PUSHBOT_DDS_NETWORK'
#: The range pushbot sets with its closed profile: the profile alone decides discovery.
CLOSED_RANGE = 'SYSTEM_DEFAULT'
CLOSED_PROFILE = 'fastdds.xml'
NETWORK_PROFILE = 'fastdds_network.xml'
NETWORK_WARNING = (
    'pushbot: the DDS graph is OPEN TO THE NETWORK ({reason}). DDS without security lets any '
    'peer that reaches this machine discover the nodes and command the robot (goals, pushes, '
    'parameters); see README, "Security". Unset it for a loopback-only graph.'
)
_TRUE = ('1', 'true', 'yes', 'on')
_warned = False


def profile_path(network: bool = False) -> Path:
    """Path of a bundled Fast DDS profile: loopback only (default) or open to the network."""
    name = NETWORK_PROFILE if network else CLOSED_PROFILE
    return Path(str(resources.files('pushbot').joinpath('data', name)))


def network_reason(environ: Mapping[str, str] | None = None) -> str | None:
    """Why the graph is opened to the network (the explicit setting), or None: closed."""
    environ = os.environ if environ is None else environ
    if environ.get(NETWORK_ENV, '').strip().lower() in _TRUE:
        return f'{NETWORK_ENV}={environ[NETWORK_ENV]}'
    if environ.get(RANGE_ENV) == 'SUBNET':
        return f'{RANGE_ENV}=SUBNET'
    return None


def dds_environment(environ: Mapping[str, str] | None = None) -> dict[str, str]:
    """The variables to add so a ROS process runs in pushbot's DDS setup (nothing set = {}).

    Closed (the default): ``FASTRTPS_DEFAULT_PROFILES_FILE`` = ``fastdds.xml`` and
    ``ROS_AUTOMATIC_DISCOVERY_RANGE`` = ``SYSTEM_DEFAULT``. Open (:func:`network_reason`):
    ``fastdds_network.xml`` and the range left as it is. A range the user set is kept; a
    profile the user set is kept and then nothing is added (its discovery is the user's).
    """
    environ = os.environ if environ is None else environ
    if environ.get(PROFILE_ENV):
        return {}
    network = network_reason(environ) is not None
    extra = {PROFILE_ENV: str(profile_path(network))}
    if not network and not environ.get(RANGE_ENV):
        extra[RANGE_ENV] = CLOSED_RANGE
    return extra


def apply_default_profile(env: MutableMapping[str, str] | None = None) -> str:
    """Apply :func:`dds_environment` to ``env`` (default ``os.environ``, inherited by children).

    Prints :data:`NETWORK_WARNING` on stderr (once per process) when the graph is opened to
    the network.

    Returns
    -------
    str
        The profile file in effect.
    """
    global _warned
    env = os.environ if env is None else env
    env.update(dds_environment(env))
    reason = network_reason(env)
    if reason and not _warned:
        _warned = True
        print(NETWORK_WARNING.format(reason=reason), file=sys.stderr, flush=True)
    return env[PROFILE_ENV]


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
        return socket.inet_ntoa(struct.pack('<I', int(text, 16)))
    raw = b''.join(struct.pack('<I', int(text[i:i + 8], 16)) for i in range(0, 32, 8))
    return str(ipaddress.ip_address(raw))


def _receive_ports(pid: int | str) -> set[int]:
    ports = set()
    for task in Path(f'/proc/{pid}/task').iterdir():
        try:
            name = (task / 'comm').read_text().strip()
        except OSError:
            continue
        if name.startswith('dds.udp.') and name[8:].isdigit():
            ports.add(int(name[8:]))
    return ports


def udp_sockets(pid: int | str = 'self') -> list[UdpSocket]:
    """The UDP sockets (IPv4 and IPv6) process ``pid`` holds, from ``/proc`` (Linux only).

    Matches the socket inodes of ``/proc/<pid>/fd`` against ``/proc/<pid>/net/udp[6]``.

    Raises
    ------
    OSError
        No ``/proc`` for that process (not Linux, or the process is gone).
    """
    inodes = set()
    for fd in Path(f'/proc/{pid}/fd').iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith('socket:['):
            inodes.add(target[8:-1])
    receiving = _receive_ports(pid)
    found = []
    for table in ('udp', 'udp6'):
        try:
            lines = Path(f'/proc/{pid}/net/{table}').read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if len(fields) > 9 and fields[9] in inodes:
                address, port = fields[1].split(':')
                found.append(UdpSocket(_hex_address(address), int(port, 16),
                                       int(port, 16) in receiving))
    return sorted(found, key=lambda s: (s.port, s.address))
