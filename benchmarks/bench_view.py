"""``pushbot view``'s subprotocol relay, measured: what the hop in front of foxglove-sdk costs.

A foxglove-sdk server (as ``pushbot view`` starts it: 127.0.0.1, port 0) with one channel,
and :class:`pushbot.viz.view_relay.SubprotocolRelay` in front of it, in this process; a
``websockets`` client (another process, so that the client's decoding does not compete for
this interpreter's GIL) subscribes either directly to the SDK server (``foxglove.sdk.v1``) or
through the relay (``foxglove.websocket.v1``, what an older Foxglove offers). The server logs
640x480 rgb8-sized messages (921,600 bytes, a camera frame) at ``--rates`` Hz for
``--seconds`` s each, with the log time = the wall clock at logging. Reported per path and
rate: messages received / logged (the SDK drops what a slow client's queue cannot hold),
latency from logging to the client's receipt (median and 95th percentile, ms), and this
process's CPU time per second (the relay runs in it; the SDK's threads too).

Usage::

    .venv/bin/python benchmarks/bench_view.py [--rates 5 15 30] [--seconds 10] [--no-write]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

FRAME_BYTES = 640 * 480 * 3

#: The client process: connect, subscribe to the one channel, record (receive ns, log ns) of
#: every message until the server says "done" (a status message), print them as JSON.
CLIENT = r"""
import json, struct, sys, time
from websockets.sync.client import connect
port, proto = int(sys.argv[1]), sys.argv[2]
got = []
with connect(f'ws://127.0.0.1:{port}', subprotocols=[proto], max_size=None) as ws:
    print('connected', flush=True)
    while True:
        frame = ws.recv(timeout=60)
        if isinstance(frame, str):
            op = json.loads(frame)
            if op['op'] == 'advertise':
                ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
                    {'id': 1, 'channelId': op['channels'][0]['id']}]}))
            elif op['op'] == 'status' and op.get('message') == 'done':
                break
            continue
        if frame[0] == 1:
            got.append((time.time_ns(), struct.unpack_from('<Q', frame, 5)[0]))
print(json.dumps(got), flush=True)
"""


def run(path: str, rate: float, seconds: float) -> dict[str, float]:
    """Log frames at ``rate`` Hz for ``seconds`` s to one client on ``path`` ('direct' or
    'relay')."""
    import foxglove
    import foxglove.websocket

    from pushbot.viz.view_relay import SubprotocolRelay

    context = foxglove.Context()
    server = foxglove.start_server(name="bench", host="127.0.0.1", port=0, context=context)
    relay = SubprotocolRelay("127.0.0.1", 0, server.port)
    relay.start()
    from pushbot.ros2cli.bag_store import message_definition

    msgdef, _ = message_definition("sensor_msgs/msg/Image")  # the channel pushbot view makes
    schema = foxglove.Schema(name="sensor_msgs/msg/Image", encoding="ros2msg",
                             data=msgdef.encode())
    channel = foxglove.Channel("/camera/color/image_raw", schema=schema, message_encoding="cdr",
                               context=context)
    port, proto = ((server.port, "foxglove.sdk.v1") if path == "direct"
                   else (relay.port, "foxglove.websocket.v1"))
    client = subprocess.Popen([sys.executable, "-c", CLIENT, str(port), proto],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert client.stdout.readline().strip() == "connected"
        deadline = time.monotonic() + 10.0
        while not channel.has_sinks() and time.monotonic() < deadline:
            time.sleep(0.01)
        payload = np.random.default_rng(0).integers(0, 256, FRAME_BYTES, np.uint8).tobytes()
        n = int(rate * seconds)
        cpu0, t0 = time.process_time(), time.monotonic()
        for k in range(n):
            due = t0 + k / rate
            while time.monotonic() < due:
                time.sleep(min(0.002, max(0.0, due - time.monotonic())))
            channel.log(payload, log_time=time.time_ns())
        time.sleep(1.0)  # the last frames' way to the client
        cpu = (time.process_time() - cpu0) / (time.monotonic() - t0)
        server.publish_status("done", foxglove.StatusLevel.Info)
        got = json.loads(client.communicate(timeout=60)[0].strip().splitlines()[-1])
    finally:
        if client.poll() is None:
            client.kill()
        relay.stop()
        server.stop()
    latency = np.array([(recv - logged) / 1e6 for recv, logged in got])
    return {"path": path, "rate": rate, "sent": n, "received": len(got),
            "p50": float(np.median(latency)) if len(got) else float("nan"),
            "p95": float(np.percentile(latency, 95)) if len(got) else float("nan"),
            "cpu": cpu}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", type=float, nargs="+", default=[5.0, 15.0, 30.0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--no-write", action="store_true", help="do not write the result page")
    args = parser.parse_args(argv)
    rows = []
    for rate in args.rates:
        for path in ("direct", "relay"):
            row = run(path, rate, args.seconds)
            rows.append(row)
            print(json.dumps(row), flush=True)
    body = (f"{args.seconds:g} s per row: 921,600-byte messages (a 640x480 rgb8 frame) logged by "
            "a foxglove-sdk server in this process to one `websockets` client in another, "
            "directly (`foxglove.sdk.v1`) or through `pushbot.viz.view_relay` (the client offers "
            "only `foxglove.websocket.v1`). Latency: logging to receipt, wall clock.\n\n"
            "| path | Hz | received / logged | latency median ms | latency p95 ms | "
            "server process CPU s per s |\n| --- | --- | --- | --- | --- | --- |\n")
    body += "".join(f"| {r['path']} | {r['rate']:g} | {r['received']} / {r['sent']} | "
                    f"{r['p50']:.1f} | {r['p95']:.1f} | {r['cpu']:.2f} |\n" for r in rows)
    body += f"\nLoad average at the end: {os.getloadavg()[0]:.1f} (shared machine).\n"
    print(body)
    if not args.no_write:
        cmd = "python benchmarks/bench_view.py " + " ".join(argv or sys.argv[1:])
        update_section("view_relay", format_section(
            "Live view: the subprotocol relay's cost (bench_view)", cmd.strip(), body))
    return 0


if __name__ == "__main__":
    sys.exit(main())
