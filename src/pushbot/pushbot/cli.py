"""The ``pushbot`` command line (console script ``pushbot = pushbot.cli:main``).

Subcommands:

- ``doctor``: check the install (versions, RMW, DDS settings, a two-process pub/sub round trip);
- ``run <node> [args...]``: start a node as ``ros2 run`` would (``--list`` lists them);
- ``up``: the whole graph as separate processes until Ctrl-C (``ros2 launch`` is not on PyPI);
- ``topic list|echo|hz|info|pub``, ``node list|info``, ``param list|get|set|dump``,
  ``service list|call``: inspect and drive the ROS graph (``ros2cli`` is not on PyPI);
- ``goal X Y YAW [--wait]``: send a goal to ``planner_node`` and follow it;
- ``demo``: what ``make demo`` runs;
- ``data <target>``, ``train <target>``, ``eval <target>``: data generation, training and
  evaluation of the learned and estimated parts (targets in :data:`TARGETS`).

Every subcommand runs with the project's Fast DDS profile (``push_ros.dds``) unless
``FASTRTPS_DEFAULT_PROFILES_FILE`` is already set.

Commands are loaded on demand: :data:`COMMANDS` and :data:`TARGETS` name each command's module
and hold its one-line help, and :func:`main` imports only the module of the command it runs
(also for that command's ``--help``), so ``pushbot --help`` imports no command module; heavy
imports (rclpy, torch) happen inside the commands, so ``pushbot --help`` always works and missing
dependencies are reported by ``pushbot doctor`` instead of a traceback. Help texts come from the
modules' docstrings through :func:`plain_help` (reStructuredText markup removed); every
option's default is shown (:class:`HelpFormatter`). A closed output pipe
(``pushbot topic echo X | head -3``) ends the command quietly with status 141, handled once
here.

Bad input ends in one line on stderr and exit status 2, for every command: a malformed command
line (:meth:`Parser.error`) and a value the command refuses (a ``ValueError`` or a file-system
error such as a missing or unwritable path, raised by the handler), handled once in
:func:`main` as ``pushbot <command> [<target>]: <reason>``. ``PUSHBOT_TRACEBACK=1`` shows the
traceback instead (for bug reports).
"""

from __future__ import annotations

import argparse
import importlib
import importlib.metadata
import os
import re
import signal
import sys
import typing
from collections.abc import Collection, Sequence

#: Exit status after a closed output pipe: 128 + SIGPIPE, what a shell reports for a command
#: killed by it.
EXIT_BROKEN_PIPE = 141
#: Exit status of bad input (a malformed command line or a refused value), as argparse uses.
EXIT_BAD_INPUT = 2
#: Errors of a handler that mean bad input (one line, exit 2) rather than a bug.
BAD_INPUT_ERRORS = (ValueError, FileNotFoundError, FileExistsError, NotADirectoryError,
                    IsADirectoryError, PermissionError)


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions kept as written; every option's help ends with its default.

    ``(default: X)`` is appended unless the help already names its default, the option is a
    flag (takes no value), the default is ``None`` (unset) or suppressed, or the argument is a
    required positional.
    """

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if ("default" in text.lower() or default is None or action.nargs == 0
                or default is argparse.SUPPRESS or action.required
                or (not action.option_strings and action.nargs not in ("?", "*"))):
            return text
        if isinstance(default, (list, tuple)):
            shown = " ".join(str(d) for d in default)
            shown = shown.replace("%", "%%")
            return f"{text} (default: {shown})" if text else f"default: {shown}"
        return f"{text} (default: %(default)s)" if text else "default: %(default)s"


class Parser(argparse.ArgumentParser):
    """The argument parser of every ``pushbot`` (sub)command: :class:`HelpFormatter` by default,
    subparsers of the same class, and a one-line error (``pushbot X: error: ... (see pushbot X
    --help)``) with exit status 2 instead of argparse's usage block."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]

    def error(self, message: str) -> typing.NoReturn:  # noqa: D102 - argparse's contract
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _version() -> str:
    try:
        return importlib.metadata.version("pushbot")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


