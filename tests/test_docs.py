"""The documented commands stay true: every ``--flag`` of a ``haptic-recog``, ``train.py`` or ``benchmarks/*.py``
command written in the README, CONTRIBUTING, RESULTS and the committed result pages is one its parser accepts.

RESULTS.md gives the exact command of every result; a flag renamed or dropped later would leave a reader a command
that fails. The parsers are asked for their ``--help`` in this process (argparse and tyro print every option)."""

from __future__ import annotations

import contextlib
import functools
import io
import pathlib
import re
import runpy
import subprocess
import sys

import pytest

from haptic_env.cli import SUBCOMMANDS, main as cli_main

ROOT = pathlib.Path(__file__).resolve().parents[1]
FLAG = re.compile(r"(?<![\w-])(--[a-zA-Z][\w.-]*)")
NEXT = r"(.*?)(?=\bhaptic-recog\s|\bpython\s|$)"  # a command's arguments run up to the next command on its line
COMMAND = re.compile(r"haptic-recog\s+([a-z][\w-]*)" + NEXT + r"|python\s+(?:-m\s+)?((?:benchmarks/)?[\w/]+\.py)" + NEXT)


def documents() -> list[pathlib.Path]:
    """The tracked Markdown pages that give commands (a clean clone has exactly these)."""
    out = subprocess.run(["git", "ls-files", "README.md", "CONTRIBUTING.md", "RESULTS.md", "docs/*.md", "results/*.md"],
                         cwd=ROOT, capture_output=True, text=True)
    if out.returncode != 0:
        pytest.skip(f"not a git checkout: {out.stderr.strip()}")
    docs = [ROOT / f for f in out.stdout.split()]
    assert ROOT / "README.md" in docs and ROOT / "RESULTS.md" in docs, docs  # else the checks below check nothing
    return docs


def commands(text: str):
    """``(parser key, the command's arguments, the line)`` for each command in ``text``: line continuations joined,
    a trailing comment and anything after a shell separator dropped."""
    text = re.sub(r"\\\n\s*", " ", text)
    for line in text.splitlines():
        for m in COMMAND.finditer(line):
            key = ("haptic-recog", m.group(1)) if m.group(1) else (m.group(3),)
            args = re.split(r"[;&|`#]|\)\s", m.group(2) if m.group(1) else m.group(4))[0]
            yield key, args, line.strip()


def _help_text(key: tuple) -> str:
    out = io.StringIO()
    argv = sys.argv
    try:
        with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
            if key[0] == "haptic-recog":
                cli_main([key[1], "--help"])
            else:
                sys.argv = [str(ROOT / key[0]), "--help"]
                runpy.run_path(str(ROOT / key[0]), run_name="__main__")
    finally:
        sys.argv = argv
    return out.getvalue()


@functools.lru_cache(maxsize=None)
def accepted_flags(key: tuple) -> frozenset:
    return frozenset(f.rstrip(".") for f in FLAG.findall(_help_text(key))) | {"--help"}


def test_commands_parse_continuations_comments_and_separators():
    text = "x\n```\nhaptic-recog analysis --objects kit8 \\\n    --trials 10   # a note --not-a-flag\n" \
           "python benchmarks/soak.py --steps 5 && python train.py --seed 1\n```\n"
    got = [(k, FLAG.findall(a)) for k, a, _ in commands(text)]
    assert got == [(("haptic-recog", "analysis"), ["--objects", "--trials"]), (("benchmarks/soak.py",), ["--steps"]),
                   (("train.py",), ["--seed"])]


def test_a_wrong_flag_is_found():
    assert "--trials" in accepted_flags(("haptic-recog", "analysis"))
    assert "--no-such-flag" not in accepted_flags(("haptic-recog", "analysis"))


