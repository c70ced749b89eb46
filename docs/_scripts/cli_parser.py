"""The ``ias-gym`` parser for sphinx-argparse, its help texts made safe for reST.

sphinx-argparse reads every help text as reST, where ``|c_h|`` would be a substitution;
the bars are escaped here, and ``--help`` keeps its plain text.
"""

from __future__ import annotations

import argparse

from docstrings import escape_bars

from ias_gym.cli import build_parser


def escaped(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """``parser`` with the bars in its and its sub-parsers' texts escaped, in place."""
    if parser.description:
        parser.description = escape_bars(parser.description)
    for action in parser._actions:
        if action.help:
            action.help = escape_bars(action.help)
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                if choice.help:
                    choice.help = escape_bars(choice.help)
            for sub in action.choices.values():
                escaped(sub)
    return parser


def parser() -> argparse.ArgumentParser:
    """The parser that ``ias-gym`` runs, for the CLI reference."""
    return escaped(build_parser())
