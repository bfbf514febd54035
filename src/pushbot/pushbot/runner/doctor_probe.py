"""One side of ``pushbot doctor``'s two-process publish/subscribe check.

Run as ``python -m pushbot.runner.doctor_probe pub|sub --nonce N [--count K] [--timeout S]``.
Both sides use the topic ``pushbot_doctor_<nonce>`` (std_msgs/msg/String, reliable, volatile,
depth 10), so concurrent doctors never see each other's messages.

- ``sub`` waits for the messages ``<nonce>:0`` .. ``<nonce>:<K-1>``.
- ``pub`` waits for a matched subscriber, publishes the K messages, waits until the
  subscriber acknowledged them, then lingers until the subscriber has left.

Each side prints exactly one JSON line on stdout describing what happened and exits 0 only when
its part succeeded: the sub when all K messages arrived, the pub when they were acknowledged.
The report also lists the UDP sockets the side's participant holds (``sockets``: address, port,
whether DDS receives on it; :func:`pushbot.runner.sockets.udp_sockets`), for doctor's exposure
check.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

from pushbot.ros2cli.discovery import RosUnavailableError, cli_node, spin_until
from pushbot.runner.sockets import udp_sockets

if TYPE_CHECKING:
    from rclpy.qos import QoSProfile

DEFAULT_COUNT = 5
DEFAULT_TIMEOUT = 20.0


def topic_for(nonce: str) -> str:
    """The probe topic for one doctor run."""
    return f"pushbot_doctor_{nonce}"


def _reliable_qos() -> QoSProfile:
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE
    )


def own_sockets() -> list[dict] | str:
    """This process's UDP sockets as JSON-ready dicts, or why they cannot be listed."""
    try:
        return [{"address": s.address, "port": s.port, "receiving": s.receiving}
                for s in udp_sockets()]
    except OSError as exc:
        return f"cannot list sockets ({exc})"


def run_publisher(nonce: str, count: int, timeout: float) -> dict:
    """Publish ``count`` nonce messages once a subscriber matched; return a report dict."""
    from rclpy.duration import Duration
    from std_msgs.msg import String

    start = time.monotonic()
    deadline = start + timeout
    report: dict = {"role": "pub", "matched": False, "published": 0, "acked": False}
    with cli_node("doctor_pub") as (node, executor):
        pub = node.create_publisher(String, topic_for(nonce), _reliable_qos())
        report["matched"] = spin_until(
            executor, lambda: pub.get_subscription_count() > 0, deadline
        )
        report["sockets"] = own_sockets()
        if report["matched"]:
            for i in range(count):
                pub.publish(String(data=f"{nonce}:{i}"))
                report["published"] += 1
                executor.spin_once(timeout_sec=0.02)
            remaining = max(deadline - time.monotonic(), 0.1)
            report["acked"] = bool(pub.wait_for_all_acked(Duration(seconds=remaining)))
            # The subscriber exits once it has everything; stay until then so that a
            # retransmission is still possible.
            spin_until(executor, lambda: pub.get_subscription_count() == 0, deadline)
    report["elapsed_s"] = round(time.monotonic() - start, 3)
    return report


def run_subscriber(nonce: str, count: int, timeout: float) -> dict:
    """Wait for the ``count`` nonce messages; return a report dict."""
    from std_msgs.msg import String

    start = time.monotonic()
    deadline = start + timeout
    received: set[int] = set()
    foreign = 0

    def on_message(msg: String) -> None:
        nonlocal foreign
        prefix, _, index = msg.data.partition(":")
        if prefix == nonce and index.isdigit():
            received.add(int(index))
        else:
            foreign += 1

    report: dict = {"role": "sub", "matched": False}
    with cli_node("doctor_sub") as (node, executor):
        sub = node.create_subscription(String, topic_for(nonce), on_message, _reliable_qos())

        def done() -> bool:
            report["matched"] = report["matched"] or sub.get_publisher_count() > 0
            return len(received) >= count

        spin_until(executor, done, deadline)
        report["sockets"] = own_sockets()
    report.update(
        received=len(received),
        expected=count,
        foreign=foreign,
        elapsed_s=round(time.monotonic() - start, 3),
    )
    return report


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m pushbot.runner.doctor_probe``."""
    parser = argparse.ArgumentParser(
        prog="python -m pushbot.runner.doctor_probe", description=__doc__.splitlines()[0]
    )
    parser.add_argument("role", choices=("pub", "sub"))
    parser.add_argument("--nonce", required=True, help="token identifying this doctor run")
    parser.add_argument("--count", type=int, default=DEFAULT_COUNT, help="messages to exchange")
    parser.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT, help="seconds")
    args = parser.parse_args(argv)
    if not args.nonce.isalnum():
        parser.error("--nonce must be alphanumeric (it becomes part of a topic name)")
    try:
        if args.role == "pub":
            report = run_publisher(args.nonce, args.count, args.timeout)
            ok = report["acked"]
        else:
            report = run_subscriber(args.nonce, args.count, args.timeout)
            ok = report["received"] >= args.count
    except RosUnavailableError as exc:
        report, ok = {"role": args.role, "error": str(exc)}, False
    except KeyboardInterrupt:
        report, ok = {"role": args.role, "error": "interrupted"}, False
    print(json.dumps(report), flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
