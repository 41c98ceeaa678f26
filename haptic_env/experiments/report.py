"""The markdown report of the analysis (``results.md``): headings, paragraphs, tables."""

from __future__ import annotations

from pathlib import Path

__all__ = ["Report", "mean_std"]


class Report:
    """Markdown lines written to ``out/results.md`` (rewritten after each experiment, so a long run shows
    what it has finished). ``out`` is also where experiments put their plots."""

    def __init__(self, out: Path):
        self.out = Path(out)
        self.lines: list[str] = []

    def h(self, text: str) -> None:
        """A ``##`` heading."""
        self.lines += ["", f"## {text}", ""]

    def p(self, text: str) -> None:
        """A paragraph."""
        self.lines += [text, ""]

    def table(self, header, rows) -> None:
        """A table: ``header`` cells and rows of cells (``str()`` of each)."""
        self.lines.append("| " + " | ".join(header) + " |")
        self.lines.append("|" + "|".join("---" for _ in header) + "|")
        for r in rows:
            self.lines.append("| " + " | ".join(str(c) for c in r) + " |")
        self.lines.append("")

    @property
    def path(self) -> Path:
        return self.out / "results.md"

    def write(self) -> Path:
        self.path.write_text("\n".join(self.lines) + "\n")
        return self.path


def mean_std(m: float, s: float, digits: int = 1) -> str:
    """``"m ± s"`` with ``digits`` decimals."""
    return f"{m:.{digits}f} ± {s:.{digits}f}"


def kde_temperature(models, n: int) -> str:
    """The ``n``-finger KDE's calibration temperature as the reports print it, marked "(corrected)" when its
    learned matrix correction comes first and "(power p)" when its power correction does (``KDEConfig.correct``);
    ``models`` a recogniser's ``ModelBank``."""
    kde = models.model(n)[1]
    corr = getattr(kde, "correction", None)
    p = getattr(corr, "p", None)  # the exponent of a PowerCorrection
    mark = "" if corr is None else (" (corrected)" if p is None else f" (power {p:.2f})")
    return f"{models.temperature(n)['kde']:.2f}" + mark
