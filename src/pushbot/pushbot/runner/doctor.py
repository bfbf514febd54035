"""``pushbot doctor``: check that the install can run the node graph.

Checks, one output line each (``OK`` or ``FAIL`` and a reason):

- versions of rclpy, the RMW implementation, torch, pybullet, OpenCV and numpy
  (a missing or broken import is a FAIL with a hint, never a traceback);
- the DDS environment: ``ROS_DOMAIN_ID``, ``ROS_AUTOMATIC_DISCOVERY_RANGE``, the RMW in use;
- a real two-process publish/subscribe round trip on this machine: a subscriber and a
  publisher run as two subprocesses of this Python (``python -m pushbot.runner.doctor_probe``) and
  must exchange messages carrying a random nonce within ``--timeout`` seconds;
- the network exposure (``DDS exposure``): the discovery range, whether the DDS profile in
  effect binds loopback only, and the UDP sockets the probes' participants actually held
  (``/proc``). ``closed`` when DDS receives on loopback only; ``OPEN by choice`` (still OK,
  with the warning) when ``PUSHBOT_DDS_NETWORK=1`` or ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET``
  opened it; FAIL when DDS receives on a non-loopback address nobody asked for.

Test hook: ``PUSHBOT_DOCTOR_SUB_DOMAIN_OFFSET=k`` starts the probe subscriber on domain
``ROS_DOMAIN_ID + k``, which makes the exchange fail for real (used by the test suite to check
the failure path; doctor says when the hook is active).
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import importlib
import importlib.metadata
import ipaddress
import json
import os
import secrets
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from push_ros.dds import NETWORK_ENV, PROFILE_ENV, RANGE_ENV, network_reason, profile_path
from pushbot.runner.doctor_probe import DEFAULT_COUNT, DEFAULT_TIMEOUT

SUB_DOMAIN_OFFSET_ENV = "PUSHBOT_DOCTOR_SUB_DOMAIN_OFFSET"
MAX_DOMAIN_ID = 232  # the largest domain id the RTPS port mapping allows
DISCOVERY_RANGES = ("SUBNET", "LOCALHOST", "OFF", "SYSTEM_DEFAULT")
DISCOVERY_HINT = "check ROS_DOMAIN_ID / firewall / FASTDDS_BUILTIN_TRANSPORTS"


@dataclass(frozen=True)
class Check:
    """Outcome of one doctor check."""

    name: str
    ok: bool
    detail: str

    def line(self) -> str:
        """The output line: status, name, detail."""
        return f'{"OK" if self.ok else "FAIL":<5}{self.name:<24}{self.detail}'


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot doctor``."""
    parser.add_argument(
        "--timeout",
        type=float,
        default=DEFAULT_TIMEOUT,
        help="seconds the publish/subscribe check may take (default: %(default)s)",
    )
    parser.add_argument(
        "--count",
        type=int,
        default=DEFAULT_COUNT,
        help="messages exchanged in the publish/subscribe check (default: %(default)s)",
    )


def _dist_version(*names: str) -> str | None:
    for name in names:
        try:
            return importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
    return None


def _flush_c_stdio() -> None:
    """fflush(NULL): push out what C code buffered while the fds pointed to /dev/null."""
    with contextlib.suppress(Exception):
        ctypes.CDLL(None).fflush(None)


