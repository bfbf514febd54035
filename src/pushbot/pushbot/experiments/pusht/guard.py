"""The guard of ``pushbot eval pusht --object-model estimated``: the env's bodies and shapes sealed.

With the estimated object model the adapter may use what a robot would have: the observation
(the image or the state's pose), the task's goal, and its own pusher (radius, controller). It
must not read the env's physics objects: the T's shapes, centre of gravity, mass or moment,
nor the agent's body and shape. :class:`SealedEnv` wraps a gym-pusht env and, after every
``reset`` (which builds new pymunk objects), replaces the env's ``block``, ``agent``, ``space``
and ``_block_shapes`` attributes with :class:`Sealed` proxies: the env's own code (modules of
``gym_pusht``, ``pymunk`` and ``gymnasium``) reads and writes through them as before, any other
caller's attribute read or write raises :class:`EnvInternalsAccess`. A test runs estimated-model
episodes under the seal (they succeed) and checks that a read from outside does trip it.
"""

from __future__ import annotations

import inspect
from typing import Any

__all__ = ["ALLOWED_MODULES", "SEALED_ATTRIBUTES", "EnvInternalsAccess", "Sealed", "SealedEnv"]

#: Module-name prefixes whose code may use the sealed objects: the env and its libraries.
ALLOWED_MODULES = ("gym_pusht", "pymunk", "gymnasium")
#: Attributes of the unwrapped env that are sealed after each reset.
SEALED_ATTRIBUTES = ("block", "agent", "space", "_block_shapes")


class EnvInternalsAccess(RuntimeError):
    """A read or write of a sealed env object from outside the env's own code."""


def _allowed(depth: int) -> bool:
    """Whether the code ``depth`` frames above the caller belongs to an allowed module."""
    frame = inspect.currentframe()
    for _ in range(depth + 1):
        frame = frame.f_back if frame is not None else None
    name = frame.f_globals.get("__name__", "") if frame is not None else ""
    return name.split(".")[0] in ALLOWED_MODULES


class Sealed:
    """A proxy of one env object (see the module docstring); ``what`` names it in errors."""

    __slots__ = ("_sealed_target", "_sealed_what")

    def __init__(self, target: object, what: str) -> None:
        object.__setattr__(self, "_sealed_target", target)
        object.__setattr__(self, "_sealed_what", what)

    def _refuse(self, name: str) -> EnvInternalsAccess:
        what = object.__getattribute__(self, "_sealed_what")
        return EnvInternalsAccess(f"the env's {what}.{name} is sealed (object model "
                                  "'estimated': the adapter may not read the env's bodies or "
                                  "shapes)")

    def __getattr__(self, name: str) -> Any:
        if not _allowed(1):
            raise self._refuse(name)
        return getattr(object.__getattribute__(self, "_sealed_target"), name)

    def __setattr__(self, name: str, value: object) -> None:
        if not _allowed(1):
            raise self._refuse(name)
        setattr(object.__getattribute__(self, "_sealed_target"), name, value)

    def __iter__(self) -> Any:
        if not _allowed(1):
            raise self._refuse("__iter__")
        return iter(object.__getattribute__(self, "_sealed_target"))

    def __len__(self) -> int:
        if not _allowed(1):
            raise self._refuse("__len__")
        return len(object.__getattribute__(self, "_sealed_target"))


class SealedEnv:
    """A gym-pusht env whose bodies and shapes are sealed after every reset.

    Forwards ``reset``, ``step``, ``render``, ``close``, the spaces and ``unwrapped`` (whose
    controller constants ``k_p``, ``k_v``, ``dt``, ``control_hz`` and ``goal_pose`` stay
    readable: the pusher's own controller and the task).
    """

    def __init__(self, env: Any) -> None:
        self._env = env

    @property
    def unwrapped(self) -> Any:
        """The env itself (its physics objects sealed once it has been reset)."""
        return self._env.unwrapped

    @property
    def action_space(self) -> Any:
        return self._env.action_space

    @property
    def observation_space(self) -> Any:
        return self._env.observation_space

    def reset(self, **kwargs: Any) -> tuple[Any, dict]:
        """The env's reset, then the seal on the objects it built."""
        out = self._env.reset(**kwargs)
        u = self._env.unwrapped
        for name in SEALED_ATTRIBUTES:
            value = u.__dict__.get(name)
            if value is not None and not isinstance(value, Sealed):
                u.__dict__[name] = Sealed(value, name)
        return out

    def step(self, action: Any) -> tuple:
        return self._env.step(action)

    def render(self) -> Any:
        return self._env.render()

    def close(self) -> None:
        self._env.close()