#: The commands: name -> (module, handler, one-line help, extra ``add_parser`` arguments), in
#: the order ``pushbot --help`` lists them. Each module defines ``add_arguments(parser)`` and
#: the handler ``(args) -> int``; it is imported only when its command runs (:func:`main`).
COMMANDS: dict[str, tuple[str, str, str, dict[str, str]]] = {
    "doctor": ("pushbot.runner.doctor", "run_doctor",
               "check the install: versions, RMW, DDS settings, pub/sub round trip", {}),
    "run": ("pushbot.runner.run", "run_node",
            "start a node like `ros2 run` (arguments, --ros-args included, pass through)",
            {"usage": "pushbot run [-h] [--list] [<pkg>] <node> [args ...]"}),
    "up": ("pushbot.runner.up", "run_up",
           "start the whole graph as separate processes until Ctrl-C (like `ros2 launch`)", {}),
    "topic": ("pushbot.ros2cli.topic", "run_topic",
              "inspect and publish topics: list, echo, hz, info, pub (like `ros2 topic`)", {}),
    "node": ("pushbot.ros2cli.node", "run_rosnode",
             "list the nodes, show their endpoints (like `ros2 node`)", {}),
    "param": ("pushbot.ros2cli.param", "run_param",
              "list, get, set and dump a node's parameters (like `ros2 param`)", {}),
    "service": ("pushbot.ros2cli.service", "run_service",
                "list and call services (like `ros2 service`)", {}),
    "goal": ("pushbot.runner.goal", "run_goal",
             "send a goal pose to planner_node; --wait follows it to the end", {}),
    "calibrate": ("pushbot.runner.calibrate", "run_calibrate",
                  "the camera's pose in world from the arm showing it a board (--serve: "
                  "publish it)", {}),
    "bag": ("pushbot.ros2cli.bag", "run_bag",
            "record, inspect and play rosbag2 (MCAP) folders (like `ros2 bag`)", {}),
    "replay": ("pushbot.experiments.replay", "run_replay",
               "render a recorded episode bag to an MP4 (and GIF) with overlays and a legend", {}),
    "view": ("pushbot.viz.view", "run_view",
             "serve the live topics to Foxglove over its WebSocket protocol", {}),
    "demo": ("pushbot.runner.demo", "run_demo",
             "what `make demo` runs: doctor, then one pushing episode through the ROS graph", {}),
}

#: Subcommand groups whose targets live in :mod:`pushbot.experiments`, not in the node
#: packages: group -> (summary, {target: (module, summary)}). Each module defines
#: ``add_arguments(parser)`` and ``run(args) -> int``, is imported only when its target runs,
#: and keeps heavy imports (torch, pybullet, rclpy) inside ``run``.
TARGETS: dict[str, tuple[str, dict[str, tuple[str, str]]]] = {
    "data": ("generate training data sets", {
        "perception": ("pushbot.experiments.perception_data",
                       "render RGB-D frames with masks, poses and outlines (segmentation CNN)"),
        "affordances": ("pushbot.experiments.affordance_data",
                        "pybullet pushes: 20 contact points x 10 representative pushes per "
                        "object sample (learned affordances)"),
        "record": ("pushbot.experiments.site_record",
                   "record a site's frames from live camera topics, labelled by the depth "
                   "segmentation and checked across frames (site adaptation)"),
    }),
    "train": ("train learned models", {
        "segmentation": ("pushbot.experiments.perception_training",
                         "train the two-stage segmentation CNN on `pushbot data perception` data"),
        "affordances": ("pushbot.experiments.affordance_training",
                        "train the learned affordance CNN on `pushbot data affordances` data"),
    }),
    "eval": ("evaluate components on held-out objects", {
        "perception": ("pushbot.experiments.perception_evaluation",
                       "mask IoU, pose, orientation, outline accuracy and latency (tri1, butter, "
                       "hex)"),
        "estimator": ("pushbot.experiments.estimator_evaluation",
                      "COM, l and m estimation and NEES/NIS of the EKF on pybullet (butter, "
                      "tri1, hex)"),
        "push": ("pushbot.experiments.evaluate",
                 "the closed-loop experiments of the source in-process (success, steps, end "
                 "error; Figs. 5.5-5.7, Tables 5.1-5.2; --ray, --graph)"),
        "calibrate": ("pushbot.experiments.calibration_evaluation",
                      "pushbot calibrate on the simulator against the placed camera's truth, "
                      "and paired pushing episodes on the calibrated vs the true extrinsics"),
        "pusht": ("pushbot.experiments.pusht.cli",
                  "the planner on gym-pusht Push-T next to Diffusion Policy"),
    }),
}


_ROLE = re.compile(r":[a-z]+:`~?([^`<]*?)(?:\s*<[^>]*>)?`")
_LITERAL = re.compile(r"``([^`]+)``")


def plain_help(docstring: str | None) -> str | None:
    """A module docstring as plain help text: reStructuredText roles and literals unmarked.

    ``:mod:`push_ros.dds``` -> ``push_ros.dds``, ``:func:`~a.b``` -> ``b``, double backquotes
    removed; everything else (paragraphs, lists, indentation) is kept for
    ``RawDescriptionHelpFormatter``.
    """
    if docstring is None:
        return None

    def role(match: re.Match[str]) -> str:
        text = match.group(1)
        return text.rsplit(".", 1)[-1] if match.group(0).split("`")[1].startswith("~") else text

    return _LITERAL.sub(r"\1", _ROLE.sub(role, docstring)).strip()


