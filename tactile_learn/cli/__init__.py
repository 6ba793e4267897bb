"""``tactile-learn``: one entry point, one small module per subcommand.

Every subcommand module defines ``HELP`` (one line), ``EXAMPLES`` (shown in its ``--help``),
``add_arguments(parser)`` and ``run(args) -> int``. :func:`main` turns any
:class:`~synth.errors.TactileError` into a one-line message and exit code 2, so scripts and tests
get a clear failure instead of a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from synth import __version__
from synth.errors import TactileError

__all__ = ["main"]

SUBCOMMANDS = (
    "generate",
    "simulate",
    "eval",
    "train",
    "export",
    "bench",
    "run",
    "calibrate",
    "adapt",
    "scenes",
    "materials",
    "sweep",
    "cards",
    "objects",
    "learn-object",
    "demo",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="tactile-learn",
        description="Simulate soft tactile and thermal sensors; invert their readings with classical and "
        "learned methods.",
        epilog="Run 'tactile-learn COMMAND --help' for a command's options and examples.",
    )
    parser.add_argument("--version", action="version", version=f"tactile-learn {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMANDS:
        module = importlib.import_module(f"tactile_learn.cli.{name.replace('-', '_')}")
        p = sub.add_parser(
            name,
            help=module.HELP,
            description=module.HELP,
            epilog="examples:\n" + module.EXAMPLES,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(list(argv) if argv is not None else None)
    if not getattr(args, "command", None):
        parser.print_help()
        return 1
    try:
        code: int = args._run(args)
    except TactileError as exc:
        print(f"tactile-learn {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"tactile-learn {args.command}: interrupted", file=sys.stderr)
        return 130
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
