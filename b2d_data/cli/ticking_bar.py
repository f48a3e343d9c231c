"""A progress bar for long runs that is redrawn every second, not only when the run reports.

Collections and evaluations report a few times a second at best, and not at all while a route sets up; a ticker
thread redraws the bar every second so that its clock (and the ETA counted down since the last report) keeps moving.
Subclasses say what the bar counts (:meth:`TickingBar.count`) and what follows the clock (:meth:`TickingBar.text`).
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable

from tqdm import tqdm


class TickingBar:
    """A tqdm bar on stderr with a one-second ticker; ``enabled=False`` keeps the state but draws nothing."""

    BAR_FORMAT = "{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt}, {elapsed} elapsed{postfix}"

    def __init__(self, desc: str, enabled: bool, clock: Callable[[], float] = time.monotonic) -> None:
        self.desc, self.enabled, self.clock = desc, enabled, clock
        self.bar: tqdm | None = None
        self._last_at = 0.0
        self._lock = threading.RLock()  # re-entrant: close() may run from an interrupt inside a redraw
        self._stop = threading.Event()
        self._ticker: threading.Thread | None = None

    def count(self) -> int:
        """How much is done (the bar's ``n``)."""
        raise NotImplementedError

    def text(self) -> str:
        """What follows the clock."""
        raise NotImplementedError

    def since_report(self) -> float:
        """Seconds since the last report (for counting an ETA down)."""
        return self.clock() - self._last_at

    def reported(self, total: int) -> None:
        """A report arrived (its state is already stored): draw, starting the bar and its ticker on the first."""
        with self._lock:
            self._last_at = self.clock()
            if not self.enabled:
                return
            if self.bar is None:
                self.bar = tqdm(total=total, initial=self.count(), desc=self.desc, dynamic_ncols=True,
                                bar_format=self.BAR_FORMAT, file=sys.stderr)  # fmt: skip
                self._ticker = threading.Thread(target=self._tick, name=f"{self.desc}-progress", daemon=True)
                self._ticker.start()
            self._draw()

    def write(self, line: str) -> None:
        """A line above the bar (or plain stderr before it exists)."""
        if self.bar is not None:
            tqdm.write(line, file=sys.stderr)
        else:
            print(line, file=sys.stderr)

    def _draw(self) -> None:
        assert self.bar is not None
        self.bar.n = self.count()
        self.bar.set_postfix_str(self.text(), refresh=False)
        self.bar.refresh()

    def _tick(self) -> None:
        while not self._stop.wait(1.0):
            with self._lock:
                if self.bar is not None:
                    self._draw()

    def close(self) -> None:
        """Stop the ticker and leave the last line on the terminal."""
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join(timeout=5)
        with self._lock:
            if self.bar is not None:
                self.bar.close()
