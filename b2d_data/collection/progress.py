"""Live progress of a collection: frame reports from the route jobs and the driver's view of the whole run.

A job reports how many frames of its route it has recorded (and the route completion) through :func:`report_frames`,
at most every :data:`FRAME_REPORT_SECONDS`; where the report goes is set per process by :func:`set_frame_sink` (a
queue to the driver for pool workers, a Ray actor for Ray tasks, the driver itself inline). The driver folds the
reports into a :class:`ProgressState`, which estimates the frames a route takes and from them the time left.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

log = logging.getLogger(__name__)

#: Shortest interval between two frame reports of one route job (the first frame is always reported).
FRAME_REPORT_SECONDS = 0.5
#: Longest interval between two progress callbacks of the driver while routes run.
REFRESH_SECONDS = 1.0
#: Route completion (percent) from which a route's own frame count extrapolates to its length.
MIN_COMPLETION_FOR_ESTIMATE = 5.0


@dataclass(frozen=True)
class FrameReport:
    """One route job's frames so far (recorded ticks, whether or not its clip is still kept)."""

    route_id: str
    clip: str
    frames: int
    #: Route completion so far, percent.
    completion: float = 0.0


FrameSink = Callable[[FrameReport], None]

_sink: FrameSink | None = None


def set_frame_sink(sink: FrameSink | None) -> FrameSink | None:
    """Send this process's frame reports to ``sink`` (None: drop them); returns the previous sink."""
    global _sink
    previous, _sink = _sink, sink
    return previous


