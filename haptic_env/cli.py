"""``haptic-recog`` command line: one entry point, one sub-command per component.

Each sub-command lives next to the code it drives and exposes ``add_parser(subparsers)``;
this module only wires them together (imports are lazy so ``--help`` stays fast).
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
from pathlib import Path

# name -> module that defines add_parser(subparsers) and sets func on its parser
SUBCOMMANDS: dict[str, str] = {
    "dataset": "haptic_env.dataset",
    "analysis": "haptic_env.experiments.cli",
    "evaluate": "agents.evaluate",
    "sweep": "haptic_env.sweep.cli",
    "scene": "haptic_env.assets",
}


class UsageError(ValueError):
    """A bad command-line value found after parsing: :func:`main` reports it as a one-line usage error."""


def whole_text(text: str) -> int | None:
    """The whole number ``text`` spells, or None: an integer as ``int`` reads it (``"200000"``, ``"1_000"``, any
    size), or a number ``float`` reads (``"2e5"``, ``"4.0"``) that is whole and below 2**53 in size (so exact); not
    ``"3.5"``, ``"nan"``, ``"inf"`` or words. The one rule of :func:`int_in` and :func:`parse_int_list`."""
    try:
        return int(text)
    except (TypeError, ValueError):
        pass
    try:
        v = float(text)
    except (TypeError, ValueError):
        return None
    return int(v) if v == v and abs(v) < 2**53 and v == int(v) else None


def int_in(lo: int, hi: int | None = None):
    """argparse ``type``: an integer in ``[lo, hi]`` (a bad value is a one-line error naming the flag); any form
    :func:`whole_text` reads (``2e5`` is 200000), as in the comma lists of :func:`parse_int_list`."""

    def parse(text: str) -> int:
        v = whole_text(text)
        if v is None:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}")
        if v < lo or (hi is not None and v > hi):
            rng = f"in [{lo}, {hi}]" if hi is not None else f">= {lo}"
            raise argparse.ArgumentTypeError(f"must be {rng}, got {v}")
        return v

    return parse


def float_in(lo: float | None = None, hi: float | None = None, *, lo_open: bool = False, hi_open: bool = False):
    """argparse ``type``: a finite float in ``[lo, hi]`` (``lo_open`` / ``hi_open``: that end excluded)."""

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        bad = v != v or v in (float("inf"), float("-inf"))
        bad |= lo is not None and (v < lo or (lo_open and v == lo))
        bad |= hi is not None and (v > hi or (hi_open and v == hi))
        if bad:
            left = "(" if lo_open else "["
            right = ")" if hi_open else "]"
            raise argparse.ArgumentTypeError(f"must be a finite number in {left}{lo if lo is not None else '-inf'}, "
                                             f"{hi if hi is not None else 'inf'}{right}, got {text}")
        return v

    return parse


def float_list_in(lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
                  hi_open: bool = False):
    """argparse ``type``: a comma list of numbers, each as :func:`float_in` takes it (``""``: an empty list)."""
    one = float_in(lo, hi, lo_open=lo_open, hi_open=hi_open)

    def parse(text: str) -> list[float]:
        return [one(word.strip()) for word in text.split(",") if word.strip()]

    return parse


def parse_int_list(text: str) -> tuple[int, ...]:
    """``"2-4,7"`` -> ``(2, 3, 4, 7)``: whole numbers (:func:`whole_text`: ``2e5`` is 200000) and ranges ``a-b``,
    comma-separated; a ``ValueError`` naming the text for anything else (``3.5``, ``x``, ``4-2``)."""
    def whole(word: str) -> int:
        v = whole_text(word)
        if v is None:
            raise ValueError(f"expected a comma list of whole numbers or ranges a-b, got {text!r}")
        return v

    out: list[int] = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        lo, sep, hi = part.partition("-") if not part.startswith("-") else ("", "", "")
        if sep:
            a, b = whole(lo), whole(hi)
            if b < a:
                raise ValueError(f"range {part!r} runs backwards in {text!r}")
            if b - a >= MAX_RANGE:  # a typo (1-1e12) is refused, not built
                raise ValueError(f"range {part!r} in {text!r} holds more than {MAX_RANGE:,} numbers")
            out += range(a, b + 1)
        else:
            out.append(whole(part))
    return tuple(out)


#: the most numbers one range ``a-b`` of :func:`parse_int_list` may hold
MAX_RANGE = 100_000


def int_list(text: str) -> tuple[int, ...]:
    """argparse ``type``: :func:`parse_int_list` (a bad list is a one-line error naming the flag)."""
    try:
        return parse_int_list(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def int_list_in(lo: int):
    """argparse ``type``: :func:`int_list` with at least one number, each ``>= lo``."""

    def parse(text: str) -> tuple[int, ...]:
        values = int_list(text)
        if not values or min(values) < lo:
            raise argparse.ArgumentTypeError(f"expected a comma list of whole numbers >= {lo}, got {text!r}")
        return values

    return parse


def distinct(parser: argparse.ArgumentParser, flag: str, values) -> None:
    """``parser.error`` when a value of ``flag`` repeats: a seed given twice would count its runs twice (a narrower
    spread over the same evidence)."""
    from haptic_env.numbers import repeated

    values = list(values)
    twice = repeated(values)
    if twice:
        parser.error(f"{flag}: each value once, got {values} ({', '.join(map(str, twice))} more than once)")


def output_path(kind: str = "file"):
    """argparse ``type``: a ``Path`` that a long run can write at its end, checked now without creating anything:
    ``kind="file"``: not an existing folder; ``kind="folder"``: not an existing file; and the nearest existing
    folder above it is writable (a typo fails at once, not after the run)."""
    if kind not in ("file", "folder"):
        raise ValueError(f"kind must be 'file' or 'folder', got {kind!r}")

    def parse(text: str) -> Path:
        path = Path(text)
        if kind == "file" and path.is_dir():
            raise argparse.ArgumentTypeError(f"{text} is a folder; give a file name")
        if kind == "folder" and path.exists() and not path.is_dir():
            raise argparse.ArgumentTypeError(f"{text} is a file; give a folder")
        # an existing folder is written into (its own rights); else the nearest existing folder above creates it
        above = path.absolute() if kind == "folder" and path.is_dir() else path.absolute().parent
        while not above.exists():
            above = above.parent
        if not above.is_dir() or not os.access(above, os.W_OK | os.X_OK):
            raise argparse.ArgumentTypeError(f"cannot create {text}: {above} is not a writable folder")
        return path

    return parse


def script_command(script: str, argv=None) -> str:
    """``python benchmarks/<script> <argv>``, shell-quoted so that it re-runs as written: the command line a
    benchmark's output records (``argv`` None: this process's own arguments)."""
    import shlex

    return shlex.join(["python", f"benchmarks/{script}", *map(str, sys.argv[1:] if argv is None else argv)])


def json_object(text: str) -> dict:
    """argparse ``type``: a JSON object (``{"key": value, ...}``)."""
    try:
        v = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not valid JSON ({exc.msg} at character {exc.pos}): {text!r}; "
                                         "expected an object such as '{\"grasp_cost\": 0.02}'") from None
    if not isinstance(v, dict):
        raise argparse.ArgumentTypeError(f"expected a JSON object ({{...}}), got {text!r}")
    return v


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="haptic-recog", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for name, module in SUBCOMMANDS.items():
        importlib.import_module(module).add_parser(sub)
        if name in sub.choices:  # so main can report a sub-command's UsageError against its own usage
            sub.choices[name].set_defaults(_cli_parser=sub.choices[name])
    return parser


def main(argv: list[str] | None = None) -> int:
    import os

    if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
        os.environ["MUJOCO_GL"] = "egl"  # the application's choice (before mujoco is imported): headless rendering
    parser = build_parser()
    args = parser.parse_args(argv)
    from haptic_env import cli  # under ``python -m haptic_env.cli`` this module is __main__, a second copy

    try:
        return int(args.func(args) or 0)
    except (UsageError, cli.UsageError) as exc:
        getattr(args, "_cli_parser", parser).error(str(exc))  # prints usage + one error line, exits 2
    except RuntimeError as exc:  # an env's or experiment's settings that leave a hand too few grasps to train on
        dataset = sys.modules.get("haptic_env.dataset")  # loaded if it raised (not imported for every command)
        if dataset is None or not isinstance(exc, dataset.TooFewGraspsError):
            raise
        getattr(args, "_cli_parser", parser).error(f"{exc} (found once the hand had grasped; change the settings)")
    except KeyboardInterrupt:  # Ctrl-C: one line (and what a rerun keeps, where the sub-command says), not a traceback
        note = getattr(args, "interrupt_note", "")
        print(f"haptic-recog {args.command}: interrupted" + (f"; {note}" if note else ""), file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
