"""By default the nodes' participants bind and announce loopback locators only.

``pushbot run planner_node`` is started with the user's default environment (no
``ROS_AUTOMATIC_DISCOVERY_RANGE``, no profile: pushbot's closed default applies, see
``push_ros.dds``). The test then

- reads the node's UDP sockets from ``/proc/<pid>/fd`` + ``/proc/<pid>/net/udp[6]``
  (:func:`pushbot.runner.sockets.udp_sockets`): every one must be bound to 127.0.0.1 or to the
  multicast group (which the loopback-only transport joins on ``lo`` only);
- listens, without sending anything, on the discovery multicast group joined on the loopback
  interface only, and parses the node's SPDP announcements (RTPS DATA from the builtin
  participant writer, parameter list): every announced unicast/multicast locator must be
  127.0.0.1, the multicast group, or the shared-memory locator.

Controls: with ``PUSHBOT_DDS_NETWORK=1`` the same node binds non-loopback sockets (so the
socket check can fail), and the announcement parser recognises the node's own announcements
(so "no non-loopback locator" is not "no announcement"). No packet is sent by the test at all;
the node's own traffic stays on ``lo``.
"""

from __future__ import annotations

import ipaddress
import os
import socket
import struct
import subprocess
import time
from typing import TYPE_CHECKING

import pytest

from push_ros.dds import NETWORK_ENV, PROFILE_ENV, RANGE_ENV
from pushbot.runner.sockets import udp_sockets

if TYPE_CHECKING:  # the fixtures come from tests/conftest.py
    from conftest import ProcessManager

pytestmark = [
    pytest.mark.ros,
    pytest.mark.graph,
    pytest.mark.skipif(not os.path.isdir("/proc/self/net"), reason="needs Linux /proc"),
]

MULTICAST_GROUP = "239.255.0.1"  # RTPS default discovery group
SPDP_WRITER = b"\x00\x01\x00\xc2"  # ENTITYID_SPDP_BUILTIN_RTPSParticipant_WRITER
LOCATOR_PIDS = {0x0031: "default unicast", 0x0032: "metatraffic unicast",
                0x0033: "metatraffic multicast", 0x0048: "default multicast"}
PID_SENTINEL = 0x0001
LOCATOR_KIND_UDPv4, LOCATOR_KIND_SHM = 1, 16
STARTUP_TIMEOUT = 60.0  # s on a loaded 2-core machine


def _start_planner(processes: ProcessManager, monkeypatch: pytest.MonkeyPatch,
                   **extra: str) -> subprocess.Popen:
    """``pushbot run planner_node`` as a user starts it: no range, no profile (pushbot decides).

    The session's ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and profile (tests/conftest.py)
    are removed for this test only; the domain id stays the session's own.
    """
    for name in (RANGE_ENV, PROFILE_ENV, NETWORK_ENV):
        monkeypatch.delenv(name, raising=False)
    return processes.node("planner_node", env=extra)


def _wait_for_receivers(pid: int) -> list:
    """The node's sockets once DDS receives on its participant's ports."""
    deadline = time.monotonic() + STARTUP_TIMEOUT
    while time.monotonic() < deadline:
        sockets = udp_sockets(pid)
        if sum(s.receiving for s in sockets) >= 3:  # multicast + metatraffic + user unicast
            time.sleep(1.0)  # let the transports finish opening their send sockets
            return udp_sockets(pid)
        time.sleep(0.2)
    pytest.fail(f"planner_node opened no DDS receive socket in {STARTUP_TIMEOUT} s")


def spdp_locators(datagram: bytes) -> set[tuple[str, int, str, int]]:
    """(kind of list, locator kind, address, port) of every locator an SPDP DATA announces."""
    found: set[tuple[str, int, str, int]] = set()
    if datagram[:4] != b"RTPS":
        return found
    offset = 20  # RTPS header
    while offset + 4 <= len(datagram):
        sub_id, flags = datagram[offset], datagram[offset + 1]
        order = "<" if flags & 1 else ">"
        (length,) = struct.unpack(order + "H", datagram[offset + 2:offset + 4])
        body = datagram[offset + 4:offset + 4 + length] if length else datagram[offset + 4:]
        if sub_id == 0x15 and body[8:12] == SPDP_WRITER:  # DATA
            (to_inline_qos,) = struct.unpack(order + "H", body[2:4])
            pos = 4 + to_inline_qos
            if flags & 2:  # inline QoS present: skip to its sentinel
                while pos + 4 <= len(body):
                    pid, size = struct.unpack(order + "HH", body[pos:pos + 4])
                    pos += 4 + size
                    if pid == PID_SENTINEL:
                        break
            scheme, pos = body[pos:pos + 2], pos + 4
            pl_order = "<" if scheme in (b"\x00\x01", b"\x00\x03") else ">"
            while pos + 4 <= len(body):
                pid, size = struct.unpack(pl_order + "HH", body[pos:pos + 4])
                value, pos = body[pos + 4:pos + 4 + size], pos + 4 + size
                if pid == PID_SENTINEL:
                    break
                if pid in LOCATOR_PIDS and size >= 24:
                    kind, port = struct.unpack(pl_order + "iI", value[:8])
                    address = (str(ipaddress.ip_address(value[20:24])) if kind == 1
                               else value[8:24].hex())
                    found.add((LOCATOR_PIDS[pid], kind, address, port))
        if length == 0:
            break
        offset += 4 + length
    return found


