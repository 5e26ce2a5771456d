"""The README and the guide cannot rot: their commands and links are checked against the code.

Every ```bash block of README.md and docs/guide/*.md is read as shell lines (a trailing
backslash continues a line, ``#`` starts a comment). For each ``masonry`` command:

- the command and each of its options exist (the same click command the shell calls);
- when it names a case file, ``masonry validate`` accepts that case with the command's own
  ``--set`` options: for ``sweep`` every combination of the listed values, for
  ``sensitivity`` every parameter at both ends of its range, for ``threshold`` the parameter
  at both bounds. No simulation runs: the checks take seconds.

Every link of these pages (``[text](path)``, pictures included) and every repository path a
bash line names (``cases/...``, ``docs/...``) must be a file or folder of the repository, and
the guide's own cases (docs/guide/cases/) name and match the case file's JSON Schema.
"""

from __future__ import annotations

import itertools
import re
import shlex
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from masonry_nscd.cli import app
from masonry_nscd.studies.batch import split_values

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs" / "guide").glob("*.md"))]
GUIDE_CASES = sorted((ROOT / "docs" / "guide" / "cases").glob("*.yaml"))
#: Folders whose paths, named on a bash line, must exist (results/ is what a run writes).
REPO_DIRS = ("cases/", "docs/", "masonry_nscd/", "tests/")

BASH_BLOCK = re.compile(r"^```bash\n(.*?)^```", re.DOTALL | re.MULTILINE)
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
#: The command tree the shell calls (typer's own click: groups have ``commands``).
GROUP = typer.main.get_command(app)


def bash_lines(page: Path) -> list[str]:
    """The shell lines of the page's ```bash blocks, continuations joined."""
    lines = []
    for block in BASH_BLOCK.findall(page.read_text()):
        lines += [ln.strip() for ln in block.replace("\\\n", " ").splitlines() if ln.strip()]
    return lines


def masonry_commands() -> list[tuple[str, list[str]]]:
    """``(where, argv after "masonry")`` of every masonry command of the pages."""
    found = []
    for page in PAGES:
        for line in bash_lines(page):
            words = shlex.split(line, comments=True)
            if words and words[0] == "masonry":
                found.append((f"{page.relative_to(ROOT)}: {' '.join(line.split())}", words[1:]))
    return found


def resolve(argv: list[str]):
    """The command of ``argv`` (``point joint`` included) and the words after it."""
    command = GROUP
    rest = list(argv)
    while hasattr(command, "commands"):
        assert rest, f"no command after {argv}"
        name = rest.pop(0)
        assert name in command.commands, f"masonry has no command {name!r}"
        command = command.commands[name]
    return command, rest


def parse(command, words: list[str]) -> tuple[list[str], dict[str, list[str]]]:
    """Positional words and the options' values (by the option's first long name); asserts
    that each option is one of the command's."""
    options = {}
    for param in command.params:
        if param.param_type_name == "option":
            for name in param.opts + param.secondary_opts:
                options[name] = param
    positional, values = [], {}
    i = 0
    while i < len(words):
        word = words[i]
        if word.startswith("-") and len(word) > 1:
            name, eq, inline = word.partition("=")
            assert name in options, f"masonry {command.name} has no option {name}"
            param = options[name]
            key = max(param.opts, key=len)
            if param.is_flag:
                values.setdefault(key, []).append("true")
            elif eq:
                values.setdefault(key, []).append(inline)
            else:
                assert i + 1 < len(words), f"{name} needs a value"
                values.setdefault(key, []).append(words[i + 1])
                i += 1
        else:
            positional.append(word)
        i += 1
    return positional, values


