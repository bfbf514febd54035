"""The operator CLI, measured: how long daemon-less discovery takes on the ``pushbot up`` graph,
how often each waiting rule would have printed an incomplete graph, and the wall time of the
everyday commands.

1. **Discovery timelines.** ``pushbot up --object rect1`` (four node processes) on a private
   ROS domain; ``--runs`` times, a fresh process with the CLI's hidden node
   (``pushbot.ros2cli.discovery.cli_node``) records, for ``--watch`` seconds, every change of what
   the graph commands print (``pushbot.ros2cli.discovery.graph_snapshot``: other nodes, topics,
   services) and of the endpoints of ``estimator/object_pose`` (what ``topic info`` prints), with
   the time since the node was created. The final view (after ``--watch`` s) is the complete graph.
2. **Rules replayed on the timelines.** For each rule, the view it would have returned and
   whether it was complete: the CLI's rule (``pushbot.ros2cli.discovery.wait_for_stable_graph``: at
   least ``MIN_DISCOVERY_TIME``, then ``SETTLE_TIME`` without a change), a 1 s quiet period alone,
   the old ``topic list`` (a fixed 3 s) and the old ``topic info`` (0.5 s after the topic's
   first sighting).
3. **Command wall times** (process start to exit, median over 5 runs): ``node list``,
   ``topic info estimator/object_pose``, ``param get /sim_bridge_node object``, ``service call
   /planner_node/reset``.

Writes ``docs/results/cli.md``. The machine is shared (2 cores): the load
average is recorded with the figures.

Usage::

    .venv/bin/python benchmarks/bench_cli.py [--runs N] [--watch S] [--no-write]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

from pushbot.ros2cli.discovery import MIN_DISCOVERY_TIME, SETTLE_TIME  # noqa: E402

PUSHBOT = Path(sys.executable).parent / "pushbot"
#: Outside the test sessions' domains (1-200, tests/conftest.py).
DOMAIN = "231"
TOPIC = "/estimator/object_pose"
#: Runs of each command for the wall times (at most).
COMMAND_RUNS = 5
WATCHER = """
import json, sys, time
from pushbot.ros2cli.discovery import cli_node, graph_snapshot

watch, topic = float(sys.argv[1]), sys.argv[2]
with cli_node('bench_watch') as (node, executor):
    start = time.monotonic()
    def view():
        nodes, topics, services = graph_snapshot(node)
        pubs = sorted(i.node_name for i in node.get_publishers_info_by_topic(topic))
        seen = any(name == topic for name, _ in topics)
        return [list(nodes), [t[0] for t in topics], [s[0] for s in services], pubs, seen]
    changes, last = [], None
    while time.monotonic() - start < watch:
        executor.spin_once(timeout_sec=0.02)
        current = view()
        if current != last:
            changes.append([time.monotonic() - start, current])
            last = current
