"""`hil` builds the parser of the one subcommand its command line names (`parser_for`), a group's subcommand too
(`hil fw build`, `hil bench loop`): the same parsing as the complete parser, without importing the other
subcommands' modules."""

from __future__ import annotations

import argparse
import subprocess
import sys
from typing import Any

import pytest

from pmsm_hil.app.cli.main import _GROUPS, build_parser, parser_for


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, Any]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _parsed(parser: argparse.ArgumentParser, argv: list[str]) -> dict[str, Any]:
    args = vars(parser.parse_args(argv))
    func = args.pop("func")
    return {**args, "func": getattr(func, "__qualname__", func)}


@pytest.mark.parametrize("argv", [
    ["fw", "build", "--src", "fw", "-o", "out.so"],
    ["fw", "build", "--debug", "--src", "fw", "--board", "mps2-an386", "-o", "fw.elf"],
    ["--debug", "mcap", "export", "runs/x/run.mcap", "--format", "asc", "-o", "x.asc"],
    ["bench", "loop", "--quiet"],
    ["bench", "plant"],
    ["plant", "replay", "--rpm", "1500", "--ts", "1e-4", "--input", "c.csv", "--output", "o.csv"],
    ["fmu", "example", "dir"],
])
def test_a_group_subcommand_parses_as_with_the_complete_parser(argv: list[str]) -> None:
    group = next(a for a in argv if a != "--debug")
    only = parser_for(argv)
    assert list(_subcommands(only)) == [group]
    assert list(_subcommands(_subcommands(only)[group])) == [argv[argv.index(group) + 1]]
    assert _parsed(only, argv) == _parsed(build_parser(), argv)


@pytest.mark.parametrize("argv", [["fw"], ["bench", "--help"], ["fw", "nosuch"], ["bench", "-q"], ["--help"]])
def test_a_group_alone_or_an_unknown_subcommand_gets_the_complete_parser(argv: list[str]) -> None:
    parser = parser_for(argv)
    assert set(_subcommands(parser)) >= {"run", "target", *_GROUPS}


def test_hil_fw_build_imports_no_other_subcommand() -> None:
    code = ("import sys\nfrom pmsm_hil.app.cli.main import parser_for\nparser_for(['fw', 'build', '--help'])\n"
            "print(sorted(m for m in sys.modules if m.startswith(('pmsm_hil.app.cli.', 'pmsm_hil.hil.runner'))))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    loaded = eval(proc.stdout)  # a printed list of module names
    assert "pmsm_hil.app.cli.fw_build" in loaded and "pmsm_hil.app.cli.run" not in loaded, loaded
    assert not [m for m in loaded if m.startswith("pmsm_hil.hil.runner")], loaded
