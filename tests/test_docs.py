"""The user's guide stays true to the code: every command its code blocks name exists with the options they
use, its relative links resolve, and its cheap Python examples run."""

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from typer.main import get_command

import evaluate
from training.__main__ import app as training_app

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", ROOT / "CHANGELOG.md", *sorted((ROOT / "docs").glob("*.md"))]
#: Python examples that take more than a few seconds (they run an experiment): run in the expensive set.
SLOW_EXAMPLES = {"command-line.md"}


def code_blocks(text: str) -> list[tuple[str, str]]:
    """(info string, body) of every fenced block, and ("", body) of every indented one."""
    blocks = [(m.group(1), m.group(2)) for m in re.finditer(r"^```(\w*)\n(.*?)^```", text, re.S | re.M)]
    fenced = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    indented = re.findall(r"(?:^\n)((?:^(?: {4}|\t).*\n?)+)", fenced, re.M)
    return blocks + [("", re.sub(r"^ {4}", "", body, flags=re.M)) for body in indented]


def command_lines(body: str) -> list[list[str]]:
    """The ``evaluate.py`` and ``python -m training`` command lines of a shell block, as tokens after the
    program (shell substitutions ``$(...)`` and ``<placeholders>`` read as one word)."""
    joined = re.sub(r"\\\n\s*", " ", body)
    while re.search(r"\$\([^()]*\)", joined):
        joined = re.sub(r"\$\([^()]*\)", "WORD", joined)
    joined = re.sub(r"<[^<>]*>", "WORD", joined)
    found = []
    for line in joined.splitlines():
        for part in re.split(r";|&&|\|\|?", line.split(" #")[0]):
            for program in ("evaluate.py", "-m training"):
                if program in part:
                    found.append([program, *shlex.split(part.split(program, 1)[1])])
    return found


def documented_commands() -> list[tuple[str, list[str]]]:
    return [
        (page.name, tokens)
        for page in PAGES
        for info, body in code_blocks(page.read_text())
        if info in ("", "bash", "sh", "console")
        for tokens in command_lines(body)
    ]


def resolve(group, tokens: list[str]):
    """The click command the tokens name (subcommands followed as far as they go) and the tokens after it."""
    command = group
    while tokens and hasattr(command, "commands") and tokens[0] in command.commands:
        command, tokens = command.commands[tokens[0]], tokens[1:]
    return command, tokens


def test_the_guide_names_commands_at_all():
    named = {tuple(t[:2]) for _, t in documented_commands()}
    for sub in ("run", "replay", "world", "report", "score", "perception", "bench"):
        assert ("evaluate.py", sub) in named, sub


@pytest.mark.parametrize("page,tokens", documented_commands(), ids=lambda v: v if isinstance(v, str) else " ".join(v))
def test_every_documented_command_exists_with_its_options(page, tokens):
    program, args = tokens[0], tokens[1:]
    group = get_command(evaluate.app if program == "evaluate.py" else training_app)
    command, rest = resolve(group, args)
    known = {opt for param in command.params for opt in (*param.opts, *param.secondary_opts)}
    used = {token.split("=")[0] for token in rest if token.startswith("--")}
    assert used <= known | {"--help"}, f"{page}: {' '.join(tokens)}: unknown option(s) {sorted(used - known)}"
    from typer.testing import CliRunner

    names = args[: len(args) - len(rest)]
    result = CliRunner().invoke(evaluate.app if program == "evaluate.py" else training_app, [*names, "--help"])
    assert result.exit_code == 0, f"{page}: {' '.join(names)} --help failed: {result.output}"


def slug(heading: str) -> str:
    """GitHub's anchor of a heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_relative_links_resolve(page):
    text = re.sub(r"^```.*?^```", "", page.read_text(), flags=re.S | re.M)
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"^[a-z]+:", target):
            continue
        path, _, anchor = target.partition("#")
        file = (page.parent / path).resolve() if path else page
        assert file.exists(), f"{page.name}: link to {target}: no {file}"
        if anchor and file.suffix == ".md":
            headings = {slug(h) for h in re.findall(r"^#+ (.+)$", file.read_text(), re.M)}
            assert anchor in headings, f"{page.name}: link to {target}: no heading #{anchor} in {file.name}"


def python_examples(slow: bool) -> list[tuple[str, str]]:
    return [
        (page.name, body)
        for page in PAGES
        for info, body in code_blocks(page.read_text())
        if info == "python" and (page.name in SLOW_EXAMPLES) == slow and "pimm_" in body
    ]


def run_example(body: str, cwd: Path) -> None:
    done = subprocess.run([sys.executable, "-c", body], cwd=cwd, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]


@pytest.mark.parametrize("page,body", python_examples(slow=False), ids=lambda v: v if v.endswith(".md") else "")
def test_the_python_examples_run(page, body, tmp_path):
    run_example(body, ROOT)


@pytest.mark.expensive
@pytest.mark.parametrize("page,body", python_examples(slow=True), ids=lambda v: v if v.endswith(".md") else "")
def test_the_slow_python_examples_run(page, body, tmp_path):
    run_example(body, tmp_path)  # it writes a results folder: not into the checkout


def test_the_readme_is_a_guide_and_the_docs_speak_of_the_software():
    assert len((ROOT / "README.md").read_text().splitlines()) <= 200
    for page in PAGES:
        found = re.search(r"\b(sessions?|round (one|two)|sitting)\b", page.read_text(), re.I)
        assert found is None, f"{page.name}: {found and found.group(0)!r}: how the work went is not documentation"
