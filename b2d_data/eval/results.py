"""Result sets: the Leaderboard records of one evaluated agent, gathered from one or many JSON files.

A result set is read from per-process checkpoint files (``eval_bench2drive220_<i>.json``), a directory
of them, or a merged.json. Bench2Drive's merge concatenates records without looking for duplicates;
here a route (keyed by its XML id, so repetitions count too) that appears more than once is reported,
and the **last record by file order wins** (files in the order given; a directory's files sorted by
name with numbers compared as numbers), unless ``strict`` asks for an error instead.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from b2d_data.format.errors import B2DFormatError
from b2d_data.format.leaderboard import LeaderboardFormatError, RouteRecord, read_results

log = logging.getLogger(__name__)

#: File names a results directory may hold that are not per-process results (merge output, our own outputs).
_DIRECTORY_SKIP = ("merged.json",)


class EvalInputError(B2DFormatError):
    """Evaluation input that does not fit together (duplicates under strict mode, routes missing from the XML...)."""


@dataclass(frozen=True)
class Duplicate:
    """A route with several records: every occurrence as ``file#record-position``, and the one kept."""

    route: str
    occurrences: tuple[str, ...]
    kept: str


@dataclass
class ResultSet:
    """The de-duplicated records of one agent and where they came from."""

    name: str
    sources: list[Path]
    records: list[RouteRecord]
    #: Where each kept record came from (``file#position``), parallel to ``records``.
    origins: list[str] = field(default_factory=list)
    duplicates: list[Duplicate] = field(default_factory=list)
    #: Files of a results directory that were not Leaderboard JSON, with the reason.
    skipped_files: list[tuple[Path, str]] = field(default_factory=list)
    #: Number of records read before de-duplication.
    records_read: int = 0


def _natural_key(path: Path) -> list[object]:
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", path.name)]


def expand_result_argument(argument: str | Path) -> tuple[list[Path], bool]:
    """Files named by one RESULT argument: a file, a directory of ``*.json``, or several joined by '+'.

    Returns the files and whether any came from a directory (whose non-Leaderboard files are skipped).
    """
    files: list[Path] = []
    from_directory = False
    for part in str(argument).split("+"):
        if not part:
            continue
        path = Path(part)
        if path.is_dir():
            found = sorted((p for p in path.glob("*.json") if p.name not in _DIRECTORY_SKIP), key=_natural_key)
            if not found:
                raise EvalInputError(path, "directory holds no result *.json file (merged.json is skipped)")
            files.extend(found)
            from_directory = True
        elif path.is_file():
            files.append(path)
        else:
            raise EvalInputError(path, "no such result file or directory")
    if not files:
        raise EvalInputError(Path(str(argument)), "names no result file")
    return files, from_directory


def default_name(argument: str | Path) -> str:
    """Column label of a RESULT argument: the directory name, or the file stem."""
    first = Path(str(argument).split("+")[0])
    return first.name if first.is_dir() else first.stem


def _route_label(record: RouteRecord) -> str:
    """The XML route id, with the repetition when it is not the first (``7``, ``7 rep 1``)."""
    return record.route_number if record.repetition == 0 else f"{record.route_number} rep {record.repetition}"


def load_result_set(
    files: Sequence[Path], name: str, strict: bool = False, skip_unreadable: bool = False
) -> ResultSet:
    """Read and de-duplicate the records of ``files`` (last wins; ``strict`` raises on duplicates).

    ``skip_unreadable`` skips files that are not Leaderboard JSON (used for directories) instead of raising.
    """
    kept: dict[str, tuple[RouteRecord, str]] = {}
    occurrences: dict[str, list[str]] = {}
    sources: list[Path] = []
    skipped: list[tuple[Path, str]] = []
    read = 0
    for path in files:
        try:
            results = read_results(path)
        except LeaderboardFormatError as exc:
            if not skip_unreadable:
                raise
            log.warning("skipping %s: %s", path, exc.problem)
            skipped.append((path, exc.problem))
            continue
        sources.append(path)
        for position, record in enumerate(results.records):
            origin = f"{path}#{position}"
            # One record per route repetition: RouteScenario_7_rep0 and _rep1 are two runs, not duplicates.
            key = record.route_id
            occurrences.setdefault(key, []).append(f"{origin} ({record.route_id})")
            # Re-inserting moves nothing: the route keeps its first position, its value becomes the last record.
            kept[key] = (record, origin)
            read += 1
    if not sources:
        raise EvalInputError(files[0] if files else Path(name), "none of the files is Leaderboard result JSON")
    duplicates = [
        Duplicate(route=_route_label(kept[key][0]), occurrences=tuple(where), kept=kept[key][1])
        for key, where in occurrences.items()
        if len(where) > 1
    ]
    if duplicates:
        first = duplicates[0]
        summary = f"{len(duplicates)} route(s) have more than one record, e.g. route {first.route}: " + "; ".join(
            first.occurrences
        )
        if strict:
            raise EvalInputError(sources[0], summary + " (strict mode: remove the duplicates or drop --strict)")
        log.warning("%s: %s; keeping the last record of each", name, summary)
    return ResultSet(
        name=name,
        sources=sources,
        records=[record for record, _ in kept.values()],
        origins=[origin for _, origin in kept.values()],
        duplicates=duplicates,
        skipped_files=skipped,
        records_read=read,
    )


def load_result_argument(argument: str | Path, name: str | None = None, strict: bool = False) -> ResultSet:
    """Read one RESULT argument (file, directory or ``a.json+b.json``) as a result set."""
    files, from_directory = expand_result_argument(argument)
    return load_result_set(files, name or default_name(argument), strict=strict, skip_unreadable=from_directory)