class FrameReporter:
    """A route job's frame callback side: forwards its frame count to the process's sink, throttled."""

    def __init__(
        self,
        route_id: str,
        clip: str,
        interval: float = FRAME_REPORT_SECONDS,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.route_id, self.clip, self.interval, self.clock = route_id, clip, interval, clock
        self._last: float | None = None

    def __call__(self, frames: int, completion: float) -> None:
        """Report ``frames`` recorded so far at ``completion`` percent (dropped when reported too recently)."""
        sink = _sink
        if sink is None:
            return
        now = self.clock()
        if self._last is not None and now - self._last < self.interval:
            return
        self._last = now
        try:
            sink(FrameReport(self.route_id, self.clip, int(frames), float(completion)))
        except Exception:  # a lost progress report must never fail a route
            log.debug("route %s: a frame report was lost", self.route_id, exc_info=True)


def frames_of(ticks: int, frames: int, record_every: int = 2) -> int:
    """Frames a finished route recorded: its clip's count, else its recorded ticks (physics-only runs)."""
    return max(int(frames), (int(ticks) + record_every - 1) // record_every)


@dataclass
class RouteProgress:
    """A running route as the driver sees it."""

    route_id: str
    scenario: str
    clip: str = ""
    frames: int = 0
    completion: float = 0.0

    def expected_frames(self, typical: float | None) -> float | None:
        """This route's frames at its end: extrapolated from its completion, else the typical route's."""
        if self.completion >= MIN_COMPLETION_FOR_ESTIMATE and self.frames > 0:
            own = self.frames * 100.0 / min(self.completion, 100.0)
            return max(own, float(self.frames))
        return None if typical is None else max(typical, float(self.frames))

    def label(self) -> str:
        """``Route1711 Accident`` (the clip name once known carries the town and weather too)."""
        return f"Route{self.route_id} {self.scenario}"


@dataclass
class ProgressState:
    """The driver's running totals: clips, attempts, frames of finished and running routes, and the ETA."""

    requested: int
    clips: int = 0
    attempts: int = 0
    failed: int = 0
    clock: Callable[[], float] = time.monotonic
    running: dict[str, RouteProgress] = field(default_factory=dict)
    #: Frames of every finished route seen (earlier sessions included): the typical route length in frames.
    finished_frames: list[int] = field(default_factory=list)
    #: Frames recorded in this session by routes that finished (the rate counts only this session's work).
    frames_done: int = 0
    attempts_this_run: int = 0
    clips_this_run: int = 0

    def __post_init__(self) -> None:
        self.started = self.clock()
        # (time, frames) at the first frame report: the frame rate is measured from there, leaving out the one-off
        # start (town generation, HD map) that would otherwise inflate the first ETAs.
        self._rate_origin: tuple[float, int] | None = None

    def elapsed(self) -> float:
        """Seconds since this session started."""
        return self.clock() - self.started

    def route_started(self, route_id: str, scenario: str) -> None:
        """A route was launched."""
        self.running[str(route_id)] = RouteProgress(str(route_id), scenario)

    def frames_reported(self, report: FrameReport) -> None:
        """A job's frame report (late reports of finished routes are ignored)."""
        route = self.running.get(report.route_id)
        if route is None:
            return
        route.clip = report.clip or route.clip
        route.frames = max(route.frames, report.frames)
        route.completion = max(route.completion, report.completion)
        if self._rate_origin is None:
            self._rate_origin = (self.clock(), self.frames_this_run())

    def route_finished(self, route_id: str, frames: int, clip: bool) -> None:
        """A route's attempt ended with ``frames`` recorded; ``clip`` when it made a clip."""
        if self._rate_origin is None:
            self._rate_origin = (self.clock(), self.frames_this_run())
        route = self.running.pop(str(route_id), None)
        frames = max(frames, route.frames if route is not None else 0)
        self.finished_frames.append(frames)
        self.frames_done += frames
        self.attempts += 1
        self.attempts_this_run += 1
        if clip:
            self.clips += 1
            self.clips_this_run += 1
        else:
            self.failed += 1

    def typical_frames(self) -> float | None:
        """Frames of a typical route: the mean of finished routes, else of the running routes' extrapolations."""
        if self.finished_frames:
            return sum(self.finished_frames) / len(self.finished_frames)
        own = [e for r in self.running.values() if (e := r.expected_frames(None)) is not None]
        return sum(own) / len(own) if own else None

    def frames_this_run(self) -> int:
        """Frames recorded in this session so far, running routes included."""
        return self.frames_done + sum(r.frames for r in self.running.values())

    def frame_rate(self) -> float | None:
        """Frames per second of this session since its first frame report (None before two reports)."""
        if self._rate_origin is None:
            return None
        since, frames_then = self._rate_origin
        seconds, frames = self.clock() - since, self.frames_this_run() - frames_then
        return frames / seconds if seconds > 0 and frames > 0 else None

    def eta(self) -> float | None:
        """Seconds left: the frames still to record over this session's frame rate (None before any estimate)."""
        typical = self.typical_frames()
        rate = self.frame_rate()
        if typical is None or rate is None:
            return None
        left = sum(max((r.expected_frames(typical) or typical) - r.frames, 0.0) for r in self.running.values())
        clips_needed = max(self.requested - self.clips - len(self.running), 0)
        # Failed attempts cost frames too: each clip still needed takes as many attempts as the clips so far did.
        attempts_per_clip = self.attempts / self.clips if self.clips else 1.0
        left += clips_needed * attempts_per_clip * typical
        return left / rate

    def routes(self) -> tuple[RouteProgress, ...]:
        """Copies of the running routes, in launch order."""
        return tuple(RouteProgress(r.route_id, r.scenario, r.clip, r.frames, r.completion)
                     for r in self.running.values())  # fmt: skip


def format_seconds(seconds: float | None) -> str:
    """``1:02:03`` / ``02:03`` like tqdm's clock, ``?`` when unknown."""
    if seconds is None or not math.isfinite(seconds):
        return "?"
    total = round(max(seconds, 0.0))
    hours, rest = divmod(total, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes:02d}:{secs:02d}"


def describe_routes(routes: Sequence[RouteProgress], typical: float | None, limit: int = 3) -> str:
    """``Route1711 Accident 123/~310 fr`` for each running route (the first ``limit``, then ``+N more``)."""
    parts = []
    for route in routes[:limit]:
        expected = route.expected_frames(typical)
        total = f"/~{expected:.0f}" if expected is not None else ""
        parts.append(f"{route.label()} {route.frames}{total} fr")
    if len(routes) > limit:
        parts.append(f"+{len(routes) - limit} more")
    return "; ".join(parts)
