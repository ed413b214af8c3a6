"""Help written for users: ``findme --help`` lists every command under a group; every
sub-command has a description and every option (and positional argument) a help string;
no developer text (RST markup, module or package names, source files) leaks into them."""

from __future__ import annotations

import argparse
import re

import pytest

from findme.cli import build_parser
from findme.cli.registry import GROUPS

from tests.cli.conftest import run_findme

#: What only a developer would write: RST markup, Python names, bare source file names (a
#: user runs ``python tools/make_certs.py``, so a script with its path may be named).
LEAKS = [re.compile(p) for p in (
    r"``", r":(class|func|mod|meth):", r"\bfindme_(core|io)\b", r"\bservices\.\w", r"\bschemas\.",
    r"(?<![/\w])\w+\.py\b", r"\bdocstring", r"\bsys\.executable\b", r"\b__\w+__\b",
    r"\bHandler\b", r"\bprovenance\.")]


def _parsers_of(command=None):
    parser = build_parser(command)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return parser, sub


def _parsers():
    return _parsers_of(None)


def _texts(name, p, one_line):
    yield f"{name}: summary", one_line
    yield f"{name}: description", p.description
    for a in p._actions:
        if not isinstance(a, argparse._HelpAction):
            yield f"{name} {'/'.join(a.option_strings) or a.dest}", a.help


def test_every_command_and_option_has_help_for_users():
    _, sub = _parsers()
    summaries = {a.dest: a.help for a in sub._choices_actions}
    missing, leaks = [], []
    for name, p in sub.choices.items():
        if not summaries.get(name):
            missing.append(f"{name}: no one-line help")
        if not p.description or len(p.description) < 80:
            missing.append(f"{name}: no description")
        for a in p._actions:
            if isinstance(a, argparse._HelpAction):
                continue
            if not a.help or a.help == argparse.SUPPRESS:
                missing.append(f"{name} {'/'.join(a.option_strings) or a.dest}: no help")
        for where, text in _texts(name, p, summaries.get(name)):
            for pat in LEAKS:
                if text and pat.search(text):
                    leaks.append(f"{where}: {pat.pattern!r} in {text[:90]!r}")
    assert not missing, "\n".join(missing)
    assert not leaks, "\n".join(leaks)


def test_descriptions_keep_their_lines_and_fit_a_terminal():
    """Descriptions are printed as written (lists and examples stay lists), each line at
    most 80 characters."""
    _, sub = _parsers()
    for name, p in sub.choices.items():
        assert p.formatter_class is argparse.RawDescriptionHelpFormatter, name
        long = [ln for ln in p.description.splitlines() if len(ln) > 80]
        assert not long, f"{name}: {long}"


def test_top_level_help_lists_every_command_once_in_groups():
    parser, sub = _parsers()
    grouped = [n for _, names in GROUPS for n in names]
    assert sorted(grouped) == sorted(sub.choices), "every command in exactly one group"
    out = run_findme("--help").stdout
    for title, names in GROUPS:
        assert f"\n{title}:\n" in out
        block = out.split(f"\n{title}:\n", 1)[1].split("\n\n", 1)[0]
        assert [ln.split()[0] for ln in block.splitlines()] == list(names)
    assert out.startswith("usage: findme [-h] [--debug] COMMAND ...\n")


@pytest.mark.parametrize("command", ["router", "app"])
def test_commands_offer_only_options_that_apply(command):
    """A router's mode is router (no --mode); ``app`` runs no selection service (no
    --auto / --interactive)."""
    _, sub = _parsers()
    opts = {o for a in sub.choices[command]._actions for o in a.option_strings}
    unwanted = {"router": {"--mode"}, "app": {"--auto", "--interactive"}}[command]
    assert not opts & unwanted


def test_every_command_help_runs():
    _, sub = _parsers()
    for name in sub.choices:
        p = run_findme(name, "--help")
        assert p.returncode == 0 and p.stdout.startswith("usage: findme " + name), name


def test_the_registry_names_each_command_s_module():
    """A command line builds the parser of its command's module alone (the others' imports
    are not paid for): each module registers exactly the commands the registry gives it."""
    from findme.cli.registry import COMMANDS
    for command, module in COMMANDS.items():
        _, sub = _parsers_of(command)
        assert set(sub.choices) == {c for c, m in COMMANDS.items() if m == module}, command
