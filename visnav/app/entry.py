"""The ``visnav`` console script: the command line's entry point, importing nothing before it can answer Ctrl-C.

:func:`visnav.app.cli.main` classifies whatever escapes a command
(:mod:`visnav.app.failures`); this wrapper covers the moment before that, while
the command line module itself is being imported.
"""

from __future__ import annotations

import sys

__all__ = ["main"]


def main() -> int:
    """Run ``visnav`` with ``sys.argv``; exit code as :mod:`visnav.app.cli_types` documents."""
    try:
        from visnav.app.cli import main as run
    except KeyboardInterrupt:
        print("visnav: interrupted (SIGINT) during start-up; nothing was run", file=sys.stderr)
        return 130
    from visnav.app.cli_types import ignore_late_interrupts

    return ignore_late_interrupts(run())


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
