"""Progress of a fit on the terminal: a rich progress bar on a TTY, plain lines when piped.

Each stage is shown with its own counter and the quantity it minimises, named as in the
result JSON: the start fits, DE/PSO and the L-BFGS polish minimise the *objective* (the
paper's distance plus the far-field term, ``info.objective``); a finished degree reports the
paper's *distance* (``measures.distance``), which is lower than the objective when the term is
on.
"""

from __future__ import annotations

import sys
import time
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    from rich.progress import Progress as Bar
    from rich.progress import TaskID

__all__ = ["Progress", "progress_mode"]

STAGES = {"de": "DE", "pso": "PSO", "polish": "L-BFGS polish"}


def progress_mode(quiet: bool, stream: TextIO | None = None) -> str:
    """'off' with --quiet, 'bar' on a terminal, 'lines' when stderr is piped or a file."""
    stream = sys.stderr if stream is None else stream
    if quiet:
        return "off"
    return "bar" if stream.isatty() else "lines"


class Progress:
    """Receives ``fit_adaptive``'s progress events and shows them."""

    def __init__(self, mode: str, iterations: int | None = None, polish_iterations: int | None = None,
                 stream: TextIO | None = None) -> None:
        self.mode = mode
        self.stream = sys.stderr if stream is None else stream
        self.totals = {"de": iterations, "pso": iterations, "polish": polish_iterations}
        self._bar: Bar | None = None
        self._task: TaskID | None = None
        self._stage = None
        self._degree = None
        self._last = 0.0
        self._normals_said = False
        self._normals_held: list[dict] = []

    # -- events ------------------------------------------------------------------------------
    def __call__(self, event: dict) -> None:
        if self.mode == "off":
            return
        kind = event.get("event")
        if kind == "degree_start":
            self._degree, self._stage = event["degree"], None
            self._line(f"degree {event['degree']}: fitting")
        elif kind == "normals":
            self._normals(event)
        elif kind == "iteration":
            self._iteration(event)
        elif kind == "topology_repair":
            self._close_bar()
            self._degree, self._stage = event["degree"], None
            if "matches" not in event:
                self._line(f"degree {event['degree']}: {event['mismatch']}; repairing it to the data's topology")
            elif event["matches"]:
                self._line(f"degree {event['degree']}: repaired to the data's topology, F-score "
                           f"{event['f_score']:.3f} ({event['seconds']:.1f} s)")
            else:
                self._line(f"degree {event['degree']}: the repair did not reach the data's topology within the "
                           f"rule's tolerance ({event['seconds']:.1f} s)")
        elif kind == "every_point":
            self._close_bar()
            self._degree, self._stage = event["degree"], None
            self._line(f"degree {event['degree']}: measuring on all {event['n_points']:,} points "
                       f"(the degrees were fitted on {event['fit_points']:,} of them spread evenly)")
        elif kind in ("mesh_points", "local_surface", "weights_variant", "normals_variant", "layers", "reorient"):
            self._close_bar()
            self._degree, self._stage = None, None
            self._line(event["message"])
        elif kind == "degree_done":
            self._close_bar()
            q = event.get("quality")
            shape = (f", F-score {q['f_score']:.3f} (precision {q['precision']:.3f}, recall {q['recall']:.3f})"
                     if q else "")
            attempts = event.get("cleanup") or []
            polishes = sum(a["target"] != "another solution" for a in attempts)
            others = len(attempts) - polishes
            repairs = (f", {polishes} repair polish(es)" if polishes else "") + \
                (f", {others} other solution(s) of the search measured" if others else "")
            self._line(f"degree {event['degree']}: distance {event['distance']:.5f}, smoothness "
                       f"{event['smoothness']:.4f}, dissimilarity {event['dissimilarity']:.5f}{shape}{repairs} "
                       f"({event['seconds']:.1f} s)")

    def close(self) -> None:
        self._close_bar()

    # -- internals -------------------------------------------------------------------------------
    def _normals(self, event: dict) -> None:
        """The stages of the normal estimation, once it has taken a second: small clouds stay quiet."""
        if event["message"] == "done":
            if self._normals_said:
                self._line(f"normals: done in {event['seconds']:.1f} s")
            self._normals_held.clear()
            return
        self._normals_held.append(event)
        if event["seconds"] >= 1.0:
            for held in self._normals_held:
                self._line(f"normals: {held['message']} ({held['seconds']:.1f} s)")
            self._normals_held.clear()
            self._normals_said = True

    def _iteration(self, event: dict) -> None:
        stage = event.get("stage", "de")
        if stage != self._stage:
            self._close_bar()
            self._stage = stage
            self._open(stage)
        if self.mode == "bar" and self._bar is not None:
            self._bar.update(self._bar_task(), completed=event.get("nit", 0),
                             objective=f"{event.get('fun', float('nan')):.5f}")
            return
        now = time.monotonic()
        if now - self._last >= 5.0:  # piped: a line every few seconds at most
            self._last = now
            total = self.totals.get(stage)
            count = f"{event.get('nit', '?')}/{total}" if total else f"{event.get('nit', '?')}"
            self._line(f"degree {self._degree}: {STAGES.get(stage, stage)} iteration {count}, objective "
                       f"{event.get('fun', float('nan')):.5f}")

    def _open(self, stage: str) -> None:
        if self.mode != "bar":
            self._line(f"degree {self._degree}: {STAGES.get(stage, stage)}")
            self._last = time.monotonic()
            return
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn
        from rich.progress import Progress as Bar

        self._bar = Bar(TextColumn("degree {task.fields[degree]}: {task.description}"), BarColumn(),
                        MofNCompleteColumn(), TextColumn("objective {task.fields[objective]}"), TimeElapsedColumn(),
                        console=Console(file=self.stream), transient=True)
        self._bar.start()
        self._task = self._bar.add_task(STAGES.get(stage, stage), total=self.totals.get(stage),
                                        degree=self._degree, objective="…")

    def _bar_task(self) -> TaskID:
        """The bar's task, which an open bar always has (``_open`` sets both)."""
        if self._task is None:
            raise RuntimeError("Progress: a bar without its task")  # a bug of ipfit's
        return self._task

    def _close_bar(self) -> None:
        if self._bar is not None:
            self._bar.stop()
            self._bar = None

    def _line(self, text: str) -> None:
        if self._bar is not None:
            self._bar.console.print(text)
        else:
            self.stream.write(text + "\n")
            self.stream.flush()