def validations(name: str, case: str, values: dict[str, list[str]]) -> list[list[str]]:
    """The ``--set`` lists with which ``masonry validate`` must accept ``case``."""
    sets = values.get("--set", [])
    if name == "sweep":
        axes = []
        for option in sets:
            path, _, listed = option.partition("=")
            axes.append([f"{path}={v}" for v in split_values(listed)])
        return [list(combo) for combo in itertools.product(*axes)]
    if name == "sensitivity":
        ends: list[list[str]] = [list(sets), list(sets)]
        for option in values.get("--param", []):
            path, _, bounds = option.partition("=")
            low, high = bounds.split(":")
            ends[0].append(f"{path}={low}")
            ends[1].append(f"{path}={high}")
        return ends
    if name == "threshold":
        (param,), (bounds,) = values["--param"], values["--bounds"]
        return [[*sets, f"{param}={bound}"] for bound in bounds.split(":")]
    return [list(sets)]


COMMANDS = masonry_commands()


def test_pages_have_commands():
    """The guide's pages were found and hold commands (the checks below are not vacuous)."""
    assert len(PAGES) >= 8
    assert len(COMMANDS) >= 20


def test_readme_opens_with_the_two_commands():
    """README's first block is the two commands that do everything on a fresh machine, and the
    README stays a page for users (200 lines at most; the reference is in docs/guide/)."""
    assert len((ROOT / "README.md").read_text().splitlines()) <= 200
    first = bash_lines(ROOT / "README.md")[:2]
    assert [shlex.split(line, comments=True) for line in first] == [["make", "run"],
                                                                      ["make", "test"]]
    targets = (ROOT / "Makefile").read_text()
    assert re.search(r"^run:", targets, re.MULTILINE) and re.search(r"^test:", targets, re.MULTILINE)


@pytest.mark.parametrize("where,argv", COMMANDS, ids=[w for w, _ in COMMANDS])
def test_command_is_valid(where, argv):
    """The command and its options exist; its case validates with its own --set options."""
    command, words = resolve(argv)
    positional, values = parse(command, words)
    cases = [p for p in positional if p.endswith((".yaml", ".yml"))]
    runner = CliRunner()
    for case in cases:
        assert (ROOT / case).is_file(), f"{where}: no case file {case}"
        for sets in validations(command.name, case, values):
            args = ["validate", str(ROOT / case)]
            for option in sets:
                args += ["--set", option]
            result = runner.invoke(app, args)
            assert result.exit_code == 0, f"{where}\n{' '.join(args)}\n{result.output}"


def test_links_and_paths_exist():
    """Every link of the pages, and every repository path their bash lines name, exists."""
    missing = []
    for page in PAGES:
        for target in LINK.findall(page.read_text()):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue
            path = (page.parent / target.split("#")[0]).resolve()
            if not path.exists():
                missing.append(f"{page.relative_to(ROOT)}: link {target}")
        for line in bash_lines(page):
            for word in shlex.split(line, comments=True):
                word = word.split("=", 1)[-1]
                if word.startswith(REPO_DIRS) and not (ROOT / word).exists():
                    missing.append(f"{page.relative_to(ROOT)}: {word}")
    assert not missing, "\n".join(missing)


@pytest.mark.parametrize("path", GUIDE_CASES, ids=[p.stem for p in GUIDE_CASES])
def test_guide_case_names_and_matches_the_schema(path):
    """A case of the guide names the case file's JSON Schema on its first line, as the shipped
    cases do (an editor then completes and checks it), and validates against that schema."""
    import json

    import jsonschema

    from masonry_nscd.case import read_yaml
    from masonry_nscd.case.reference import JSON_FILE

    text = path.read_text(encoding="utf-8")
    first = text.splitlines()[0]
    prefix = "# yaml-language-server: $schema="
    assert first.startswith(prefix), first
    assert (path.parent / first[len(prefix):]).resolve() == (ROOT / JSON_FILE).resolve()
    schema = json.loads((ROOT / JSON_FILE).read_text(encoding="utf-8"))
    errors = [f"{e.json_path}: {e.message}"
              for e in jsonschema.Draft202012Validator(schema).iter_errors(read_yaml(text))]
    assert not errors, errors
