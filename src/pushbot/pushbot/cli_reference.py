"""The docs/CLI.md's command reference, generated from the ``pushbot`` argument parsers.

Every option of every ``pushbot`` command is listed in ``docs/CLI.md`` between the markers
``<!-- BEGIN cli-reference -->`` and ``<!-- END cli-reference -->``; the text is generated here
from :func:`pushbot.cli.build_parser` (the same parsers and help strings ``--help`` prints), and
``tests/test_cli.py`` checks that docs/CLI.md holds exactly this text, so the reference cannot
drift from the code. After changing an option, regenerate it::

    .venv/bin/python -m pushbot.cli_reference docs/CLI.md
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path

BEGIN = "<!-- BEGIN cli-reference -->"
END = "<!-- END cli-reference -->"


def _leaf_parsers(parser: argparse.ArgumentParser, path: tuple[str, ...]
                  ) -> Iterator[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    """(command path, parser) of every parser that takes options, depth first, in the order
    ``--help`` lists them."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if len(path) > 1 or not subs:
        yield path, parser
    for action in subs:
        for name, sub in action.choices.items():
            yield from _leaf_parsers(sub, (*path, name))


def _help(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    formatter = parser._get_formatter()
    text = formatter._expand_help(action) if action.help else ""
    return re.sub(r"\s+", " ", text).strip()


def _signature(action: argparse.Action, parser: argparse.ArgumentParser) -> str:
    formatter = parser._get_formatter()
    if not action.option_strings:
        return formatter._get_default_metavar_for_positional(action) if action.metavar is None \
            else (action.metavar if isinstance(action.metavar, str) else " ".join(action.metavar))
    if action.nargs == 0:
        return ", ".join(action.option_strings)
    args = formatter._format_args(action, formatter._get_default_metavar_for_optional(action))
    return ", ".join(f"{o} {args}" for o in action.option_strings)


def reference_markdown() -> str:
    """The command reference: one line per command and one bullet per argument.

    Returns
    -------
    str
        Markdown, without the BEGIN/END markers; positional arguments are listed with their
        metavar, options with every spelling and their argument (``--rate R``); ``-h`` is left
        out (every command has it).
    """
    from pushbot.cli import build_parser

    lines: list[str] = []
    for path, parser in _leaf_parsers(build_parser(), ("pushbot",)):
        actions = [a for a in parser._actions
                   if not isinstance(a, (argparse._HelpAction, argparse._SubParsersAction,
                                         argparse._VersionAction))]
        if not actions:
            continue
        lines.append(f'- `{" ".join(path)}`')
        for action in actions:
            help_text = _help(parser, action)
            entry = f"  - `{_signature(action, parser)}`"
            lines.append(f"{entry}: {help_text}" if help_text else entry)
    return "\n".join(lines) + "\n"


def readme_section(text: str) -> str | None:
    """The text between the markers in ``text`` (None without them)."""
    match = re.search(re.escape(BEGIN) + r"\n(.*?)" + re.escape(END), text, flags=re.S)
    return match.group(1) if match else None


def main(argv: Sequence[str] | None = None) -> int:
    """Rewrite the reference section of docs/CLI.md given as the only argument."""
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 1:
        print("usage: python -m pushbot.cli_reference docs/CLI.md", file=sys.stderr)
        return 2
    path = Path(args[0])
    text = path.read_text(encoding="utf-8")
    if readme_section(text) is None:
        print(f"{path}: no {BEGIN} ... {END} section", file=sys.stderr)
        return 2
    new = re.sub(re.escape(BEGIN) + r"\n.*?" + re.escape(END),
                 lambda _: f"{BEGIN}\n{reference_markdown()}{END}", text, flags=re.S)
    path.write_text(new, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
