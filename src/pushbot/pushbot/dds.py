"""The project's default DDS settings for processes started by ``pushbot`` and by the tests.

The bundled profile (``pushbot/data/fastdds.xml``; its comment explains every setting) gives
each participant shared-memory segments of 32 MB and UDPv4 sockets with 4 MB buffers, so that
640 x 480 camera images (2.1 MB per frame) reach other processes, and 100 ms heartbeats for
reliable writers. It replaces Fast DDS's builtin transports, so ``FASTDDS_BUILTIN_TRANSPORTS``
has no effect on processes that use it.

Fast DDS reads ``FASTRTPS_DEFAULT_PROFILES_FILE`` when a participant is created, so
:func:`apply_default_profile` must run before ``rclpy.init``. A value the user already set
wins.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping
from importlib import resources
from pathlib import Path

PROFILE_ENV = 'FASTRTPS_DEFAULT_PROFILES_FILE'


def profile_path() -> Path:
    """Path of the bundled Fast DDS profile (``pushbot/data/fastdds.xml``)."""
    return Path(str(resources.files('pushbot').joinpath('data', 'fastdds.xml')))


def apply_default_profile(env: MutableMapping[str, str] | None = None) -> str:
    """Point Fast DDS at the bundled profile unless a profile is already configured.

    Parameters
    ----------
    env : mapping, optional
        Environment to update (default ``os.environ``, inherited by child processes).

    Returns
    -------
    str
        The profile file in effect.
    """
    env = os.environ if env is None else env
    if not env.get(PROFILE_ENV):
        env[PROFILE_ENV] = str(profile_path())
    return env[PROFILE_ENV]
