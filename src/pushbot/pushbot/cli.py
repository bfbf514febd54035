"""The ``pushbot`` command line (console script ``pushbot = pushbot.cli:main``).

Subcommands:

- ``doctor``: check the install (versions, RMW, DDS settings, a two-process pub/sub round trip);
- ``run <node> [args...]``: start a node as ``ros2 run`` would (``--list`` lists them);
- ``topic list|echo|hz|info``: inspect the ROS graph (``ros2 topic`` is not on PyPI);
- ``demo``: what ``make demo`` runs;
- ``data <target>``, ``train <target>``, ``eval <target>``: data generation, training and
  evaluation of the learned and estimated parts (targets in :data:`TARGETS`).

Every subcommand runs with the project's Fast DDS profile (``pushbot.dds``) unless
``FASTRTPS_DEFAULT_PROFILES_FILE`` is already set.

Heavy imports (rclpy, torch) happen inside the subcommands, so ``pushbot --help`` always works
and missing dependencies are reported by ``pushbot doctor`` instead of a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.metadata
import sys
from collections.abc import Sequence

from pushbot import dds, demo, doctor, nodes, topic


def _version() -> str:
    try:
        return importlib.metadata.version('pushbot')
    except importlib.metadata.PackageNotFoundError:
        return 'unknown'


#: Subcommand groups whose targets live in :mod:`pushbot.experiments` (and
#: :mod:`pushbot.evaluate`), not in the node packages: group -> (summary, {target:
#: (module, summary)}). Each module defines ``add_arguments(parser)`` and ``run(args) -> int``
#: and keeps heavy imports (torch, pybullet, rclpy) inside ``run``, so ``pushbot --help`` stays
#: fast and works even when those are broken.
TARGETS: dict[str, tuple[str, dict[str, tuple[str, str]]]] = {
    'data': ('generate training data sets', {
        'perception': ('pushbot.experiments.perception_data',
                       'render RGB-D frames with masks, poses and outlines (segmentation CNN)'),
        'affordances': ('pushbot.experiments.affordance_data',
                        'pybullet pushes: 20 contact points x 10 representative pushes per '
                        'object sample (learned affordances)'),
    }),
    'train': ('train learned models', {
        'segmentation': ('pushbot.experiments.perception_training',
                         'train the two-stage segmentation CNN on `pushbot data perception` data'),
        'affordances': ('pushbot.experiments.affordance_training',
                        'train the learned affordance CNN on `pushbot data affordances` data'),
    }),
    'eval': ('evaluate components on held-out objects', {
        'perception': ('pushbot.experiments.perception_evaluation',
                       'mask IoU, pose, orientation, outline accuracy and latency (tri1, butter, '
                       'hex)'),
        'estimator': ('pushbot.experiments.estimator_evaluation',
                      'COM, l and m estimation and NEES/NIS of the EKF on pybullet (butter, '
                      'tri1, hex)'),
        'push': ('pushbot.evaluate',
                 'the closed-loop experiments of SPEC section 5 in-process (success, steps, end '
                 'error; Figs. 5.5-5.7, Tables 5.1-5.2; --ray, --graph)'),
        'pusht': ('pushbot.experiments.pusht', 'the planner on gym-pusht Push-T (issue 16)'),
    }),
}


def _add_targets(sub: argparse._SubParsersAction) -> None:
    for group, (summary, targets) in TARGETS.items():
        parser = sub.add_parser(group, help=summary, description=summary)
        group_sub = parser.add_subparsers(dest='target', metavar='<target>')
        group_sub.required = True
        for target, (module_name, help_text) in targets.items():
            module = importlib.import_module(module_name)
            p = group_sub.add_parser(target, help=help_text, description=module.__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
            module.add_arguments(p)
            p.set_defaults(handler=module.run)


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog='pushbot',
        description='Vision-based planar pushing on ROS 2 Jazzy: tools for the pip install.',
    )
    parser.add_argument('--version', action='version', version=f'pushbot {_version()}')
    sub = parser.add_subparsers(dest='command', metavar='<command>')
    sub.required = True

    for name, module, handler, summary, extra in (
        ('doctor', doctor, doctor.run_doctor,
         'check the install: versions, RMW, DDS settings, pub/sub round trip', {}),
        ('run', nodes, nodes.run_node,
         'start a node like `ros2 run` (arguments, --ros-args included, pass through)',
         {'usage': 'pushbot run [-h] [--list] [<pkg>] <node> [args ...]'}),
        ('topic', topic, topic.run_topic,
         'inspect topics: list, echo, hz, info (like `ros2 topic`)', {}),
        ('demo', demo, demo.run_demo,
         'what `make demo` runs: doctor, then one pushing episode through the ROS graph',
         {}),
    ):
        p = sub.add_parser(name, help=summary, description=module.__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter, **extra)
        module.add_arguments(p)
        p.set_defaults(handler=handler)
    _add_targets(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv`` (default: ``sys.argv[1:]``) and run the subcommand; returns the exit code."""
    args = build_parser().parse_args(argv)
    # Every process pushbot starts (nodes, doctor probes, topic tools) uses the project's DDS
    # profile unless the user configured one (see pushbot.dds).
    dds.apply_default_profile()
    try:
        return args.handler(args)
    except KeyboardInterrupt:
        print('interrupted', file=sys.stderr)
        return 130
    except Exception as exc:
        # rclpy's SIGINT handler shuts the context down; spinning then raises this.
        if type(exc).__name__ != 'ExternalShutdownException':
            raise
        print('interrupted', file=sys.stderr)
        return 130


if __name__ == '__main__':
    sys.exit(main())
