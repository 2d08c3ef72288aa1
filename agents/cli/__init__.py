"""The ``vrloco`` command line.

Subcommands are registered in :func:`build_parser` (:mod:`agents.cli.parser`, with the shared
argument types); each one's command function lives in a module of its wing
(:mod:`~agents.cli.benchmark`, :mod:`~agents.cli.learned` for train and evaluate,
:mod:`~agents.cli.recordings` for record, estimate and data, :mod:`~agents.cli.experiments`,
:mod:`~agents.cli.overview` for demo and techniques), and its work lives in its own module,
imported lazily so that ``vrloco --help`` stays fast.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from agents.cli.parser import build_parser

__all__ = ["build_parser", "main"]


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "func", None) is None:
        parser.print_help()
        return 0
    try:
        return int(args.func(args))
    except ValueError as err:  # a bad value found by the work itself: one line, no traceback
        print(f"vrloco {args.command}: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # the command has kept what it finished and said so
        print(f"vrloco {args.command}: stopped (Ctrl-C)", file=sys.stderr)
        return 130
