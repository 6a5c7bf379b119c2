"""The `drs` argument parser: a mistyped option is named, not blamed on the next argument.

argparse sets an option it does not know aside and goes on, so ``drs predict --lattitude 67.89``
handed ``67.89`` to the optional ``bench`` word and said "argument action: invalid choice: '67.89'",
which names neither the mistake nor the fix. Every subparser is made from the root parser's class,
so this one class covers every command.
"""

from __future__ import annotations

import argparse
import difflib
import functools
from collections.abc import Sequence
from typing import Any, NoReturn


class DrsArgumentParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors name the first unknown option, with the closest real one."""

    def __init__(self, *args: Any, root: DrsArgumentParser | None = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._argv: list[str] = []
        self._root = root
        """The `drs` parser itself, for a command's parser: `drs mo serve -v` is told where -v goes."""

    def add_subparsers(self, **kwargs: Any) -> Any:
        kwargs.setdefault("parser_class", functools.partial(type(self), root=self._root or self))
        return super().add_subparsers(**kwargs)

    def parse_known_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> tuple[argparse.Namespace, list[str]]:
        if args is None:
            return super().parse_known_args(args, namespace)
        self._argv = list(args)
        parsed, extras = super().parse_known_args(self._argv, namespace)
        if self._unknown_option() is not None:
            self.error("")  # extras that look like options: always a typo, never a value left for later
        return parsed, extras

    def error(self, message: str) -> NoReturn:
        unknown = self._unknown_option()
        if unknown is not None:
            message = f"unrecognized option {unknown}"
            close = difflib.get_close_matches(unknown, self._long_options(), n=1, cutoff=0.6)
            if self._root is not None and (unknown in self._root._option_string_actions or self._root._short_with_value(unknown)):
                message += f" here: it is an option of drs itself, given before the command (drs {unknown} …)"
            elif close:
                message += f" (did you mean {close[0]}?)"
        super().error(message)

    def _long_options(self) -> list[str]:
        return [option for option in self._option_string_actions if option.startswith("--")]

    def _unknown_option(self) -> str | None:
        """The first word of this parser's own arguments that looks like an option it does not have.

        A subcommand's words are its own parser's business, so the scan stops at the first one.
        """
        commands = {
            name
            for action in self._actions
            if isinstance(action, argparse._SubParsersAction)
            for name in action.choices
        }
        for word in self._argv:
            if word == "--" or word in commands:
                return None
            if not word.startswith("-") or word == "-" or self._negative_number_matcher.match(word):
                continue
            name = word.split("=", 1)[0]
            if name in self._option_string_actions or self._abbreviates(name) or self._short_with_value(word):
                continue
            return name
        return None

    def _abbreviates(self, name: str) -> bool:
        """``--lat`` for ``--latitude``: argparse accepts a unique prefix (and says itself when it is not unique)."""
        return self.allow_abbrev and name.startswith("--") and any(o.startswith(name) for o in self._long_options())

    def _short_with_value(self, word: str) -> bool:
        """``-n5`` or ``-vv``: a known short option with its value or repeats attached."""
        return not word.startswith("--") and word[:2] in self._option_string_actions