@contextlib.contextmanager
def _silenced_output() -> Iterator[None]:
    """Silence file descriptors 1 and 2 (pybullet prints a banner from C on import)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    try:
        with open(os.devnull, "w") as devnull:
            for fd in saved:
                os.dup2(devnull.fileno(), fd)
            try:
                yield
            finally:
                _flush_c_stdio()
    finally:
        for fd, copy in saved.items():
            os.dup2(copy, fd)
            os.close(copy)


def check_module(
    label: str, module: str, dists: tuple[str, ...], version: Callable[[object], str] | None = None
) -> Check:
    """Import ``module`` and report its version; a failed import is a FAIL, not a traceback."""
    try:
        with _silenced_output():
            mod = importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name and module.split(".")[0] == exc.name.split(".")[0]:
            return Check(label, False, f"{label} is not installed: run make venv")
        return Check(label, False, f"{label} is broken ({exc}): run make venv")
    except Exception as exc:
        return Check(label, False, f"{label} cannot be imported ({type(exc).__name__}: {exc})")
    found = version(mod) if version else _dist_version(*dists)
    return Check(label, True, found or getattr(mod, "__version__", "unknown version"))


def check_versions() -> list[Check]:
    """Versions of rclpy, the RMW implementation and the science stack."""
    checks = [check_module("rclpy", "rclpy", ("ros-jazzy-rclpy", "ros-rclpy", "rclpy"))]
    if checks[0].ok:
        checks.append(check_rmw())
        checks.append(check_module("std_msgs", "std_msgs.msg", ("ros-std-msgs",)))
    checks += [
        check_module("torch", "torch", ("torch",), lambda m: m.__version__),
        check_module("pybullet", "pybullet", ("pybullet",)),
        check_module("OpenCV", "cv2", ("opencv-python-headless", "opencv-python"),
                     lambda m: m.__version__),
        check_module("numpy", "numpy", ("numpy",), lambda m: m.__version__),
    ]
    return checks


def check_rmw() -> Check:
    """The RMW implementation rclpy loaded."""
    try:
        from rclpy.utilities import get_rmw_implementation_identifier

        identifier = get_rmw_implementation_identifier()
    except Exception as exc:
        return Check("RMW implementation", False, f"cannot be determined ({exc}): run make venv")
    requested = os.environ.get("RMW_IMPLEMENTATION")
    source = f"RMW_IMPLEMENTATION={requested}" if requested else "default"
    return Check("RMW implementation", True, f"{identifier} ({source})")


def check_environment() -> list[Check]:
    """ROS_DOMAIN_ID and the discovery range, as the probes will inherit them."""
    checks = []
    raw = os.environ.get("ROS_DOMAIN_ID", "")
    if not raw:
        checks.append(Check("ROS_DOMAIN_ID", True, "0 (default)"))
    elif raw.isdigit() and int(raw) <= MAX_DOMAIN_ID:
        checks.append(Check("ROS_DOMAIN_ID", True, raw))
    else:
        checks.append(Check(
            "ROS_DOMAIN_ID", False, f"'{raw}' is not an integer in 0..{MAX_DOMAIN_ID}"
        ))
    scope = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "")
    if not scope:
        checks.append(Check("discovery range", True, "SUBNET (default)"))
    elif scope not in DISCOVERY_RANGES:
        checks.append(Check(
            "discovery range", False,
            f"ROS_AUTOMATIC_DISCOVERY_RANGE='{scope}' is not one of {', '.join(DISCOVERY_RANGES)}",
        ))
    elif scope == "OFF":
        checks.append(Check(
            "discovery range", False,
            "ROS_AUTOMATIC_DISCOVERY_RANGE=OFF: nodes in different processes cannot meet",
        ))
    else:
        checks.append(Check("discovery range", True, scope))
    notes = [f"{key}={os.environ[key]}" for key in (
        "FASTDDS_BUILTIN_TRANSPORTS", "ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS", PROFILE_ENV,
        NETWORK_ENV,
    ) if os.environ.get(key)]
    checks.append(Check("DDS settings", True, ", ".join(notes) or "no overrides"))
    return checks


def _probe_env(role: str) -> tuple[dict[str, str], str | None]:
    """Environment of one probe process; applies the test hook to the subscriber."""
    env = dict(os.environ)
    env["PYTHONUNBUFFERED"] = "1"
    offset = os.environ.get(SUB_DOMAIN_OFFSET_ENV)
    if role != "sub" or not offset:
        return env, None
    try:
        base = int(os.environ.get("ROS_DOMAIN_ID") or 0)
        domain = (base + int(offset)) % (MAX_DOMAIN_ID + 1)
    except ValueError:
        return env, f"{SUB_DOMAIN_OFFSET_ENV}={offset!r} ignored: not an integer"
    env["ROS_DOMAIN_ID"] = str(domain)
    return env, f"{SUB_DOMAIN_OFFSET_ENV}={offset}: subscriber on domain {domain}"


def _report(output: str) -> dict:
    for line in reversed(output.strip().splitlines()):
        with contextlib.suppress(ValueError):
            data = json.loads(line)
            if isinstance(data, dict):
                return data
    return {}


def profile_binding(path: str | None) -> str:
    """What the profile at ``path`` does with the UDPv4 interfaces, in a few words."""
    if not path:
        return "no profile: Fast DDS builtin transports on every interface"
    if path == str(profile_path()):
        return "profile binds 127.0.0.1 only (pushbot fastdds.xml)"
    if path == str(profile_path(network=True)):
        return "profile binds every interface (pushbot fastdds_network.xml)"
    try:
        text = open(path, encoding="utf-8").read()
    except OSError as exc:
        return f"profile {path} unreadable ({exc.strerror})"
    if "interfaceWhiteList" in text or "<allowlist>" in text:
        return f"profile {path} has an interface allowlist"
    return f"profile {path} has no interface allowlist"


def check_exposure(reports: list[dict]) -> Check:
    """The exposure verdict from the environment, the profile and the probes' sockets."""
    name = "DDS exposure"
    scope = os.environ.get(RANGE_ENV) or "SUBNET (default)"
    reason = network_reason()
    parts = [f"discovery {scope}", profile_binding(os.environ.get(PROFILE_ENV))]
    listed = [r["sockets"] for r in reports if isinstance(r.get("sockets"), list)]
    if not listed:
        why = next((r["sockets"] for r in reports if isinstance(r.get("sockets"), str)),
                   "the probes reported no sockets")
        detail = "; ".join(parts + [why])
        if reason:
            return Check(name, True, f"OPEN by choice ({reason}): {detail}")
        return Check(name, False, f"unverified: {detail}")
    sockets = {(s["address"], s["port"], s["receiving"]) for sockets in listed for s in sockets}
    exposed = sorted(f"{a}:{p}" for a, p, rx in sockets if rx and not _loopback(a))
    sending = sorted(f"{a}:{p}" for a, p, rx in sockets if not rx and not _loopback(a))
    receiving = sorted(f"{a}:{p}" for a, p, rx in sockets if rx and _loopback(a))
    parts.append("probe receives on " + (", ".join(exposed + receiving) or "no UDP socket"))
    if sending:
        parts.append("send sockets on " + ", ".join(sending))
    detail = "; ".join(parts)
    if reason:
        return Check(name, True, f"OPEN by choice ({reason}): {detail}. WARNING: DDS without "
                                 "security lets any peer on the network command the robot")
    if exposed:
        return Check(name, False, f'OPEN to the network: {detail}. Unset {RANGE_ENV} and '
                                  f'{PROFILE_ENV} for pushbot\'s loopback-only default, or '
                                  f'set {NETWORK_ENV}=1 if the network is meant (README, '
                                  '"Security")')
    if sending:
        hint = (f" (rmw_fastrtps adds them under {RANGE_ENV}=LOCALHOST; unset it for "
                "loopback-only sockets)") if os.environ.get(RANGE_ENV) == "LOCALHOST" else ""
        return Check(name, True, f"closed (DDS receives on loopback only): {detail}{hint}")
    return Check(name, True, f"closed (loopback only): {detail}")


