"""The README's CLI conventions table is the truth: every option it lists exists in that command's --help."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from ipfit.cli import SUBCOMMANDS, main

README = Path(__file__).resolve().parents[1] / "README.md"


def conventions() -> dict[str, list[str]]:
    text = README.read_text(encoding="utf-8")
    table = text.split("### Conventions", 1)[1].split("\n\n", 2)[1]
    rows = {}
    for line in table.splitlines()[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        command = re.fullmatch(r"`ipfit (\w+)`", cells[0]).group(1)
        rows[command] = re.findall(r"`(--[a-z][a-z-]*)`", cells[3])
    return rows


def help_text(command: str, capsys) -> str:
    with pytest.raises(SystemExit) as stop:
        main([command, "--help"])
    assert stop.value.code == 0
    return capsys.readouterr().out


def test_every_subcommand_is_in_the_table():
    assert set(conventions()) == set(SUBCOMMANDS)


@pytest.mark.parametrize("command", sorted(conventions()))
def test_every_listed_option_exists(command, capsys):
    text = help_text(command, capsys)
    for option in conventions()[command] + ["--help"]:
        assert re.search(rf"(?<![\w-]){re.escape(option)}(?![\w-])", text), f"ipfit {command} has no {option}"
    if command not in ("datasets", "export", "score"):  # these write to stdout or update RESULT.json
        assert "-o" in text and "--output" in text