def _announced_locators(domain: int, seconds: float) -> set[tuple[str, int, str, int]]:
    """Listen (never send) on the discovery group, joined on the loopback interface only."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((MULTICAST_GROUP, 7400 + 250 * domain))
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP,
                        socket.inet_aton(MULTICAST_GROUP) + socket.inet_aton("127.0.0.1"))
        sock.settimeout(0.5)
        found: set[tuple[str, int, str, int]] = set()
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            try:
                datagram, _ = sock.recvfrom(65536)
            except TimeoutError:
                continue
            found |= spdp_locators(datagram)
        return found
    finally:
        sock.close()


def test_a_node_binds_loopback_sockets_only_by_default(processes: ProcessManager,
        monkeypatch: pytest.MonkeyPatch) -> None:
    node = _start_planner(processes, monkeypatch)
    sockets = _wait_for_receivers(node.pid)
    assert node.poll() is None
    outside = [str(s) for s in sockets if not s.loopback]
    assert not outside, f"planner_node binds non-loopback UDP sockets: {outside} of {sockets}"
    assert any(s.address == "127.0.0.1" and s.receiving for s in sockets), sockets


def test_a_node_announces_loopback_locators_only_by_default(processes: ProcessManager,
        monkeypatch: pytest.MonkeyPatch) -> None:
    node = _start_planner(processes, monkeypatch)
    _wait_for_receivers(node.pid)
    domain = int(os.environ["ROS_DOMAIN_ID"])
    # Fast DDS announces every few seconds at first (initial announcements), then every 3 s.
    locators = _announced_locators(domain, seconds=8.0)
    udp = {loc for loc in locators if loc[1] == LOCATOR_KIND_UDPv4}
    assert udp, f"no SPDP announcement heard on {MULTICAST_GROUP} (lo): {locators}"
    assert any(kind == "metatraffic unicast" for kind, *_ in udp), locators
    foreign = [loc for loc in locators
               if loc[1] not in (LOCATOR_KIND_UDPv4, LOCATOR_KIND_SHM)
               or (loc[1] == LOCATOR_KIND_UDPv4 and not (
                   ipaddress.ip_address(loc[2]).is_loopback or loc[2] == MULTICAST_GROUP))]
    assert not foreign, f"non-loopback locators announced: {foreign} (all: {locators})"


def _has_non_loopback_interface() -> bool:
    return any(name != "lo" for _, name in socket.if_nameindex())


@pytest.mark.skipif(not _has_non_loopback_interface(), reason="only a loopback interface")
def test_control_the_network_mode_binds_every_interface(processes: ProcessManager,
        monkeypatch: pytest.MonkeyPatch) -> None:
    node = _start_planner(processes, monkeypatch, **{NETWORK_ENV: "1"})
    sockets = _wait_for_receivers(node.pid)
    assert [s for s in sockets if s.receiving and not s.loopback], sockets


def test_the_parser_reads_a_known_announcement() -> None:
    locator = struct.pack("<iI", 1, 7410) + bytes(12) + bytes([127, 0, 0, 1])
    params = struct.pack("<HH", 0x0032, 24) + locator + struct.pack("<HH", PID_SENTINEL, 0)
    payload = b"\x00\x03\x00\x00" + params
    data = struct.pack("<HH", 0, 16) + b"\x00\x01\x00\xc7" + SPDP_WRITER + bytes(8) + payload
    datagram = b"RTPS" + bytes(16) + bytes([0x15, 0x05]) + struct.pack("<H", len(data)) + data
    assert spdp_locators(datagram) == {("metatraffic unicast", 1, "127.0.0.1", 7410)}


def _report(*sockets: tuple[str, int, bool]) -> dict:
    return {"sockets": [{"address": a, "port": p, "receiving": rx} for a, p, rx in sockets]}


def test_doctor_verdicts(monkeypatch: pytest.MonkeyPatch) -> None:
    from push_ros.dds import profile_path
    from pushbot.runner.doctor import check_exposure

    for name in (RANGE_ENV, NETWORK_ENV):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv(PROFILE_ENV, str(profile_path()))
    closed = check_exposure([_report(("127.0.0.1", 7410, True), ("239.255.0.1", 7400, True),
                                     ("127.0.0.1", 40000, False))])
    assert closed.ok and closed.detail.startswith("closed (loopback only)"), closed.detail
    assert "profile binds 127.0.0.1 only" in closed.detail
    # LOCALHOST: rmw_fastrtps's own transport adds send sockets only; still closed for input.
    monkeypatch.setenv(RANGE_ENV, "LOCALHOST")
    sending = check_exposure([_report(("127.0.0.1", 7410, True), ("0.0.0.0", 40001, False))])
    assert sending.ok and "send sockets on 0.0.0.0:40001" in sending.detail
    assert "unset it" in sending.detail
    # Receiving on every interface without asking for it: FAIL.
    monkeypatch.delenv(RANGE_ENV)
    monkeypatch.setenv(PROFILE_ENV, str(profile_path(network=True)))
    opened = check_exposure([_report(("0.0.0.0", 7410, True))])
    assert not opened.ok and opened.detail.startswith("OPEN to the network"), opened.detail
    # ... and asked for: OK, with the warning.
    monkeypatch.setenv(NETWORK_ENV, "1")
    chosen = check_exposure([_report(("0.0.0.0", 7410, True))])
    assert chosen.ok and chosen.detail.startswith(f"OPEN by choice ({NETWORK_ENV}=1)")
    assert "any peer on the network command the robot" in chosen.detail
    # No socket list (not Linux, or the probes failed): not verified, FAIL unless opened.
    monkeypatch.delenv(NETWORK_ENV)
    assert not check_exposure([{}]).ok