print(json.dumps(changes))
"""


def _pushbot(*args: str, env: dict[str, str]) -> tuple[float, int]:
    start = time.monotonic()
    code = subprocess.run([str(PUSHBOT), *args], env=env, capture_output=True,
                          stdin=subprocess.DEVNULL, check=False).returncode
    return time.monotonic() - start, code


def _at(changes: list, t: float) -> list:
    """The view at time ``t`` (the last change at or before it)."""
    view = changes[0][1]
    for time_, current in changes:
        if time_ > t:
            break
        view = current
    return view


def _rule_end(changes: list, min_time: float, settle: float, watch: float,
              start: float = 0.0, part: int | None = None) -> float:
    """When ``wait_for_stable_graph`` started at ``start`` would return (``ready``: some other
    node; ``part``: watch only that part of the view, as ``topic info`` watches one topic)."""
    events: list[tuple[float, object]] = []
    for time_, view in changes:
        watched = view[:3] if part is None else view[part]
        if time_ <= start:
            events = [(start, watched)]
        elif not events or watched != events[-1][1]:
            events.append((time_, watched))
    for i, (time_, _) in enumerate(events):
        candidate = max(time_ + settle, start + min_time)
        following = events[i + 1][0] if i + 1 < len(events) else watch
        ready = part is not None or _at(changes, candidate)[0]
        if candidate <= following and ready:
            return min(candidate, watch)
    return watch


def _complete(view: list, final: list, parts: tuple[int, ...] = (0, 1, 2)) -> bool:
    return all(view[p] == final[p] for p in parts)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--watch", type=float, default=8.0,
                        help="seconds each discovery timeline is recorded")
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args(argv)
    env = {**os.environ, "ROS_DOMAIN_ID": DOMAIN, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
           "PYTHONUNBUFFERED": "1"}
    env.pop("ROS_LOCALHOST_ONLY", None)
    with tempfile.TemporaryDirectory(prefix="bench_cli_") as tmp:
        up = subprocess.Popen([str(PUSHBOT), "up", "--object", "rect1", "--log-dir",
                               str(Path(tmp) / "logs")], env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
        try:
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline:
                listed = subprocess.run([str(PUSHBOT), "node", "list"], env=env, text=True,
                                        capture_output=True, check=False).stdout.split()
                if len(listed) >= 4:
                    break
            else:
                print("pushbot up did not start", file=sys.stderr)
                return 1
            timelines = []
            for run in range(args.runs):
                out = subprocess.run([sys.executable, "-c", WATCHER, str(args.watch), TOPIC],
                                     env=env, text=True, capture_output=True, check=True).stdout
                timelines.append(json.loads(out))
                print(f"timeline {run + 1}/{args.runs}: {len(timelines[-1])} changes, last at "
                      f"{timelines[-1][-1][0]:.2f} s", flush=True)
            commands = {
                "node list": ("node", "list"),
                f"topic info {TOPIC}": ("topic", "info", TOPIC),
                "param get /sim_bridge_node object": ("param", "get", "/sim_bridge_node",
                                                      "object"),
                "service call /planner_node/reset": ("service", "call", "/planner_node/reset",
                                                     "std_srvs/srv/Trigger"),
            }
            walls: dict[str, list[float]] = {name: [] for name in commands}
            failures: dict[str, int] = dict.fromkeys(commands, 0)
            for _ in range(min(args.runs, COMMAND_RUNS)):
                for name, command in commands.items():
                    wall, code = _pushbot(*command, env=env)
                    walls[name].append(wall)
                    failures[name] += code != 0
            load = os.getloadavg()
        finally:
            up.send_signal(signal.SIGINT)
            try:
                up.wait(timeout=60)
            except subprocess.TimeoutExpired:
                up.kill()
                up.wait()

    rules = {
        f"CLI rule: >= {MIN_DISCOVERY_TIME:g} s, then {SETTLE_TIME:g} s quiet":
            lambda c: _rule_end(c, MIN_DISCOVERY_TIME, SETTLE_TIME, args.watch),
        "1 s quiet only": lambda c: _rule_end(c, 0.0, 1.0, args.watch),
        ">= 2.5 s, then 1.5 s quiet": lambda c: _rule_end(c, 2.5, 1.5, args.watch),
        ">= 3 s, then 2 s quiet": lambda c: _rule_end(c, 3.0, 2.0, args.watch),
        ">= 3 s, then 2.5 s quiet": lambda c: _rule_end(c, 3.0, 2.5, args.watch),
        "fixed 3 s (old topic list)": lambda c: 3.0,
    }
    lines = ["| rule | incomplete views (nodes, topics, services) | median / max wait (s) |",
             "| --- | --- | --- |"]
    for label, rule in rules.items():
        ends = [rule(c) for c in timelines]
        bad = sum(not _complete(_at(c, end), c[-1][1]) for c, end in zip(timelines, ends,
                                                                          strict=True))
        lines.append(f"| {label} | {bad}/{len(timelines)} | {statistics.median(ends):.2f} / "
                     f"{max(ends):.2f} |")
    # topic info: the old rule looked 0.5 s after the topic's first sighting; the CLI's rule
    # replays on the publisher view.
    old_info_bad = new_info_bad = 0
    for changes in timelines:
        final_pubs = changes[-1][1][3]
        first = next((t for t, view in changes if view[4]), None)
        if first is None or _at(changes, first + 0.5)[3] != final_pubs:
            old_info_bad += 1
        if first is not None:
            end = _rule_end(changes, MIN_DISCOVERY_TIME, SETTLE_TIME, args.watch, first, 3)
            new_info_bad += _at(changes, end)[3] != final_pubs
        else:
            new_info_bad += 1
    last_change = [c[-1][0] for c in timelines]
    gaps = [max((b[0] - a[0] for a, b in zip(c, c[1:], strict=False)), default=0.0)
            for c in timelines]
    complete_at = [next(t for t, view in c if _complete(view, c[-1][1])) for c in timelines]
    body = "\n".join([
        f"`pushbot up --object rect1` (four node processes) on ROS domain {DOMAIN}; {args.runs} "
        f"fresh CLI processes each recorded the graph for {args.watch:g} s (the view after "
        f"{args.watch:g} s is taken as complete). Load average during the run: "
        f"{load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} (1 / 5 / 15 min).",
        "",
        f"- graph complete after: median {statistics.median(complete_at):.2f} s, max "
        f"{max(complete_at):.2f} s; last change at: median {statistics.median(last_change):.2f}"
        f" s, max {max(last_change):.2f} s; longest quiet gap before a change: median "
        f"{statistics.median(gaps):.2f} s, max {max(gaps):.2f} s",
        f"- `topic info {TOPIC}` publishers incomplete: old rule (0.5 s after the topic first "
        f"appears) {old_info_bad}/{len(timelines)}, CLI rule {new_info_bad}/{len(timelines)}",
        "",
        *lines,
        "",
        "| command | median wall time (s) | max (s) | failures |",
        "| --- | --- | --- | --- |",
        *[f"| `pushbot {name}` | {statistics.median(w):.2f} | {max(w):.2f} | "
          f"{failures[name]}/{len(w)} |" for name, w in walls.items()],
    ])
    command = "python benchmarks/bench_cli.py" + (f" --runs {args.runs}" if args.runs != 20
                                                  else "")
    section = format_section("cli: daemon-less discovery and command wall times", command, body)
    print(section)
    if not args.no_write:
        update_section("cli", section)
    return 0


if __name__ == "__main__":
    sys.exit(main())