def test_every_documented_flag_exists():
    bad = []
    for doc in documents():
        for key, args, line in commands(doc.read_text(encoding="utf-8")):
            if key[0] == "haptic-recog" and key[1] not in SUBCOMMANDS:
                if FLAG.search(args):  # prose such as "the haptic-recog command" has no flags
                    bad.append(f"{doc.name}: unknown sub-command {key[1]!r}: {line}")
                continue
            if key[0] != "haptic-recog" and not (ROOT / key[0]).is_file():
                bad.append(f"{doc.name}: no script {key[0]}: {line}")
                continue
            flags = accepted_flags(key)
            bad += [f"{doc.relative_to(ROOT)}: {' '.join(key)} has no {f}: {line[:120]}"
                    for f in (f.rstrip(".") for f in FLAG.findall(args)) if f not in flags]
    assert not bad, "\n".join(bad)


@pytest.mark.slow
def test_readme_python_blocks_run(tmp_path, monkeypatch):
    """The README's Python examples run as pasted, in order, in one namespace (a later block may use an earlier
    one's imports), on the embedded default set: a snippet that rots fails here (about a minute, a fresh cache)."""
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), flags=re.S)
    assert blocks, "the README has no Python example"
    namespace: dict = {}
    for i, block in enumerate(blocks):
        with contextlib.redirect_stdout(io.StringIO()):
            exec(compile(block, f"README.md python block {i + 1}", "exec"), namespace)


def _anchor(heading: str) -> str:
    """GitHub's anchor of a Markdown heading: lower case, every character but letters, marks, digits, ``_``, ``-``
    and spaces dropped, spaces turned to ``-`` (github-slugger's rule; repeats get ``-1``, ``-2``, ...)."""
    import unicodedata

    kept = (ch for ch in heading.strip().lower()
            if ch in " -" or unicodedata.category(ch)[0] in "LMN" or unicodedata.category(ch) == "Pc")
    return "".join(kept).replace(" ", "-")


def results_contents(text: str) -> str:
    """The contents list RESULTS.md should carry: its chapters (``#``) and sections (``##``, ``###``) outside code
    blocks, as nested links, without the title and the contents heading itself (sections before the first chapter
    stand at the top level)."""
    lines, seen, code, chapter = [], {}, False, False
    for line in text.splitlines():
        if line.startswith("```"):
            code = not code
            continue
        m = None if code else re.match(r"^(#{1,3}) (.*)$", line)
        if not m:
            continue
        level, heading = len(m.group(1)), m.group(2).strip()
        anchor = _anchor(heading)
        repeat = seen.get(anchor, 0)
        seen[anchor] = repeat + 1
        if repeat:
            anchor = f"{anchor}-{repeat}"
        if (level, heading) in ((1, "haptic-recog results"), (2, "Contents")):
            continue
        chapter = chapter or level == 1
        lines.append("  " * (level - 1 if chapter else 0) + f"- [{heading}](#{anchor})")
    return "\n".join(lines)


def test_anchor_follows_githubs_rule():
    assert _anchor("kit8, experiment 2 for n = 2 and 5-10") == "kit8-experiment-2-for-n--2-and-5-10"
    assert _anchor("Speed (`python benchmarks/bench_env.py`)") == "speed-python-benchmarksbench_envpy"
    assert _anchor("Result bar (λ = 0.85, 4 fingers + normals)") == "result-bar-λ--085-4-fingers--normals"


def test_results_contents_lists_every_section():
    """RESULTS.md's "Contents" links every chapter and section, in order, to its heading (a section added, renamed
    or moved without its entry fails here; the message holds the list to paste)."""
    text = (ROOT / "RESULTS.md").read_text()
    m = re.search(r"^## Contents\n\n(.*?)\n\n", text, flags=re.S | re.M)
    assert m, "RESULTS.md has no '## Contents' section followed by a list"
    expected = results_contents(text)
    assert m.group(1) == expected, f"RESULTS.md's contents are out of date; they should read:\n\n{expected}\n"