def _loopback(address: str) -> bool:
    ip = ipaddress.ip_address(address)
    return ip.is_loopback or ip.is_multicast


def check_pubsub(timeout: float, count: int, reports: list[dict] | None = None) -> Check:
    """Exchange ``count`` messages between two fresh processes within ``timeout`` seconds.

    The probes' JSON reports are appended to ``reports`` when given.
    """
    name = "pub/sub (2 processes)"
    nonce = secrets.token_hex(6)
    hook = None
    procs: dict[str, subprocess.Popen] = {}
    start = time.monotonic()
    try:
        for role in ("sub", "pub"):  # subscriber first: it waits for the publisher
            env, note = _probe_env(role)
            hook = hook or note
            procs[role] = subprocess.Popen(
                [sys.executable, "-m", "pushbot.runner.doctor_probe", role, "--nonce", nonce,
                 "--count", str(count), "--timeout", str(timeout)],
                env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            )
        outputs = {}
        for role, proc in procs.items():
            # Generous margin over the probes' own deadline for interpreter start-up.
            budget = max(timeout + 15.0 - (time.monotonic() - start), 1.0)
            try:
                outputs[role] = proc.communicate(timeout=budget)
            except subprocess.TimeoutExpired:
                proc.kill()
                outputs[role] = proc.communicate()
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    elapsed = time.monotonic() - start
    sub, pub = _report(outputs["sub"][0]), _report(outputs["pub"][0])
    if reports is not None:
        reports += [sub, pub]
    suffix = f" [{hook}]" if hook else ""
    for role, report in (("sub", sub), ("pub", pub)):
        if "error" in report:
            return Check(name, False, f'{role} probe failed: {report["error"]}{suffix}')
        if not report:
            tail = outputs[role][1].strip().splitlines()[-3:]
            return Check(
                name, False,
                f"{role} probe exited with code {procs[role].returncode} without a report: "
                + (" | ".join(tail) or "no output") + suffix,
            )
    received = sub.get("received", 0)
    if received >= count and procs["sub"].returncode == 0:
        return Check(
            name, True,
            f'{received}/{count} messages with nonce {nonce} from pid {procs["pub"].pid} to '
            f'pid {procs["sub"].pid} in {elapsed:.1f} s{suffix}',
        )
    if not sub.get("matched") and not pub.get("matched"):
        why = "the two processes never discovered each other"
    elif received:
        why = f"only {received} of {count} messages arrived"
    else:
        why = "the processes matched but no message arrived"
    if received:
        detail = f"{why} within {timeout:g} s: {DISCOVERY_HINT}"
    else:
        detail = f"no message reached the subscriber within {timeout:g} s ({why}): {DISCOVERY_HINT}"
    return Check(name, False, detail + suffix)


def run_doctor(args: argparse.Namespace) -> int:
    """Run every check, print one line per check; 0 when all passed, 1 otherwise."""
    timeout = getattr(args, "timeout", DEFAULT_TIMEOUT)
    count = getattr(args, "count", DEFAULT_COUNT)
    print("pushbot doctor", flush=True)
    checks = check_versions()
    for check in checks:
        print(check.line(), flush=True)
    for check in check_environment():
        checks.append(check)
        print(check.line(), flush=True)
    rclpy_ok = checks[0].ok
    reports: list[dict] = []
    if rclpy_ok:
        pubsub = check_pubsub(timeout, count, reports)
    else:
        pubsub = Check("pub/sub (2 processes)", False, "skipped: rclpy cannot be imported")
    exposure = check_exposure(reports)
    for check in (pubsub, exposure):
        checks.append(check)
        print(check.line(), flush=True)
    failed = [c for c in checks if not c.ok]
    if failed:
        print(f"doctor: {len(failed)} of {len(checks)} checks FAILED: "
              + "; ".join(f"{c.name}: {c.detail}" for c in failed), flush=True)
        return 1
    print(f"doctor: all {len(checks)} checks passed", flush=True)
    return 0
