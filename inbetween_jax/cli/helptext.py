"""Help texts as users see them: the module docstrings they come from, without their Sphinx markup."""
from __future__ import annotations

import argparse
import re

__all__ = ["plain", "plain_help"]

_ROLE = re.compile(r":(?:mod|func|class|meth|attr|data|obj|exc):`~?([^`]+)`")


def plain(text):
    """``text`` without Sphinx markup: ````x```` -> x, :mod:`a.b` -> a.b (None stays None)."""
    return _ROLE.sub(r"\1", text).replace("``", "") if isinstance(text, str) else text


def plain_help(parser: argparse.ArgumentParser) -> None:
    """Strip Sphinx markup (:func:`plain`) from every description, epilog and help of ``parser`` and of its
    subcommands, in place."""
    parser.description, parser.epilog = plain(parser.description), plain(parser.epilog)
    for action in parser._actions:
        action.help = plain(action.help)
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                choice.help = plain(choice.help)
            for sub in action.choices.values():
                plain_help(sub)