def _group_doctor_options(parser: argparse.ArgumentParser) -> None:
    """Show the doctor's options (added first by ``pushbot.runner.demo``) after the demo's own,
    in a group of their own; parsing is unchanged."""
    probe = argparse.ArgumentParser(add_help=False)
    importlib.import_module(COMMANDS["doctor"][0]).add_arguments(probe)
    doctor_dests = {action.dest for action in probe._actions}
    group = parser.add_argument_group("doctor options (the check before the episode)")
    optionals = parser._optionals._group_actions
    for action in [a for a in optionals if a.dest in doctor_dests and a.dest != "help"]:
        optionals.remove(action)
        group._group_actions.append(action)
        parser._actions.remove(action)  # the usage line lists them last too
        parser._actions.append(action)


def _load(parser: argparse.ArgumentParser, module_name: str, handler: str) -> None:
    """Import a command's module and give ``parser`` its description, arguments and handler."""
    module = importlib.import_module(module_name)
    parser.description = plain_help(module.__doc__)
    module.add_arguments(parser)
    parser.set_defaults(handler=getattr(module, handler))


def _add_targets(sub: argparse._SubParsersAction, load: Collection[str] | None) -> None:
    for group, (summary, targets) in TARGETS.items():
        parser = sub.add_parser(group, help=summary, description=summary)
        group_sub = parser.add_subparsers(dest="target", metavar="<target>")
        group_sub.required = True
        for target, (module_name, help_text) in targets.items():
            p = group_sub.add_parser(target, help=help_text)
            if load is None or f"{group} {target}" in load:
                _load(p, module_name, "run")


def selected_commands(argv: Sequence[str]) -> set[str]:
    """The command a command line names, as :func:`build_parser` takes it.

    The first argument that is not an option is the command (``pushbot`` itself takes only
    ``-h`` and ``--version``); for a group (``data``, ``train``, ``eval``) the next such argument
    is its target, named ``'<group> <target>'``. Empty when there is none (``pushbot --help``).
    """
    words = [a for a in argv if not a.startswith("-")]
    if not words:
        return set()
    if words[0] in TARGETS and len(words) > 1:
        return {words[0], f"{words[0]} {words[1]}"}
    return {words[0]}


def build_parser(load: Collection[str] | None = None) -> argparse.ArgumentParser:
    """The argument parser of every command.

    Parameters
    ----------
    load : collection of str, optional
        The commands whose modules are imported for their arguments and handler (names as
        :func:`selected_commands` returns them); the others get a parser with their one-line
        help only. ``None`` (default): every command, as the CLI reference and the tests read
        them.

    Returns
    -------
    argparse.ArgumentParser
        The ``pushbot`` parser; a loaded command's parser sets ``handler`` in the namespace.
    """
    parser = Parser(
        prog="pushbot",
        description="Vision-based planar pushing on ROS 2 Jazzy: tools for the pip install.",
    )
    parser.add_argument("--version", action="version", version=f"pushbot {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="<command>")
    sub.required = True

    for name, (module_name, handler, summary, extra) in COMMANDS.items():
        p = sub.add_parser(name, help=summary, **extra)
        if load is None or name in load:
            _load(p, module_name, handler)
            if name == "demo":
                _group_doctor_options(p)
    _add_targets(sub, load)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv`` (default: ``sys.argv[1:]``) and run the subcommand; returns the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser(selected_commands(argv)).parse_args(argv)
    from push_ros import dds  # after parsing: --help and --version need neither numpy nor ROS
    # Every process pushbot starts (nodes, doctor probes, topic tools) uses the project's DDS
    # profile unless the user configured one (see push_ros.dds).
    dds.apply_default_profile()
    # A shell starts background jobs (`cmd &` in a script) with SIGINT ignored, and Python then
    # installs no Ctrl-C handler: take SIGINT explicitly, once for every subcommand, so that
    # `kill -INT` stops `pushbot up`, `bag record`, `view`, `demo` ... in every case.
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        status = args.handler(args)
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's final flush
        return status
    except BrokenPipeError:
        return _closed_pipe()
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BAD_INPUT_ERRORS as exc:
        if os.environ.get("PUSHBOT_TRACEBACK"):
            raise
        return _bad_input(args, exc)
    except Exception as exc:
        # rclpy's SIGINT handler shuts the context down; spinning then raises this.
        if type(exc).__name__ != "ExternalShutdownException":
            raise
        print("interrupted", file=sys.stderr)
        return 130


def _bad_input(args: argparse.Namespace, exc: BaseException) -> int:
    """One line on stderr naming the command and the reason; the exit status of bad input."""
    command = " ".join(str(part) for part in (args.command, getattr(args, "target", None))
                       if part)
    reason = " ".join(str(exc).split()) or type(exc).__name__
    print(f"pushbot {command}: {reason}", file=sys.stderr)
    return EXIT_BAD_INPUT


def _closed_pipe() -> int:
    """The reader of stdout went away (``| head``): stop quietly. stdout is pointed at
    /dev/null so the interpreter's final flush does not raise a second BrokenPipeError."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):
        pass
    return EXIT_BROKEN_PIPE


if __name__ == "__main__":
    sys.exit(main())
