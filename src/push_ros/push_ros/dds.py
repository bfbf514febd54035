"""The project's DDS rule: one for every way a node is started (console script, ``ros2 run``,
the launch file, ``pushbot``) and for the tests.

The bundled profile (``push_ros/data/fastdds.xml``; its comment explains every setting) gives
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
:func:`apply_default_profile` must run before ``rclpy.init``: :func:`push_ros.node.run_node`
(every node's ``main()``) does, ``pushbot`` does for its children, the launch file passes
:func:`dds_environment` to every node. Values the user already set win; :func:`describe` says
in one line what is in effect (each node logs it at start-up).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping, MutableMapping
from importlib import resources
from pathlib import Path

__all__ = ["BUILTIN_ENV", "CLOSED_PROFILE", "CLOSED_RANGE", "NETWORK_ENV", "NETWORK_PROFILE",
           "NETWORK_WARNING", "PROFILE_ENV", "RANGE_ENV", "apply_default_profile", "describe",
           "dds_environment", "network_reason", "profile_path"]

PROFILE_ENV = "FASTRTPS_DEFAULT_PROFILES_FILE"
RANGE_ENV = "ROS_AUTOMATIC_DISCOVERY_RANGE"
NETWORK_ENV = "PUSHBOT_DDS_NETWORK"
#: The range pushbot sets with its closed profile: the profile alone decides discovery.
CLOSED_RANGE = "SYSTEM_DEFAULT"
CLOSED_PROFILE = "fastdds.xml"
NETWORK_PROFILE = "fastdds_network.xml"
NETWORK_WARNING = (
    'pushbot: the DDS graph is OPEN TO THE NETWORK ({reason}). DDS without security lets any '
    'peer that reaches this machine discover the nodes and command the robot (goals, pushes, '
    'parameters); see README, "Security". Unset it for a loopback-only graph.'
)
_TRUE = ("1", "true", "yes", "on")
_warned = False


def profile_path(network: bool = False) -> Path:
    """Path of a bundled Fast DDS profile: loopback only (default) or open to the network."""
    name = NETWORK_PROFILE if network else CLOSED_PROFILE
    return Path(str(resources.files("push_ros").joinpath("data", name)))


def network_reason(environ: Mapping[str, str] | None = None) -> str | None:
    """Why the graph is opened to the network (the explicit setting), or None: closed."""
    environ = os.environ if environ is None else environ
    if environ.get(NETWORK_ENV, "").strip().lower() in _TRUE:
        return f"{NETWORK_ENV}={environ[NETWORK_ENV]}"
    if environ.get(RANGE_ENV) == "SUBNET":
        return f"{RANGE_ENV}=SUBNET"
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


BUILTIN_ENV = "FASTDDS_BUILTIN_TRANSPORTS"


def describe(environ: Mapping[str, str] | None = None) -> str:
    """One line: the DDS profile in effect and what it means for the user's own settings."""
    environ = os.environ if environ is None else environ
    path = environ.get(PROFILE_ENV, "")
    if not path:
        text = ("DDS: no profile (Fast DDS defaults: large camera frames may be lost between "
                "processes)")
    elif path in (str(profile_path()), str(profile_path(network=True))):
        kind = "open to the network" if path == str(profile_path(network=True)) else "loopback only"
        text = f"DDS: bundled profile {path} ({kind})"
        if environ.get(BUILTIN_ENV):
            text += (f"; {BUILTIN_ENV}={environ[BUILTIN_ENV]} has no effect under it (the profile "
                     "declares its own transports)")
    else:
        text = f"DDS: the user's profile {path}"
    return text + f', {RANGE_ENV}={environ.get(RANGE_ENV, "(unset)")}'
