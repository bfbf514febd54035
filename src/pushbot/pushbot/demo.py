"""``pushbot demo`` (what ``make demo`` runs): for now, the most complete thing that exists.

This is a stand-in. It will be replaced by the closed-loop demo (sim_bridge, perception,
estimator and planner pushing an object to a goal) once those nodes land. Until then it:

1. runs ``pushbot doctor`` (versions and a real two-process publish/subscribe round trip);
2. prints a short summary of the object library when ``push_core.objects`` is importable
   (``library_names()`` and ``load_object(name)``), and says clearly when it is not there yet.
"""

from __future__ import annotations

import argparse
import importlib
from typing import Any

from pushbot.doctor import add_arguments as add_doctor_arguments
from pushbot.doctor import run_doctor


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot demo`` (for now those of ``doctor``)."""
    add_doctor_arguments(parser)


def _describe(spec: Any) -> str:
    """One line about an ``ObjectSpec``; tolerant of fields the library may not have yet."""
    parts = []
    shape = getattr(spec, 'shape', None)
    kind = getattr(shape, 'type', None) or getattr(shape, 'kind', None) or (
        type(shape).__name__ if shape is not None else None)
    if kind:
        parts.append(str(kind))
    area = getattr(spec, 'area', None)
    area = area() if callable(area) else area
    if isinstance(area, (int, float)):
        parts.append(f'area={area * 1e4:.3g} cm^2')
    for field, unit, scale in (('mass', 'kg', 1.0), ('thickness', 'mm', 1000.0),
                               ('friction_table', '', 1.0), ('friction_pusher', '', 1.0)):
        value = getattr(spec, field, None)
        if isinstance(value, (int, float)):
            parts.append(f'{field}={value * scale:.3g}{" " + unit if unit else ""}')
    return ', '.join(parts) or repr(spec)


def print_object_library() -> int:
    """Print the bundled object library; 0 if printed or not available yet, 1 on errors."""
    try:
        objects = importlib.import_module('push_core.objects')
    except ModuleNotFoundError as exc:
        if exc.name not in ('push_core', 'push_core.objects'):
            raise
        print('object library: push_core.objects is not available yet (issue in progress); '
              'nothing to show')
        return 0
    try:
        names = list(objects.library_names())
    except AttributeError:
        print('object library: push_core.objects has no library_names() yet; nothing to show')
        return 0
    print(f'object library: {len(names)} objects')
    status = 0
    for name in names:
        try:
            spec = objects.load_object(name)
        except (ValueError, OSError) as exc:
            print(f'  {name:<12} FAILED to load: {exc}')
            status = 1
            continue
        print(f'  {name:<12} {_describe(spec)}')
    return status


def run_demo(args: argparse.Namespace) -> int:
    """Run the placeholder demo; see the module docstring."""
    print('pushbot demo: the closed-loop pushing demo is not built yet; running the install '
          'check and showing the object library instead.\n', flush=True)
    status = run_doctor(args)
    if status != 0:
        print('pushbot demo: doctor failed (see above); fix the install first.')
        return status
    print()
    return print_object_library()
