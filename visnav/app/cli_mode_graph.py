"""``visnav mode-graph``: the supervisor's mode graph, or a problem's automaton (DOT or JSON)."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from visnav.app.cli_verify import user_problem
from visnav.app.cli_types import EXIT_BAD_INPUT, EXIT_OK

__all__ = ["add_parser"]


def add_parser(sub: Any) -> None:
    """Register the subcommand on ``visnav``'s subparsers."""
    graph = sub.add_parser("mode-graph", help="print the supervisor's mode graph (Graphviz DOT or JSON)")
    graph.add_argument("--scenario", default="paper")
    graph.add_argument("--problem", default=None, metavar="SPEC",
                       help="the automaton of a verification problem instead (PKG.MOD:OBJ or FILE.py:OBJ, or a "
                            "SpaceEx model FILE.xml[:COMPONENT] with --config FILE.cfg: the flattened automaton)")
    graph.add_argument("--config", default=None, metavar="FILE.cfg",
                       help="with --problem FILE.xml[:COMPONENT]: the SpaceEx configuration (docs/spaceex.md)")
    graph.add_argument("--format", choices=("dot", "json"), default="dot",
                       help="dot: Graphviz with guards and resets as labels; json: the automaton's description")
    graph.set_defaults(func=_cmd_mode_graph)


def _cmd_mode_graph(args: argparse.Namespace) -> int:
    from hybrid import to_dot, to_json

    from visnav.scenario import load_scenario
    from visnav.supervisor import build_supervisor

    if args.problem is not None:
        problem = user_problem(args.problem, args.config)
        if isinstance(problem, int):
            return problem
        automaton = problem.automaton
        if automaton is None:
            print(f"visnav: error: problem {problem.name!r} declares no automaton (VerificationProblem.automaton); "
                  "build it with analysis.verify.problems.hybrid_problem or sampled_problem, or set automaton=",
                  file=sys.stderr)
            return EXIT_BAD_INPUT
    else:
        scenario = load_scenario(args.scenario)
        automaton = build_supervisor(scenario.envelopes, scenario.supervisor, len(scenario.obstacles)).automaton
    if args.format == "json":
        print(json.dumps(to_json(automaton), sort_keys=True, indent=2))
    else:
        print(to_dot(automaton), end="")
    return EXIT_OK
