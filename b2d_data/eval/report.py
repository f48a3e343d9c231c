"""Human-facing outputs of an evaluation: the comparison table and the abilities bar chart (PNG)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from b2d_data.eval.abilities import ABILITIES
from b2d_data.eval.summary import SetSummary

#: Marker printed for a figure that could not be computed.
NOT_AVAILABLE = "n/a"
MEAN_LABEL = "Mean"


@dataclass(frozen=True)
class TableRow:
    """One metric row: its label and how to read the value from a summary (None → not available)."""

    label: str
    value: Callable[[SetSummary], float | None]


def _ability_value(ability_index: int) -> Callable[[SetSummary], float | None]:
    def read(s: SetSummary) -> float | None:
        return s.abilities.scores[ABILITIES[ability_index]].value if s.abilities else None

    return read


def table_rows(summaries: Sequence[SetSummary]) -> list[TableRow]:
    """The numeric rows shown for these summaries (smoothness and ability rows only when computed)."""
    rows = [
        TableRow("Driving score", lambda s: s.scores.driving_score),
        TableRow("Success rate (%)", lambda s: s.scores.success_rate),
        TableRow("Route completion (%)", lambda s: s.scores.route_completion),
        TableRow("Infraction penalty (%)", lambda s: s.scores.infraction_penalty),
        TableRow("Efficiency (%)", lambda s: s.efficiency.value),
    ]
    if any(s.smoothness is not None for s in summaries):
        rows.append(TableRow("Smoothness (%)", lambda s: s.smoothness.value if s.smoothness else None))
    if any(s.smoothness_corrected is not None for s in summaries):
        rows.append(
            TableRow(
                "Smoothness, corrected units (%)",
                lambda s: s.smoothness_corrected.value if s.smoothness_corrected else None,
            )
        )
    if any(s.abilities is not None for s in summaries):
        for i, ability in enumerate(ABILITIES):
            rows.append(TableRow(f"{ability.value} (%)", _ability_value(i)))
        rows.append(TableRow("Mean ability (%)", lambda s: s.abilities.mean if s.abilities else None))
    return rows


def _fmt(value: float | None) -> str:
    return NOT_AVAILABLE if value is None else f"{value:.2f}"


def format_table(summaries: Sequence[SetSummary]) -> str:
    """A plain-text table, one column per result set, figures with 2 decimals, then the warnings."""
    header = ["Metric"] + [s.name for s in summaries]
    counts = [f"{s.scores.num_records}/{s.scores.num_routes}" for s in summaries]
    lines: list[list[str]] = [["Records / expected routes", *counts]]
    for row in table_rows(summaries):
        lines.append([row.label] + [_fmt(row.value(s)) for s in summaries])
    widths = [max(len(r[i]) for r in [header, *lines]) for i in range(len(header))]

    def render(cells: list[str]) -> str:
        return "  ".join([cells[0].ljust(widths[0])] + [c.rjust(w) for c, w in zip(cells[1:], widths[1:])])

    out = [render(header), "  ".join("-" * w for w in widths)] + [render(r) for r in lines]
    counted = [f"[{s.name}] {s.scores.num_routes}: {s.route_count.reason}" for s in summaries if s.route_count]
    if counted:
        out += ["", "Expected routes (denominator of driving score and success rate):"] + [f"  {c}" for c in counted]
    notes = [f"[{s.name}] {w}" for s in summaries for w in s.warnings]
    if notes:
        out += ["", "Notes:"] + [f"  {n}" for n in notes]
    return "\n".join(out)


def ability_bars(summaries: Sequence[SetSummary]) -> tuple[list[str], list[list[float | None]]]:
    """Group labels (five abilities + mean) and, per result set, the bar values (percent, None if undefined)."""
    labels = [a.value for a in ABILITIES] + [MEAN_LABEL]
    values: list[list[float | None]] = []
    for s in summaries:
        if s.abilities is None:
            values.append([None] * len(labels))
        else:
            values.append([s.abilities.scores[a].value for a in ABILITIES] + [s.abilities.mean])
    return labels, values


def plot_abilities(summaries: Sequence[SetSummary], path: str | Path) -> list[list[float]]:
    """Write a grouped bar chart (one bar per ability and mean per result set) to ``path``; return bar heights."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    labels, values = ability_bars(summaries)
    n_sets = max(len(summaries), 1)
    width = 0.8 / n_sets
    fig, ax = plt.subplots(figsize=(max(8.0, 1.6 * len(labels) * max(1.0, n_sets / 2)), 4.8))
    drawn: list[list[float]] = []
    try:
        for k, (summary, row) in enumerate(zip(summaries, values)):
            heights = [v if v is not None else 0.0 for v in row]
            xs = [i - 0.4 + width * (k + 0.5) for i in range(len(labels))]
            bars = ax.bar(xs, heights, width=width, label=summary.name)
            texts = [_fmt(v) for v in row]
            ax.bar_label(bars, labels=texts, padding=2, fontsize=8)
            drawn.append([float(b.get_height()) for b in bars])
        ax.set_xticks(range(len(labels)), labels)
        ax.set_ylabel("success rate (%)")
        ax.set_ylim(0, 110)
        ax.set_title("Bench2Drive abilities")
        ax.legend(loc="upper right", fontsize=8)
        fig.tight_layout()
        fig.savefig(Path(path), format="png", dpi=100)
    finally:
        plt.close(fig)
    return drawn
