"""One line naming the machine a figure was measured on (benchmarks, model cards, reports)."""

from __future__ import annotations

import os
import platform
import socket

__all__ = ["machine_info"]


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _version(module: str) -> str:
    try:
        return __import__(module).__version__
    except ImportError:
        return "not installed"


def machine_info() -> str:
    """One line describing the machine and software the figures were measured on.

    Returns
    -------
    str
        Hostname, CPU model (``/proc/cpuinfo``), logical core count (and how many this process
        may use), Python, numpy and torch versions.
    """
    cores = os.cpu_count()
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else cores
    return (
        f"{socket.gethostname()}, {_cpu_model()}, {cores} logical cores ({usable} usable), "
        f"Python {platform.python_version()}, numpy {_version('numpy')}, "
        f"torch {_version('torch')}"
    )
