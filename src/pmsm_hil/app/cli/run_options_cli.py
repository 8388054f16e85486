"""The run-option schema (src/pmsm_hil/hil/runner/run_options.py) as argparse options and `--config` keys: nothing about
a run option is declared here, only how the command line and TOML files present it."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from pmsm_hil.app.cli.config_file import ConfigKey
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.runner.run_options import RUN_OPTIONS, RunOption, Scope


def argparse_type(option: RunOption, *, check: bool = False) -> Callable[[str], Any]:
    """An argparse `type=` for `option`: its own parse (and with `check` its range check), errors as argparse's.
    The command line leaves ranges to `RunConfig.from_options` (one-line errors naming the option)."""
    def parse(text: str) -> Any:
        try:
            return option.parse(text, check=check)
        except ParameterError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    parse.__name__ = option.kind
    return parse


def add_option(parser: argparse.ArgumentParser | argparse._ArgumentGroup, option: RunOption, *,
               help: str | None = None, repeatable: bool = False) -> None:
    """`option` on `parser`; every default is None (or [] for tables) so a config file can fill it in later.
    `help`: a command's own words for what the option does there (a bench); `repeatable`: a list of values (a bench
    measuring several)."""
    names: dict[str, Any] = {"dest": option.target, "help": help or option.help_text()}
    metavar = option.metavar or ("N" if option.kind == "integer" else {"s": "S", "A": "A"}.get(option.unit))
    if repeatable:
        parser.add_argument(option.option, type=argparse_type(option, check=True), action="append", metavar=metavar,
                            **names)
    elif option.kind == "flag":
        parser.add_argument(option.option, action="store_true", default=None, **names)
    elif option.kind == "table":
        parser.add_argument(option.option, action="append", default=[], metavar=option.metavar, **names)
    elif option.kind == "choice":
        parser.add_argument(option.option, choices=option.choices, **names)
    elif option.kind == "path":
        parser.add_argument(option.option, type=Path, metavar=option.metavar, **names)
    elif option.kind == "text":
        parser.add_argument(option.option, metavar=option.metavar, **names)
    else:
        parser.add_argument(option.option, type=argparse_type(option), metavar=metavar, **names)


def add_options(parser: argparse.ArgumentParser, scopes: Iterable[Scope] = ("run",)) -> None:
    """Every option of the schema in `scopes`, in the schema's order."""
    wanted = set(scopes)
    for option in RUN_OPTIONS:
        if option.scope in wanted:
            add_option(parser, option)


def config_key(option: RunOption) -> ConfigKey:
    """How a `--config` file (and a sweep grid) gives `option`."""
    kind = {"integer": "number", "frequency": "number"}.get(option.kind, option.kind)
    parse = argparse_type(option, check=True) if kind == "number" else None
    return ConfigKey(option.key, option.option, option.target, kind, parse=parse, choices=option.choices,
                     table_text=option.table_text)


def config_keys(scopes: Iterable[Scope] = ("run", "output")) -> dict[str, ConfigKey]:
    """The `--config` keys of the options in `scopes`."""
    wanted = set(scopes)
    return {o.key: config_key(o) for o in RUN_OPTIONS if o.scope in wanted}


__all__ = ["add_option", "add_options", "argparse_type", "config_key", "config_keys"]
